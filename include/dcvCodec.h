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
#ifndef dcvCodec_h
#define dcvCodec_h

#include "DelaunayCompressionExport.h"
#include "dcvApproximation.h"
#include "dcvRefinementEngine.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

/** \file dcvCodec.h
 * The payload of a .dcv file (docs/format.md): the positions (dcvPositionCoder.h), then the
 * quantized values, each predicted from the mean of its Delaunay neighbours decoded before it and
 * coded as an adaptive signed residual, all in one arithmetic-coded stream. The decoder rebuilds the
 * tetrahedralization from the positions before it reads the values, and hands it on for rasterizing.
 * \ingroup DelaunayCompression
 */
namespace dcv
{

/** Codes the points and values of `a` (values must be q0 + k q with integer k, |k| < 2^30). */
DelaunayCompression_EXPORT std::vector<uint8_t>
                           EncodePayload(const Approximation & a, double q0, double q);

/** Decodes `count` points and their values, with the tetrahedra over them, ready for Rasterize().
 * Throws FormatError starting with `name` when the payload is truncated or damaged. */
DelaunayCompression_EXPORT Approximation
                           DecodePayload(const std::vector<uint8_t> & payload,
                                         const GridSize &             grid,
                                         uint32_t                     count,
                                         double                       q0,
                                         double                       q,
                                         const std::string &          name);

/** The quantization step dcv compress uses by default: 1/64 of the PSNR peak (4 for 8-bit data),
 * a whole number for integer data. */
inline double
DefaultQuantizationStep(double peak, bool integer)
{
  return integer ? std::max(1.0, std::round(peak / 64.0)) : peak / 64.0;
}

/** What ApproximateToBudget() did. */
struct BudgetResult
{
  std::vector<uint8_t> payload;     // EncodePayload() of the engine's final approximation
  std::size_t          firstCount;  // the point count the method ran with
  unsigned             adjustments; // Resize() steps after it
  double               step;        // the quantization step of the payload
};

/** Rate control: approximates with the payload of best quality that fits `payloadBytes` (at least 97% of
 * it unless the approximation becomes exact first), running the method once.
 *
 * Point count: the coded size is nearly proportional to the count, at a number of bits per point that
 * grows slowly as points get sparser. So the method runs once, with a count predicted by
 * log2(voxels / n) + c bits per point, and then each measured size predicts the count that fills
 * 98.5% of the budget; the engine reaches it by Resize() (decimation or more refinement on the same
 * tetrahedralization, least squares again), which costs a fraction of a run.
 * Quantization step: the engine's step times each of `stepMultiples` (>= 1) is tried on the fitted
 * mesh (SetQuantizationStep, least squares in modes that have it), its error carried to the budget by
 * the local rate-distortion law measured while fitting; the best is kept and the count fitted again.
 * The engine ends holding exactly the returned payload's approximation; values are q0 + k step.
 * Throws std::length_error when even the 8 corners do not fit. */
DelaunayCompression_EXPORT BudgetResult
ApproximateToBudget(RefinementEngine &                         engine,
                    std::size_t                                payloadBytes,
                    double                                     q0,
                    const std::vector<double> &                stepMultiples = { 1.0 },
                    const RefinementEngine::ProgressFunction & progress = RefinementEngine::ProgressFunction());

} // namespace dcv

#endif
