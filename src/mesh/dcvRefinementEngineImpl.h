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
#ifndef dcvRefinementEngineImpl_h
#define dcvRefinementEngineImpl_h

// The refinement engine's state and its steps (insertion, decimation, cell scans, heaps), shared by
// dcvRefinementEngine.cxx (the engine's interface) and dcvLeastSquares.cxx (the values' optimization).
// Private to the library.
#include "dcvRefinementEngine.h"
#include "dcvParallel.h"
#include "dcvPixelSource.h"
#include "dcvTetrahedralization.h"

#include <boost/container/small_vector.hpp>
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCore>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <queue>
#include <stdexcept>
#include <string>

namespace dcv
{
namespace engine
{
inline constexpr uint64_t NoVoxel = ~uint64_t(0);
inline constexpr uint32_t NoCell = Tetrahedralization::NoCell;
inline constexpr uint32_t NumberOfCorners = 8; // vertex ids 0-7, never removed

/** Max-heap entry: a key and the cell it belongs to. Entries of dead cells are skipped when they
 * surface (lazy deletion); a cell only changes on a full rescan, which rebuilds the heaps. Ties
 * (frequent on integer images) go to the lower worst voxel: cell ids follow CGAL's memory order,
 * which varies from run to run, and the encoder must be reproducible. The voxel is the cell's
 * cellWorstVoxel, read by the order (ByKey) instead of stored: 16 bytes an entry instead of 24, and
 * the heaps hold one or two entries for each cell id. */
#pragma pack(push, 4)
template <typename TKey>
struct HeapEntry
{
  TKey     key; // a cell's error (double: 12 bytes an entry, packed) or worst voxel error (float: 8 bytes)
  uint32_t cell;
};
#pragma pack(pop)

/** The heaps' order: the key, then the lower worst voxel of the entry's cell. */
struct ByKey
{
  const std::vector<uint64_t> * worstVoxel;
  template <typename TKey>
  bool
  operator()(const HeapEntry<TKey> & a, const HeapEntry<TKey> & b) const
  {
    return a.key < b.key || (a.key == b.key && (*worstVoxel)[a.cell] > (*worstVoxel)[b.cell]);
  }
};
template <typename TKey>
using CellHeap = std::priority_queue<HeapEntry<TKey>, std::vector<HeapEntry<TKey>>, ByKey>;

/** Min-heap entry of the decimation: removal cost of a vertex, valid while its stamp is current. */
struct RemovalEntry
{
  double   cost;
  uint32_t vertex;
  uint32_t stamp;
  bool
  operator<(const RemovalEntry & o) const
  {
    return cost > o.cost || (cost == o.cost && vertex < o.vertex); // smallest cost on top
  }
};

/** Adds the seconds of its scope to a stage's total. */
class StageTimer
{
public:
  explicit StageTimer(double & total)
    : m_Total(total)
    , m_Start(std::chrono::steady_clock::now())
  {}
  ~StageTimer() { m_Total += std::chrono::duration<double>(std::chrono::steady_clock::now() - m_Start).count(); }
  StageTimer(const StageTimer &) = delete;
  StageTimer &
  operator=(const StageTimer &) = delete;

private:
  double &                              m_Total;
  std::chrono::steady_clock::time_point m_Start;
};

/** ForEachSpan with every row of the cell found first and its first and last voxels in `image` (and in
 * `other`, and their words of the bit set `bits`, where not null) asked for from memory at once; then
 * f(y, z, x0, x1) for each row, in ForEachSpan's order. A cell's rows are short (9 voxels on average on
 * norm-256 at 0.03125 bpv) and their starts missed the cache one after the other; asked for together, the
 * misses overlap (ct-avm at 0.0625 bpv: CPU time 0.86, 0.91 with the last voxels, 0.98 with the bits).
 * The rows are kept on the stack (a thread_local list cost a call to find it per cell); a cell of more
 * than 128 rows, some thousand voxels, puts them on the heap. */
template <typename TPixel, typename TFunction>
void
ForEachSpanPrefetched(const GridSize & grid, const std::array<GridPoint, 4> & p, const TPixel * image,
                      const float * other, const uint64_t * bits, TFunction && f)
{
  struct Span
  {
    int32_t y, z, x0, x1;
  };
  boost::container::small_vector<Span, 128> spans;
  ForEachSpan(grid, p, [&](int32_t y, int32_t z, int32_t x0, int32_t x1) {
    spans.push_back({ y, z, x0, x1 });
    const uint64_t first = grid.Offset(x0, y, z), last = first + uint64_t(x1 - x0);
    __builtin_prefetch(image + first);
    __builtin_prefetch(image + last); // the row's second cache line, if it has one
    if (other)
    {
      __builtin_prefetch(other + first);
      __builtin_prefetch(other + last);
    }
    if (bits)
      __builtin_prefetch(bits + (first >> 6));
  });
  for (const Span & s : spans)
  {
    f(s.y, s.z, s.x0, s.x1);
  }
}

/** What rasterizing a cell against the image gives: its error sums, voxel count and worst voxel. */
struct CellScan
{
  double   sse{ 0.0 };
  double   sseSelection{ 0.0 };
  uint64_t count{ 0 };
  uint64_t worstVoxel{ NoVoxel };
  float    worst{ 0.0f };
  double   volume{ 0.0 };
};
} // namespace engine
using namespace engine;

struct RefinementEngine::Impl
{
  const float *                image;
  std::unique_ptr<PixelSource> pixels; // what the scans read of `image`
  GridSize                     grid;
  RefinementParameters         parameters;
  const float *                selection; // I_c: where positions are chosen (I* first, then I)
  double                       smoothedPSNR{ 0.0 };
  Tetrahedralization           mesh;

  // Per vertex id.
  std::vector<double>   values;
  std::vector<double>   errorBefore;  // E_m^-(p), Eq. 3: error of the cells p's insertion replaced
  std::vector<double>   volumeBefore; // mu_m(p), Eq. 5 at insertion (six times the volume)
  std::vector<uint32_t> stamp;        // decimation heap validity
  std::vector<char>     vertexAlive;
  std::vector<double>   removalCost; // RemovalCost() as last computed, while removalCostValid
  std::vector<char>     removalCostValid;
  VertexId              lastInserted{ 0 };
  Timings               timings;

  // Per cell id.
  std::vector<double>   cellError;      // E(T) against I, Eq. 1
  std::vector<double>   cellSelection;  // E(T) against I_c while I_c = I* (empty once I_c = I: cellError)
  std::vector<float>    cellWorstError; // largest |I_c - L| over the cell's non-vertex voxels
  std::vector<uint64_t> cellWorstVoxel;
  std::vector<char>     cellAlive;
  std::size_t           liveCells{ 0 }; // CGAL counts its cells in linear time

  CellHeap<double> byCellError{ ByKey{ &cellWorstVoxel } };  // MaxTetrahedronErrorPosition
  CellHeap<float>  byVoxelError{ ByKey{ &cellWorstVoxel } }; // MaxErrorPosition
  bool             heapsPending{ false };                    // made from the cells' state when next read

  std::vector<uint64_t> isVertex;                   // one bit per voxel
  uint64_t              meshVersion{ 0 };           // counts insertions and removals
  uint64_t              solvedMesh{ ~uint64_t(0) }; // the mesh version `solved` belongs to
  std::vector<double>   solved;                     // least-squares values per vertex id (unquantized)
  double                squaredError{ 0.0 };
  uint64_t              step{ 0 };

  std::vector<Tetrahedralization::CellId> killed;
  std::vector<Tetrahedralization::Cell>   created;
  std::vector<CellScan>                   scans;      // of the created cells
  std::vector<std::array<double, 2>>      valueSums;  // of the created cells, for ChooseValue
  std::vector<VertexId>                   staleCosts; // UpdateRemovalCosts
  std::vector<std::vector<std::pair<Tetrahedralization::CellId, uint64_t>>> incidentOfNeighbours; // RemoveUpdatingCosts

  bool
  IsVertex(uint64_t voxel) const
  {
    return (isVertex[voxel >> 6] >> (voxel & 63)) & 1u;
  }
  void
  SetVertex(uint64_t voxel, bool on)
  {
    const uint64_t bit = uint64_t(1) << (voxel & 63);
    isVertex[voxel >> 6] = on ? (isVertex[voxel >> 6] | bit) : (isVertex[voxel >> 6] & ~bit);
  }

  GridPoint
  ToPoint(uint64_t voxel) const
  {
    const uint64_t x = voxel % uint64_t(grid.x);
    const uint64_t yz = voxel / uint64_t(grid.x);
    return { int32_t(x), int32_t(yz % uint64_t(grid.y)), int32_t(yz / uint64_t(grid.y)) };
  }

  /** The nearest allowed vertex value: on the quantization lattice (if any) and within the range. */
  double
  Quantize(double v) const
  {
    return Quantize(v, parameters.quantizationStep);
  }
  /** The same on the lattice of another step. */
  double
  Quantize(double v, double step) const
  {
    const RefinementParameters & p = parameters;
    if (!(step > 0.0))
    {
      return v;
    }
    auto   at = [&p, step](double k) { return p.quantizationOrigin + k * step; };
    double k = std::round((v - p.quantizationOrigin) / step);
    while (at(k) > p.valueMax && at(k - 1) >= p.valueMin)
    {
      k -= 1;
    }
    while (at(k) < p.valueMin && at(k + 1) <= p.valueMax)
    {
      k += 1;
    }
    return at(k);
  }

  // The live vertices' values quantized again at `step` (by vertex id), as SetQuantizationStep(step) sets
  // them: a solution of this mesh as it is (solving does not depend on the step), else each vertex's
  // source, I(p) or I*(p) where that is nearer its current value. Throws unless the step is positive.
  std::vector<double>
  ValuesAtStep(double step) const
  {
    if (!(step > 0.0))
    {
      throw std::invalid_argument("RefinementEngine: the quantization step must be positive, got " +
                                  std::to_string(step));
    }
    std::vector<double> out = values;
    const bool          fromSolution = parameters.leastSquares && solvedMesh == meshVersion;
    for (VertexId v = 0; v < mesh.NumberOfVertexIds(); ++v)
    {
      if (fromSolution && vertexAlive[v] && std::isfinite(solved[v]))
      {
        out[v] = Quantize(std::clamp(solved[v], parameters.valueMin, parameters.valueMax), step);
      }
      else if (vertexAlive[v])
      {
        const GridPoint p = mesh.Point(v);
        const uint64_t  voxel = grid.Offset(p[0], p[1], p[2]);
        double          source = image[voxel];
        if (parameters.smoothed &&
            std::abs(values[v] - double(parameters.smoothed[voxel])) < std::abs(values[v] - source))
        {
          source = parameters.smoothed[voxel];
        }
        out[v] = Quantize(source, step);
      }
    }
    return out;
  }

  // The live vertices (numbered densely in the order the cells by id first name them), `vertexValues`
  // theirs (by vertex id), and the cells.
  Approximation
  ApproximationOf(const std::vector<double> & vertexValues) const
  {
    Approximation a;
    a.grid = grid;
    a.scale = parameters.scale;
    // Vertex ids have holes once vertices were removed: number the live ones densely.
    std::vector<uint32_t> index(mesh.NumberOfVertexIds(), NoCell);
    auto                  indexOf = [&](uint32_t v) {
      if (index[v] == NoCell)
      {
        index[v] = uint32_t(a.points.size());
        a.points.push_back(mesh.Point(v));
        a.values.push_back(vertexValues[v]);
      }
      return index[v];
    };
    // Sized at once: grown by doubling, the points and values would take up to twice their size, and
    // rate control codes them at the encoder's peak.
    a.points.reserve(mesh.NumberOfVertices());
    a.values.reserve(mesh.NumberOfVertices());
    a.tetrahedra.reserve(mesh.NumberOfFiniteCells());
    ForEachIdRange([&](const std::vector<Tetrahedralization::Cell> & cells) {
      for (const auto & c : cells)
      {
        a.tetrahedra.push_back(
          { indexOf(c.vertices[0]), indexOf(c.vertices[1]), indexOf(c.vertices[2]), indexOf(c.vertices[3]) });
      }
    });
    return a;
  }

  double
  PSNROf(double sse) const
  {
    return PSNR(sse, grid.NumberOfVoxels(), parameters.peak);
  }

  void
  Kill(const std::vector<Tetrahedralization::CellId> & cells)
  {
    for (auto c : cells)
    {
      liveCells -= cellAlive[c] ? 1 : 0;
      cellAlive[c] = 0;
      squaredError -= cellError[c];
    }
  }

  // Sizes the per-vertex state for ids up to n - 1, reserved exactly: Refine() asks for the ids of all
  // its insertions at once, where growing by doubling held up to twice the ids (35 MB of zeros at the
  // encoder's peak, norm-256 at 0.25 bpv: 1.2 M ids in 2.1 M slots of 38 bytes).
  void
  GrowVertices(std::size_t n)
  {
    auto grow = [n](auto & v) {
      if (v.size() < n)
      {
        v.reserve(n);
        v.resize(n);
      }
    };
    grow(values);
    grow(errorBefore);
    grow(volumeBefore);
    grow(stamp);
    grow(vertexAlive);
    grow(removalCost);
    grow(removalCostValid);
  }

  void
  AddVertex(const GridPoint & p, uint32_t hint)
  {
    const uint64_t voxel = grid.Offset(p[0], p[1], p[2]);
    const auto     id = mesh.Insert(p, hint, killed, created);
    ++meshVersion;
    if (values.size() <= id)
    {
      GrowVertices(std::max<std::size_t>(id + 1, values.size() + values.size() / 2));
    }
    lastInserted = id;
    vertexAlive[id] = 1;
    SetVertex(voxel, true);
    double before = 0.0;
    for (auto c : killed)
    {
      before += cellError[c];
    }
    errorBefore[id] = before;
    Kill(killed);
    values[id] = ChooseValue(id, voxel);
    ScanCreated();
    double volume = 0.0;
    for (std::size_t i = 0; i < created.size(); ++i)
    {
      volume += scans[i].volume;
    }
    volumeBefore[id] = volume;
  }

  // The vertex value: I(p), or the best over the new cells of I(p), I*(p) and the local optimum.
  double
  ChooseValue(VertexId id, uint64_t voxel)
  {
    const double imageValue = Quantize(image[voxel]);
    if (!parameters.smoothed && !parameters.localOptimalValue)
    {
      return imageValue;
    }
    // Over the new cells the error is sum (r - w v)^2 = C - 2 v B + v^2 A, with w the new vertex's
    // barycentric weight and r the residual with v = 0: one pass gives A and B for every candidate.
    // Per cell, then summed in order: the same doubles whether cells ran on one thread or several.
    std::vector<std::array<double, 2>> & sums = valueSums;
    sums.resize(created.size());
    OverCreated([&](std::size_t i) {
      const auto &             c = created[i];
      std::array<GridPoint, 4> p;
      std::array<double, 4>    without, weight;
      for (int k = 0; k < 4; ++k)
      {
        p[k] = mesh.Point(c.vertices[k]);
        without[k] = c.vertices[k] == id ? 0.0 : values[c.vertices[k]];
        weight[k] = c.vertices[k] == id ? 1.0 : 0.0;
      }
      const LinearFunction L0{ CanonicalTetrahedron(p, without) };
      const LinearFunction W{ CanonicalTetrahedron(p, weight) };
      double               a = 0.0, b = 0.0;
      pixels->Visit([&](const auto * data) {
        ForEachSpanPrefetched(grid, p, data, nullptr, nullptr, [&](int32_t y, int32_t z, int32_t x0, int32_t x1) {
          const auto * row = data + grid.Offset(0, y, z);
          for (int32_t x = x0; x <= x1; ++x)
          {
            const double w = W(x, y, z);
            a += w * w;
            b += w * ((*pixels)(row, x) - L0(x, y, z));
          }
        });
      });
      sums[i] = { a, b };
    });
    double A = 0.0, B = 0.0;
    for (const auto & ab : sums)
    {
      A += ab[0];
      B += ab[1];
    }
    auto   cost = [A, B](double v) { return v * v * A - 2.0 * v * B; };
    double best = imageValue;
    if (parameters.smoothed && cost(Quantize(parameters.smoothed[voxel])) < cost(best))
    {
      best = Quantize(parameters.smoothed[voxel]);
    }
    if (parameters.localOptimalValue && A > 0.0)
    {
      const double optimum = Quantize(std::clamp(B / A, parameters.valueMin, parameters.valueMax));
      if (cost(optimum) < cost(best))
      {
        best = optimum;
      }
    }
    return best;
  }

  void
  GrowCells(std::size_t id)
  {
    if (cellError.size() <= id)
    {
      // Half as much again, reserved exactly (resize alone would double the capacity).
      const std::size_t n = std::max<std::size_t>(id + 1, cellError.size() + cellError.size() / 2);
      auto              grow = [n](auto & v) {
        v.reserve(n);
        v.resize(n);
      };
      grow(cellError);
      if (selection != image)
      {
        grow(cellSelection);
      }
      grow(cellWorstError);
      grow(cellWorstVoxel);
      grow(cellAlive);
    }
  }

  // Six times a cell's volume: an exact integer, whatever the order of its vertices.
  uint64_t
  Volume6(const Tetrahedralization::Cell & c) const
  {
    return uint64_t(std::abs(SignedVolume6(
      { mesh.Point(c.vertices[0]), mesh.Point(c.vertices[1]), mesh.Point(c.vertices[2]), mesh.Point(c.vertices[3]) })));
  }

  // Reads only: cells can be scanned on several threads at once.
  CellScan
  Scan(const Tetrahedralization::Cell & c) const
  {
    return pixels->Visit([&](const auto * data) { return Scan(c, data); });
  }
  template <typename TPixel>
  CellScan
  Scan(const Tetrahedralization::Cell & c, const TPixel * data) const
  {
    return Scan(c, data, values);
  }
  // The same with other vertex values (by vertex id).
  template <typename TPixel>
  CellScan
  Scan(const Tetrahedralization::Cell & c, const TPixel * data, const std::vector<double> & vertexValues) const
  {
    std::array<GridPoint, 4> p;
    std::array<double, 4>    v;
    for (int i = 0; i < 4; ++i)
    {
      p[i] = mesh.Point(c.vertices[i]);
      v[i] = vertexValues[c.vertices[i]];
    }
    const CanonicalTetrahedron t(p, v);
    const LinearFunction       L(t);
    const bool                 separate = selection != image;
    CellScan                   s;
    double                     sse = 0.0, sseSelection = 0.0;
    float                      worst = 0.0f;
    uint64_t                   worstVoxel = NoVoxel;
    auto                       scanRow = [&](int32_t y, int32_t z, int32_t x0, int32_t x1) {
      const double   base = L.RowBase(y, z);
      const uint64_t rowOffset = grid.Offset(0, y, z);
      const TPixel * row = data + rowOffset;
      const float *  rowSelection = selection + rowOffset;
      for (int32_t x = x0; x <= x1; ++x)
      {
        // The same expression as Rasterize(), so decoder and engine agree to the bit.
        const double l = base + L.gx * double(x - L.origin[0]);
        const double e = (*pixels)(row, x) - l;
        sse += e * e;
        double es = e;
        if (separate)
        {
          es = double(rowSelection[x]) - l;
          sseSelection += es * es;
        }
        const float ae = float(std::fabs(es));
        if (ae > worst && !IsVertex(rowOffset + uint64_t(x)))
        {
          worst = ae;
          worstVoxel = rowOffset + uint64_t(x);
        }
      }
      s.count += uint64_t(x1 - x0 + 1);
    };
    ForEachSpanPrefetched(grid, t.p, data, separate ? selection : nullptr, isVertex.data(), scanRow);
    s.sse = sse;
    s.sseSelection = separate ? sseSelection : sse;
    s.worst = worst;
    s.worstVoxel = worstVoxel;
    s.volume = double(std::abs(SignedVolume6(p)));
    return s;
  }

  // Records a scanned cell as live: its state, the error total and the heaps.
  // push: false where the heaps are rebuilt from the cells' state afterwards (RebuildHeaps).
  void
  Commit(uint32_t id, const CellScan & s, bool push = true)
  {
    GrowCells(id);
    cellError[id] = s.sse;
    if (selection != image)
    {
      cellSelection[id] = s.sseSelection;
    }
    cellWorstError[id] = s.worst;
    cellWorstVoxel[id] = s.worstVoxel;
    liveCells += cellAlive[id] ? 0 : 1;
    cellAlive[id] = 1;
    squaredError += s.sse;
    if (push && !heapsPending && s.worstVoxel != NoVoxel)
    {
      byCellError.push(HeapEntry<double>{ s.sseSelection, id });
      byVoxelError.push(HeapEntry<float>{ s.worst, id });
    }
  }

  // Calls f(i) for every created cell: on several threads when the cells cover many voxels (the early
  // insertions, whose cavities span much of the volume, are most of the refinement's work).
  template <typename F>
  void
  OverCreated(F && f)
  {
    uint64_t volume6 = 0;
    for (const auto & c : created)
    {
      volume6 += Volume6(c);
    }
    constexpr uint64_t parallelVoxels = 32768; // a few hundred microseconds of scanning
    if (volume6 / 6 >= parallelVoxels && created.size() > 1)
    {
      ParallelFor(created.size(), 1, f);
    }
    else
    {
      for (std::size_t i = 0; i < created.size(); ++i)
      {
        f(i);
      }
    }
  }

  // Scans the cells an insertion or a removal created, and commits them in order.
  void
  ScanCreated()
  {
    scans.resize(created.size());
    OverCreated([&](std::size_t i) { scans[i] = Scan(created[i]); });
    CommitCreated();
  }

  // Commits the scanned new cells in order.
  void
  CommitCreated()
  {
    for (std::size_t i = 0; i < created.size(); ++i)
    {
      Commit(created[i].id, scans[i]);
      // The vertices whose incident cells changed are those of the new cells (every vertex of a dead
      // cell is on the boundary of the cavity or the hole).
      for (auto v : created[i].vertices)
      {
        removalCostValid[v] = 0;
      }
    }
  }

  // Keeps the per-cell state in proportion to the live cells: cell ids are never reused, so without
  // this the decimation rounds of a long run would hold state for every cell they ever created. Live
  // cells keep their order (cell ids decide orders and ties), and each has exactly one entry in each
  // heap, so the heaps rebuilt from them pop the same cells as the old ones.
  void
  CompactIfSparse()
  {
    const std::size_t live = liveCells;
    if (2 * mesh.NumberOfCellIds() < 3 * live + 8192)
    {
      return;
    }
    const auto renumbered = mesh.CompactCellIds();
    if (mesh.NumberOfCellIds() != live)
    {
      throw std::logic_error("RefinementEngine: live cells out of step with the tetrahedralization");
    }
    auto move = [&](auto & v) {
      if (v.empty())
      {
        return; // cellSelection once I_c = I
      }
      for (std::size_t old = 0; old < renumbered.size(); ++old)
      {
        if (renumbered[old] != NoCell)
        {
          v[renumbered[old]] = v[old]; // renumbered[old] <= old: nothing unread is overwritten
        }
      }
      v.resize(live);
      v.shrink_to_fit();
    };
    move(cellError);
    move(cellSelection);
    move(cellWorstError);
    move(cellWorstVoxel);
    move(cellAlive);
    RebuildHeaps();
  }

  // Frees the heaps, to be made anew from the live cells' state when next read (EnsureHeaps): not
  // while rate control codes the mesh after a rescan (20 bytes a cell at its peak), nor at all when
  // only decimation follows. Live cells own disjoint voxels, so no two entries tie on the key and the
  // worst voxel, and each live cell has one entry: the heaps pop the same cells whether built at once,
  // later, or entry by entry.
  void
  RebuildHeaps()
  {
    byCellError = CellHeap<double>(ByKey{ &cellWorstVoxel });
    byVoxelError = CellHeap<float>(ByKey{ &cellWorstVoxel });
    heapsPending = true;
  }

  // Makes the heaps from the live cells' state if RebuildHeaps() left them to be made, with room for the
  // entries to come up to the next compaction (a push beyond a vector's capacity doubles it).
  void
  EnsureHeaps()
  {
    if (!heapsPending)
    {
      return;
    }
    heapsPending = false;
    const std::vector<double> &    selectionError = cellSelection.empty() ? cellError : cellSelection;
    const std::size_t              room = liveCells + liveCells / 2 + 8192;
    std::vector<HeapEntry<double>> bySelection;
    std::vector<HeapEntry<float>>  byWorst;
    bySelection.reserve(room);
    byWorst.reserve(room);
    for (uint32_t c = 0; c < cellAlive.size(); ++c)
    {
      if (cellAlive[c] && cellWorstVoxel[c] != NoVoxel)
      {
        bySelection.push_back(HeapEntry<double>{ selectionError[c], c });
        byWorst.push_back(HeapEntry<float>{ cellWorstError[c], c });
      }
    }
    byCellError = CellHeap<double>(ByKey{ &cellWorstVoxel }, std::move(bySelection));
    byVoxelError = CellHeap<float>(ByKey{ &cellWorstVoxel }, std::move(byWorst));
  }

  // Frees the cells' state and heaps, which a full rescan (RescanAll) makes anew: the least squares do
  // not read them, and their peak is where the engine's is.
  void
  ReleaseCellState()
  {
    byCellError = CellHeap<double>(ByKey{ &cellWorstVoxel });
    byVoxelError = CellHeap<float>(ByKey{ &cellWorstVoxel });
    heapsPending = false; // nothing to make them from until a rescan
    std::vector<double>().swap(cellError);
    std::vector<double>().swap(cellSelection);
    std::vector<float>().swap(cellWorstError);
    std::vector<uint64_t>().swap(cellWorstVoxel);
    std::vector<char>().swap(cellAlive);
  }

  // Positions first to last - 1 of `cells` sorted by each cell's lowest vertex (z, then y, then x): visited
  // in this order, cells read the image slice by slice instead of jumping through it in the order of their ids.
  std::vector<uint32_t>
  SpatialOrder(const std::vector<Tetrahedralization::Cell> & cells, std::size_t first, std::size_t last) const
  {
    std::vector<std::pair<uint64_t, uint32_t>> keyed(last - first);
    ParallelFor(keyed.size(), 1024, [&](std::size_t k) {
      keyed[k] = { LowestVertexKey(cells[first + k]), uint32_t(first + k) };
    });
    ParallelSort(keyed.begin(), keyed.end()); // distinct keys: (a vertex's position, the cell's place)
    std::vector<uint32_t> order(keyed.size());
    for (std::size_t k = 0; k < order.size(); ++k)
    {
      order[k] = keyed[k].second;
    }
    return order;
  }

  // A cell's lowest vertex (z, then y, then x) as one integer.
  uint64_t
  LowestVertexKey(const Tetrahedralization::Cell & cell) const
  {
    uint64_t key = ~uint64_t(0);
    for (auto v : cell.vertices)
    {
      const GridPoint & q = mesh.Point(v);
      key = std::min(key, (uint64_t(q[2]) << 32) | (uint64_t(q[1]) << 16) | uint64_t(q[0]));
    }
    return key;
  }

  // The ids of all live cells sorted as SpatialOrder() sorts a part of them (ties by id): 4 bytes a cell,
  // where a part of the ids spans the whole volume.
  std::vector<uint32_t>
  CellIdsInSpatialOrder() const
  {
    std::vector<std::pair<uint64_t, uint32_t>> keyed;
    keyed.reserve(liveCells);
    ForEachIdRange([&](const std::vector<Tetrahedralization::Cell> & cells) {
      const std::size_t at = keyed.size();
      keyed.resize(at + cells.size());
      ParallelFor(cells.size(), 1024, [&](std::size_t k) {
        keyed[at + k] = { LowestVertexKey(cells[k]), cells[k].id };
      });
    });
    ParallelSort(keyed.begin(), keyed.end()); // distinct keys: (a vertex's position, the cell's id)
    std::vector<uint32_t> ids(keyed.size());
    for (std::size_t k = 0; k < ids.size(); ++k)
    {
      ids[k] = keyed[k].second;
    }
    return ids;
  }

  // Cells worked a part at a time (ForEachIdRange): their results in hand stay a few MB.
  static constexpr std::size_t chunk = std::size_t(1) << 18;

  // Calls f(cells) with the live cells of consecutive ranges of ids (`ids` at a time), by id: all the
  // cells a part at a time, never a list of all of them (20 bytes a cell).
  template <typename F>
  void
  ForEachIdRange(F && f, std::size_t ids = chunk) const
  {
    std::vector<Tetrahedralization::Cell> cells;
    for (std::size_t first = 0; first < mesh.NumberOfCellIds(); first += ids)
    {
      mesh.FiniteCells(uint32_t(first), uint32_t(std::min(mesh.NumberOfCellIds(), first + ids)), cells);
      f(cells);
    }
  }

  // Recomputes every live cell (after the selection image or the values changed): scanned in
  // parallel, committed in id order, so the sums and heaps do not depend on the threads.
  void
  RescanAll()
  {
    // Every live cell is committed again: its state is made anew, sized to the ids.
    ReleaseCellState();
    const std::size_t ids = mesh.NumberOfCellIds();
    auto              fresh = [ids](auto & v) { v.resize(ids); };
    fresh(cellError);
    if (selection != image)
    {
      fresh(cellSelection);
    }
    fresh(cellWorstError);
    fresh(cellWorstVoxel);
    fresh(cellAlive);
    liveCells = 0;
    squaredError = 0.0;
    std::fill(removalCostValid.begin(), removalCostValid.end(), 0);
    ScanAllCells(values, [this](uint32_t id, const CellScan & s) { Commit(id, s, false); });
    RebuildHeaps();
  }

  // Scans every live cell with `vertexValues` (by vertex id), a part of the ids at a time, on every thread
  // in SpatialOrder(), and calls take(id, scan) for each in the order of the ids: what the cells' state and
  // the squared error are made from, whatever the threads.
  template <typename F>
  void
  ScanAllCells(const std::vector<double> & vertexValues, F && take) const
  {
    // A quarter of the usual part: its results (48 bytes a cell, 3 MB) come from the allocator's free
    // memory, not from a mapping of their own faulted in page by page at every rescan.
    std::vector<CellScan> scans;
    ForEachIdRange(
      [&](const std::vector<Tetrahedralization::Cell> & cells) {
        const auto order = SpatialOrder(cells, 0, cells.size());
        scans.resize(cells.size());
        ParallelFor(order.size(), 64, [&](std::size_t k) {
          scans[order[k]] = pixels->Visit([&](const auto * data) { return Scan(cells[order[k]], data, vertexValues); });
        });
        for (std::size_t i = 0; i < cells.size(); ++i)
        {
          take(cells[i].id, scans[i]);
        }
      },
      chunk / 4);
  }

  // Top live cell of a heap, or NoCell when none is left.
  template <typename TKey>
  static uint32_t
  Top(CellHeap<TKey> & heap, const std::vector<char> & alive)
  {
    while (!heap.empty() && !alive[heap.top().cell])
    {
      heap.pop();
    }
    return heap.empty() ? NoCell : heap.top().cell;
  }

  // One refinement step; false when no voxel has a non-zero error left.
  bool
  Step()
  {
    CompactIfSparse();
    EnsureHeaps();
    // Silva: odd steps take the globally worst voxel, even steps the worst voxel of the worst cell.
    const bool     global = (step % 2) == 0;
    const uint32_t cell = global ? Top(byVoxelError, cellAlive) : Top(byCellError, cellAlive);
    if (cell == NoCell || cellWorstError[cell] <= 0.0f)
    {
      return false;
    }
    ++step;
    AddVertex(ToPoint(cellWorstVoxel[cell]), cell);
    if (selection != image && PSNROf(squaredError) >= parameters.alpha * smoothedPSNR)
    {
      selection = image; // I_c = I from now on (section 3)
      std::vector<double>().swap(cellSelection);
      RescanAll();
    }
    return true;
  }

  double
  RemovalCost(VertexId v);

  // The same from v's incident cells and their volumes (Tetrahedralization::IncidentVolumes).
  double
  RemovalCost(VertexId v, const std::vector<std::pair<Tetrahedralization::CellId, uint64_t>> & incident) const;

  double
  CachedRemovalCost(VertexId v);

  // Brings the cached removal costs of `vertices` (alive, distinct) up to date on several threads: a cost
  // only reads the mesh and the cells' state and is stored at its own vertex, so the values are those
  // of CachedRemovalCost() one by one.
  void
  UpdateRemovalCosts(const std::vector<VertexId> & vertices, std::size_t grain);

  // Removes v from the mesh and forgets its cells (its hole's new cells not yet scanned).
  void
  RemoveFromMesh(VertexId v);

  void
  Remove(VertexId v);

  // Remove(v), and the removal costs of its neighbours (the vertices of the new cells, alive and not
  // corners, by id, into `neighbours`) brought up to date: their stars are walked while the new cells
  // are scanned (each reads the mesh only; a removal's scans and walks are some 10 us each, so they go
  // side by side instead of each split over the threads), then the costs are summed from the scans.
  void
  RemoveUpdatingCosts(VertexId v, std::vector<VertexId> & neighbours);
};
} // namespace dcv

#endif
