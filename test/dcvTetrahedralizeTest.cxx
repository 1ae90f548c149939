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
// Tetrahedralize, the decoder's tetrahedralization: from 20,000 points on several threads it is CGAL's
// concurrent triangulation (src/mesh/dcvTetrahedralize.cxx). Its listing must not depend on the threads, and
// its cells must be the encoder's (Tetrahedralization, built point by point).
#include "dcvParallel.h"
#include "dcvTestUtilities.h"
#include "dcvTetrahedralization.h"

#include <algorithm>
#include <set>

namespace
{
using namespace dcv;

struct Case
{
  const char *           name;
  std::vector<GridPoint> points;
  GridScale              scale;
};

/** Point sets of more than 20,000 points: a whole lattice (every cell's sphere holds more points than
 * its four: the symbolic perturbation decides every cell), random points at an anisotropic scale, and
 * random points in a thin slab with a scale across it. */
std::vector<Case>
Cases()
{
  std::vector<Case>      cases;
  std::vector<GridPoint> lattice;
  for (int32_t z = 0; z < 24; ++z)
    for (int32_t y = 0; y < 30; ++y)
      for (int32_t x = 0; x < 30; ++x)
        lattice.push_back({ x, y, z });
  cases.push_back({ "lattice", lattice, { { 1, 1, 1 } } });
  cases.push_back({ "random, scale 2,3,5", test::RandomPoints(GridSize{ 64, 60, 40 }, 21000, 11), { { 2, 3, 5 } } });
  cases.push_back({ "slab, scale 1,1,16", test::RandomPoints(GridSize{ 200, 180, 3 }, 21000, 5), { { 1, 1, 16 } } });
  return cases;
}

std::vector<Tetrahedron>
OnThreads(unsigned threads, const Case & c)
{
  return WithThreads(threads, [&] { return Tetrahedralize(c.points, c.scale); });
}

TEST(Tetrahedralize, TheSameListingWhateverTheThreads)
{
  for (const Case & c : Cases())
  {
    const std::vector<Tetrahedron> one = OnThreads(1, c);
    ASSERT_GT(one.size(), c.points.size()) << c.name;
    EXPECT_EQ(OnThreads(2, c), one) << c.name;
    EXPECT_EQ(OnThreads(4, c), one) << c.name;
  }
}

TEST(Tetrahedralize, TheEncodersCellsEachListedInOneOrderAndPositivelyOriented)
{
  for (const Case & c : Cases())
  {
    Tetrahedralization mesh;
    mesh.SetScale(c.scale);
    for (const GridPoint & p : c.points) // one at a time, as the encoder inserts
    {
      std::vector<Tetrahedralization::CellId> killed;
      std::vector<Tetrahedralization::Cell>   created;
      mesh.Insert(p, Tetrahedralization::NoCell, killed, created);
    }
    std::set<Tetrahedron> encoders;
    for (const auto & cell : mesh.FiniteCells())
    {
      Tetrahedron t = cell.vertices;
      std::sort(t.begin(), t.end());
      encoders.insert(t);
    }
    const std::vector<Tetrahedron> listed = OnThreads(2, c);
    std::set<Tetrahedron>          decoders;
    for (const Tetrahedron & t : listed)
    {
      // Ascending ids but for the last two, swapped where that keeps the orientation positive.
      ASSERT_TRUE(t[0] < t[1] && t[1] < t[2] && t[1] < t[3] && t[2] != t[3]) << c.name;
      std::array<GridPoint, 4> p;
      for (int k = 0; k < 4; ++k)
        for (int d = 0; d < 3; ++d)
          p[k][d] = c.points[t[k]][d] * c.scale[d];
      ASSERT_GT(SignedVolume6(p), 0) << c.name;
      Tetrahedron sorted = t;
      std::sort(sorted.begin(), sorted.end());
      decoders.insert(sorted);
    }
    EXPECT_EQ(decoders.size(), listed.size()) << c.name << ": a cell listed twice";
    EXPECT_EQ(decoders, encoders) << c.name;
  }
}

TEST(Tetrahedralize, RefusesDuplicatesAndPointsBeyondTheGridsOnEveryPath)
{
  for (unsigned threads : { 1u, 2u })
  {
    Case c = Cases()[1];
    c.points.push_back(c.points[100]);
    EXPECT_THROW(OnThreads(threads, c), std::invalid_argument) << threads << " threads";
    c.points.pop_back();
    c.points.push_back({ (int32_t(1) << 20) / 2, 0, 0 }); // at scale 2: 2^20, one past the last
    EXPECT_THROW(OnThreads(threads, c), std::invalid_argument) << threads << " threads";
    c.scale = { { 1, 17, 1 } };
    c.points.pop_back();
    EXPECT_THROW(OnThreads(threads, c), std::invalid_argument) << threads << " threads";
  }
}
} // namespace
