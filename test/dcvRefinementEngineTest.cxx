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

#include <cstring>

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
ExpectDecoderEqualsEngine(const std::vector<float> & image, const GridSize & grid, std::size_t points)
{
  RefinementEngine engine(image.data(), grid);
  engine.Refine(points);
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

TEST(RefinementEngine, ErrorDecreasesAsPointsAreAdded)
{
  DCV_REQUIRE_DATA("head-mr.nrrd");
  const test::Volume v = test::ReadVolume("head-mr.nrrd");
  RefinementEngine      engine(v.voxels.data(), v.grid);
  double                previous = engine.GetSquaredError();
  double                psnr = PSNR(previous, v.grid.NumberOfVoxels(), v.peak);
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
