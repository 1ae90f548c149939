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
#include "dcvRefinementEngine.h"
#include "dcvTetrahedralization.h"

#include <cmath>
#include <queue>
#include <stdexcept>
#include <string>

namespace dcv
{
namespace
{
constexpr uint64_t NoVoxel = ~uint64_t(0);

/** Max-heap entry: a key and the cell it belongs to. Entries of dead cells are skipped when they
 * surface (lazy deletion); a cell never changes while alive, so no stamp is needed. */
struct HeapEntry
{
  double   key;
  uint32_t cell;
  bool
  operator<(const HeapEntry & o) const
  {
    return key < o.key || (key == o.key && cell > o.cell); // ties: the older cell first
  }
};
} // namespace

struct RefinementEngine::Impl
{
  const float *      image;
  GridSize           grid;
  Tetrahedralization mesh;
  std::vector<double> values; // by vertex id

  // Per cell id.
  std::vector<double>   cellError;      // E(T), Eq. 1
  std::vector<float>    cellWorstError; // largest |I - L| over the cell's non-vertex voxels
  std::vector<uint64_t> cellWorstVoxel;
  std::vector<uint64_t> cellVoxels;
  std::vector<char>     cellAlive;

  std::priority_queue<HeapEntry> byCellError;  // MaxTetrahedronErrorPosition
  std::priority_queue<HeapEntry> byVoxelError; // MaxErrorPosition

  std::vector<uint64_t> isVertex; // one bit per voxel
  double                squaredError{ 0.0 };
  uint64_t              step{ 0 };
  bool                  exact{ false };

  std::vector<Tetrahedralization::CellId> killed;
  std::vector<Tetrahedralization::Cell>   created;

  bool
  IsVertex(uint64_t voxel) const
  {
    return (isVertex[voxel >> 6] >> (voxel & 63)) & 1u;
  }
  void
  MarkVertex(uint64_t voxel)
  {
    isVertex[voxel >> 6] |= uint64_t(1) << (voxel & 63);
  }

  GridPoint
  ToPoint(uint64_t voxel) const
  {
    const uint64_t x = voxel % uint64_t(grid.x);
    const uint64_t yz = voxel / uint64_t(grid.x);
    return { int32_t(x), int32_t(yz % uint64_t(grid.y)), int32_t(yz / uint64_t(grid.y)) };
  }

  void
  AddVertex(const GridPoint & p, Tetrahedralization::CellId hint)
  {
    const uint64_t voxel = grid.Offset(p[0], p[1], p[2]);
    const auto     id = mesh.Insert(p, hint, killed, created);
    if (values.size() <= id)
    {
      values.resize(id + 1);
    }
    values[id] = image[voxel];
    MarkVertex(voxel);
    for (auto c : killed)
    {
      cellAlive[c] = 0;
      squaredError -= cellError[c];
    }
    for (const auto & c : created)
    {
      ScanCell(c);
    }
  }

  // Rasterizes a new cell against the image: its error sum, voxel count and worst voxel.
  void
  ScanCell(const Tetrahedralization::Cell & c)
  {
    std::array<GridPoint, 4> p;
    std::array<double, 4>    v;
    for (int i = 0; i < 4; ++i)
    {
      p[i] = mesh.Point(c.vertices[i]);
      v[i] = values[c.vertices[i]];
    }
    const CanonicalTetrahedron t(p, v);
    const LinearFunction       L(t);
    double                     sse = 0.0;
    uint64_t                   count = 0;
    float                      worst = 0.0f;
    uint64_t                   worstVoxel = NoVoxel;
    ForEachSpan(grid, t.p, [&](int32_t y, int32_t z, int32_t x0, int32_t x1) {
      const double   base = L.RowBase(y, z);
      const uint64_t rowOffset = grid.Offset(0, y, z);
      const float *  row = image + rowOffset;
      for (int32_t x = x0; x <= x1; ++x)
      {
        // The same expression as Rasterize(), so decoder and engine agree to the bit.
        const double e = double(row[x]) - (base + L.gx * double(x - L.origin[0]));
        sse += e * e;
        const float ae = float(std::fabs(e));
        if (ae > worst && !IsVertex(rowOffset + uint64_t(x)))
        {
          worst = ae;
          worstVoxel = rowOffset + uint64_t(x);
        }
      }
      count += uint64_t(x1 - x0 + 1);
    });
    const std::size_t id = c.id;
    if (cellError.size() <= id)
    {
      const std::size_t n = std::max<std::size_t>(id + 1, cellError.size() * 2);
      cellError.resize(n);
      cellWorstError.resize(n);
      cellWorstVoxel.resize(n);
      cellVoxels.resize(n);
      cellAlive.resize(n);
    }
    cellError[id] = sse;
    cellWorstError[id] = worst;
    cellWorstVoxel[id] = worstVoxel;
    cellVoxels[id] = count;
    cellAlive[id] = 1;
    squaredError += sse;
    if (worstVoxel != NoVoxel)
    {
      byCellError.push(HeapEntry{ sse, c.id });
      byVoxelError.push(HeapEntry{ worst, c.id });
    }
  }

  // Top live cell of a heap, or NoCell when none is left.
  static uint32_t
  Top(std::priority_queue<HeapEntry> & heap, const std::vector<char> & alive)
  {
    while (!heap.empty() && !alive[heap.top().cell])
    {
      heap.pop();
    }
    return heap.empty() ? Tetrahedralization::NoCell : heap.top().cell;
  }

  // One refinement step; false when no voxel has a non-zero error left.
  bool
  Step()
  {
    // Silva: odd steps take the globally worst voxel, even steps the worst voxel of the worst cell.
    const bool     global = (step % 2) == 0;
    const uint32_t cell = Top(global ? byVoxelError : byCellError, cellAlive);
    if (cell == Tetrahedralization::NoCell || cellWorstError[cell] <= 0.0f)
    {
      return false;
    }
    ++step;
    AddVertex(ToPoint(cellWorstVoxel[cell]), cell);
    return true;
  }
};

RefinementEngine::RefinementEngine(const float * image, const GridSize & grid)
  : m_Impl(std::make_unique<Impl>())
{
  for (int32_t n : { grid.x, grid.y, grid.z })
  {
    if (n < 2 || n > MaximumGridExtent)
    {
      throw std::invalid_argument("RefinementEngine: each axis needs 2 to " + std::to_string(MaximumGridExtent) +
                                  " voxels, got " + std::to_string(grid.x) + "x" + std::to_string(grid.y) + "x" +
                                  std::to_string(grid.z));
    }
  }
  if (image == nullptr)
  {
    throw std::invalid_argument("RefinementEngine: no image");
  }
  Impl & d = *m_Impl;
  d.image = image;
  d.grid = grid;
  d.isVertex.assign((grid.NumberOfVoxels() + 63) / 64, 0);
  for (int k = 0; k < 8; ++k)
  {
    const GridPoint corner{ (k & 1) ? grid.x - 1 : 0, (k & 2) ? grid.y - 1 : 0, (k & 4) ? grid.z - 1 : 0 };
    d.AddVertex(corner, Tetrahedralization::NoCell);
  }
}

RefinementEngine::~RefinementEngine() = default;

void
RefinementEngine::Refine(std::size_t numberOfPoints, const ProgressFunction & progress)
{
  Impl &            d = *m_Impl;
  const std::size_t start = d.mesh.NumberOfVertices();
  const std::size_t total = numberOfPoints > start ? numberOfPoints - start : 0;
  const std::size_t every = std::max<std::size_t>(1, total / 100);
  for (std::size_t i = 0; i < total; ++i)
  {
    if (!d.Step())
    {
      break; // exact: every voxel is interpolated without error
    }
    if (progress && (i + 1) % every == 0)
    {
      progress(double(i + 1) / double(total));
    }
  }
  if (progress)
  {
    progress(1.0);
  }
}

std::size_t
RefinementEngine::GetNumberOfPoints() const
{
  return m_Impl->mesh.NumberOfVertices();
}

double
RefinementEngine::GetSquaredError() const
{
  return std::max(0.0, m_Impl->squaredError);
}

const GridSize &
RefinementEngine::GetGrid() const
{
  return m_Impl->grid;
}

Approximation
RefinementEngine::GetApproximation() const
{
  const Impl &  d = *m_Impl;
  Approximation a;
  a.grid = d.grid;
  // Vertex ids are dense while no vertex has been removed; compact them anyway.
  std::vector<uint32_t> index(d.mesh.NumberOfVertexIds(), Tetrahedralization::NoCell);
  const auto            cells = d.mesh.FiniteCells();
  auto                  indexOf = [&](uint32_t v) {
    if (index[v] == Tetrahedralization::NoCell)
    {
      index[v] = uint32_t(a.points.size());
      a.points.push_back(d.mesh.Point(v));
      a.values.push_back(d.values[v]);
    }
    return index[v];
  };
  a.tetrahedra.reserve(cells.size());
  for (const auto & c : cells)
  {
    a.tetrahedra.push_back({ indexOf(c.vertices[0]), indexOf(c.vertices[1]), indexOf(c.vertices[2]), indexOf(c.vertices[3]) });
  }
  return a;
}

std::vector<RefinementEngine::CellStatistics>
RefinementEngine::GetCellStatistics() const
{
  const Impl &                d = *m_Impl;
  std::vector<CellStatistics> out;
  for (const auto & c : d.mesh.FiniteCells())
  {
    out.push_back(CellStatistics{ c.id, d.cellVoxels[c.id], d.cellError[c.id] });
  }
  return out;
}

} // namespace dcv
