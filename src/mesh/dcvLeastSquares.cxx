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
// The least-squares values of the refinement engine's vertices (RefinementEngine::OptimizeValues): the
// normal equations of the spline's error over all cells, solved by conjugate gradients.
#include "dcvRefinementEngineImpl.h"

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCore>

namespace dcv
{
namespace
{
/** The pattern of the normal equations' sparse matrix, its values not set: each vertex and the vertices it
 * shares a cell with (column c holds the rows of c's cells' vertices, sorted; the matrix is symmetric).
 * `cells` holds each cell's vertices as rows. Built from the cells of each column (an int a cell and
 * vertex), a quarter of the columns at a time on each thread: all of them at once (16 bytes a cell) beside
 * the cells and the matrix set the encoder's peak (norm-256 at 0.25 bpv). */
Eigen::SparseMatrix<double>
NormalPattern(int n, const std::vector<std::array<int, 4>> & cells)
{
  std::vector<int> first(std::size_t(n) + 1, 0);
  for (const auto & c : cells)
    for (int r : c)
      ++first[std::size_t(r) + 1];
  for (int c = 0; c < n; ++c)
    first[c + 1] += first[c];
  Eigen::SparseMatrix<double> M(n, n);
  // Calls column(c, forEachRow) for every column c of a quarter of them (`part`), in order; forEachRow(row)
  // calls row(r) for each row of c once (the first visit of r in c marks it). The part's incidence is made
  // anew for each pass, and the parts go to the threads, each with its incidence and marks.
  constexpr int parts = 4;
  auto          forEachColumn = [&](int part, auto && column) {
    const int             lo = int(std::int64_t(n) * part / parts), hi = int(std::int64_t(n) * (part + 1) / parts);
    const int             base = first[lo];
    std::vector<uint32_t> incident(std::size_t(first[hi] - base));
    std::vector<int>      fill(first.begin() + lo, first.begin() + hi);
    std::vector<int>      mark(std::size_t(n), -1);
    for (std::size_t i = 0; i < cells.size(); ++i)
      for (int r : cells[i])
        if (r >= lo && r < hi)
          incident[std::size_t(fill[r - lo]++ - base)] = uint32_t(i);
    for (int c = lo; c < hi; ++c)
      column(c, [&](auto && row) {
        for (int k = first[c]; k < first[c + 1]; ++k)
          for (int r : cells[incident[std::size_t(k - base)]])
            if (mark[std::size_t(r)] != c)
            {
              mark[std::size_t(r)] = c;
              row(r);
            }
      });
  };
  int * const outer = M.outerIndexPtr();
  outer[0] = 0;
  ParallelFor(parts, 1, [&](std::size_t part) {
    forEachColumn(int(part), [&](int c, auto && forEachRow) {
      int count = 0;
      forEachRow([&](int) { ++count; });
      outer[c + 1] = count;
    });
  });
  for (int c = 0; c < n; ++c)
    outer[c + 1] += outer[c];
  M.resizeNonZeros(outer[n]);
  int * const inner = M.innerIndexPtr();
  ParallelFor(parts, 1, [&](std::size_t part) {
    forEachColumn(int(part), [&](int c, auto && forEachRow) {
      int at = outer[c];
      forEachRow([&](int r) { inner[at++] = r; });
      std::sort(inner + outer[c], inner + at);
    });
  });
  return M;
}

/** The position of `row` among the sorted rows inner[first, last) of a column, which hold it: a binary
 * search whose steps add, not branch (std::lower_bound's branch, mispredicted at every other step, was
 * half of adding the blocks once the cells came in spatial order). */
inline int
RowPosition(const int * inner, int first, int last, int row)
{
  const int * base = inner + first;
  for (int length = last - first; length > 1;)
  {
    const int half = length / 2;
    base += half * int(base[half - 1] < row);
    length -= half;
  }
  return int(base - inner) + (*base < row);
}

/** Adds the blocks of `cells` (the upper triangle of each cell's 4x4, by rows; blocks[i] is cells[i]'s)
 * into M, and their right-hand sides into b, cell by cell, without triplets (16 x 16 bytes a cell) and the
 * transposed copy Eigen's setFromTriplets sorts them in: gigabytes at 0.25 bpv on norm-256. The cells come
 * sorted by their lowest vertex, whose column (`index`, in the order of the voxels) is their smallest: the
 * columns they add to are near those added to before, where cells in the order of their ids missed the
 * cache at nearly every entry. The columns are split among the threads at the lowest columns of evenly
 * spaced cells, each thread reading the cells up to its last column and adding to its own columns only:
 * each sum keeps its order whatever the threads. */
void
AddCellBlocks(Eigen::SparseMatrix<double> & M, Eigen::VectorXd & b, const std::vector<int> & index,
              const std::vector<Tetrahedralization::Cell> & cells, const std::vector<std::array<double, 10>> & blocks,
              const std::vector<std::array<double, 4>> & rhs)
{
  const int *       outer = M.outerIndexPtr();
  const int *       inner = M.innerIndexPtr();
  double * const    value = M.valuePtr();
  const std::size_t parts = CurrentThreads();
  const int         n = int(M.cols());
  auto              lowestColumn = [&](std::size_t i) {
    const auto & v = cells[i].vertices;
    return std::min(std::min(index[v[0]], index[v[1]]), std::min(index[v[2]], index[v[3]]));
  };
  ParallelFor(parts, 1, [&](std::size_t part) {
    const int first = part == 0 ? 0 : lowestColumn(cells.size() * part / parts);
    const int end = part + 1 == parts ? n : lowestColumn(cells.size() * (part + 1) / parts);
    for (std::size_t i = 0; i < cells.size(); ++i)
    {
      const auto & v = cells[i].vertices;
      const int    column[4] = { index[v[0]], index[v[1]], index[v[2]], index[v[3]] };
      if (std::min(std::min(column[0], column[1]), std::min(column[2], column[3])) >= end)
      {
        break; // the cells after it have no column below end either
      }
      for (int k = 0; k < 4; ++k)
      {
        if (column[k] < first || column[k] >= end)
        {
          continue;
        }
        b[column[k]] += rhs[i][k];
        for (int j = 0; j < 4; ++j)
        {
          const int at = RowPosition(inner, outer[column[k]], outer[column[k] + 1], column[j]);
          const int lo = std::min(j, k), hi = std::max(j, k);
          value[at] += blocks[i][lo * 4 - lo * (lo + 1) / 2 + hi];
        }
      }
    }
  });
}
} // namespace

double
RefinementEngine::OptimizeValues()
{
  Impl &           d = *m_Impl;
  const StageTimer timer(d.timings.leastSquares);
  // The solution depends on the mesh and the image only: the step trials of rate control, which
  // requantize the values on one mesh, reuse it.
  if (d.solvedMesh != d.meshVersion)
  {
    d.ReleaseCellState(); // the rescan below makes it again
    // The ids of dead cells go while there is no state to move: the rescan sizes the state to the ids
    // (21 bytes an id, and 8 for the cell's handle), and rate control codes the mesh after it, at the
    // encoder's peak (norm-256 at 0.25 bpv: 1.22 ids a live cell). The live cells keep their order.
    if (d.mesh.NumberOfCellIds() > d.liveCells)
    {
      d.mesh.CompactCellIds();
    }
    // Compact indices of the live vertices in the order of their voxels (z, then y, then x): a cell's
    // vertices get near indices, so the columns of the cells added in the same order (below) are near
    // in memory, where in the order of the ids (insertions) each missed the cache.
    std::vector<int> index(d.mesh.NumberOfVertexIds(), -1);
    int              n = 0;
    {
      std::vector<std::pair<uint64_t, VertexId>> byVoxel;
      byVoxel.reserve(d.mesh.NumberOfVertices());
      for (VertexId v = 0; v < index.size(); ++v)
      {
        if (d.vertexAlive[v])
        {
          const GridPoint & q = d.mesh.Point(v);
          byVoxel.emplace_back(d.grid.Offset(q[0], q[1], q[2]), v);
        }
      }
      ParallelSort(byVoxel.begin(), byVoxel.end()); // distinct keys: one vertex a voxel
      for (const auto & [voxel, v] : byVoxel)
      {
        index[v] = n++;
      }
    }
    // The cells by their lowest vertex, for the values' assembly (below).
    std::vector<uint32_t> byPlace = d.CellIdsInSpatialOrder();
    // Normal equations of min sum_x (I(x) - sum_k v_k phi_k(x))^2: M_jk = sum phi_j phi_k, b_j = sum I phi_j.
    // The pattern from each cell's vertices as rows (16 bytes a cell), a list gone before the values
    // are first touched: the cells, the pattern's work and the matrix at once set the encoder's peak.
    Eigen::SparseMatrix<double> M = [&] {
      std::vector<std::array<int, 4>> rows;
      rows.reserve(d.liveCells);
      d.ForEachIdRange([&](const std::vector<Tetrahedralization::Cell> & cells) {
        for (const auto & c : cells)
          rows.push_back({ index[c.vertices[0]], index[c.vertices[1]], index[c.vertices[2]], index[c.vertices[3]] });
      });
      return NormalPattern(n, rows);
    }();
    std::fill_n(M.valuePtr(), M.nonZeros(), 0.0);
    // Each cell's 4x4 block (its upper triangle) and 4 right-hand-side terms on a thread into its own
    // slots, a part of the cells at a time (their blocks are 112 bytes a cell beside the matrix); M and b
    // are then summed in the cells' order.
    Eigen::VectorXd                       b = Eigen::VectorXd::Zero(n);
    std::vector<std::array<double, 10>>   blocks;
    std::vector<std::array<double, 4>>    rhs;
    std::vector<Tetrahedralization::Cell> cells;
    for (std::size_t first = 0; first < byPlace.size(); first += Impl::chunk / 4)
    {
      const std::size_t count = std::min(Impl::chunk / 4, byPlace.size() - first);
      d.mesh.FiniteCells(byPlace.data() + first, count, cells);
      blocks.resize(count);
      rhs.resize(count);
      ParallelFor(count, 64, [&](std::size_t i) {
        const auto &             c = cells[i];
        std::array<GridPoint, 4> p;
        for (int k = 0; k < 4; ++k)
        {
          p[k] = d.mesh.Point(c.vertices[k]);
        }
        std::array<LinearFunction, 3> phi;
        for (int k = 0; k < 3; ++k)
        {
          std::array<double, 4> unit{ 0, 0, 0, 0 };
          unit[k] = 1.0;
          phi[k] = LinearFunction(CanonicalTetrahedron(p, unit));
        }
        double m[4][4] = {};
        double r[4] = {};
        // Along a row each weight is a + g u (u = x - x0), so a row adds a_j a_k count + (a_j g_k + a_k g_j)
        // sum u + g_j g_k sum u^2 to M_jk and a_j sum I + g_j sum u I to b_j: the voxels are read for sum I
        // and sum u I only (sum u and sum u^2 are closed forms, exact). The same values as summing w_j w_k
        // per voxel up to rounding; the files of the dev volumes came out the same.
        d.pixels->Visit([&](const auto * data) {
          ForEachSpanPrefetched(d.grid, p, data, nullptr, nullptr, [&](int32_t y, int32_t z, int32_t x0, int32_t x1) {
            double sumI, sumUI;
            d.pixels->RowSums(data + d.grid.Offset(0, y, z), x0, x1, sumI, sumUI);
            const double count = double(x1 - x0 + 1);
            const double sumU = count * (count - 1.0) / 2.0;
            const double sumUU = (count - 1.0) * count * (2.0 * count - 1.0) / 6.0;
            double       a[4], g[4];
            for (int k = 0; k < 3; ++k)
            {
              a[k] = phi[k](x0, y, z);
              g[k] = phi[k].gx;
            }
            a[3] = 1.0 - a[0] - a[1] - a[2];
            g[3] = -(g[0] + g[1] + g[2]);
            for (int j = 0; j < 4; ++j)
            {
              r[j] += a[j] * sumI + g[j] * sumUI;
              for (int k = j; k < 4; ++k)
              {
                m[j][k] += a[j] * a[k] * count + (a[j] * g[k] + a[k] * g[j]) * sumU + g[j] * g[k] * sumUU;
              }
            }
          });
        });
        for (int j = 0, e = 0; j < 4; ++j)
        {
          rhs[i][j] = r[j];
          for (int k = j; k < 4; ++k)
            blocks[i][e++] = m[j][k];
        }
      });
      AddCellBlocks(M, b, index, cells, blocks, rhs);
    }
    std::vector<uint32_t>().swap(byPlace);
    // Gone before the solver's vectors come.
    std::vector<std::array<double, 10>>().swap(blocks);
    std::vector<std::array<double, 4>>().swap(rhs);
    Eigen::VectorXd current(n);
    for (VertexId v = 0; v < index.size(); ++v)
    {
      if (index[v] >= 0)
      {
        current[index[v]] = d.values[v];
      }
    }
    Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> solver;
    solver.setTolerance(1e-10);
    solver.setMaxIterations(2000);
    solver.compute(M);
    const Eigen::VectorXd solution = solver.solveWithGuess(b, current);

    d.solved.assign(index.size(), std::numeric_limits<double>::quiet_NaN());
    for (VertexId v = 0; v < index.size(); ++v)
    {
      if (index[v] >= 0)
      {
        d.solved[v] = solution[index[v]];
      }
    }
    d.solvedMesh = d.meshVersion;
  }
  const std::vector<double> old = d.values;
  const double              before = d.squaredError;
  for (VertexId v = 0; v < d.solved.size(); ++v)
  {
    if (d.vertexAlive[v] && std::isfinite(d.solved[v]))
    {
      d.values[v] = d.Quantize(std::clamp(d.solved[v], d.parameters.valueMin, d.parameters.valueMax));
    }
  }
  d.RescanAll();
  if (d.squaredError > before)
  {
    d.values = old; // clamping, quantization or an unconverged solve made it worse: keep what we had
    d.RescanAll();
  }
  return std::max(0.0, before - d.squaredError);
}
} // namespace dcv
