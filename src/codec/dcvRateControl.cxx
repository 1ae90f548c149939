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
#include "dcvRateControl.h"
#include "dcvCodec.h"
#include "dcvMemory.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace dcv
{
using namespace RateControl;

double
FittedCount(const std::vector<std::pair<double, double>> & states, double voxels, double target)
{
  if (states.empty() || !(states.back().first > 0.0) || !(states.back().second > 0.0) || !(target > 0.0))
  {
    throw std::invalid_argument("FittedCount: needs a state with points and bytes, and a target");
  }
  const auto [count, size] = states.back();
  double beta = 0.0;
  for (std::size_t i = states.size() - 1; i-- > 0 && beta == 0.0;)
  {
    const auto [n, s] = states[i];
    if (n != count && n > 0.0 && s > 0.0 && s != size)
    {
      beta = std::log(size / s) / std::log(count / n);
    }
  }
  if (!(beta > 0.0))
  {
    const double bitsPerPoint = size * 8.0 / count;
    beta = bitsPerPoint > 1.0 ? 1.0 - SubsetLawFactor / (std::log(2.0) * bitsPerPoint) : 1.0;
  }
  beta = std::clamp(beta, 0.5, 1.5);
  return std::clamp(count * std::pow(target / size, 1.0 / beta), 8.0, std::max(8.0, voxels));
}

namespace
{
/** The fraction of ApproximateToBudget done, from the units of work done and those estimated to be left
 * (RemovalWork and the others): shown only when it grows. */
class BudgetProgress
{
public:
  explicit BudgetProgress(const RefinementEngine::ProgressFunction & report)
    : m_Report(report)
  {}

  /** A progress function for a stage of `units`, after which `after` units are estimated to be left. */
  RefinementEngine::ProgressFunction
  Stage(double units, double after)
  {
    if (!m_Report)
      return {};
    return [this, units, after](double f) { Show(m_Done + f * units, (1.0 - f) * units + after); };
  }

  /** A stage of `units` is done; `after` units are estimated to be left. */
  void
  Done(double units, double after)
  {
    m_Done += units;
    Show(m_Done, after);
  }

private:
  void
  Show(double done, double left)
  {
    // Short of 1 until the end (progress(1.0)): the estimate may see nothing left before the last step.
    const double f = std::clamp(done / std::max(1.0, done + left), 0.0, 0.99);
    if (m_Report && f > m_Shown)
    {
      m_Shown = f;
      m_Report(f);
    }
  }

  const RefinementEngine::ProgressFunction & m_Report;
  double                                     m_Done{ 0.0 };
  double                                     m_Shown{ 0.0 };
};
} // namespace

BudgetResult
ApproximateToBudget(RefinementEngine & engine, std::size_t payloadBytes, double q0,
                    const std::vector<double> & stepMultiples, const RefinementEngine::ProgressFunction & progress,
                    const std::function<double()> & competitor, const std::function<bool()> & competitorReady,
                    const std::function<double()> & competitorBound)
{
  const double step = engine.GetParameters().quantizationStep;
  if (!(step > 0.0) || stepMultiples.empty() ||
      std::any_of(stepMultiples.begin(), stepMultiples.end(), [](double m) { return !(m >= 1.0); }))
  {
    throw std::invalid_argument("ApproximateToBudget: needs a quantization step and step multiples >= 1");
  }
  const double budget = double(payloadBytes);
  const double voxels = double(engine.GetGrid().NumberOfVoxels());
  // First count: solve n (log2(voxels / n) + c) = 8 budget by a few fixed-point steps.
  const bool   decimates = engine.GetParameters().decimation;
  const double c = decimates ? BitsPerPointOffsetDecimating : BitsPerPointOffsetRefining;
  double       n = std::max(8.0, budget * 8.0 / 16.0);
  for (int i = 0; i < 20; ++i)
  {
    n = std::clamp(budget * 8.0 / (std::log2(std::max(1.0, voxels / n)) + c), 8.0, voxels);
  }
  BudgetResult result{ {}, std::size_t(n), 0, step };
  // (size, squared error) of encoded states.
  std::vector<std::pair<double, double>> states;
  auto                                   encode = [&] {
    // The pages the last stage freed (a rescan's, the least squares') go back before the mesh is coded,
    // the encoder's peak: about 65,000 KiB of them at norm-256's last steps at 0.25 bpv.
    ReturnFreedMemory();
    result.payload = EncodePayload(engine.GetApproximation(), q0, engine.GetParameters().quantizationStep, true);
    states.emplace_back(double(result.payload.size()), engine.GetSquaredError());
  };

  // An optimistic estimate of the error at the target size: carried from a measured state by
  // error ~ size^-4 below the target and size^-0.5 above it. Laws measured while fitting are near
  // size^-1, but a run far below the target may gain much more from the count and the step together
  // (ct-avm at 0.25 bpv: from 73% of the target, 5.6 times less error).
  auto carried = [&](double error, double size) {
    const double ratio = size / (TargetFill * budget);
    return error * (ratio < 1.0 ? std::pow(ratio, 4.0) : std::sqrt(ratio));
  };
  // Work left after an encoded state of `count` points (RemovalWork and the others), the size law
  // predicting the final count from the fit's states; with the step trials and a correction after them
  // while they are to come. Before the first encode the first count is taken for the final one.
  const double trials = double(stepMultiples.size() - 1);
  auto         workLeft = [&](const std::vector<std::pair<double, double>> & fitted, bool stepsToCome) {
    const double count = fitted.empty() ? double(result.firstCount) : fitted.back().first;
    const double size = fitted.empty() ? TargetFill * budget : fitted.back().second;
    // (An estimate only: where the law has nothing to go on, an empty payload or budget, the count stays.)
    const bool   law = !fitted.empty() && count > 0.0 && size > 0.0 && budget > 0.0;
    const double final = law ? FittedCount(fitted, voxels, TargetFill * budget) : count;
    double       work = 0.0;
    if (!(size <= budget && size >= MinimumFill * budget))
    {
      work += std::abs(final - count) * (final > count ? 1.0 : RemovalWork) +
              (1.0 + CorrectionsPerOctave * std::abs(std::log2(final / count))) * CorrectionWork * final;
    }
    if (stepsToCome && trials > 0.0)
      work += (trials + 1.0) * StepTrialWork * final + CorrectionWork * final;
    return work;
  };
  // The first run: the refinement, the schedule of removals and insertions back (k = n/2, n/4, ...:
  // about n of each), a solve and an encode.
  const double   first = double(result.firstCount);
  const double   schedule = decimates ? (RemovalWork + 1.0) * first : 0.0;
  BudgetProgress shown(progress);
  double         afterFirstRun = workLeft({}, true);
  // The refinement alone first: where even its error, carried to the target size and lowered by the
  // most the rest of the method and the rate control were measured to gain, stays above the
  // competitor's, the points are abandoned.
  engine.Refine(result.firstCount, shown.Stage(first, schedule + CorrectionWork * first + afterFirstRun));
  shown.Done(first, schedule + CorrectionWork * first + afterFirstRun);
  // The check on the refinement's state, made as soon as the competitor is ready: a competitor still in
  // the making is not waited for, the schedule goes on meanwhile and stops where the check abandons the
  // points (the same decision as if it had waited; norm-256 at 0.03125 bpv waited 0.2 to 0.26 s here).
  // The schedule asks at each of its progress reports (every 1% of a refinement or a decimation).
  double competitorError = std::numeric_limits<double>::infinity();
  bool   checked = !competitor;
  auto   ask = [&] {
    checked = true;
    competitorError = competitor();
  };
  const double refinedError = engine.GetSquaredError();
  double       refinedSize = 0.0;
  auto         abandonsRefinedBy = [&](double error) { // false against an infinite error
    return carried(refinedError, refinedSize) / AbandonAfterRefinement > error;
  };
  auto abandonsRefined = [&] { return abandonsRefinedBy(competitorError); };
  // Before the competitor is ready: against its bound, which its error will not exceed.
  auto abandonsRefinedByBound = [&] { return competitorBound && abandonsRefinedBy(competitorBound()); };
  auto abandon = [&] {
    result.abandoned = true;
    result.payload.clear();
    return result;
  };
  if (competitor && (!competitorReady || competitorReady()))
    ask();
  // The refinement's size only where a competitor may be compared with it (an encode of the first count).
  if (!checked || std::isfinite(competitorError))
  {
    refinedSize =
      double(EncodePayload(engine.GetApproximation(), q0, engine.GetParameters().quantizationStep, true).size());
    afterFirstRun = workLeft({ { first, refinedSize } }, true); // the law's final count, not the first
    if (checked ? abandonsRefined() : abandonsRefinedByBound())
      return abandon();
  }
  // Approximate() has only its schedule left to report (the refinement is done).
  const RefinementEngine::ProgressFunction scheduleShown =
    shown.Stage(schedule, CorrectionWork * first + afterFirstRun);
  struct Abandoned
  {};
  try
  {
    engine.Approximate(result.firstCount, [&](double f) {
      if (scheduleShown)
        scheduleShown(f);
      if (!checked && competitorReady())
      {
        ask();
        if (abandonsRefined())
          throw Abandoned{};
      }
      else if (!checked && abandonsRefinedByBound())
      {
        throw Abandoned{};
      }
    });
  }
  catch (const Abandoned &)
  {
    return abandon(); // the engine stopped inside its schedule
  }
  if (!checked)
  {
    ask();
    if (abandonsRefined())
      return abandon();
  }
  encode();
  // (count, size) of the states of the current step: what the work left is estimated from.
  std::vector<std::pair<double, double>> fitted{ { double(engine.GetNumberOfPoints()),
                                                   double(result.payload.size()) } };
  bool                                   stepsToCome = stepMultiples.size() > 1;
  shown.Done(schedule + CorrectionWork * first, workLeft(fitted, stepsToCome));
  if (double(result.payload.size()) >= AbandonNearTarget * TargetFill * budget &&
      carried(engine.GetSquaredError(), double(result.payload.size())) / AbandonAfterFirstRun > competitorError)
  {
    return abandon();
  }
  // Adjusts the point count until the payload fills MinimumFill to all of the budget. (Fitting the
  // count without solving for least-squares values at each step, and solving once at the end, was
  // measured 0.01 to 0.03 dB worse on neghip, ironprot and ct-avm: the solved values guide decimation.)
  auto resize = [&](std::size_t target) {
    const double count = double(engine.GetNumberOfPoints());
    const double change = std::abs(double(target) - count) * (double(target) > count ? 1.0 : RemovalWork);
    const double stage = change + CorrectionWork * double(target);
    // While the points change, the work left is what the state before estimated, less what is done.
    engine.Resize(target, shown.Stage(change, std::max(stage, workLeft(fitted, stepsToCome)) - change));
    ++result.adjustments;
    encode();
    fitted.emplace_back(double(engine.GetNumberOfPoints()), double(result.payload.size()));
    shown.Done(stage, workLeft(fitted, stepsToCome));
    // The competitor is in hand since the first run; before the step trials only (stepsToCome).
    const double size = double(result.payload.size());
    if (stepsToCome && size >= AbandonNearTarget * TargetFill * budget &&
        carried(engine.GetSquaredError(), size) / AbandonDuringFit > competitorError)
      throw Abandoned{};
  };
  auto fit = [&] {
    for (unsigned i = 0; i < MaximumCorrections; ++i)
    {
      const double size = double(result.payload.size());
      if (size <= budget && size >= MinimumFill * budget)
      {
        break;
      }
      const std::size_t count = engine.GetNumberOfPoints();
      const double      bitsPerPoint = size * 8.0 / double(count);
      std::size_t       target = std::size_t(std::max(8.0, std::floor(TargetFill * budget * 8.0 / bitsPerPoint)));
      if (target == count)
      {
        target = size > budget ? count - 1 : count + 1;
      }
      resize(target);
      if (engine.GetNumberOfPoints() == count)
      {
        break; // exact approximation: no point left to add
      }
    }
    // Whatever is still over the budget goes by decimation alone.
    while (double(result.payload.size()) > budget)
    {
      const std::size_t count = engine.GetNumberOfPoints();
      if (count <= 8)
      {
        throw std::length_error("even the 8 corners need " + std::to_string(result.payload.size()) +
                                " bytes of payload, more than the " + std::to_string(payloadBytes) + " allowed");
      }
      const double excess = 1.0 - TargetFill * budget / double(result.payload.size());
      resize(count - std::max<std::size_t>(1, std::size_t(std::ceil(excess * double(count)))));
    }
  };
  try
  {
    fit();
  }
  catch (const Abandoned &)
  {
    return abandon();
  }

  if (stepMultiples.size() > 1)
  {
    // Step choice on the fitted mesh: each step's values are quantized again on it (from the
    // least-squares solution, in modes with least squares); its squared error E at size S is carried to the budget T
    // with the local law E ~ S^-b, b measured between the last two fitted states of different sizes (1 without them).
    // The best step is kept and the count fitted again. Measured on ../shared/data at 0.03125 and
    // 0.25 bpv, it picked the best of the three steps on 9 of 10 runs (a sweep of whole runs decided).
    double b = 1.0;
    for (std::size_t i = states.size(); i-- > 1;)
    {
      const auto [s1, e1] = states[i - 1];
      const auto [s2, e2] = states[i];
      if (s1 != s2 && e1 > 0.0 && e2 > 0.0)
      {
        b = std::clamp(std::log(e1 / e2) / std::log(s2 / s1), 0.3, 3.0);
        break;
      }
    }
    const double target = TargetFill * budget;
    auto         predicted = [&] { return states.back().second * std::pow(states.back().first / target, b); };
    double       bestMultiple = 1.0, bestError = predicted();
    // The mesh is solved (fit() ends so): each step quantizes the solution again. A trial codes the mesh
    // at its step and leaves the engine at the current one, whose cells' state and payload stay in hand
    // should it remain the best (a full rescan and a coding less).
    stepsToCome = false;
    const double count = double(engine.GetNumberOfPoints());
    for (double m : stepMultiples)
    {
      if (m != 1.0)
      {
        double error = 0.0;
        ReturnFreedMemory(); // as encode() does
        const auto size =
          double(EncodePayload(engine.GetApproximationAtStep(m * step, error), q0, m * step, true).size());
        states.emplace_back(size, error);
        shown.Done(StepTrialWork * count, workLeft({ { count, size } }, false));
        if (predicted() < bestError)
        {
          bestMultiple = m;
          bestError = predicted();
        }
      }
    }
    if (bestError / AbandonAfterSteps > competitorError)
    {
      return abandon();
    }
    if (bestMultiple != 1.0)
    {
      engine.SetQuantizationStep(bestMultiple * step);
      encode();
    }
    // The law of the final fit starts from the chosen step's state.
    fitted.assign(1, { count, double(result.payload.size()) });
    shown.Done(bestMultiple != 1.0 ? StepTrialWork * count : 0.0, workLeft(fitted, false));
    result.step = bestMultiple * step;
    fit();
  }
  if (progress)
    progress(1.0);
  return result;
}

BudgetResult
ApproximateToQuality(RefinementEngine & engine, double squaredError, double q0,
                     const DecodedErrorFunction & decodedError, const RefinementEngine::ProgressFunction & progress)
{
  const double step = engine.GetParameters().quantizationStep;
  if (!(step > 0.0) || !(squaredError >= 0.0) || !decodedError)
  {
    throw std::invalid_argument("ApproximateToQuality: needs a quantization step, a target and an error measure");
  }
  const std::size_t voxels = std::size_t(engine.GetGrid().NumberOfVoxels());
  // First count: what 0.03125 bits per voxel affords (about one point in 600 voxels); the law then
  // moves the count towards the target.
  BudgetResult result{ {}, std::max<std::size_t>(8, voxels / 600), 0, step };
  engine.Approximate(result.firstCount, [&](double f) {
    if (progress)
      progress(0.5 * f);
  });
  std::size_t               pass = 0;     // smallest count known to reach the target (0: none yet)
  std::size_t               fail = 7;     // largest count known to miss it (8: the corners)
  double                    b = 1.0;      // error ~ count^-b
  std::pair<double, double> last{ 0, 0 }; // (count, error) of the previous state
  double                    bestError = std::numeric_limits<double>::infinity();
  for (unsigned i = 0; i < MaximumQualitySteps; ++i)
  {
    const std::size_t count = engine.GetNumberOfPoints();
    const double      error = decodedError(engine);
    bestError = std::min(bestError, error);
    if (last.first > 0.0 && last.first != double(count) && error > 0.0 && last.second > 0.0)
    {
      b = std::clamp(std::log(last.second / error) / std::log(double(count) / last.first), 0.3, 3.0);
    }
    last = { double(count), error };
    if (error <= squaredError)
    {
      pass = count;
    }
    else
    {
      fail = std::max(fail, count);
      if (pass != 0 && pass <= count)
      {
        pass = 0; // the mesh changed under resizing: the earlier pass no longer holds
      }
    }
    if (progress)
      progress(0.5 + 0.5 * double(i + 1) / double(MaximumQualitySteps));
    const bool close = pass != 0 && double(pass - std::min(pass, fail)) <= std::max(1.0, QualityCountTolerance * pass);
    if (close && count == pass)
    {
      break;
    }
    std::size_t target;
    if (pass == 0)
    {
      // Grow by the law, at least 5% and at most 4 times.
      const double factor = error > 0.0 ? std::pow(error / std::max(squaredError, 1e-300), 1.0 / b) : 1.0;
      target = std::size_t(std::ceil(double(count) * std::clamp(factor * 1.02, 1.05, 4.0)));
      if (count < voxels)
      {
        engine.Resize(std::min(std::max(target, count + 1), voxels));
      }
      if (engine.GetNumberOfPoints() == count) // every voxel is a point, or the approximation is exact
      {
        throw std::range_error("the target is not reached: the smallest squared error is " + std::to_string(bestError) +
                               " at " + std::to_string(count) + " points (quantization step " + std::to_string(step) +
                               ")");
      }
      ++result.adjustments;
      continue;
    }
    if (close)
    {
      target = pass; // back to the passing count, measured again there
    }
    else
    {
      // Between the largest failing and the smallest passing count: the law's prediction, kept
      // strictly inside the bracket.
      const double predicted = double(count) * std::pow(error / std::max(squaredError, 1e-300), 1.0 / b);
      target = std::size_t(std::clamp(predicted, double(fail + 1), double(pass - 1)));
      if (target <= fail || target >= pass)
        target = fail + (pass - fail) / 2;
    }
    engine.Resize(target);
    ++result.adjustments;
  }
  if (pass == 0 || engine.GetNumberOfPoints() != pass || decodedError(engine) > squaredError)
  {
    // Out of steps: grow until the target is met, 2% at a time.
    for (;;)
    {
      const std::size_t count = engine.GetNumberOfPoints();
      if (decodedError(engine) <= squaredError)
        break;
      engine.Resize(std::min(voxels, std::max(count + 1, std::size_t(std::ceil(count * 1.02)))));
      ++result.adjustments;
      if (engine.GetNumberOfPoints() == count)
      {
        throw std::range_error("the target is not reached: the smallest squared error is " +
                               std::to_string(decodedError(engine)) + " at " + std::to_string(count) + " points");
      }
    }
  }
  result.payload = EncodePayload(engine.GetApproximation(), q0, step, true);
  if (progress)
    progress(1.0);
  return result;
}

} // namespace dcv
