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
// src/mesh/dcvGridKernel.h: its integer predicates against Epick's exact ones, sign for sign, on degenerate
// grids, on random points up to the coordinate limit and on cospherical points of the largest sphere
// the limit holds; and triangulations made with it against Epick's, cell for cell, through insertions
// and removals.
#include "dcvGridKernel.h"
#include "dcvTestUtilities.h"

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <random>
#include <vector>

namespace
{
using dcv::GridKernel;
using Point = CGAL::Epick::Point_3;
constexpr int64_t Limit = GridKernel::CoordinateLimit;

/** Compares both predicates with Epick's on the five points; counts the zero signs seen. */
struct Checker
{
  CGAL::Epick epick;
  GridKernel  grid;
  std::size_t zeros{ 0 };
  std::size_t checked{ 0 };
  ::testing::AssertionResult
  operator()(const std::array<Point, 5> & p)
  {
    const auto sphere = grid.side_of_oriented_sphere_3_object()(p[0], p[1], p[2], p[3], p[4]);
    const auto sphereExact = epick.side_of_oriented_sphere_3_object()(p[0], p[1], p[2], p[3], p[4]);
    const auto orientation = grid.orientation_3_object()(p[0], p[1], p[2], p[3]);
    const auto orientationExact = epick.orientation_3_object()(p[0], p[1], p[2], p[3]);
    ++checked;
    zeros += (sphereExact == CGAL::ZERO) + (orientationExact == CGAL::ZERO);
    if (sphere != sphereExact || orientation != orientationExact)
    {
      auto failure = ::testing::AssertionFailure();
      for (const Point & q : p)
        failure << "(" << q.x() << ", " << q.y() << ", " << q.z() << ") ";
      return failure << "in-sphere " << int(sphere) << " against " << int(sphereExact) << ", orientation "
                     << int(orientation) << " against " << int(orientationExact);
    }
    return ::testing::AssertionSuccess();
  }
};

TEST(GridKernel, PredicatesMatchEpickOnDegenerateGrids)
{
  // Coordinates 0..3: coplanar and cospherical tuples everywhere (and repeated points).
  std::mt19937                           random(7);
  std::uniform_int_distribution<int64_t> coordinate(0, 3);
  Checker                                check;
  for (int n = 0; n < 200000; ++n)
  {
    std::array<Point, 5> p;
    for (Point & q : p)
      q = Point(double(coordinate(random)), double(coordinate(random)), double(coordinate(random)));
    ASSERT_TRUE(check(p));
  }
  EXPECT_GT(check.zeros, check.checked / 10) << "the grid should give many degenerate tuples";
}

TEST(GridKernel, PredicatesMatchEpickUpToTheCoordinateLimit)
{
  std::mt19937 random(11);
  Checker      check;
  // Anywhere below the limit, and near its two ends, where the determinants are largest.
  std::uniform_int_distribution<int64_t> anywhere(0, Limit - 1), low(0, 3), high(Limit - 4, Limit - 1);
  for (int n = 0; n < 200000; ++n)
  {
    std::array<Point, 5> p;
    for (Point & q : p)
    {
      double c[3];
      for (double & x : c)
      {
        const int kind = int(random() % 3);
        x = double(kind == 0 ? anywhere(random) : kind == 1 ? low(random) : high(random));
      }
      q = Point(c[0], c[1], c[2]);
    }
    ASSERT_TRUE(check(p));
  }
}

TEST(GridKernel, PredicatesMatchEpickOnTheLargestSpheres)
{
  // The six poles of the largest sphere around the middle of the range: exactly cospherical at the
  // largest magnitudes, then each pole moved by one unit, in or out (in-sphere determinants of some
  // 2^100 decided by a difference of one unit in one coordinate).
  const int64_t              c = Limit / 2, r = Limit / 2 - 1;
  const std::array<Point, 6> poles = {
    Point(double(c + r), double(c), double(c)), Point(double(c - r), double(c), double(c)),
    Point(double(c), double(c + r), double(c)), Point(double(c), double(c - r), double(c)),
    Point(double(c), double(c), double(c + r)), Point(double(c), double(c), double(c - r))
  };
  Checker                         check;
  std::vector<std::array<int, 5>> choices;
  for (int a = 0; a < 6; ++a)
    for (int b = 0; b < 6; ++b)
      for (int d = 0; d < 6; ++d)
        for (int e = 0; e < 6; ++e)
          for (int f = 0; f < 6; ++f)
            choices.push_back({ a, b, d, e, f });
  for (const auto & k : choices)
  {
    for (int moved = -1; moved < 5; ++moved)
      for (int axis = 0; axis < 3; ++axis)
        for (int step : { -1, 1 })
        {
          std::array<Point, 5> p;
          for (int i = 0; i < 5; ++i)
            p[std::size_t(i)] = poles[std::size_t(k[std::size_t(i)])];
          if (moved >= 0)
          {
            double q[3] = { p[std::size_t(moved)].x(), p[std::size_t(moved)].y(), p[std::size_t(moved)].z() };
            q[axis] = std::min(double(Limit - 1), std::max(0.0, q[axis] + step));
            p[std::size_t(moved)] = Point(q[0], q[1], q[2]);
          }
          ASSERT_TRUE(check(p));
        }
  }
  EXPECT_GT(check.zeros, std::size_t(0));
}

template <typename K>
using Delaunay = CGAL::Delaunay_triangulation_3<
  K, CGAL::Triangulation_data_structure_3<CGAL::Triangulation_vertex_base_with_info_3<uint32_t, K>,
                                          CGAL::Delaunay_triangulation_cell_base_3<K>>>;

TEST(GridKernel, TriangulationsAreEpicksCellForCell)
{
  // A whole lattice (cospherical everywhere), then random points at a large scale, inserted one by one
  // and removed again, compared after every change.
  for (const int64_t scale : { int64_t(1), int64_t(9973) })
  {
    std::vector<Point> points;
    for (int z = 0; z < 5; ++z)
      for (int y = 0; y < 5; ++y)
        for (int x = 0; x < 5; ++x)
          points.emplace_back(double(x * scale), double(y * scale), double(z * scale));
    std::mt19937                           random(3);
    std::uniform_int_distribution<int64_t> coordinate(0, 100);
    for (int n = 0; n < 150; ++n)
      points.emplace_back(double(coordinate(random) * scale / 25),
                          double(coordinate(random) * scale / 25),
                          double(coordinate(random) * scale / 25));
    Delaunay<CGAL::Epick>                                      epick;
    Delaunay<GridKernel>                                       grid;
    std::vector<typename Delaunay<CGAL::Epick>::Vertex_handle> epickVertices;
    std::vector<typename Delaunay<GridKernel>::Vertex_handle>  gridVertices;
    for (uint32_t i = 0; i < points.size(); ++i)
    {
      const auto a = epick.insert(points[i]);
      const auto b = grid.insert(points[i]);
      a->info() = i;
      b->info() = i;
      epickVertices.push_back(a);
      gridVertices.push_back(b);
      ASSERT_EQ(dcv::test::ListedCells(epick), dcv::test::ListedCells(grid))
        << "after inserting point " << i << " at scale " << scale;
    }
    for (uint32_t i = 0; i < points.size(); i += 3)
    {
      if (epickVertices[i]->info() != i)
        continue; // a repeated point: the same vertex as an earlier one
      epick.remove(epickVertices[i]);
      grid.remove(gridVertices[i]);
      ASSERT_EQ(dcv::test::ListedCells(epick), dcv::test::ListedCells(grid))
        << "after removing point " << i << " at scale " << scale;
    }
    EXPECT_TRUE(grid.is_valid());
  }
}
} // namespace
