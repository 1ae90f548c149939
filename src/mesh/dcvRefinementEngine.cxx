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
#include "dcvRefinementEngineImpl.h"

#include <stdexcept>
#include <string>

namespace dcv
{

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
  // (flair-mr, head-mr at low rates) where it lost up to 1.03 dB (docs/method.md):
  // each vertex's value, the better of I(p) and I*(p) over its new cells, is a greedy choice the
  // least squares then undo. It also spares the bilateral filter (the 5 mm CT series: 0.76 s).
  // The greedy local optimum of each new vertex's value was measured to hurt (head-mr, 3000 points:
  // 27.20 -> 25.15 dB with decimation), so no mode uses it; least squares at the end pays instead.
  p.leastSquares = mode == Mode::Best;
  return p;
}


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
