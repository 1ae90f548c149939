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
// The decimation's part of the refinement engine: the approximate error change of removing a vertex
// (the paper's Eqs. 2-7) and the removals themselves.
#include "dcvRefinementEngineImpl.h"

namespace dcv
{
double
RefinementEngine::Impl::RemovalCost(VertexId v)
{
  static thread_local std::vector<std::pair<Tetrahedralization::CellId, uint64_t>> incident;
  mesh.IncidentVolumes(v, incident);
  return RemovalCost(v, incident);
}

// The same from v's incident cells and their volumes (Tetrahedralization::IncidentVolumes).
double
RefinementEngine::Impl::RemovalCost(VertexId                                                             v,
                                    const std::vector<std::pair<Tetrahedralization::CellId, uint64_t>> & incident) const
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
RefinementEngine::Impl::CachedRemovalCost(VertexId v)
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
RefinementEngine::Impl::UpdateRemovalCosts(const std::vector<VertexId> & vertices, std::size_t grain)
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
RefinementEngine::Impl::RemoveFromMesh(VertexId v)
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
RefinementEngine::Impl::Remove(VertexId v)
{
  RemoveFromMesh(v);
  ScanCreated();
}

// Remove(v), and the removal costs of its neighbours (the vertices of the new cells, alive and not
// corners, by id, into `neighbours`) brought up to date: their stars are walked while the new cells
// are scanned (each reads the mesh only; a removal's scans and walks are some 10 us each, so they go
// side by side instead of each split over the threads), then the costs are summed from the scans.
void
RefinementEngine::Impl::RemoveUpdatingCosts(VertexId v, std::vector<VertexId> & neighbours)
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

} // namespace dcv
