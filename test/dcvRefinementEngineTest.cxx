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
// The refinement engine: exact accounting, decoder agreement, convergence.
#include "dcvPhantom.h"
#include "dcvRefinementEngine.h"
#include "dcvTestUtilities.h"

#include <cmath>
#include <cstring>
#include <map>

namespace
{
using namespace dcv;

/** Brute-force value of the spline at a voxel: barycentric interpolation in any cell that contains
 * it (the spline is continuous, so any containing cell gives the same value). */
double
BruteForceValue(const Approximation & a, const GridPoint & q)
{
  for (const Tetrahedron & t : a.tetrahedra)
  {
    std::array<GridPoint, 4> p{ a.points[t[0]], a.points[t[1]], a.points[t[2]], a.points[t[3]] };
    const double             whole = double(SignedVolume6(p));
    if (whole == 0)
      continue;
    double value = 0.0;
    bool   inside = true;
    for (int i = 0; i < 4 && inside; ++i)
    {
      std::array<GridPoint, 4> r = p;
      r[i] = q;
      const double weight = double(SignedVolume6(r)) / whole;
      inside = weight >= 0.0;
      value += weight * a.values[t[i]];
    }
    if (inside)
      return value;
  }
  ADD_FAILURE() << "no cell contains voxel " << q[0] << "," << q[1] << "," << q[2];
  return 0.0;
}

std::vector<float>
PhantomVolume(const GridSize & grid)
{
  const auto bytes = SheppLoganPhantom(grid);
  return std::vector<float>(bytes.begin(), bytes.end());
}

TEST(RefinementEngine, LinearVolumeIsExactWithTheCorners)
{
  const GridSize     grid{ 20, 17, 9 };
  std::vector<float> image(grid.NumberOfVoxels());
  for (int32_t z = 0; z < grid.z; ++z)
    for (int32_t y = 0; y < grid.y; ++y)
      for (int32_t x = 0; x < grid.x; ++x)
        image[grid.Offset(x, y, z)] = float(7 + 2 * x - 3 * y + 5 * z);
  RefinementEngine engine(image.data(), grid);
  engine.Refine(1000);
  EXPECT_EQ(engine.GetNumberOfPoints(), 8u); // nothing left to refine
  EXPECT_EQ(engine.GetSquaredError(), 0.0);
  std::vector<float> out(grid.NumberOfVoxels(), -1.0f);
  Rasterize(engine.GetApproximation(), out.data());
  EXPECT_EQ(out, image);
}

TEST(RefinementEngine, CellErrorsSumToTheBruteForceTotal)
{
  const GridSize           grid{ 23, 19, 21 };
  const std::vector<float> image = PhantomVolume(grid);
  RefinementEngine         engine(image.data(), grid);
  engine.Refine(250);
  ASSERT_EQ(engine.GetNumberOfPoints(), 250u);
  const auto stats = engine.GetCellStatistics();
  uint64_t   voxels = 0;
  double     cellSum = 0.0;
  for (const auto & s : stats)
  {
    voxels += s.voxels;
    cellSum += s.squaredError;
  }
  EXPECT_EQ(voxels, grid.NumberOfVoxels());

  const Approximation a = engine.GetApproximation();
  double              bruteForce = 0.0;
  for (int32_t z = 0; z < grid.z; ++z)
    for (int32_t y = 0; y < grid.y; ++y)
      for (int32_t x = 0; x < grid.x; ++x)
      {
        const double e = image[grid.Offset(x, y, z)] - BruteForceValue(a, { x, y, z });
        bruteForce += e * e;
      }
  EXPECT_NEAR(cellSum, bruteForce, 1e-9 * bruteForce);
  EXPECT_NEAR(engine.GetSquaredError(), bruteForce, 1e-9 * bruteForce);
}

/** Engine output against a decoder that knows only the points and values. */
void
ExpectDecoderEqualsEngine(const std::vector<float> & image, const GridSize & grid, std::size_t points,
                          const RefinementParameters & parameters = {})
{
  RefinementEngine engine(image.data(), grid, parameters);
  engine.Approximate(points);
  EXPECT_EQ(engine.GetNumberOfPoints(), points);
  const Approximation fromEngine = engine.GetApproximation();
  std::vector<float>  engineOutput(grid.NumberOfVoxels(), std::nanf(""));
  Rasterize(fromEngine, engineOutput.data());

  // Points only, in another order.
  Approximation decoded;
  decoded.grid = grid;
  std::vector<std::size_t> order(fromEngine.points.size());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937(1));
  for (auto i : order)
  {
    decoded.points.push_back(fromEngine.points[i]);
    decoded.values.push_back(fromEngine.values[i]);
  }
  std::vector<float> decoderOutput(grid.NumberOfVoxels(), std::nanf(""));
  Decode(decoded, decoderOutput.data());
  EXPECT_EQ(decoded.tetrahedra.size(), fromEngine.tetrahedra.size());
  EXPECT_EQ(std::memcmp(engineOutput.data(), decoderOutput.data(), engineOutput.size() * sizeof(float)), 0);
  // The engine's own accounting agrees with what the decoder produces.
  const double sse = SquaredError(image.data(), decoderOutput.data(), grid.NumberOfVoxels());
  EXPECT_NEAR(engine.GetSquaredError(), sse, 1e-3 * sse + 1e-6);
}

TEST(RefinementEngine, DecoderEqualsEngineOnThePhantom)
{
  const GridSize grid{ 48, 40, 44 };
  ExpectDecoderEqualsEngine(PhantomVolume(grid), grid, 3000);
}

TEST(RefinementEngine, DecoderEqualsEngineOnRealCT)
{
  DCV_REQUIRE_DATA("headsq-ct.nrrd");
  const test::Volume v = test::ReadVolume("headsq-ct.nrrd");
  ExpectDecoderEqualsEngine(v.voxels, v.grid, 5000);
}

TEST(RefinementEngine, DecoderEqualsEngineOnRealMR)
{
  DCV_REQUIRE_DATA("head-mr.nrrd");
  const test::Volume v = test::ReadVolume("head-mr.nrrd");
  ExpectDecoderEqualsEngine(v.voxels, v.grid, 4000);
}

/** A smoothed copy of a volume (3x3x3 box mean), standing in for the bilateral I* in engine tests. */
std::vector<float>
Smoothed(const std::vector<float> & image, const GridSize & g)
{
  std::vector<float> out(image.size());
  for (int32_t z = 0; z < g.z; ++z)
    for (int32_t y = 0; y < g.y; ++y)
      for (int32_t x = 0; x < g.x; ++x)
      {
        double sum = 0.0;
        int    n = 0;
        for (int dz = -1; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx)
            {
              const int32_t a = x + dx, b = y + dy, c = z + dz;
              if (a >= 0 && b >= 0 && c >= 0 && a < g.x && b < g.y && c < g.z)
              {
                sum += image[g.Offset(a, b, c)];
                ++n;
              }
            }
        out[g.Offset(x, y, z)] = float(sum / n);
      }
  return out;
}

RefinementParameters
ParametersFor(Mode mode, const std::vector<float> & smoothed)
{
  RefinementParameters p = ParametersForMode(mode);
  if (UsesSmoothedImage(mode))
  {
    p.smoothed = smoothed.data();
  }
  p.valueMin = 0.0;
  p.valueMax = 255.0;
  return p;
}

TEST(RefinementEngine, DecoderEqualsEngineInEveryMode)
{
  DCV_REQUIRE_DATA("head-mr.nrrd");
  const test::Volume       v = test::ReadVolume("head-mr.nrrd");
  const std::vector<float> smoothed = Smoothed(v.voxels, v.grid);
  for (Mode mode : { Mode::Silva, Mode::Dec, Mode::DecCom, Mode::Best })
  {
    SCOPED_TRACE(ModeName(mode));
    ExpectDecoderEqualsEngine(v.voxels, v.grid, 1500, ParametersFor(mode, smoothed));
  }
}

TEST(RefinementEngine, ModesKeepThePapersOrdering)
{
  DCV_REQUIRE_DATA("head-mr.nrrd");
  const test::Volume       v = test::ReadVolume("head-mr.nrrd");
  const std::vector<float> smoothed = Smoothed(v.voxels, v.grid);
  std::map<Mode, double>   error;
  for (Mode mode : { Mode::Silva, Mode::Dec, Mode::Best })
  {
    RefinementEngine engine(v.voxels.data(), v.grid, ParametersFor(mode, smoothed));
    engine.Approximate(2000);
    error[mode] = engine.GetSquaredError();
  }
  EXPECT_LT(error[Mode::Dec], error[Mode::Silva]);
  EXPECT_LT(error[Mode::Best], error[Mode::Dec]);
}

TEST(RefinementEngine, DecimationLeavesTheScheduledNumberOfPoints)
{
  const GridSize           grid{ 32, 30, 28 };
  const std::vector<float> image = PhantomVolume(grid);
  RefinementEngine         engine(image.data(), grid);
  engine.Refine(800);
  engine.Decimate(300);
  EXPECT_EQ(engine.GetNumberOfPoints(), 500u);
  engine.Refine(800);
  EXPECT_EQ(engine.GetNumberOfPoints(), 800u);

  RefinementParameters withDecimation;
  withDecimation.decimation = true;
  RefinementEngine scheduled(image.data(), grid, withDecimation);
  scheduled.Approximate(777);
  EXPECT_EQ(scheduled.GetNumberOfPoints(), 777u);
  // Accounting stays exact through removals.
  double   cellSum = 0.0;
  uint64_t voxels = 0;
  for (const auto & s : scheduled.GetCellStatistics())
  {
    cellSum += s.squaredError;
    voxels += s.voxels;
  }
  EXPECT_EQ(voxels, grid.NumberOfVoxels());
  std::vector<float> out(grid.NumberOfVoxels());
  Rasterize(scheduled.GetApproximation(), out.data());
  const double sse = SquaredError(image.data(), out.data(), grid.NumberOfVoxels());
  EXPECT_NEAR(cellSum, sse, 1e-3 * sse);
  EXPECT_NEAR(scheduled.GetSquaredError(), sse, 1e-3 * sse);
}

TEST(RefinementEngine, LongRunsKeepStateForTheLiveCellsOnly)
{
  // The decimation rounds kill many more cells than stay alive; ids are compacted on the way, and the
  // removal costs kept between rounds are those computed afresh.
  const GridSize           grid{ 40, 36, 32 };
  const std::vector<float> image = PhantomVolume(grid);
  RefinementEngine         engine(image.data(), grid, ParametersForMode(Mode::Best));
  engine.Approximate(3000);
  const auto stats = engine.GetCellStatistics();
  ASSERT_FALSE(stats.empty());
  uint32_t largest = 0;
  for (const auto & s : stats)
  {
    largest = std::max(largest, s.id);
  }
  // Without compaction the ids of a 3000-point schedule run past 150,000.
  EXPECT_LT(largest, 3 * stats.size() + 4096);
  // The accounting survives the renumbering.
  std::vector<float> out(grid.NumberOfVoxels());
  Rasterize(engine.GetApproximation(), out.data());
  const double sse = SquaredError(image.data(), out.data(), grid.NumberOfVoxels());
  EXPECT_NEAR(engine.GetSquaredError(), sse, 1e-6 * sse);
}

TEST(RefinementEngine, DecimationChoosesByTheFreshRemovalCosts)
{
  const GridSize           grid{ 30, 28, 26 };
  const std::vector<float> image = PhantomVolume(grid);
  RefinementParameters     p;
  p.decimation = true;
  RefinementEngine engine(image.data(), grid, p);
  engine.Approximate(700); // costs kept through 9 rounds of decimation and refinement
  // The vertex of smallest fresh cost (ties: the highest id, as the decimation heap orders them).
  double                     smallest = std::numeric_limits<double>::infinity();
  RefinementEngine::VertexId chosen = 0;
  std::size_t                live = 0;
  for (RefinementEngine::VertexId v = 8; v < 20000; ++v)
  {
    try
    {
      const double cost = engine.EstimateRemovalCost(v);
      ++live;
      if (cost <= smallest)
      {
        smallest = cost;
        chosen = v;
      }
    }
    catch (const std::invalid_argument &) // removed, or never inserted
    {}
  }
  ASSERT_EQ(live + 8, engine.GetNumberOfPoints());
  engine.Decimate(1);
  EXPECT_THROW(engine.EstimateRemovalCost(chosen), std::invalid_argument); // it is the one removed
}

TEST(RefinementEngine, ResizeReachesTheCountBothWays)
{
  const GridSize           grid{ 32, 30, 28 };
  const std::vector<float> image = PhantomVolume(grid);
  RefinementParameters     p = ParametersForMode(Mode::Best);
  RefinementEngine         engine(image.data(), grid, p);
  engine.Approximate(600);
  const double atSix = engine.GetSquaredError();
  engine.Resize(450); // decimation, then least squares again
  EXPECT_EQ(engine.GetNumberOfPoints(), 450u);
  EXPECT_GT(engine.GetSquaredError(), atSix);
  engine.Resize(700); // refinement
  EXPECT_EQ(engine.GetNumberOfPoints(), 700u);
  engine.Resize(3); // never below the corners
  EXPECT_EQ(engine.GetNumberOfPoints(), 8u);
  // Accounting stays exact.
  std::vector<float> out(grid.NumberOfVoxels());
  Rasterize(engine.GetApproximation(), out.data());
  const double sse = SquaredError(image.data(), out.data(), grid.NumberOfVoxels());
  EXPECT_NEAR(engine.GetSquaredError(), sse, 1e-6 * sse);
}

TEST(RefinementEngine, EstimatedRemovalCostOfAJustInsertedVertexIsExact)
{
  const GridSize           grid{ 30, 28, 26 };
  const std::vector<float> image = PhantomVolume(grid);
  const std::vector<float> smoothed = Smoothed(image, grid);
  for (bool combined : { false, true })
  {
    RefinementParameters parameters;
    parameters.smoothed = combined ? smoothed.data() : nullptr;
    RefinementEngine engine(image.data(), grid, parameters);
    for (std::size_t n : { 50u, 200u, 600u })
    {
      engine.Refine(n);
      const auto   v = engine.GetLastInsertedVertex();
      const double estimate = engine.EstimateRemovalCost(v);
      const double before = engine.GetSquaredError();
      engine.RemoveVertex(v);
      const double exact = engine.GetSquaredError() - before;
      EXPECT_NEAR(estimate, exact, 1e-6 * before) << n << " points, combined " << combined;
      EXPECT_EQ(engine.GetNumberOfPoints(), n - 1);
    }
  }
}

TEST(RefinementEngine, LeastSquaresValuesAreNoWorse)
{
  DCV_REQUIRE_DATA("headsq-ct.nrrd");
  const test::Volume   v = test::ReadVolume("headsq-ct.nrrd");
  RefinementParameters parameters;
  parameters.valueMin = -32768;
  parameters.valueMax = 32767;
  RefinementEngine engine(v.voxels.data(), v.grid, parameters);
  engine.Refine(3000);
  const double before = engine.GetSquaredError();
  const double gain = engine.OptimizeValues();
  EXPECT_GE(gain, 0.0);
  EXPECT_LT(engine.GetSquaredError(), before); // strictly better on real data
  EXPECT_NEAR(before - engine.GetSquaredError(), gain, 1e-6 * before);
  // A second solve has nothing left to gain.
  EXPECT_LE(engine.OptimizeValues(), 1e-6 * before);
}

/** The least-squares values against the normal equations assembled voxel by voxel from barycentric weights
 * and solved directly: OptimizeValues() assembles per row from closed forms, and solves iteratively. */
TEST(RefinementEngine, LeastSquaresValuesSolveTheNormalEquations)
{
  const GridSize           grid{ 22, 18, 16 };
  const std::vector<float> image = PhantomVolume(grid);
  RefinementEngine         engine(image.data(), grid, RefinementParameters{}); // no step, no range: no rounding
  engine.Refine(60);
  engine.OptimizeValues();
  const Approximation a = engine.GetApproximation();
  const std::size_t   n = a.points.size();
  ASSERT_EQ(n, 60u);
  std::vector<double> m(n * n, 0.0), b(n, 0.0);
  for (int32_t z = 0; z < grid.z; ++z)
    for (int32_t y = 0; y < grid.y; ++y)
      for (int32_t x = 0; x < grid.x; ++x)
      {
        // The first cell containing the voxel; on a shared face the weights are the same from either side.
        bool found = false;
        for (const Tetrahedron & t : a.tetrahedra)
        {
          std::array<GridPoint, 4> p{ a.points[t[0]], a.points[t[1]], a.points[t[2]], a.points[t[3]] };
          const double             whole = double(SignedVolume6(p));
          if (whole == 0)
            continue;
          std::array<double, 4> w;
          bool                  inside = true;
          for (int i = 0; i < 4 && inside; ++i)
          {
            std::array<GridPoint, 4> r = p;
            r[i] = { x, y, z };
            w[i] = double(SignedVolume6(r)) / whole;
            inside = w[i] >= 0.0;
          }
          if (!inside)
            continue;
          for (int j = 0; j < 4; ++j)
          {
            b[t[j]] += w[j] * image[grid.Offset(x, y, z)];
            for (int k = 0; k < 4; ++k)
              m[t[j] * n + t[k]] += w[j] * w[k];
          }
          found = true;
          break;
        }
        ASSERT_TRUE(found) << x << "," << y << "," << z;
      }
  // Gaussian elimination with partial pivoting.
  for (std::size_t c = 0; c < n; ++c)
  {
    std::size_t pivot = c;
    for (std::size_t r = c + 1; r < n; ++r)
      if (std::fabs(m[r * n + c]) > std::fabs(m[pivot * n + c]))
        pivot = r;
    ASSERT_GT(std::fabs(m[pivot * n + c]), 1e-12);
    for (std::size_t k = 0; k < n; ++k)
      std::swap(m[c * n + k], m[pivot * n + k]);
    std::swap(b[c], b[pivot]);
    for (std::size_t r = c + 1; r < n; ++r)
    {
      const double f = m[r * n + c] / m[c * n + c];
      for (std::size_t k = c; k < n; ++k)
        m[r * n + k] -= f * m[c * n + k];
      b[r] -= f * b[c];
    }
  }
  std::vector<double> solution(n);
  for (std::size_t c = n; c-- > 0;)
  {
    double sum = b[c];
    for (std::size_t k = c + 1; k < n; ++k)
      sum -= m[c * n + k] * solution[k];
    solution[c] = sum / m[c * n + c];
  }
  for (std::size_t i = 0; i < n; ++i)
  {
    EXPECT_NEAR(a.values[i], solution[i], 1e-4) << "vertex " << i;
  }
}

TEST(RefinementEngine, QuantizedValuesStayOnTheLatticeAndDecodeExactly)
{
  const GridSize           grid{ 34, 30, 26 };
  const std::vector<float> image = PhantomVolume(grid);
  const std::vector<float> smoothed = Smoothed(image, grid);
  for (Mode mode : { Mode::Silva, Mode::Best })
  {
    RefinementParameters p = ParametersFor(mode, smoothed);
    p.quantizationStep = 6.0;
    p.quantizationOrigin = 1.0;
    RefinementEngine engine(image.data(), grid, p);
    engine.Approximate(400);
    for (double v : engine.GetApproximation().values)
    {
      const double k = (v - 1.0) / 6.0;
      ASSERT_EQ(k, std::round(k)) << ModeName(mode) << " value " << v;
      ASSERT_GE(v, 0.0);
      ASSERT_LE(v, 255.0);
    }
    ExpectDecoderEqualsEngine(image, grid, 400, p);
  }
}

/** A step trial gives what SetQuantizationStep() then gives, to the bit, and leaves the engine as it was:
 * with least squares (the solution quantized again) and without (each vertex's source). */
TEST(RefinementEngine, StepTrialsGiveTheSetStepsResultAndChangeNothing)
{
  const GridSize           grid{ 34, 30, 26 };
  const std::vector<float> image = PhantomVolume(grid);
  const std::vector<float> smoothed = Smoothed(image, grid);
  for (Mode mode : { Mode::Silva, Mode::Best })
  {
    RefinementParameters p = ParametersFor(mode, smoothed);
    p.quantizationStep = 2.0;
    RefinementEngine engine(image.data(), grid, p);
    engine.Approximate(300);
    const Approximation before = engine.GetApproximation();
    const double        beforeError = engine.GetSquaredError();
    double              error = -1.0;
    const Approximation trial = engine.GetApproximationAtStep(5.0, error);
    const Approximation after = engine.GetApproximation();
    EXPECT_EQ(after.values, before.values) << ModeName(mode);
    EXPECT_EQ(after.tetrahedra, before.tetrahedra) << ModeName(mode);
    EXPECT_EQ(engine.GetSquaredError(), beforeError) << ModeName(mode);
    EXPECT_NE(trial.values, before.values) << ModeName(mode); // the step changed them
    engine.SetQuantizationStep(5.0);
    const Approximation set = engine.GetApproximation();
    EXPECT_EQ(trial.points, set.points) << ModeName(mode);
    EXPECT_EQ(trial.values, set.values) << ModeName(mode);
    EXPECT_EQ(trial.tetrahedra, set.tetrahedra) << ModeName(mode);
    EXPECT_EQ(error, engine.GetSquaredError()) << ModeName(mode);
    EXPECT_THROW(engine.GetApproximationAtStep(0.0, error), std::invalid_argument);
  }
}

TEST(RefinementEngine, RefusesBadParameters)
{
  std::vector<float>   image(64, 1.0f);
  RefinementParameters p;
  p.alpha = 0.0;
  EXPECT_THROW(RefinementEngine(image.data(), GridSize{ 4, 4, 4 }, p), std::invalid_argument);
  p.alpha = -1.0;
  EXPECT_THROW(RefinementEngine(image.data(), GridSize{ 4, 4, 4 }, p), std::invalid_argument);
  EXPECT_THROW(ParseMode("fast"), std::invalid_argument);
  EXPECT_EQ(ParseMode("dec+com"), Mode::DecCom);
  RefinementEngine engine(image.data(), GridSize{ 4, 4, 4 });
  EXPECT_THROW(engine.RemoveVertex(0), std::invalid_argument); // a corner
}

TEST(RefinementEngine, ErrorDecreasesAsPointsAreAdded)
{
  DCV_REQUIRE_DATA("head-mr.nrrd");
  const test::Volume v = test::ReadVolume("head-mr.nrrd");
  RefinementEngine   engine(v.voxels.data(), v.grid);
  double             previous = engine.GetSquaredError();
  double             psnr = PSNR(previous, v.grid.NumberOfVoxels(), v.peak);
  for (std::size_t n = 50; n <= 6400; n *= 2)
  {
    engine.Refine(n);
    ASSERT_EQ(engine.GetNumberOfPoints(), n);
    EXPECT_LT(engine.GetSquaredError(), previous) << n << " points";
    previous = engine.GetSquaredError();
    const double next = PSNR(previous, v.grid.NumberOfVoxels(), v.peak);
    EXPECT_GT(next, psnr);
    psnr = next;
  }
  EXPECT_GT(psnr, 29.0); // measured 29.73 dB: 6400 points on the 125k voxels of this MR
}

TEST(RefinementEngine, ProgressIsReportedUpToOne)
{
  const GridSize           grid{ 16, 16, 16 };
  const std::vector<float> image = PhantomVolume(grid);
  RefinementEngine         engine(image.data(), grid);
  std::vector<double>      reports;
  engine.Refine(300, [&](double f) { reports.push_back(f); });
  ASSERT_FALSE(reports.empty());
  EXPECT_TRUE(std::is_sorted(reports.begin(), reports.end()));
  EXPECT_EQ(reports.back(), 1.0);
  // Removals too, every 1%: a decimation of 173,000 vertices (norm-256 at 0.25 bpv) is 17 s.
  reports.clear();
  engine.Decimate(200, [&](double f) { reports.push_back(f); });
  EXPECT_EQ(reports.size(), 101u);
  EXPECT_TRUE(std::is_sorted(reports.begin(), reports.end()));
  EXPECT_EQ(reports.front(), 0.01);
  EXPECT_EQ(reports.back(), 1.0);
}

TEST(RefinementEngine, TheSchedulesProgressWeighsARemovalAsRemovalWorkInsertions)
{
  // Approximate(n) with decimation: n insertions, then removals and insertions of k = n/2, n/4, ...
  // The fraction at the end of the first decimation tells the weights apart.
  const GridSize           grid{ 16, 16, 16 };
  const std::vector<float> image = PhantomVolume(grid);
  RefinementParameters     p;
  p.decimation = true;
  RefinementEngine    engine(image.data(), grid, p);
  std::vector<double> reports;
  const std::size_t   n = 400;
  const double        insertions = double(n - engine.GetNumberOfPoints()); // from the 8 corners
  engine.Approximate(n, [&](double f) { reports.push_back(f); });
  double total = insertions;
  for (std::size_t k = n / 2; k > 0; k /= 2)
    total += (RefinementEngine::RemovalWork + 1.0) * double(k);
  const double scheduled = (insertions + RefinementEngine::RemovalWork * double(n / 2)) / total;
  EXPECT_TRUE(std::is_sorted(reports.begin(), reports.end()));
  EXPECT_NE(std::find_if(reports.begin(), reports.end(), [&](double f) { return std::abs(f - scheduled) < 1e-12; }),
            reports.end())
    << "no report at the end of the first decimation, " << scheduled;
  EXPECT_EQ(reports.back(), 1.0);
}

TEST(RefinementEngine, RefusesGridsItCannotTetrahedralize)
{
  std::vector<float> image(100, 0.0f);
  EXPECT_THROW(RefinementEngine(image.data(), GridSize{ 10, 10, 1 }), std::invalid_argument);
  EXPECT_THROW(RefinementEngine(nullptr, GridSize{ 4, 5, 5 }), std::invalid_argument);
}

TEST(Approximation, CheckPointsNamesTheProblem)
{
  const GridSize         grid{ 5, 5, 5 };
  std::vector<GridPoint> points = test::Corners(grid);
  EXPECT_NO_THROW(CheckPoints(grid, points));
  points.push_back({ 5, 0, 0 });
  EXPECT_THROW(CheckPoints(grid, points), std::invalid_argument);
  points.pop_back();
  points.pop_back();
  EXPECT_THROW(CheckPoints(grid, points), std::invalid_argument);
}

} // namespace
