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
#ifndef dcvInterSliceWavelet_h
#define dcvInterSliceWavelet_h

#include "DelaunayCompressionExport.h"
#include "dcvFileFormat.h"

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

/** \file dcvInterSliceWavelet.h
 * The inter-slice wavelet of a residual layer (docs/format.md): JPEG 2000's reversible 5/3 lifting along
 * z, applied `levels` times to the low band, before the slices are coded in 2D. Where neighbouring slices
 * are alike (near-isotropic volumes) the high bands are nearly empty, which per-slice coding cannot
 * exploit (avg152t1 at 0.125 bpv: 33.6 dB with 4 levels, 22.5 dB without). Each band is then weighted by
 * its synthesis norm so that JPEG 2000's rate allocation, which knows nothing of the z transform, trades
 * the same squared error per byte in every band; the weights are at least 1 and rounded, so the whole
 * forward transform is exactly invertible.
 * \ingroup DelaunayCompression
 */
namespace dcv
{

/** Most levels a file may give (each level halves the low band; it needs two slices or more). */
constexpr int32_t MaximumInterSliceLevels = 6;

/** The weights of the bands, in 1/4096: the 5/3 synthesis norm of the band over that of the finest high
 * band. LowBandWeight[l - 1] is the low band after l levels, HighBandWeight[k - 1] the high band of
 * level k (1 the finest). */
constexpr std::array<int64_t, MaximumInterSliceLevels> LowBandWeight{ 5917, 8012, 11201, 15795, 22321, 31560 };
constexpr std::array<int64_t, MaximumInterSliceLevels> HighBandWeight{ 4096, 4639, 6084, 8428, 11856, 16744 };

/** The most levels `slices` slices take: every level's input holds two slices or more (0 for one slice),
 * at most MaximumInterSliceLevels. */
DelaunayCompression_EXPORT int32_t
InterSliceLevels(int32_t slices);

/** Forward transform of samples laid out as the grid (x fastest), in place: the slices become the low
 * band after `levels` levels (slices 0 to ceil(z / 2^levels) - 1), then the high bands from the coarsest
 * to the finest (level k at slices ceil(z / 2^k) to ceil(z / 2^(k-1)) - 1), each sample multiplied by its
 * band's weight and rounded. 0 levels: unchanged. Throws std::invalid_argument past InterSliceLevels(z). */
DelaunayCompression_EXPORT void
ForwardInterSlice(std::vector<int32_t> & samples, const GridSize & grid, int32_t levels);

/** The inverse of ForwardInterSlice, for any samples (a decoded layer): each sample divided by its
 * weight and rounded, then the 5/3 synthesis; results beyond the int32 range are clamped. */
DelaunayCompression_EXPORT void
InverseInterSlice(std::vector<int32_t> & samples, const GridSize & grid, int32_t levels);

/** The same, reading the transformed samples of slice z's row y (x of them) from `source(y, z)` and
 * writing the result to `out` (one per voxel, laid out as the grid): a decoder takes them straight from
 * where they were decoded (a mosaic), without a copy laid out as the grid first. `source` is called from
 * several threads, each row once, and may point into `out` itself. */
DelaunayCompression_EXPORT void
InverseInterSlice(const std::function<const int32_t *(int32_t y, int32_t z)> & source, int32_t * out,
                  const GridSize & grid, int32_t levels);
/** The same, giving each result row to `sink(y, z, row)` (x samples, valid during the call) instead of
 * writing a volume: a caller that only reads the layer once (the encoder's error of a trial) needs no
 * volume of it. `sink` is called from several threads, each row once. */
DelaunayCompression_EXPORT void
InverseInterSlice(const std::function<const int32_t *(int32_t y, int32_t z)> &           source,
                  const std::function<void(int32_t y, int32_t z, const int32_t * row)> & sink, const GridSize & grid,
                  int32_t levels);
/** ForwardInterSlice row by row: `source(y, z, row)` writes slice z's row y (x samples), and the
 * transformed row goes to `sink(y, z, row)`: the encoder computes the samples straight into JPEG 2000's
 * image, without a volume of them laid out as the grid. Both are called from several threads, each row
 * once; all the rows of an image row y are read before any of them is given to `sink`. */
DelaunayCompression_EXPORT void
ForwardInterSlice(const std::function<void(int32_t y, int32_t z, int32_t * row)> &       source,
                  const std::function<void(int32_t y, int32_t z, const int32_t * row)> & sink, const GridSize & grid,
                  int32_t levels);

} // namespace dcv

#endif
