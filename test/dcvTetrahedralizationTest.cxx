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
// The decoder relies on the Delaunay tetrahedralization of a grid point set being unique.
#include "dcvTestUtilities.h"
#include "dcvTetrahedralization.h"

#include <algorithm>
#include <set>
#include <thread>

namespace
{
using namespace dcv;
using CellSet = std::set<std::array<GridPoint, 4>>;

/** Cells as sorted vertex positions: comparable across point orders. */
CellSet
Cells(const std::vector<GridPoint> & points, const std::vector<Tetrahedron> & tets)
{
  CellSet out;
  for (const auto & t : tets)
  {
    std::array<GridPoint, 4> c{ points[t[0]], points[t[1]], points[t[2]], points[t[3]] };
    std::sort(c.begin(), c.end());
    out.insert(c);
  }
  return out;
}

TEST(Tetrahedralization, UniqueWhateverTheInsertionOrder)
{
  const GridSize         grid{ 16, 16, 16 };
  std::vector<GridPoint> points = test::RandomPoints(grid, 600, 7);
  const CellSet          reference = Cells(points, Tetrahedralize(points));
  std::mt19937           random(3);
  for (int order = 0; order < 10; ++order)
  {
    std::shuffle(points.begin(), points.end(), random);
    EXPECT_EQ(Cells(points, Tetrahedralize(points)), reference) << "order " << order;
  }
}

TEST(Tetrahedralization, ScaledSpaceIsUniqueAndThinsCellsAcrossSlices)
{
  const GridSize         grid{ 20, 20, 6 };
  const GridScale        thick{ { 1, 1, 8 } };
  std::vector<GridPoint> points = test::RandomPoints(grid, 300, 11);
  const CellSet          reference = Cells(points, Tetrahedralize(points, thick));
  std::mt19937           random(5);
  for (int order = 0; order < 5; ++order)
  {
    std::shuffle(points.begin(), points.end(), random);
    EXPECT_EQ(Cells(points, Tetrahedralize(points, thick)), reference) << "order " << order;
  }
  EXPECT_NE(Cells(points, Tetrahedralize(points)), reference); // another metric, another mesh
  // Cells that span several slices are rarer when slices count as thick.
  auto spanning = [&points](const std::vector<Tetrahedron> & tets) {
    std::size_t n = 0;
    for (const auto & t : tets)
    {
      const auto [lo, hi] = std::minmax({ points[t[0]][2], points[t[1]][2], points[t[2]][2], points[t[3]][2] });
      n += hi - lo > 1 ? 1 : 0;
    }
    return n;
  };
  EXPECT_LT(spanning(Tetrahedralize(points, thick)), spanning(Tetrahedralize(points)));
  Tetrahedralization bad;
  EXPECT_THROW(bad.SetScale({ { 1, 0, 1 } }), std::invalid_argument);
  EXPECT_THROW(bad.SetScale({ { 1, 1, MaximumGridScale + 1 } }), std::invalid_argument);
}

TEST(Tetrahedralization, IncrementalInsertionReportsTheCavity)
{
  const GridSize                        grid{ 12, 10, 9 };
  const std::vector<GridPoint>          points = test::RandomPoints(grid, 150, 11);
  Tetrahedralization                    mesh;
  std::vector<uint32_t>                 killed;
  std::vector<Tetrahedralization::Cell> created;
  std::set<uint32_t>                    alive;
  for (const GridPoint & p : points)
  {
    mesh.Insert(p, Tetrahedralization::NoCell, killed, created);
    for (auto k : killed)
    {
      ASSERT_EQ(alive.erase(k), 1u) << "a dead cell was not alive";
    }
    for (const auto & c : created)
    {
      ASSERT_TRUE(alive.insert(c.id).second) << "a cell identifier was reused";
    }
  }
  ASSERT_TRUE(mesh.IsValid());
  // What the reports left alive is exactly the set of finite cells.
  std::set<uint32_t> finite;
  for (const auto & c : mesh.FiniteCells())
  {
    finite.insert(c.id);
  }
  EXPECT_EQ(alive, finite);
  // And it equals the bulk build of the same points.
  std::vector<Tetrahedron> incremental;
  for (const auto & c : mesh.FiniteCells())
  {
    incremental.push_back(c.vertices);
  }
  EXPECT_EQ(Cells(points, incremental), Cells(points, Tetrahedralize(points)));
}

TEST(Tetrahedralization, RemovalGivesTheTetrahedralizationOfTheRest)
{
  const GridSize         grid{ 16, 16, 16 };
  std::vector<GridPoint> points = test::RandomPoints(grid, 400, 5);
  Tetrahedralization     mesh;
  mesh.InsertMany(points);
  std::vector<uint32_t>                 killed;
  std::vector<Tetrahedralization::Cell> created;
  std::set<uint32_t>                    removed;
  for (uint32_t v = 8; v < points.size(); v += 3) // never a corner
  {
    mesh.Remove(v, killed, created);
    removed.insert(v);
    EXPECT_FALSE(killed.empty());
  }
  ASSERT_TRUE(mesh.IsValid());
  std::vector<GridPoint> rest;
  for (uint32_t v = 0; v < points.size(); ++v)
  {
    if (!removed.count(v))
    {
      rest.push_back(points[v]);
    }
  }
  std::vector<Tetrahedron> after;
  for (const auto & c : mesh.FiniteCells())
  {
    after.push_back(c.vertices);
  }
  EXPECT_EQ(Cells(points, after), Cells(rest, Tetrahedralize(rest)));
}

TEST(Tetrahedralization, CompactedCellIdsAreDenseAndKeepTheirOrder)
{
  const GridSize         grid{ 16, 16, 16 };
  std::vector<GridPoint> points = test::RandomPoints(grid, 300, 7);
  Tetrahedralization     mesh;
  mesh.InsertMany(points);
  std::vector<uint32_t>                 killed;
  std::vector<Tetrahedralization::Cell> created;
  for (uint32_t v = 8; v < points.size(); v += 2)
  {
    mesh.Remove(v, killed, created);
  }
  const auto before = mesh.FiniteCells();
  ASSERT_GT(mesh.NumberOfCellIds(), before.size());     // dead ids are kept until compaction
  ASSERT_EQ(before.size(), mesh.NumberOfFiniteCells()); // CGAL's own count: every dead cell was forgotten
  // Ranges of ids give the same cells, a part at a time.
  std::vector<Tetrahedralization::Cell> parts, part;
  for (uint32_t first = 0; first < mesh.NumberOfCellIds(); first += 37)
  {
    mesh.FiniteCells(first, first + 37, part);
    for (const auto & c : part)
    {
      EXPECT_TRUE(c.id >= first && c.id < first + 37);
    }
    parts.insert(parts.end(), part.begin(), part.end());
  }
  ASSERT_EQ(parts.size(), before.size());
  for (std::size_t i = 0; i < parts.size(); ++i)
  {
    EXPECT_EQ(parts[i].id, before[i].id);
    EXPECT_EQ(parts[i].vertices, before[i].vertices);
  }
  // A list of ids gives their cells in its order; a dead id is refused.
  std::vector<Tetrahedralization::CellId> ids;
  for (std::size_t i = before.size(); i-- > 0;)
  {
    ids.push_back(before[i].id);
  }
  mesh.FiniteCells(ids.data(), ids.size(), part);
  ASSERT_EQ(part.size(), before.size());
  for (std::size_t i = 0; i < part.size(); ++i)
  {
    EXPECT_EQ(part[i].id, ids[i]);
    EXPECT_EQ(part[i].vertices, before[before.size() - 1 - i].vertices);
  }
  Tetrahedralization::CellId dead = 0;
  while (std::any_of(before.begin(), before.end(), [&](const auto & c) { return c.id == dead; }))
  {
    ++dead;
  }
  EXPECT_THROW(mesh.FiniteCells(&dead, 1, part), std::invalid_argument);
  const auto renumbered = mesh.CompactCellIds();
  EXPECT_EQ(renumbered.size(), std::size_t(before.back().id) + 1);
  EXPECT_EQ(mesh.NumberOfCellIds(), before.size());
  const auto after = mesh.FiniteCells();
  ASSERT_EQ(after.size(), before.size());
  for (std::size_t i = 0; i < after.size(); ++i)
  {
    EXPECT_EQ(after[i].id, i);                        // dense
    EXPECT_EQ(after[i].vertices, before[i].vertices); // same cells, same order
    EXPECT_EQ(renumbered[before[i].id], Tetrahedralization::CellId(i));
  }
  // The new ids work as hints and in further operations.
  mesh.Insert({ 3, 4, 5 }, after.front().id, killed, created);
  for (auto c : killed)
  {
    EXPECT_LT(c, after.size());
  }
  for (const auto & c : created)
  {
    EXPECT_GE(c.id, after.size());
  }
  EXPECT_TRUE(mesh.IsValid());
}

/** The finite cells incident to each vertex, by brute force over all finite cells (those CGAL's own
 * incident_cells lists), as sorted lists of (id, vertices): a cell listed twice shows. */
using Star = std::vector<std::pair<uint32_t, Tetrahedron>>;
std::vector<Star>
StarsOfAllCells(const Tetrahedralization & mesh)
{
  std::vector<Star> stars(mesh.NumberOfVertexIds());
  for (const auto & c : mesh.FiniteCells())
  {
    for (auto v : c.vertices)
    {
      stars[v].emplace_back(c.id, c.vertices);
    }
  }
  for (auto & s : stars)
  {
    std::sort(s.begin(), s.end());
  }
  return stars;
}

Star
WalkedStar(const Tetrahedralization & mesh, uint32_t v)
{
  std::vector<Tetrahedralization::Cell> cells;
  mesh.IncidentCells(v, cells);
  Star s;
  for (const auto & c : cells)
  {
    s.emplace_back(c.id, c.vertices);
  }
  std::sort(s.begin(), s.end());
  return s;
}

TEST(Tetrahedralization, IncidentCellsWalkFindsTheWholeStar)
{
  // Random points (vertices on the hull's faces and edges among them: their stars go through infinite
  // cells), and a centre on a sphere of 84 grid points (2 * 84 - 4 cells: more than the walk's hash table
  // takes). Removals and insertions then recycle CGAL's cells, so walks start from varied cells.
  const GridSize         grid{ 17, 17, 17 };
  std::vector<GridPoint> points = test::RandomPoints(grid, 500, 13);
  std::vector<GridPoint> sphere{ { 8, 8, 8 } };
  for (int32_t z = 1; z < 16; ++z)
  {
    for (int32_t y = 1; y < 16; ++y)
    {
      for (int32_t x = 1; x < 16; ++x)
      {
        if ((x - 8) * (x - 8) + (y - 8) * (y - 8) + (z - 8) * (z - 8) == 50)
        {
          sphere.push_back({ x, y, z });
        }
      }
    }
  }
  ASSERT_EQ(sphere.size(), 85u);
  Tetrahedralization mesh;
  mesh.InsertMany(test::Corners(grid));
  mesh.InsertMany(sphere);
  std::vector<uint32_t>                 killed;
  std::vector<Tetrahedralization::Cell> created;
  EXPECT_GT(WalkedStar(mesh, 8).size(), 128u); // the centre
  EXPECT_EQ(WalkedStar(mesh, 8), StarsOfAllCells(mesh)[8]);
  for (std::size_t i = 8; i < points.size(); ++i)
  {
    if (std::find(sphere.begin(), sphere.end(), points[i]) == sphere.end())
    {
      mesh.Insert(points[i], Tetrahedralization::NoCell, killed, created);
    }
  }
  const uint32_t firstRandom = 8 + 85;
  for (uint32_t v = firstRandom; v < mesh.NumberOfVertexIds(); v += 4)
  {
    mesh.Remove(v, killed, created);
  }
  ASSERT_TRUE(mesh.IsValid());
  const std::vector<Star> reference = StarsOfAllCells(mesh);
  std::vector<uint32_t>   alive;
  for (uint32_t v = 0; v < mesh.NumberOfVertexIds(); ++v)
  {
    if (!reference[v].empty())
    {
      alive.push_back(v);
    }
  }
  ASSERT_EQ(alive.size(), mesh.NumberOfVertices());
  for (uint32_t v : alive)
  {
    ASSERT_EQ(WalkedStar(mesh, v), reference[v]) << "vertex " << v;
  }
  // It only reads: walks on several threads at once find the same.
  std::vector<std::thread> threads;
  std::vector<int>         wrong(4, 0);
  for (std::size_t t = 0; t < wrong.size(); ++t)
  {
    threads.emplace_back([&, t] {
      for (int pass = 0; pass < 20; ++pass)
      {
        for (uint32_t v : alive)
        {
          wrong[t] += WalkedStar(mesh, v) != reference[v] ? 1 : 0;
        }
      }
    });
  }
  for (auto & t : threads)
  {
    t.join();
  }
  EXPECT_EQ(wrong, std::vector<int>(wrong.size(), 0));
  EXPECT_THROW(mesh.IncidentCells(firstRandom, created), std::logic_error); // removed
}

/** IncidentVolumes() against the brute-force stars: the same cells, each with |SignedVolume6| of its grid
 * points (not of the scaled points the tetrahedralization is built on). */
void
ExpectStarVolumes(const Tetrahedralization & mesh)
{
  const std::vector<Star>                    reference = StarsOfAllCells(mesh);
  std::vector<std::pair<uint32_t, uint64_t>> walked;
  std::size_t                                checked = 0;
  for (uint32_t v = 0; v < mesh.NumberOfVertexIds(); ++v)
  {
    if (reference[v].empty())
    {
      continue;
    }
    std::vector<std::pair<uint32_t, uint64_t>> expected;
    for (const auto & [id, vertices] : reference[v])
    {
      const std::array<GridPoint, 4> p{
        mesh.Point(vertices[0]), mesh.Point(vertices[1]), mesh.Point(vertices[2]), mesh.Point(vertices[3])
      };
      expected.emplace_back(id, uint64_t(std::abs(SignedVolume6(p))));
    }
    mesh.IncidentVolumes(v, walked);
    std::sort(walked.begin(), walked.end());
    ASSERT_EQ(walked, expected) << "vertex " << v;
    ++checked;
  }
  EXPECT_EQ(checked, mesh.NumberOfVertices());
}

TEST(Tetrahedralization, IncidentVolumesAreThoseOfTheStar)
{
  // Anisotropic scale, then insertions one by one and removals (cells CGAL recycles), then many at once.
  const GridSize     grid{ 21, 15, 9 };
  Tetrahedralization mesh;
  mesh.SetScale({ 2, 1, 3 });
  mesh.InsertMany(test::Corners(grid));
  std::vector<uint32_t>                 killed;
  std::vector<Tetrahedralization::Cell> created;
  const std::vector<GridPoint>          points = test::RandomPoints(grid, 300, 7);
  for (std::size_t i = 8; i < 200; ++i)
  {
    mesh.Insert(points[i], Tetrahedralization::NoCell, killed, created);
  }
  for (uint32_t v = 8; v < 200; v += 3)
  {
    mesh.Remove(v, killed, created);
  }
  ExpectStarVolumes(mesh);
  mesh.InsertMany(std::vector<GridPoint>(points.begin() + 200, points.end()));
  ExpectStarVolumes(mesh);
  std::vector<std::pair<uint32_t, uint64_t>> removed;
  EXPECT_THROW(mesh.IncidentVolumes(8, removed), std::logic_error);
}

TEST(Tetrahedralization, IncidentVolumesBeyond24Bits)
{
  // A 1000 x 800 x 600 grid with a few points: six times the volume of some cells is above the 24 bits
  // kept with each cell (those are computed from their points), of others below.
  const GridSize     grid{ 1000, 800, 600 };
  Tetrahedralization mesh;
  mesh.InsertMany(test::RandomPoints(grid, 12, 5));
  uint64_t smallest = ~uint64_t(0), largest = 0;
  for (const auto & c : mesh.FiniteCells())
  {
    const uint64_t v = uint64_t(std::abs(SignedVolume6(
      { mesh.Point(c.vertices[0]), mesh.Point(c.vertices[1]), mesh.Point(c.vertices[2]), mesh.Point(c.vertices[3]) })));
    smallest = std::min(smallest, v);
    largest = std::max(largest, v);
  }
  ASSERT_GT(largest, uint64_t(1) << 24);
  ASSERT_LT(smallest, uint64_t(1) << 24);
  ExpectStarVolumes(mesh);
}

TEST(Tetrahedralization, DuplicatePointsAreRefused)
{
  std::vector<GridPoint> points = test::Corners(GridSize{ 4, 4, 4 });
  points.push_back(points[3]);
  EXPECT_THROW(Tetrahedralize(points), std::invalid_argument);
}

TEST(Tetrahedralization, PointsBeyondTheLargestGridAreRefusedBeforeAnyChange)
{
  // The largest grid, 65535 voxels an axis at a scale of 16, is held (the integer predicates of
  // src/mesh/dcvGridKernel.h are exact below 2^20 scaled); a point at 2^20 or beyond, or below 0, is refused
  // and leaves the mesh as it was.
  const GridSize     grid{ MaximumGridExtent, MaximumGridExtent, MaximumGridExtent };
  Tetrahedralization mesh;
  mesh.SetScale({ MaximumGridScale, MaximumGridScale, MaximumGridScale });
  mesh.InsertMany(test::Corners(grid));
  std::vector<Tetrahedralization::CellId> killed;
  std::vector<Tetrahedralization::Cell>   created;
  mesh.Insert({ MaximumGridExtent - 2, 1, MaximumGridExtent / 2 }, Tetrahedralization::NoCell, killed, created);
  EXPECT_TRUE(mesh.IsValid());
  const std::size_t cells = mesh.NumberOfFiniteCells();
  for (const GridPoint & p :
       { GridPoint{ MaximumGridExtent + 1, 0, 0 }, GridPoint{ 0, -1, 0 }, GridPoint{ 3, 4, 70000 } })
  {
    EXPECT_THROW(mesh.Insert(p, Tetrahedralization::NoCell, killed, created), std::invalid_argument);
    EXPECT_THROW(mesh.InsertMany({ { 1, 1, 1 }, p }), std::invalid_argument);
  }
  EXPECT_EQ(mesh.NumberOfVertexIds(), 9u);
  EXPECT_EQ(mesh.NumberOfFiniteCells(), cells);
  EXPECT_TRUE(mesh.IsValid());
}

} // namespace
