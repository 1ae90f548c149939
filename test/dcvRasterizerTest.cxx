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
// Exact rasterization: every voxel of the box has exactly one owner, whatever the tetrahedralization.
#include "dcvTestUtilities.h"

#include <cstring>

namespace
{
using namespace dcv;

/** Exact test that a voxel lies in the closed tetrahedron (independent of the span code). */
bool
InClosedTetrahedron(const std::array<GridPoint, 4> & p, const GridPoint & q)
{
  const int64_t whole = SignedVolume6(p);
  for (int i = 0; i < 4; ++i)
  {
    std::array<GridPoint, 4> r = p;
    r[i] = q;
    const int64_t part = SignedVolume6(r);
    if ((whole > 0 && part < 0) || (whole < 0 && part > 0))
    {
      return false;
    }
  }
  return true;
}

/** Rasterizes every cell and checks that each voxel is owned once, by a cell that contains it. */
void
ExpectEveryVoxelOwnedOnce(const GridSize & grid, const std::vector<GridPoint> & points)
{
  const std::vector<Tetrahedron> cells = Tetrahedralize(points);
  std::vector<int>               owners(grid.NumberOfVoxels(), 0);
  uint64_t                       counted = 0;
  for (const Tetrahedron & t : cells)
  {
    const std::array<GridPoint, 4> p{ points[t[0]], points[t[1]], points[t[2]], points[t[3]] };
    ForEachSpan(grid, p, [&](int32_t y, int32_t z, int32_t x0, int32_t x1) {
      for (int32_t x = x0; x <= x1; ++x)
      {
        ++owners[grid.Offset(x, y, z)];
        ASSERT_TRUE(InClosedTetrahedron(p, { x, y, z })) << "voxel " << x << "," << y << "," << z;
      }
      counted += uint64_t(x1 - x0 + 1);
    });
  }
  EXPECT_EQ(counted, grid.NumberOfVoxels());
  for (int32_t z = 0; z < grid.z; ++z)
  {
    for (int32_t y = 0; y < grid.y; ++y)
    {
      for (int32_t x = 0; x < grid.x; ++x)
      {
        ASSERT_EQ(owners[grid.Offset(x, y, z)], 1) << "voxel " << x << "," << y << "," << z;
      }
    }
  }
}

TEST(Rasterizer, EveryVoxelOwnedOnceRandomPoints)
{
  const GridSize grid{ 13, 9, 11 };
  for (unsigned seed = 1; seed <= 20; ++seed)
  {
    SCOPED_TRACE(seed);
    ExpectEveryVoxelOwnedOnce(grid, test::RandomPoints(grid, 5 + 7 * seed, seed));
  }
}

TEST(Rasterizer, EveryVoxelOwnedOnceWhenEveryVoxelIsAVertex)
{
  // The most degenerate set: all points of a grid, every cube's 8 corners cospherical.
  for (const GridSize grid : { GridSize{ 5, 5, 5 }, GridSize{ 2, 2, 2 }, GridSize{ 2, 7, 3 } })
  {
    std::vector<GridPoint> points;
    for (int32_t z = 0; z < grid.z; ++z)
      for (int32_t y = 0; y < grid.y; ++y)
        for (int32_t x = 0; x < grid.x; ++x)
          points.push_back({ x, y, z });
    ExpectEveryVoxelOwnedOnce(grid, points);
  }
}

TEST(Rasterizer, EveryVoxelOwnedOnceOnDegenerateLattices)
{
  const GridSize grid{ 17, 17, 17 };
  // A coarse lattice (cospherical cubes with voxels on every shared face), and the 8 corners alone.
  std::vector<GridPoint> lattice;
  for (int32_t z = 0; z < grid.z; z += 4)
    for (int32_t y = 0; y < grid.y; y += 4)
      for (int32_t x = 0; x < grid.x; x += 4)
        lattice.push_back({ x, y, z });
  ExpectEveryVoxelOwnedOnce(grid, lattice);
  ExpectEveryVoxelOwnedOnce(grid, test::Corners(grid));

  // Points on the faces of the box only, and points on one mid plane.
  std::vector<GridPoint> faces = test::Corners(grid);
  std::vector<GridPoint> plane = test::Corners(grid);
  for (int32_t a = 1; a < 16; a += 3)
    for (int32_t b = 2; b < 16; b += 5)
    {
      faces.push_back({ 0, a, b });
      faces.push_back({ a, 16, b });
      faces.push_back({ a, b, 0 });
      plane.push_back({ a, b, 8 });
    }
  ExpectEveryVoxelOwnedOnce(grid, faces);
  ExpectEveryVoxelOwnedOnce(grid, plane);
}

TEST(Rasterizer, LinearFunctionInterpolatesVertexValues)
{
  const std::array<GridPoint, 4> p{
    GridPoint{ 3, 1, 0 }, GridPoint{ 0, 0, 0 }, GridPoint{ 0, 5, 2 }, GridPoint{ 1, 1, 7 }
  };
  const std::array<double, 4> v{ 10.0, -2.0, 4.5, 100.0 };
  const LinearFunction        L{ CanonicalTetrahedron(p, v) };
  for (int i = 0; i < 4; ++i)
  {
    EXPECT_NEAR(L(p[i][0], p[i][1], p[i][2]), v[i], 1e-12);
  }
  // The order the vertices come in does not change a single bit.
  const std::array<GridPoint, 4> q{ p[2], p[0], p[3], p[1] };
  const std::array<double, 4>    w{ v[2], v[0], v[3], v[1] };
  const LinearFunction           M{ CanonicalTetrahedron(q, w) };
  EXPECT_EQ(L(1, 1, 2), M(1, 1, 2));
  EXPECT_EQ(L.gx, M.gx);
}

TEST(Rasterizer, ConvertValueRoundsAndClamps)
{
  EXPECT_EQ(ConvertValue<uint8_t>(-3.0), 0);
  EXPECT_EQ(ConvertValue<uint8_t>(254.5), 255);
  EXPECT_EQ(ConvertValue<uint8_t>(1e9), 255);
  EXPECT_EQ(ConvertValue<int16_t>(-2.5), -2);
  EXPECT_EQ(ConvertValue<int16_t>(-2.51), -3);
  EXPECT_EQ(ConvertValue<int16_t>(std::nan("")), std::numeric_limits<int16_t>::lowest());
  EXPECT_EQ(ConvertValue<float>(0.25), 0.25f);
}

TEST(Rasterizer, FlatTetrahedronOwnsNothing)
{
  const GridSize                 grid{ 4, 4, 4 };
  const std::array<GridPoint, 4> flat{
    GridPoint{ 0, 0, 0 }, GridPoint{ 3, 0, 0 }, GridPoint{ 0, 3, 0 }, GridPoint{ 3, 3, 0 }
  };
  int spans = 0;
  ForEachSpan(grid, flat, [&](int32_t, int32_t, int32_t, int32_t) { ++spans; });
  EXPECT_EQ(spans, 0);
}

} // namespace

TEST(Rasterizer, ThreadsAndSlabsGiveTheSameVoxels)
{
  // Few cells over a large grid are shared out by slabs of slices, many cells by chunks of cells: both,
  // with a residual layer, must give exactly what one thread gives.
  const GridSize grid{ 70, 64, 61 }; // above the size where one thread does it all
  for (const std::size_t n : { std::size_t(0), std::size_t(40), std::size_t(3000) })
  {
    SCOPED_TRACE(n);
    Approximation a;
    a.grid = grid;
    a.points = test::RandomPoints(grid, n, 7);
    for (std::size_t i = 0; i < a.points.size(); ++i)
      a.values.push_back(double((i * 37) % 251) - 3.25);
    a.tetrahedra = Tetrahedralize(a.points);
    a.residual.step = 1.5;
    a.residual.samples.resize(grid.NumberOfVoxels());
    for (std::size_t i = 0; i < a.residual.samples.size(); ++i)
      a.residual.samples[i] = int32_t(i % 13) - 6;
    std::vector<int16_t> one(grid.NumberOfVoxels(), 0);
    Rasterize(a, one.data(), 1);
    for (const unsigned int threads : { 2u, 3u, 8u })
    {
      std::vector<int16_t> many(grid.NumberOfVoxels(), 0);
      Rasterize(a, many.data(), threads);
      ASSERT_EQ(many, one) << threads << " threads";
    }
  }
}

namespace
{
/** The voxels as the rule gives them: each cell on its own, then the residual layer voxel by voxel. */
template <typename T>
std::vector<T>
CellByCell(const Approximation & a)
{
  std::vector<T> out(a.grid.NumberOfVoxels(), T(0));
  for (const Tetrahedron & t : a.tetrahedra)
    RasterizeTetrahedron(a.grid,
                         { a.points[t[0]], a.points[t[1]], a.points[t[2]], a.points[t[3]] },
                         { a.values[t[0]], a.values[t[1]], a.values[t[2]], a.values[t[3]] },
                         out.data());
  if (!a.residual.samples.empty())
    for (std::size_t i = 0; i < out.size(); ++i)
      out[i] = AddResidual(out[i], a.residual, i);
  return out;
}

template <typename T>
void
ExpectTheVoxelsOfTheCells(const Approximation & a)
{
  const std::vector<T> expected = CellByCell<T>(a);
  for (const unsigned int threads : { 1u, 2u })
  {
    std::vector<T> got(expected.size(), T(7));
    Rasterize(a, got.data(), threads);
    // Bytes, not values: a zero's sign counts for real types.
    ASSERT_EQ(std::memcmp(got.data(), expected.data(), got.size() * sizeof(T)), 0) << threads << " threads";
  }
}
} // namespace

TEST(Rasterizer, OneValueAndWholeStepsGiveWhatTheCellsGive)
{
  // The spline of one value (the corners under a residual layer) is filled without its cells, and a whole
  // step adds the layer in double without rounding: both must give the voxels of the plain rule, clamping
  // and zeros' signs included.
  const GridSize grid{ 67, 33, 40 };
  Approximation  a;
  a.grid = grid;
  a.points = test::RandomPoints(grid, 0, 1); // the 8 corners
  a.tetrahedra = Tetrahedralize(a.points);
  for (const double value : { 100.0, -0.0, 0.0, 3.5, -70000.25 })
  {
    for (const bool varied : { false, true })
    {
      a.values.assign(a.points.size(), value);
      if (varied)
        a.values.back() = value + 2.0; // not one value: the cells' path
      for (const double step : { 0.0, 1.0, 3.0, 2.5, double(1 << 20) })
      {
        SCOPED_TRACE("value " + std::to_string(value) + (varied ? " varied" : "") + ", step " + std::to_string(step));
        a.residual = {};
        if (step > 0.0)
        {
          a.residual.step = step;
          a.residual.samples.resize(grid.NumberOfVoxels());
          for (std::size_t i = 0; i < a.residual.samples.size(); ++i)
            a.residual.samples[i] = (i % 97 == 0) ? ((i % 2) ? 1 << 30 : -(1 << 30)) : int32_t(i % 61) * 401 - 12000;
        }
        ExpectTheVoxelsOfTheCells<uint8_t>(a);
        ExpectTheVoxelsOfTheCells<int16_t>(a);
        ExpectTheVoxelsOfTheCells<uint16_t>(a);
        ExpectTheVoxelsOfTheCells<int32_t>(a);
        ExpectTheVoxelsOfTheCells<float>(a);
        ExpectTheVoxelsOfTheCells<double>(a);
      }
    }
  }
}
