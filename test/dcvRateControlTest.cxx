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
// Rate control: the size law that predicts the final count, and the progress it reports.
#include "dcvPhantom.h"
#include "dcvRateControl.h"

#include <algorithm>
#include <random>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>

namespace
{
using namespace dcv;

TEST(RateControl, FittedCountFollowsTheLawBetweenTheLastTwoStates)
{
  // size = 1000 (count / 100)^0.6 through both states: the count of 2000 bytes is 100 x 2^(1 / 0.6).
  const double a = 1000.0 * std::pow(3.0, 0.6);
  EXPECT_NEAR(FittedCount({ { 50.0, 1.0 }, { 100.0, 1000.0 }, { 300.0, a } }, 1e6, 2000.0) /
                (100.0 * std::pow(2.0, 1.0 / 0.6)),
              1.0,
              1e-9)
    << "the law is measured between the last two states, not with the first";
  // Equal counts say nothing of the law: the one before them is used.
  EXPECT_NEAR(FittedCount({ { 100.0, 1000.0 }, { 300.0, a }, { 300.0, a } }, 1e6, 2000.0) /
                (100.0 * std::pow(2.0, 1.0 / 0.6)),
              1.0,
              1e-9);
}

TEST(RateControl, FittedCountFromOneStateIsTheMeasuredFallOfTheLawOfASubset)
{
  // 10 bits a point: the local exponent of n (log2(V / n) + c) is 1 - 1 / (10 ln 2); the bits a point
  // fall SubsetLawFactor times as fast.
  const double beta = 1.0 - RateControl::SubsetLawFactor / (10.0 * std::log(2.0));
  EXPECT_NEAR(FittedCount({ { 800.0, 1000.0 } }, 1e6, 1500.0), 800.0 * std::pow(1.5, 1.0 / beta), 1e-6);
  // Further than a step of the old correction (one bits-per-point): 800 x 1.5 = 1200.
  EXPECT_GT(FittedCount({ { 800.0, 1000.0 } }, 1e6, 1500.0), 1200.0);
  // Smaller targets give fewer points; the count stays within 8 and the voxels.
  EXPECT_LT(FittedCount({ { 800.0, 1000.0 } }, 1e6, 500.0), 800.0);
  EXPECT_EQ(FittedCount({ { 800.0, 1000.0 } }, 1000.0, 1e9), 1000.0);
  EXPECT_EQ(FittedCount({ { 800.0, 1000.0 } }, 1e6, 1e-9), 8.0);
  EXPECT_THROW(FittedCount({}, 1e6, 1000.0), std::invalid_argument);
  EXPECT_THROW(FittedCount({ { 0.0, 1000.0 } }, 1e6, 1000.0), std::invalid_argument);
}

/** Mode best for 8-bit volumes, as the encoder sets it. */
RefinementParameters
EightBitBest()
{
  RefinementParameters p = ParametersForMode(Mode::Best);
  p.peak = 255.0;
  p.quantizationStep = DefaultQuantizationStep(255.0, true);
  p.valueMin = 0.0;
  p.valueMax = 255.0;
  return p;
}

/** The engine of the rate-control tests: mode best on a Shepp-Logan phantom, 8-bit steps. */
struct PhantomEngine
{
  explicit PhantomEngine(const GridSize & grid)
    : bytes(SheppLoganPhantom(grid))
    , image(bytes.begin(), bytes.end())
  {
    engine = std::make_unique<RefinementEngine>(image.data(), grid, EightBitBest());
  }
  std::vector<uint8_t>              bytes;
  std::vector<float>                image;
  std::unique_ptr<RefinementEngine> engine;
};

/** The points' squared error when rate control runs them to the end without a competitor (0 where it
 * abandoned them, which it cannot without one). */
double
FinalErrorWithoutCompetitor(const GridSize & grid, std::size_t budget)
{
  PhantomEngine e(grid);
  return ApproximateToBudget(*e.engine, budget, 0.0, RateControl::StepMultiples()).abandoned
           ? 0.0
           : e.engine->GetSquaredError();
}

TEST(RateControl, PointsAbandonedAfterTheStepTrialsWhenTheCompetitorIsAhead)
{
  // A budget whose first run needs a correction: the checks on the refinement and the first run come
  // before it, so the points abandoned after a correction were abandoned by the check after the step
  // trials (the only one after the first fit).
  const GridSize   grid{ 32, 32, 32 };
  constexpr size_t budget = 4000;
  double           final = 0.0; // the points' error when they run to the end
  unsigned         corrections = 0;
  {
    PhantomEngine      e(grid);
    const BudgetResult r = ApproximateToBudget(*e.engine, budget, 0.0, RateControl::StepMultiples());
    ASSERT_FALSE(r.abandoned);
    ASSERT_GT(r.adjustments, 0u) << "the test needs a first run that misses the budget";
    final = e.engine->GetSquaredError();
    corrections = r.adjustments;
  }
  // A competitor 10% closer than the points' final error: the step trials' prediction stands above it
  // by more than AbandonAfterSteps, where the earlier checks' wider margins let the points go on.
  {
    PhantomEngine      e(grid);
    const BudgetResult r =
      ApproximateToBudget(*e.engine, budget, 0.0, RateControl::StepMultiples(), {}, [&] { return 0.9 * final; });
    EXPECT_TRUE(r.abandoned);
    EXPECT_TRUE(r.payload.empty());
    EXPECT_GT(r.adjustments, 0u) << "abandoned before the first fit: the test no longer reaches the step trials";
  }
  // A competitor as close as the points: they go on to the end, with the same result as without one.
  {
    PhantomEngine      e(grid);
    const BudgetResult r =
      ApproximateToBudget(*e.engine, budget, 0.0, RateControl::StepMultiples(), {}, [&] { return final; });
    EXPECT_FALSE(r.abandoned);
    EXPECT_EQ(r.adjustments, corrections);
    EXPECT_EQ(e.engine->GetSquaredError(), final);
  }
}

/** A smooth field with noise: the first count's guess of the bits a point is off, so the first fit takes
 * several corrections, as on norm-256. */
struct TexturedEngine
{
  explicit TexturedEngine(const GridSize & grid)
    : image(grid.NumberOfVoxels())
  {
    std::mt19937                     random(7);
    std::normal_distribution<double> noise(0.0, 2.0);
    for (int32_t z = 0; z < grid.z; ++z)
      for (int32_t y = 0; y < grid.y; ++y)
        for (int32_t x = 0; x < grid.x; ++x)
        {
          const double v = 128.0 + 60.0 * std::sin(0.3 * x) * std::cos(0.25 * y) + 40.0 * std::sin(0.2 * z + 0.1 * x);
          image[grid.Offset(x, y, z)] = float(std::clamp(std::round(v + noise(random)), 0.0, 255.0));
        }
    engine = std::make_unique<RefinementEngine>(image.data(), grid, EightBitBest());
  }
  std::vector<float>                image;
  std::unique_ptr<RefinementEngine> engine;
};

TEST(RateControl, PointsAbandonedInsideTheFitWhenTheCompetitorIsFarAhead)
{
  const GridSize   grid{ 32, 32, 32 };
  constexpr size_t budget = 8000;
  // The corrections of the first fit alone (one step: no step trials, and no check inside the fit).
  unsigned firstFit = 0;
  {
    TexturedEngine e(grid);
    firstFit = ApproximateToBudget(*e.engine, budget, 0.0, { 1.0 }).adjustments;
    ASSERT_GE(firstFit, 2u) << "the test needs a first fit of several corrections";
  }
  double final = 0.0;
  {
    TexturedEngine     e(grid);
    const BudgetResult r = ApproximateToBudget(*e.engine, budget, 0.0, RateControl::StepMultiples());
    ASSERT_FALSE(r.abandoned);
    final = e.engine->GetSquaredError();
  }
  // A competitor far ahead: a correction near the target, its error carried to it and divided by
  // AbandonDuringFit, stands above it, and the fit stops there.
  {
    TexturedEngine     e(grid);
    const BudgetResult r =
      ApproximateToBudget(*e.engine, budget, 0.0, RateControl::StepMultiples(), {}, [&] { return 0.4 * final; });
    EXPECT_TRUE(r.abandoned);
    EXPECT_GE(r.adjustments, 1u) << "abandoned before the fit";
    EXPECT_LT(r.adjustments, firstFit) << "not abandoned inside the fit";
  }
  // A competitor nearer the points: the fit's wider margin lets them on to the step trials, whose check
  // abandons them after the whole first fit.
  {
    TexturedEngine     e(grid);
    const BudgetResult r =
      ApproximateToBudget(*e.engine, budget, 0.0, RateControl::StepMultiples(), {}, [&] { return 0.6 * final; });
    EXPECT_TRUE(r.abandoned);
    EXPECT_EQ(r.adjustments, firstFit);
  }
}

TEST(RateControl, ACompetitorNotReadyIsNotWaitedForAndDecidesTheSame)
{
  // The check after the first refinement, made when the competitor answers (here after a few polls of
  // the schedule), decides as the one that waits for it: abandoned where that abandons, and where it
  // does not, the same run to the end.
  const GridSize grid{ 48, 44, 40 };
  const double   final = FinalErrorWithoutCompetitor(grid, 3000);
  ASSERT_GT(final, 0.0);
  for (const double factor : { 0.2, 1.0 })
  {
    bool waited = false;
    {
      PhantomEngine e(grid);
      waited = ApproximateToBudget(*e.engine, 3000, 0.0, RateControl::StepMultiples(), {}, [&] {
                 return factor * final;
               }).abandoned;
    }
    ASSERT_EQ(waited, factor < 1.0) << "the test needs a competitor that abandons the points and one that does not";
    PhantomEngine      e(grid);
    int                polls = 0;
    bool               askedEarly = false;
    const BudgetResult r = ApproximateToBudget(
      *e.engine,
      3000,
      0.0,
      RateControl::StepMultiples(),
      {},
      [&] {
        askedEarly = askedEarly || polls <= 4;
        return factor * final;
      },
      [&] { return ++polls > 4; });
    EXPECT_FALSE(askedEarly) << "the competitor was asked for before it was ready";
    EXPECT_GT(polls, 4) << "factor " << factor;
    EXPECT_EQ(r.abandoned, waited) << "factor " << factor;
    EXPECT_EQ(r.payload.empty(), r.abandoned);
    if (r.abandoned)
    {
      EXPECT_EQ(r.adjustments, 0u);
      EXPECT_NE(e.engine->GetNumberOfPoints(), r.firstCount) << "stopped inside the schedule, not after it";
    }
    else
    {
      EXPECT_EQ(e.engine->GetSquaredError(), final);
    }
  }
}

TEST(RateControl, ACompetitorsBoundAbandonsBeforeItIsReadyAsItWould)
{
  // The bound (the most the competitor's error will be: its best so far while it is made) abandons the
  // points where the competitor would (0.2 of the points' final error, as in the test above), without
  // waiting for it: right after the refinement when the bound is known by then, inside the schedule
  // when it comes later. A bound that does not abandon leaves the run as it is without one.
  const GridSize grid{ 48, 44, 40 };
  const double   final = FinalErrorWithoutCompetitor(grid, 3000);
  ASSERT_GT(final, 0.0);
  const double unknown = std::numeric_limits<double>::infinity();
  for (const int knownAfter : { 0, 3 }) // polls of the competitor before the bound is known
  {
    PhantomEngine      e(grid);
    int                polls = 0;
    bool               asked = false;
    const BudgetResult r = ApproximateToBudget(
      *e.engine,
      3000,
      0.0,
      RateControl::StepMultiples(),
      {},
      [&] {
        asked = true;
        return 0.2 * final;
      },
      [&] {
        ++polls;
        return false; // not ready during the schedule
      },
      [&] { return polls >= knownAfter ? 0.2 * final : unknown; });
    EXPECT_TRUE(r.abandoned) << "known after " << knownAfter << " polls";
    EXPECT_TRUE(r.payload.empty());
    EXPECT_FALSE(asked) << "abandoned by the bound: the competitor is not asked for";
    if (knownAfter == 0)
    {
      EXPECT_EQ(e.engine->GetNumberOfPoints(), r.firstCount) << "abandoned before the schedule";
    }
    else
    {
      EXPECT_GE(polls, knownAfter);
      EXPECT_NE(e.engine->GetNumberOfPoints(), r.firstCount) << "stopped inside the schedule, not after it";
    }
  }
  {
    PhantomEngine      e(grid);
    const BudgetResult r = ApproximateToBudget(
      *e.engine,
      3000,
      0.0,
      RateControl::StepMultiples(),
      {},
      [&] { return final; },
      [] { return false; },
      [&] { return final; });
    EXPECT_FALSE(r.abandoned);
    EXPECT_EQ(e.engine->GetSquaredError(), final);
  }
}

TEST(RateControl, ProgressMovesAtEveryCorrectionAndNeverFalls)
{
  // A budget the first count misses (the first count is chosen low): rate control corrects it, and the
  // progress shown moves with each correction, not only at the end of a fit.
  PhantomEngine            e(GridSize{ 48, 44, 40 });
  RefinementEngine &       engine = *e.engine;
  std::vector<double>      shown;
  std::vector<std::size_t> counts; // the engine's point count at each value shown
  const BudgetResult       r = ApproximateToBudget(engine, 3000, 0.0, RateControl::StepMultiples(), [&](double f) {
    shown.push_back(f);
    counts.push_back(engine.GetNumberOfPoints());
  });
  ASSERT_GE(r.adjustments, 2u) << "the test needs a budget that takes corrections";
  ASSERT_FALSE(shown.empty());
  EXPECT_EQ(shown.back(), 1.0);
  for (std::size_t i = 0; i < shown.size(); ++i)
  {
    EXPECT_GE(shown[i], 0.0);
    EXPECT_LE(shown[i], 1.0);
    EXPECT_LE(shown[i], i + 1 < shown.size() ? shown[i + 1] : 1.0) << "progress falls after value " << i;
  }
  // Values shown after the first run (which ends at the first count; each correction changes the count):
  // at least one per correction before the end.
  std::size_t last = 0;
  for (std::size_t i = 0; i < shown.size(); ++i)
  {
    last = counts[i] == r.firstCount ? i : last;
  }
  std::size_t afterFirstRun = 0;
  for (std::size_t i = last + 1; i < shown.size(); ++i)
  {
    afterFirstRun += shown[i] < 1.0 ? 1 : 0;
  }
  EXPECT_GE(afterFirstRun, r.adjustments);
}

} // namespace
