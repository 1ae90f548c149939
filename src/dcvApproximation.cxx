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
#include "dcvApproximation.h"
#include "dcvTetrahedralization.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace dcv
{

namespace
{
/** Spreads the low 21 bits of v to every third bit. */
uint64_t
Spread(uint64_t v)
{
  v &= 0x1fffff;
  v = (v | (v << 32)) & 0x1f00000000ffffULL;
  v = (v | (v << 16)) & 0x1f0000ff0000ffULL;
  v = (v | (v << 8)) & 0x100f00f00f00f00fULL;
  v = (v | (v << 4)) & 0x10c30c30c30c30c3ULL;
  v = (v | (v << 2)) & 0x1249249249249249ULL;
  return v;
}
} // namespace

std::vector<Tetrahedron>
Tetrahedralize(const std::vector<GridPoint> & points, const GridScale & scale)
{
  Tetrahedralization mesh;
  mesh.SetScale(scale);
  mesh.InsertMany(points);
  const auto cells = mesh.FiniteCells();
  // CGAL lists cells in memory order, which is scattered in space; rasterizing them in the Morton
  // order of their centroids keeps the voxels being written in cache (several times faster).
  std::vector<std::pair<uint64_t, Tetrahedron>> keyed;
  keyed.reserve(cells.size());
  for (const auto & c : cells)
  {
    uint64_t sum[3] = { 0, 0, 0 };
    for (auto v : c.vertices)
    {
      for (int d = 0; d < 3; ++d)
      {
        sum[d] += uint64_t(points[v][d]);
      }
    }
    keyed.emplace_back(Spread(sum[0]) | (Spread(sum[1]) << 1) | (Spread(sum[2]) << 2), c.vertices);
  }
  std::sort(keyed.begin(), keyed.end(), [](const auto & a, const auto & b) { return a.first < b.first; });
  std::vector<Tetrahedron> out;
  out.reserve(keyed.size());
  for (const auto & k : keyed)
  {
    out.push_back(k.second);
  }
  return out;
}

void
CheckPoints(const GridSize & grid, const std::vector<GridPoint> & points)
{
  int corners = 0;
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    const GridPoint & p = points[i];
    if (p[0] < 0 || p[1] < 0 || p[2] < 0 || p[0] >= grid.x || p[1] >= grid.y || p[2] >= grid.z)
    {
      throw std::invalid_argument("point " + std::to_string(i) + " (" + std::to_string(p[0]) + ", " +
                                  std::to_string(p[1]) + ", " + std::to_string(p[2]) + ") lies outside the " +
                                  std::to_string(grid.x) + "x" + std::to_string(grid.y) + "x" + std::to_string(grid.z) +
                                  " grid");
    }
    const bool cx = p[0] == 0 || p[0] == grid.x - 1;
    const bool cy = p[1] == 0 || p[1] == grid.y - 1;
    const bool cz = p[2] == 0 || p[2] == grid.z - 1;
    corners += (cx && cy && cz) ? 1 : 0;
  }
  if (corners < 8)
  {
    throw std::invalid_argument("the points do not include the 8 corners of the grid, so they cannot cover it");
  }
}

double
PSNR(double squaredError, uint64_t voxels, double peak)
{
  if (squaredError <= 0.0 || voxels == 0)
  {
    return std::numeric_limits<double>::infinity();
  }
  const double mse = squaredError / double(voxels);
  return 10.0 * std::log10(peak * peak / mse);
}

} // namespace dcv
