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
#ifndef dcvRateControl_h
#define dcvRateControl_h

#include "DelaunayCompressionExport.h"
#include "dcvRefinementEngine.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

/** \file dcvRateControl.h
 * Rate control: how many points, and which quantization step, for a bit budget (ApproximateToBudget)
 * or a quality target (ApproximateToQuality). Both run the method once and then adjust the point count
 * on the same tetrahedralization (RefinementEngine::Resize), which costs a fraction of a run.
 * \ingroup DelaunayCompression
 */
namespace dcv
{

/** The tolerances and model constants of rate control, named once. */
namespace RateControl
{
/** A budget is met when the payload fills at least this share of it (and never more than all of it). */
constexpr double MinimumFill = 0.97;
/** Point-count corrections aim midway in [MinimumFill, 1], so that the size law's noise rarely leaves
 * the band. */
constexpr double TargetFill = 0.985;
/** First point count from n (log2(voxels / n) + c) = budget bits. With decimation c = 6.5 starts a few
 * percent above the budget, and decimating down measured better than starting at the final count
 * (ironprot, 556 points, mode best: 27.66 against 27.39 dB). */
constexpr double BitsPerPointOffsetDecimating = 6.5;
/** Without decimation (silva) decimating without refinement back measured worse (24.58 against
 * 25.85 dB), so c = 9.5 starts below and refinement continues upwards: exactly the method run at the
 * final count. */
constexpr double BitsPerPointOffsetRefining = 9.5;
/** Corrections of the count before only decimation is used to get under the budget. */
constexpr unsigned MaximumCorrections = 6;
/** Progress is reported in units of work, an insertion being 1, from the times of norm-256's stages at
 * 0.03125 and 0.25 bpv: a removal costs RemovalWork, a correction of the count (a least-squares solve,
 * its rescan and an encode) CorrectionWork per point, a step trial (a rescan and an encode)
 * StepTrialWork per point. A fit is expected to take 1 + CorrectionsPerOctave x |log2(final / current
 * count)| corrections (2 at 0.03125 bpv, 5 at 0.25 on norm-256). The work left is estimated again after
 * each encode; the fraction shown never goes back. */
constexpr double RemovalWork = RefinementEngine::RemovalWork;
constexpr double CorrectionWork = 0.25;
constexpr double StepTrialWork = 0.1;
constexpr double CorrectionsPerOctave = 2.5;
/** A competitor's squared error abandons the points when theirs, carried to the target size (error ~
 * size^-4 below it, size^-0.5 above: optimistic, see ApproximateToBudget) and divided by this, is
 * still above it: after the first refinement, where decimation and least squares then lowered the
 * error at the same count by at most 1.8 times (2.5 dB; ../shared/data at 0.03125 to 0.25 bpv, mode
 * best) ... */
constexpr double AbandonAfterRefinement = 2.5;
/** ... and after the first run when its size is within this share of the target, where the fit and the
 * step choice then lowered the error by at most 1.07 times (0.3 dB). The margins also cover the bytes
 * the points leave to a residual layer (+0.3 dB at most). */
constexpr double AbandonNearTarget = 0.9;
constexpr double AbandonAfterFirstRun = 1.2;
/** ... and after each correction of the first fit whose size is within AbandonNearTarget of the target,
 * where the rest of the fit and the step choice lowered the error by at most 1.50 times (ct-avm at 0.25
 * bpv; 1.36 at 0.99 of the target, ct-avm at 0.125; docs/profile.md). A correction refines or decimates
 * without the schedule, so its state is further from the final one than the first run's. */
constexpr double AbandonDuringFit = 1.6;
/** ... and after the step trials, where the best step's error predicted at the target size is within
 * 4.3% of the final one on every dev run that went on (the second fit and the points' own residual
 * layer gained at most that: ct-avm at 0.125 bpv, 0.4446 -> 0.4265 of the competitor's error; they lost
 * up to 2.4% as well), and every run that stood above this ratio there ended with the competitor
 * (docs/profile.md: norm-256 at 0.03125 to 0.125 bpv, head-mr, flair-mr, ...).
 * What it spares is the second fit and the points' layer trial: norm-256 at 0.03125 bpv 1.5 s of 8.4. */
constexpr double AbandonAfterSteps = 1.06;
/** The steps tried, as multiples of DefaultQuantizationStep (measured at 0.03125 to 0.25 bpv on
 * ../shared/data: each of the three wins somewhere). */
inline const std::vector<double> &
StepMultiples()
{
  static const std::vector<double> multiples{ 1.0, 2.0, 4.0 };
  return multiples;
}
/** FittedCount from one state: the bits a point fall this many times as fast with the count as they do
 * over an arbitrary subset of the voxels (log2(voxels / count) + c), as measured between the first run
 * and the fitted count on the 40 dev runs (docs/profile.md): median 1.55, 1.07 to
 * 2.25 over the 12 runs whose count moved by more than 10%. */
constexpr double SubsetLawFactor = 1.55;
/** Quality target: the count is accepted when within this share of the smallest count that reaches it. */
constexpr double QualityCountTolerance = 0.01;
/** Quality target: at most this many Resize() steps before giving up. */
constexpr unsigned MaximumQualitySteps = 40;
} // namespace RateControl

/** The smallest whole .dcv file a bit budget of `budgetBytes` promises, RateControl::MinimumFill of it (a
 * file never exceeds the budget), unless the approximation becomes exact first. The points' payload is
 * fitted to it (ApproximateToBudget); a residual layer that takes the budget is filled to it
 * (ResidualSearch::Fill), past the steps in which its codestream grows at a few hundred bytes. */
inline std::size_t
MinimumFileBytes(std::size_t budgetBytes)
{
  return std::size_t(std::ceil(RateControl::MinimumFill * double(budgetBytes)));
}

/** The point count whose payload the size law puts at `target` bytes, from the (count, size) states of
 * one fit (the last is the current one; all with one quantization step): between the last two states
 * of different counts, size ~ count^beta with beta measured there; from one state, beta = 1 -
 * SubsetLawFactor / (ln 2 x bits per point), SubsetLawFactor times the fall of the law of an arbitrary
 * subset of `voxels` (bits per point = log2(voxels / count) + c, whose local exponent is 1 - 1 / (ln 2 x
 * bits per point)). beta is kept in [0.5, 1.5]. Rate control uses it to
 * estimate the work left for its progress; its fit keeps the bits-per-point correction (beta 1), since
 * fits by this law, quicker on norm-256 at 0.25 bpv (beta near 0.65 there), gave other meshes and
 * 0.004 to 0.07 dB less on 4 to 7 of the 40 dev runs (docs/profile.md). */
DelaunayCompression_EXPORT double
FittedCount(const std::vector<std::pair<double, double>> & states, double voxels, double target);

/** The default quantization step: 1/64 of the PSNR peak (4 for 8-bit data), a whole number for
 * integer data. */
inline double
DefaultQuantizationStep(double peak, bool integer)
{
  return integer ? std::max(1.0, std::round(peak / 64.0)) : peak / 64.0;
}

/** The step for a quality target of `squaredError` over `voxels` voxels: the default step, made smaller
 * when uniform quantization alone (mean squared error step^2 / 12 at the vertices) would cost more than
 * a quarter of the allowed mean squared error. */
inline double
QualityQuantizationStep(double peak, bool integer, double squaredError, double voxels)
{
  const double bound = std::sqrt(3.0 * squaredError / voxels);
  const double step = std::min(DefaultQuantizationStep(peak, integer), bound);
  return integer ? std::max(1.0, std::floor(step)) : std::max(step, peak * 1e-9);
}

/** What rate control did. */
struct BudgetResult
{
  std::vector<uint8_t> payload;            // EncodePayload() of the engine's final approximation
  std::size_t          firstCount;         // the point count the method ran with
  unsigned             adjustments;        // Resize() steps after it
  double               step;               // the quantization step of the payload
  bool                 abandoned{ false }; // the points cannot beat the competitor (no payload)
};

/** Approximates with the payload of best quality that fits `payloadBytes` (at least MinimumFill of it
 * unless the approximation becomes exact first), running the method once. `competitor`: the squared error
 * another coding reaches in the same bytes (asked for once, from the end of the first refinement on, so
 * that it can be computed meanwhile on another thread; none: infinity); the points are abandoned
 * (BudgetResult::abandoned, no payload, the engine left where it was stopped, possibly inside the
 * schedule) as soon as an optimistic estimate of theirs stays above it (AbandonAfterRefinement,
 * AbandonAfterFirstRun, AbandonAfterSteps). `competitorReady`, where given, says whether `competitor`
 * would answer at once: while it would not, the method goes on, and the check on the first refinement's
 * state is made when it would, at a progress report of the schedule or after it (the same decision
 * as waiting for it). `competitorBound`, where given, answers at once with a squared error the
 * competitor's is at most (its best so far while it is being made, infinity before): until the
 * competitor is ready, the check on the first refinement's state is also made against it, right after
 * the refinement and at each progress report of the schedule. Where it abandons the points, the check
 * against the competitor would too, later: the same decision, without the rest of the schedule.
 *
 * Point count: the coded size is nearly proportional to the count, at a number of bits per point that
 * grows slowly as points get sparser. So the method runs once, with a count predicted by
 * log2(voxels / n) + c bits per point, and then each measured size predicts the count that fills
 * TargetFill of the budget; the engine reaches it by Resize().
 * Quantization step: the engine's step times each of `stepMultiples` (>= 1) is tried on the fitted
 * mesh (SetQuantizationStep, least squares in modes that have it), its error carried to the budget by
 * the local rate-distortion law measured while fitting; the best is kept and the count fitted again.
 * The engine ends holding exactly the returned payload's approximation; values are q0 + k step.
 * Throws std::length_error when even the 8 corners do not fit. */
DelaunayCompression_EXPORT BudgetResult
ApproximateToBudget(RefinementEngine & engine, std::size_t payloadBytes, double q0,
                    const std::vector<double> &                stepMultiples = { 1.0 },
                    const RefinementEngine::ProgressFunction & progress = RefinementEngine::ProgressFunction(),
                    const std::function<double()> & competitor = {}, const std::function<bool()> & competitorReady = {},
                    const std::function<double()> & competitorBound = {});

/** The squared error a decoder's image will have for the engine's current approximation. */
using DecodedErrorFunction = std::function<double(const RefinementEngine &)>;

/** Approximates with the fewest points whose decoded squared error (`decodedError`) is at most
 * `squaredError`, at the engine's quantization step: the method runs once at a predicted count, then
 * Resize() steps follow the law error ~ count^-b (b measured) until the smallest passing count is
 * known within QualityCountTolerance. Throws std::range_error when no count reaches the target (the
 * message gives the best error reached). */
DelaunayCompression_EXPORT BudgetResult
ApproximateToQuality(RefinementEngine & engine, double squaredError, double q0,
                     const DecodedErrorFunction &               decodedError,
                     const RefinementEngine::ProgressFunction & progress = RefinementEngine::ProgressFunction());

} // namespace dcv

#endif
