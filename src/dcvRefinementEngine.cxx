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
namespace
{
constexpr uint64_t NoVoxel = ~uint64_t(0);
constexpr uint32_t NoCell = Tetrahedralization::NoCell;
constexpr uint32_t NumberOfCorners = 8; // vertex ids 0-7, never removed

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
} // namespace

const char *
ModeName(Mode mode)
{
  switch (mode)
  {
    case Mode::Silva:
      return "silva";
    case Mode::Dec:
      return "dec";
    case Mode::DecCom:
      return "dec+com";
    case Mode::Best:
      return "best";
  }
  return "?";
}

Mode
ParseMode(const std::string & name)
{
  for (Mode m : { Mode::Silva, Mode::Dec, Mode::DecCom, Mode::Best })
  {
    if (name == ModeName(m))
    {
      return m;
    }
  }
  throw std::invalid_argument("unknown mode '" + name + "' (use silva, dec, dec+com or best)");
}

bool
UsesSmoothedImage(Mode mode)
{
  return mode == Mode::DecCom;
}

RefinementParameters
ParametersForMode(Mode mode)
{
  RefinementParameters p;
  p.decimation = mode != Mode::Silva;
  // Best does not use I*: with least-squares values and the residual layer it paid on none of the 40 dev
  // runs (../shared/data, 0.03125 to 0.25 bpv: 35 files the same, 5 better by 0.08 to 0.98 dB, the CT
  // volumes ct-avm-4mm and headsq-ct from 0.0625 bpv on), and points alone it gained at most 0.08 dB
  // (flair-mr, head-mr at low rates) where it lost up to 1.03 dB (docs/profile.md, sixth session of
  // 12-05): each vertex's value, the better of I(p) and I*(p) over its new cells, is a greedy choice the
  // least squares then undo. It also spares the bilateral filter (the 5 mm CT series: 0.76 s).
  // The greedy local optimum of each new vertex's value was measured to hurt (head-mr, 3000 points:
  // 27.20 -> 25.15 dB with decimation), so no mode uses it; least squares at the end pays instead.
  p.leastSquares = mode == Mode::Best;
  return p;
}

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
  RemovalCost(VertexId v)
  {
    static thread_local std::vector<std::pair<Tetrahedralization::CellId, uint64_t>> incident;
    mesh.IncidentVolumes(v, incident);
    return RemovalCost(v, incident);
  }

  // The same from v's incident cells and their volumes (Tetrahedralization::IncidentVolumes).
  double
  RemovalCost(VertexId v, const std::vector<std::pair<Tetrahedralization::CellId, uint64_t>> & incident) const
  {
    // The errors summed in a fixed order, ascending (the incident cells come in the order of a walk that
    // starts wherever CGAL last pointed v), for reproducible keys. The volumes are integers whose sum (at
    // most 6 times the grid's voxels, < 2^53) is exact in any order: only the errors are sorted.
    boost::container::small_vector<double, 64> errors;
    uint64_t                                   volume6 = 0;
    for (const auto & [cell, cellVolume6] : incident)
    {
      errors.push_back(cellError[cell]); // as Scan() gives it
      volume6 += cellVolume6;
    }
    std::sort(errors.begin(), errors.end());
    double error = 0.0;
    for (double e : errors)
    {
      error += e;
    }
    const double volume = double(volume6);
    // Eq. 6: the error without v, as stored at its insertion, scaled to its incident volume now.
    const double without = volumeBefore[v] > 0.0 ? errorBefore[v] * volume / volumeBefore[v] : 0.0;
    return without - error;
  }

  double
  CachedRemovalCost(VertexId v)
  {
    if (!removalCostValid[v])
    {
      removalCost[v] = RemovalCost(v);
      removalCostValid[v] = 1;
    }
    return removalCost[v];
  }

  // Brings the cached removal costs of `vertices` (alive, distinct) up to date on several threads: a cost
  // only reads the mesh and the cells' state and is stored at its own vertex, so the values are those
  // of CachedRemovalCost() one by one.
  void
  UpdateRemovalCosts(const std::vector<VertexId> & vertices, std::size_t grain)
  {
    std::vector<VertexId> & stale = staleCosts;
    stale.clear();
    for (VertexId v : vertices)
    {
      if (!removalCostValid[v])
      {
        stale.push_back(v);
      }
    }
    ParallelFor(stale.size(), grain, [&](std::size_t i) { removalCost[stale[i]] = RemovalCost(stale[i]); });
    for (VertexId v : stale)
    {
      removalCostValid[v] = 1;
    }
  }

  // Removes v from the mesh and forgets its cells (its hole's new cells not yet scanned).
  void
  RemoveFromMesh(VertexId v)
  {
    if (v < NumberOfCorners || v >= vertexAlive.size() || !vertexAlive[v])
    {
      throw std::invalid_argument("RefinementEngine: vertex " + std::to_string(v) + " cannot be removed");
    }
    CompactIfSparse();
    const GridPoint p = mesh.Point(v);
    mesh.Remove(v, killed, created);
    ++meshVersion;
    vertexAlive[v] = 0;
    SetVertex(grid.Offset(p[0], p[1], p[2]), false);
    Kill(killed);
  }

  void
  Remove(VertexId v)
  {
    RemoveFromMesh(v);
    ScanCreated();
  }

  // Remove(v), and the removal costs of its neighbours (the vertices of the new cells, alive and not
  // corners, by id, into `neighbours`) brought up to date: their stars are walked while the new cells
  // are scanned (each reads the mesh only; a removal's scans and walks are some 10 us each, so they go
  // side by side instead of each split over the threads), then the costs are summed from the scans.
  void
  RemoveUpdatingCosts(VertexId v, std::vector<VertexId> & neighbours)
  {
    RemoveFromMesh(v);
    neighbours.clear();
    for (const auto & c : created)
    {
      neighbours.insert(neighbours.end(), c.vertices.begin(), c.vertices.end());
    }
    std::sort(neighbours.begin(), neighbours.end());
    neighbours.erase(std::unique(neighbours.begin(), neighbours.end()), neighbours.end());
    neighbours.erase(std::remove_if(neighbours.begin(),
                                    neighbours.end(),
                                    [this](VertexId u) { return u < NumberOfCorners || !vertexAlive[u]; }),
                     neighbours.end());
    if (incidentOfNeighbours.size() < neighbours.size())
    {
      incidentOfNeighbours.resize(neighbours.size());
    }
    scans.resize(created.size());
    ParallelInvoke([&] { OverCreated([&](std::size_t i) { scans[i] = Scan(created[i]); }); },
                   [&] {
                     for (std::size_t k = 0; k < neighbours.size(); ++k)
                     {
                       mesh.IncidentVolumes(neighbours[k], incidentOfNeighbours[k]);
                     }
                   });
    CommitCreated();
    for (std::size_t k = 0; k < neighbours.size(); ++k)
    {
      removalCost[neighbours[k]] = RemovalCost(neighbours[k], incidentOfNeighbours[k]);
      removalCostValid[neighbours[k]] = 1;
    }
  }
};

RefinementEngine::RefinementEngine(const float * image, const GridSize & grid, const RefinementParameters & parameters)
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
  if (!(parameters.alpha > 0.0))
  {
    throw std::invalid_argument("RefinementEngine: alpha must be positive, got " + std::to_string(parameters.alpha));
  }
  if (!(parameters.peak > 0.0) || !(parameters.valueMin <= parameters.valueMax))
  {
    throw std::invalid_argument("RefinementEngine: the peak must be positive and valueMin <= valueMax");
  }
  if (!(parameters.quantizationStep >= 0.0))
  {
    throw std::invalid_argument("RefinementEngine: the quantization step must be positive or 0 (none)");
  }
  Impl & d = *m_Impl;
  d.mesh.SetScale(parameters.scale);
  d.image = image;
  d.pixels = std::make_unique<PixelSource>(image, grid.NumberOfVoxels());
  d.grid = grid;
  d.parameters = parameters;
  d.selection = parameters.smoothed ? parameters.smoothed : image;
  if (parameters.smoothed)
  {
    d.smoothedPSNR = d.PSNROf(SquaredError(image, parameters.smoothed, grid.NumberOfVoxels()));
  }
  d.isVertex.assign((grid.NumberOfVoxels() + 63) / 64, 0);
  for (int k = 0; k < 8; ++k)
  {
    const GridPoint corner{ (k & 1) ? grid.x - 1 : 0, (k & 2) ? grid.y - 1 : 0, (k & 4) ? grid.z - 1 : 0 };
    d.AddVertex(corner, NoCell);
  }
}

RefinementEngine::~RefinementEngine() = default;

void
RefinementEngine::Approximate(std::size_t numberOfPoints, const ProgressFunction & progress)
{
  Impl & d = *m_Impl;
  // Work units: the insertions still to make and the removals (RemovalWork each) and insertions of the
  // schedule, for the progress fraction (a caller that refined first sees only the schedule's).
  const std::size_t refinements = numberOfPoints > GetNumberOfPoints() ? numberOfPoints - GetNumberOfPoints() : 0;
  double            total = double(refinements);
  if (d.parameters.decimation)
  {
    for (std::size_t k = numberOfPoints / 2; k > 0; k /= 2)
    {
      total += (RemovalWork + 1.0) * double(k);
    }
  }
  double done = 0.0;
  auto   part = [&](double units) {
    const double from = done;
    done += units;
    return progress ? ProgressFunction([&, from, units](double f) {
      progress(std::min(1.0, (from + f * units) / std::max(1.0, total)));
    })
                      : ProgressFunction();
  };
  Refine(numberOfPoints, part(double(refinements)));
  if (d.parameters.decimation)
  {
    for (std::size_t k = numberOfPoints / 2; k > 0; k /= 2)
    {
      const std::size_t before = GetNumberOfPoints();
      Decimate(std::min(k, before > NumberOfCorners ? before - NumberOfCorners : 0), part(RemovalWork * double(k)));
      Refine(before, part(double(k)));
    }
  }
  if (d.parameters.leastSquares)
  {
    OptimizeValues();
  }
  if (progress)
  {
    progress(1.0);
  }
}

void
RefinementEngine::Refine(std::size_t numberOfPoints, const ProgressFunction & progress)
{
  Impl &            d = *m_Impl;
  const StageTimer  timer(d.timings.refinement);
  const std::size_t start = d.mesh.NumberOfVertices();
  const std::size_t total = numberOfPoints > start ? numberOfPoints - start : 0;
  const std::size_t every = std::max<std::size_t>(1, total / 100);
  // Every insertion takes a new id, on a voxel that is not yet a vertex.
  d.GrowVertices(d.mesh.NumberOfVertexIds() +
                 std::min<std::size_t>(total, d.grid.NumberOfVoxels() - d.mesh.NumberOfVertices()));
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

void
RefinementEngine::Decimate(std::size_t count, const ProgressFunction & progress)
{
  Impl &                d = *m_Impl;
  const StageTimer      timer(d.timings.decimation);
  std::vector<VertexId> candidates;
  candidates.reserve(d.mesh.NumberOfVertices());
  for (VertexId v = NumberOfCorners; v < d.mesh.NumberOfVertexIds(); ++v)
  {
    if (d.vertexAlive[v])
    {
      candidates.push_back(v);
    }
  }
  // Costs are kept between rounds: only vertices whose incident cells changed are computed again.
  d.UpdateRemovalCosts(candidates, 256);
  std::vector<RemovalEntry> entries;
  entries.reserve(candidates.size());
  for (VertexId v : candidates)
  {
    entries.push_back(RemovalEntry{ d.CachedRemovalCost(v), v, ++d.stamp[v] });
  }
  std::priority_queue<RemovalEntry> heap(std::less<RemovalEntry>(), std::move(entries));
  std::vector<VertexId>             neighbours;
  const std::size_t                 every = std::max<std::size_t>(1, count / 100);
  for (std::size_t removed = 0; removed < count && !heap.empty();)
  {
    const RemovalEntry e = heap.top();
    heap.pop();
    if (!d.vertexAlive[e.vertex] || e.stamp != d.stamp[e.vertex])
    {
      continue; // stale: the vertex died or its neighbourhood changed
    }
    // The neighbours' new costs, pushed in the order of their ids.
    d.RemoveUpdatingCosts(e.vertex, neighbours);
    ++removed;
    for (VertexId v : neighbours)
    {
      heap.push(RemovalEntry{ d.CachedRemovalCost(v), v, ++d.stamp[v] });
    }
    if (progress && removed % every == 0)
    {
      progress(double(removed) / double(count));
    }
  }
  if (progress)
  {
    progress(1.0);
  }
}

void
RefinementEngine::Resize(std::size_t numberOfPoints, const ProgressFunction & progress)
{
  const std::size_t n = GetNumberOfPoints();
  numberOfPoints = std::max<std::size_t>(numberOfPoints, NumberOfCorners);
  if (numberOfPoints == n)
  {
    return;
  }
  if (numberOfPoints < n)
  {
    Decimate(n - numberOfPoints, progress);
  }
  else
  {
    Refine(numberOfPoints, progress);
  }
  if (m_Impl->parameters.leastSquares)
  {
    OptimizeValues();
  }
}

void
RefinementEngine::SetQuantizationStep(double step)
{
  Impl & d = *m_Impl;
  d.values = d.ValuesAtStep(step); // checks the step before anything changes
  d.parameters.quantizationStep = step;
  d.RescanAll();
}

Approximation
RefinementEngine::GetApproximationAtStep(double step, double & squaredError) const
{
  const Impl &              d = *m_Impl;
  const std::vector<double> values = d.ValuesAtStep(step);
  // The cells' errors summed by id, as RescanAll() sums them into the engine's own.
  double sum = 0.0;
  d.ScanAllCells(values, [&sum](uint32_t, const CellScan & s) { sum += s.sse; });
  squaredError = std::max(0.0, sum);
  return d.ApproximationOf(values);
}

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

double
RefinementEngine::EstimateRemovalCost(VertexId v) const
{
  if (v >= m_Impl->vertexAlive.size() || !m_Impl->vertexAlive[v])
  {
    throw std::invalid_argument("RefinementEngine: no vertex " + std::to_string(v));
  }
  return m_Impl->RemovalCost(v);
}

void
RefinementEngine::RemoveVertex(VertexId v)
{
  m_Impl->Remove(v);
}

RefinementEngine::VertexId
RefinementEngine::GetLastInsertedVertex() const
{
  return m_Impl->lastInserted;
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

const RefinementEngine::Timings &
RefinementEngine::GetTimings() const
{
  return m_Impl->timings;
}

double
RefinementEngine::GetSmoothedPSNR() const
{
  return m_Impl->smoothedPSNR;
}

bool
RefinementEngine::GetSelectingOnImage() const
{
  return m_Impl->selection == m_Impl->image;
}

const GridSize &
RefinementEngine::GetGrid() const
{
  return m_Impl->grid;
}

const RefinementParameters &
RefinementEngine::GetParameters() const
{
  return m_Impl->parameters;
}

Approximation
RefinementEngine::GetApproximation() const
{
  return m_Impl->ApproximationOf(m_Impl->values);
}

std::vector<RefinementEngine::CellStatistics>
RefinementEngine::GetCellStatistics() const
{
  const Impl &                d = *m_Impl;
  std::vector<CellStatistics> out;
  for (const auto & c : d.mesh.FiniteCells())
  {
    out.push_back(CellStatistics{ c.id, d.Scan(c).count, d.cellError[c.id] });
  }
  return out;
}

} // namespace dcv
