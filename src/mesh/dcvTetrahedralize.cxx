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
// Tetrahedralize: the decoder's tetrahedralization of a whole point set at once. It needs none of
// Tetrahedralization's bookkeeping (cell ids, removals), and from ConcurrentFrom points on it is built by
// CGAL's concurrent triangulation on the threads of the current task arena. The Delaunay
// tetrahedralization of a point set is unique (the kernel's predicates are exact, CGAL's symbolic
// perturbation orders cospherical points by their coordinates), so the cells are the encoder's whatever
// the threads; their listing is made independent of how CGAL built them (each cell's vertices in one
// order, the cells sorted by a key that no two share).
#include "dcvApproximation.h"
#include "dcvGridKernel.h"
#include "dcvParallel.h"

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Delaunay_triangulation_cell_base_3.h>
#include <CGAL/Spatial_lock_grid_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace dcv
{
namespace
{
// The concurrent triangulation's locks do not wait: a thread that finds a lock taken lets go of its own
// and tries that point again. CGAL's default waits (spinning) for a thread of higher priority, and
// where the threads outnumber the free cores that thread may not be running: with two other busy
// processes on the two cores, ct-avm at 0.25 bpv (322,210 points) took 4.2 to 4.9 s to build
// against 1.3 to 1.5 s on one thread; 1.5 s without the wait (0.66 s on an idle machine).
template <typename Tag>
using DelaunayOf = CGAL::Delaunay_triangulation_3<
  GridKernel,
  CGAL::Triangulation_data_structure_3<CGAL::Triangulation_vertex_base_with_info_3<uint32_t, GridKernel>,
                                       CGAL::Delaunay_triangulation_cell_base_3<GridKernel>, Tag>,
  CGAL::Default, CGAL::Spatial_lock_grid_3<CGAL::Tag_non_blocking>>;

/** Below this many points one thread builds the triangulation: CGAL's concurrent one costs a quarter
 * more on one thread (its containers and locks), which two threads repaid from 10,000 to 30,000 points
 * (docs/profile.md). */
constexpr std::size_t ConcurrentFrom = 20000;

/** The concurrent triangulation's lock grid has about this many points a cell (CGAL locks the grid
 * cells a conflict region touches: coarse cells make the threads wait on each other; at 300 points a
 * cell, 10 cells an axis, ct-avm's build took 6 times as long with CGAL's waiting locks). 0.1 to 1
 * measured alike. */
constexpr double PointsPerLockCell = 0.5;

/** The finite cells of dt, each positively oriented (CGAL's order of its vertices, up to an even
 * permutation) with its vertex ids ascending but for the last two, which are swapped where ascending
 * would reverse the orientation: the same listing for the same cell however it was built. */
template <typename Delaunay>
std::vector<Tetrahedron>
CanonicalCells(const Delaunay & dt)
{
  std::vector<Tetrahedron> cells;
  cells.reserve(dt.number_of_finite_cells());
  for (auto c = dt.finite_cells_begin(); c != dt.finite_cells_end(); ++c)
  {
    Tetrahedron t{ c->vertex(0)->info(), c->vertex(1)->info(), c->vertex(2)->info(), c->vertex(3)->info() };
    bool        odd = false; // the parity of the swaps that sort the ids
    detail::SortFour([&](int i, int j) {
      if (t[j] < t[i])
      {
        std::swap(t[i], t[j]);
        odd = !odd;
      }
    });
    if (odd)
    {
      std::swap(t[2], t[3]);
    }
    cells.push_back(t);
  }
  return cells;
}

template <typename Delaunay, typename... Lock>
std::vector<Tetrahedron>
Build(const std::vector<std::pair<GridKernel::Point_3, uint32_t>> & input, Lock *... locks)
{
  Delaunay dt(locks...);
  dt.insert(input.begin(), input.end());
  if (dt.number_of_vertices() != input.size())
  {
    throw std::invalid_argument("Tetrahedralization: duplicate points");
  }
  return CanonicalCells(dt);
}

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
  CheckGridScale(scale);
  std::vector<std::pair<GridKernel::Point_3, uint32_t>> input;
  input.reserve(points.size());
  double upper[3] = { 1.0, 1.0, 1.0 };
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    input.emplace_back(ToGridKernel(points[i], scale), uint32_t(i));
    for (int d = 0; d < 3; ++d)
      upper[d] = std::max(upper[d], input.back().first[d]);
  }
  std::vector<Tetrahedron> cells;
  if (points.size() >= ConcurrentFrom && CurrentThreads() > 1)
  {
    using Concurrent = DelaunayOf<CGAL::Parallel_tag>;
    const int perAxis = std::clamp(int(std::cbrt(double(points.size()) / PointsPerLockCell)), 8, 128);
    typename Concurrent::Lock_data_structure locks(CGAL::Bbox_3(0.0, 0.0, 0.0, upper[0], upper[1], upper[2]), perAxis);
    cells = Build<Concurrent>(input, &locks);
  }
  else
  {
    cells = Build<DelaunayOf<CGAL::Sequential_tag>>(input);
  }
  std::vector<std::pair<GridKernel::Point_3, uint32_t>>().swap(input);
  // CGAL lists cells in memory order, which is scattered in space; rasterizing them in the Morton
  // order of their centroids keeps the voxels being written in cache (several times faster). Ties
  // are broken by the vertices: no two cells share both, so the order does not depend on the threads.
  std::vector<std::pair<uint64_t, Tetrahedron>> keyed(cells.size());
  ParallelFor(cells.size(), 4096, [&](std::size_t i) {
    uint64_t sum[3] = { 0, 0, 0 };
    for (auto v : cells[i])
    {
      for (int d = 0; d < 3; ++d)
      {
        sum[d] += uint64_t(points[v][d]);
      }
    }
    keyed[i] = { Spread(sum[0]) | (Spread(sum[1]) << 1) | (Spread(sum[2]) << 2), cells[i] };
  });
  ParallelSort(keyed.begin(), keyed.end());
  ParallelFor(keyed.size(), 4096, [&](std::size_t i) { cells[i] = keyed[i].second; });
  return cells;
}

} // namespace dcv
