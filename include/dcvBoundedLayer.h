/*=========================================================================
 *
 *  Copyright NumFOCUS
 *
 *  Licensed under the Apache License, Version 2.0 (the "License");
 *  you may not use this file except in compliance with the License.
 *  You may obtain a copy of the License at
 *
 *         http://www.apache.org/licenses/LICENSE-2.0.txt
 *
 *  Unless required by applicable law or agreed to in writing, software
 *  distributed under the License is distributed on an "AS IS" BASIS,
 *  WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
 *  See the License for the specific language governing permissions and
 *  limitations under the License.
 *
 *=========================================================================*/
#ifndef dcvBoundedLayer_h
#define dcvBoundedLayer_h

#include "DelaunayCompressionExport.h"
#include "dcvApproximation.h"

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

/** \file dcvBoundedLayer.h
 * The bounded-error layer (docs/format.md, "Bounded-error layer"): integer samples coded by
 * a 3D predictive coder (a blend of in-slice and across-slice predictors weighted by their recent errors,
 * a bias correction per context, the residual coded with the project's adaptive arithmetic coder in
 * contexts of the local error), each sample within `near` of the encoder's. Over a constant spline and with
 * the file's residual step h, the decoded voxel is q0 + h r: integers with h = 1 and near = E; floats on a
 * lattice of step h, near 4 steps.
 * \ingroup DelaunayCompression
 */
namespace dcv
{

/** What a bounded-error layer states before its coded slabs. */
struct BoundedLayerHeader
{
  /** The bound the file guarantees, in the input's units: every decoded voxel is within it of the input
   * (0: lossless). Informative for readers (`dcv info`); the samples alone decide the voxels. */
  double   maximumError{ 0.0 };
  int32_t  minimum{ 0 };    // the smallest sample
  uint32_t range{ 0 };      // the largest sample minus the smallest
  uint32_t slabSlices{ 0 }; // slices of each independently coded slab (the last may have fewer)
  uint32_t near{ 0 };       // every sample decodes within it of the encoder's (0: without loss)
};

/** The slices of each slab for a grid: about 4 million voxels a slab (so that the slabs of a large volume
 * code on every core), at least 8 slices. Chosen by the grid alone: the file is the same for any number of
 * threads. */
DelaunayCompression_EXPORT uint32_t
BoundedLayerSlabSlices(const GridSize & grid);

/** Codes the samples (laid out as the grid, x fastest), each within `near` (0: without loss; JPEG-LS's
 * near-lossless quantization of the prediction's residual), and replaces them with what the decoder will
 * give; `maximumError` is stored as the bound the file states. Slabs are coded on the current task arena's
 * threads; `progress`, when set, is called from the calling thread with the fraction of slabs done. */
DelaunayCompression_EXPORT std::vector<uint8_t>
EncodeBoundedLayer(int32_t * samples, const GridSize & grid, uint32_t near, double maximumError,
                   const std::function<void(double)> & progress = {});

/** Reads the header of a layer; throws FormatError starting with `name` when it is damaged. */
DelaunayCompression_EXPORT BoundedLayerHeader
ReadBoundedLayerHeader(const std::vector<uint8_t> & layer, const GridSize & grid, const std::string & name);

/** Decodes a layer into its samples; throws FormatError starting with `name` when it is damaged (the
 * decoder reads no byte beyond a slab and refuses a slab that ends early or late). */
DelaunayCompression_EXPORT ResidualSamples
DecodeBoundedLayer(const std::vector<uint8_t> & layer, const GridSize & grid, const std::string & name);

} // namespace dcv

#endif
