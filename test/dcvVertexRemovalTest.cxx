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
// The decimation's vertex removal (src/mesh/dcvVertexRemoval.h) against CGAL's own: after every removal the
// same cells with their vertices in the same order (what the least squares and the costs read), on
// random points, on whole lattices (every cell cospherical with its neighbours) and on the hull.
#include "dcvVertexRemoval.h"
#include "dcvGridKernel.h"
#include "dcvTestUtilities.h"

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Delaunay_triangulation_cell_base_3.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <random>
#include <vector>

namespace
{
constexpr uint32_t NoCell = 0xffffffffu;
struct CellInfo // as the engine's: an id, NoCell when made
{
  uint32_t id{ NoCell };
  uint32_t
  Id() const
  {
    return id;
  }
  void
  SetId(uint32_t v)
  {
    id = v;
  }
};
using Kernel = dcv::GridKernel; // the library's (src/mesh/dcvTetrahedralization.cxx)
using VertexBase = CGAL::Triangulation_vertex_base_with_info_3<uint32_t, Kernel>;
using CellBase =
  CGAL::Triangulation_cell_base_with_info_3<CellInfo, Kernel, CGAL::Delaunay_triangulation_cell_base_3<Kernel>>;
using Delaunay =
  CGAL::Delaunay_triangulation_3<Kernel,
                                 CGAL::Triangulation_data_structure_3<VertexBase, CellBase, CGAL::Sequential_tag>>;
using Cells = std::vector<std::array<uint32_t, 4>>;

struct Compared
{
  std::size_t byLink{ 0 };
  std::size_t removals{ 0 };
};

/** Builds two triangulations of `points`, removes `order` from both (one by RemoveByLink, one by CGAL),
 * and compares them after each removal. */
Compared
RemoveFromBoth(const std::vector<std::array<int, 3>> & points, const std::vector<std::size_t> & order)
{
  Delaunay                             mine, theirs;
  std::vector<Delaunay::Vertex_handle> mineV, theirsV;
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    const Delaunay::Point p(points[i][0], points[i][1], points[i][2]);
    mineV.push_back(mine.insert(p));
    mineV.back()->info() = uint32_t(i);
    theirsV.push_back(theirs.insert(p));
    theirsV.back()->info() = uint32_t(i);
  }
  EXPECT_EQ(dcv::test::ListedCells(mine), dcv::test::ListedCells(theirs));
  dcv::VertexRemovalScratch<Delaunay> scratch;
  std::vector<Delaunay::Cell_handle>  hole, created, cgal;
  Compared                            result;
  for (std::size_t i : order)
  {
    hole.clear();
    mine.incident_cells(mineV[i], std::back_inserter(hole));
    if (dcv::RemoveByLink(mine, mineV[i], hole, created, scratch, NoCell))
      ++result.byLink;
    else
      mine.remove(mineV[i]);
    cgal.clear();
    theirs.remove_and_give_new_cells(theirsV[i], std::back_inserter(cgal));
    ++result.removals;
    EXPECT_TRUE(mine.is_valid()) << "after removing vertex " << i;
    const Cells a = dcv::test::ListedCells(mine), b = dcv::test::ListedCells(theirs);
    EXPECT_EQ(a, b) << "after removing vertex " << i;
    if (a != b)
      break;
  }
  return result;
}

std::vector<std::array<int, 3>>
Box(int n) // the 8 corners of [0, n]^3
{
  std::vector<std::array<int, 3>> corners;
  for (int z : { 0, n })
    for (int y : { 0, n })
      for (int x : { 0, n })
        corners.push_back({ x, y, z });
  return corners;
}
} // namespace

TEST(VertexRemoval, TheSameCellsAsCGALsOnRandomPoints)
{
  std::mt19937                    random(11);
  std::vector<std::array<int, 3>> points = Box(40);
  while (points.size() < 600)
  {
    const std::array<int, 3> p{ int(random() % 41), int(random() % 41), int(random() % 41) };
    if (std::find(points.begin(), points.end(), p) == points.end())
      points.push_back(p);
  }
  std::vector<std::size_t> order;
  for (std::size_t i = 8; i < points.size(); ++i)
    order.push_back(i);
  std::shuffle(order.begin(), order.end(), random);
  order.resize(450);
  const Compared c = RemoveFromBoth(points, order);
  EXPECT_EQ(c.removals, 450u);
  EXPECT_EQ(c.byLink, c.removals) << "CGAL's removal was asked for";
}

TEST(VertexRemoval, TheSameCellsAsCGALsOnALatticeAndItsFaces)
{
  // A whole 6 x 6 x 6 lattice: every removal's link is cospherical and much of it on the hull (the box's
  // faces), where the infinite vertex is in the link.
  std::vector<std::array<int, 3>> points = Box(5);
  for (int z = 0; z <= 5; ++z)
    for (int y = 0; y <= 5; ++y)
      for (int x = 0; x <= 5; ++x)
        if (std::find(points.begin(), points.end(), std::array<int, 3>{ x, y, z }) == points.end())
          points.push_back({ x, y, z });
  std::vector<std::size_t> order;
  for (std::size_t i = 8; i < points.size(); ++i)
    order.push_back(i);
  std::mt19937 random(5);
  std::shuffle(order.begin(), order.end(), random);
  const Compared c = RemoveFromBoth(points, order);
  EXPECT_EQ(c.removals, points.size() - 8);
  EXPECT_EQ(c.byLink, c.removals) << "CGAL's removal was asked for";
}
