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
#include "dcvTetrahedralization.h"
#include "dcvVertexRemoval.h"
#include "dcvGridKernel.h"
#include "dcvParallel.h"

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Delaunay_triangulation_cell_base_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>

#include <boost/container/small_vector.hpp>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>

namespace dcv
{
namespace
{
// Integer coordinates are exact in doubles, and the kernel's predicates are exact (dcvGridKernel.h).
using Kernel = GridKernel;
using VertexBase = CGAL::Triangulation_vertex_base_with_info_3<Tetrahedralization::VertexId, Kernel>;
constexpr uint32_t LargeVolume6 = (uint32_t(1) << 24) - 1;
// CGAL default-initializes the info of the cells it creates: give the identifier a safe default.
// Six times the cell's volume in grid units is kept with its id, so that the decimation's removal
// costs read no vertex. Packed into 7 bytes, the info fills the padding after CGAL's own byte, and
// the cell stays 72 bytes (with 8 it is 80: 44 MB more at norm-256's 0.25 bpv, where the peak is);
// a volume beyond 24 bits (a cell of more than 2.8 M voxels: the first few) is computed instead.
#pragma pack(push, 1)
struct CellInfo
{
  // Bytes only, read and written by value: a reference to a member of a packed struct could be
  // misaligned (the id starts at the cell's 65th byte).
  uint8_t id[4];
  uint8_t volume6[3]{ 0, 0, 0 }; // little-endian, LargeVolume6 if it does not fit

  CellInfo() { SetId(Tetrahedralization::NoCell); }
  Tetrahedralization::CellId
  Id() const
  {
    Tetrahedralization::CellId v;
    std::memcpy(&v, id, sizeof v);
    return v;
  }
  void
  SetId(Tetrahedralization::CellId v)
  {
    std::memcpy(id, &v, sizeof v);
  }
  void
  SetVolume6(uint64_t v)
  {
    const uint32_t kept = v < LargeVolume6 ? uint32_t(v) : LargeVolume6;
    volume6[0] = uint8_t(kept);
    volume6[1] = uint8_t(kept >> 8);
    volume6[2] = uint8_t(kept >> 16);
  }
  uint32_t
  Volume6() const
  {
    return uint32_t(volume6[0]) | uint32_t(volume6[1]) << 8 | uint32_t(volume6[2]) << 16;
  }
};
#pragma pack(pop)
using CellBase =
  CGAL::Triangulation_cell_base_with_info_3<CellInfo, Kernel, CGAL::Delaunay_triangulation_cell_base_3<Kernel>>;
using DataStructure = CGAL::Triangulation_data_structure_3<VertexBase, CellBase, CGAL::Sequential_tag>;
using Delaunay = CGAL::Delaunay_triangulation_3<Kernel, DataStructure>;
using CellHandle = Delaunay::Cell_handle;
using VertexHandle = Delaunay::Vertex_handle;
using CgalPoint = Kernel::Point_3;
// A cell's sorted vertex ids, the first two and the last two in one integer each: compared as a pair.
using KeyedCell = std::pair<std::pair<uint64_t, uint64_t>, CellHandle>;

/** The cell record of a finite CGAL cell under the id `id`. */
Tetrahedralization::Cell
CellOf(Tetrahedralization::CellId id, const CellHandle & c)
{
  return { id, { c->vertex(0)->info(), c->vertex(1)->info(), c->vertex(2)->info(), c->vertex(3)->info() } };
}

} // namespace

struct Tetrahedralization::Impl
{
  Delaunay                       dt;
  GridScale                      scale{ { 1, 1, 1 } };
  std::vector<GridPoint>         points;   // by vertex id
  std::vector<VertexHandle>      vertices; // by vertex id (null once removed)
  std::vector<CellHandle>        cells;    // by cell id (null once the cell died)
  std::vector<CellHandle>        scratch;
  std::vector<CellHandle>        hole;  // Remove's
  std::vector<KeyedCell>         keyed; // RegisterInOrder's
  VertexRemovalScratch<Delaunay> removal;

  uint64_t
  Volume6(const CellHandle & c) const
  {
    return uint64_t(std::abs(SignedVolume6({ points[c->vertex(0)->info()],
                                             points[c->vertex(1)->info()],
                                             points[c->vertex(2)->info()],
                                             points[c->vertex(3)->info()] })));
  }

  // Calls f(c) for every cell of v's star, infinite ones included, in no fixed order.
  template <typename F>
  void
  ForEachIncident(VertexId id, F && f) const;

  // Gives ids to the new finite cells and reports them.
  void
  Register(CellHandle c, std::vector<Cell> * created)
  {
    if (dt.is_infinite(c))
    {
      c->info().SetId(NoCell);
      return;
    }
    const CellId id = CellId(cells.size());
    if (id == NoCell)
    {
      throw std::length_error("Tetrahedralization: too many cells");
    }
    c->info().SetId(id);
    c->info().SetVolume6(Volume6(c));
    cells.push_back(c);
    if (created)
    {
      created->push_back(CellOf(id, c));
    }
  }

  // Registers the cells in `scratch` in an order fixed by their vertices: CGAL hands them over in
  // memory order, which varies between runs, and cell ids, heap ties and error sums must not. Each
  // cell's key (its sorted vertex ids) is made once, not at every comparison; no two cells share one.
  void
  RegisterInOrder(std::vector<Cell> & created)
  {
    keyed.clear();
    for (const CellHandle & c : scratch)
    {
      uint64_t k[4] = { c->vertex(0)->info(), c->vertex(1)->info(), c->vertex(2)->info(), c->vertex(3)->info() };
      // By a sorting network (std::sort's loops were a third of this function's time).
      detail::SortFour([&k](int i, int j) {
        const uint64_t a = std::min(k[i], k[j]), b = std::max(k[i], k[j]);
        k[i] = a;
        k[j] = b;
      });
      keyed.emplace_back(std::make_pair(k[0] << 32 | k[1], k[2] << 32 | k[3]), c);
    }
    std::sort(keyed.begin(), keyed.end(), [](const auto & a, const auto & b) { return a.first < b.first; });
    for (const auto & kc : keyed)
    {
      Register(kc.second, &created);
    }
  }

  // Forgets the handles of dead cells: CGAL recycles them for new cells.
  void
  Kill(const std::vector<CellId> & dead)
  {
    for (CellId id : dead)
    {
      cells[id] = CellHandle();
    }
  }

  // Re-numbers every finite cell (after operations whose new cells CGAL does not report).
  void
  RegisterAll()
  {
    std::fill(cells.begin(), cells.end(), CellHandle());
    for (auto c = dt.all_cells_begin(); c != dt.all_cells_end(); ++c)
    {
      Register(c, nullptr);
    }
  }
};

Tetrahedralization::Tetrahedralization()
  : m_Impl(std::make_unique<Impl>())
{
  m_Impl->dt.infinite_vertex()->info() = 0xffffffffu; // CGAL leaves it uninitialized; cell ordering reads it
}

Tetrahedralization::~Tetrahedralization() = default;

void
Tetrahedralization::SetScale(const GridScale & scale)
{
  CheckGridScale(scale);
  if (!m_Impl->points.empty())
  {
    throw std::logic_error("Tetrahedralization: the scale is set before any point is inserted");
  }
  m_Impl->scale = scale;
}

void
Tetrahedralization::InsertMany(const std::vector<GridPoint> & points)
{
  Impl &                                      d = *m_Impl;
  std::vector<std::pair<CgalPoint, VertexId>> input;
  input.reserve(points.size());
  const VertexId first = VertexId(d.points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    input.emplace_back(ToGridKernel(points[i], d.scale), first + VertexId(i)); // checks before anything changes
  }
  d.points.insert(d.points.end(), points.begin(), points.end());
  d.vertices.resize(d.points.size());
  // The range insertion sorts spatially (fast) and keeps the info of each point.
  const std::size_t before = d.dt.number_of_vertices();
  d.dt.insert(input.begin(), input.end());
  if (d.dt.number_of_vertices() - before != points.size())
  {
    throw std::invalid_argument("Tetrahedralization: duplicate points");
  }
  for (auto v = d.dt.finite_vertices_begin(); v != d.dt.finite_vertices_end(); ++v)
  {
    d.vertices[v->info()] = v;
  }
  d.RegisterAll();
}

Tetrahedralization::VertexId
Tetrahedralization::Insert(const GridPoint & p, CellId hint, std::vector<CellId> & killed, std::vector<Cell> & created)
{
  Impl & d = *m_Impl;
  killed.clear();
  created.clear();
  const VertexId  id = VertexId(d.points.size());
  const CgalPoint q = ToGridKernel(p, d.scale);
  if (d.dt.dimension() < 3)
  {
    // Lower-dimensional start (the first corners): let CGAL build it and number what exists.
    VertexHandle v = d.dt.insert(q);
    v->info() = id;
    d.points.push_back(p);
    d.vertices.push_back(v);
    if (d.dt.dimension() == 3)
    {
      for (auto c = d.dt.all_cells_begin(); c != d.dt.all_cells_end(); ++c)
      {
        d.Register(c, &created);
      }
    }
    return id;
  }
  Delaunay::Locate_type lt;
  int                   li = 0, lj = 0;
  const CellHandle      start = (hint != NoCell && hint < d.cells.size()) ? d.cells[hint] : CellHandle();
  const CellHandle      c = d.dt.locate(q, lt, li, lj, start);
  if (lt == Delaunay::VERTEX)
  {
    throw std::logic_error("Tetrahedralization: point is already a vertex");
  }
  // The located cell contains q, so it is in conflict with it (Delaunay insertion, as CGAL does).
  d.scratch.clear();
  Delaunay::Facet facet;
  d.dt.find_conflicts(q, c, CGAL::Oneset_iterator<Delaunay::Facet>(facet), std::back_inserter(d.scratch));
  for (const CellHandle & dead : d.scratch)
  {
    if (dead->info().Id() != NoCell)
    {
      killed.push_back(dead->info().Id());
    }
  }
  d.Kill(killed);
  VertexHandle v = d.dt.insert_in_hole(q, d.scratch.begin(), d.scratch.end(), facet.first, facet.second);
  v->info() = id;
  d.points.push_back(p);
  d.vertices.push_back(v);
  d.scratch.clear();
  d.dt.incident_cells(v, std::back_inserter(d.scratch));
  d.RegisterInOrder(created);
  return id;
}

void
Tetrahedralization::Remove(VertexId id, std::vector<CellId> & killed, std::vector<Cell> & created)
{
  Impl & d = *m_Impl;
  killed.clear();
  created.clear();
  if (id >= d.vertices.size() || d.vertices[id] == VertexHandle())
  {
    throw std::logic_error("Tetrahedralization: no such vertex");
  }
  VertexHandle v = d.vertices[id];
  d.hole.clear();
  d.dt.incident_cells(v, std::back_inserter(d.hole));
  for (const CellHandle & dead : d.hole)
  {
    if (dead->info().Id() != NoCell)
    {
      killed.push_back(dead->info().Id());
    }
  }
  d.Kill(killed);
  // The cells CGAL's removal gives, without its hash maps (dcvVertexRemoval.h); CGAL's own removal where
  // the link is not plainly three-dimensional.
  if (!RemoveByLink(d.dt, v, d.hole, d.scratch, d.removal, NoCell))
  {
    d.scratch.clear();
    d.dt.remove_and_give_new_cells(v, std::back_inserter(d.scratch));
  }
  d.vertices[id] = VertexHandle();
  d.RegisterInOrder(created);
}

template <typename F>
void
Tetrahedralization::Impl::ForEachIncident(VertexId id, F && f) const
{
  const VertexHandle v = vertices.at(id);
  if (v == VertexHandle())
  {
    throw std::logic_error("Tetrahedralization: no such vertex");
  }
  if (dt.dimension() < 3)
  {
    return; // no cell has an id yet
  }
  // Our own walk, not CGAL's incident_cells: that one marks the cells it visits in the cells themselves
  // (Sequential_tag), so two threads could not list incident cells at once. This one only reads the
  // triangulation. From v's cell, across the facets that contain v (all but the one opposite v), to
  // every cell of v's star, infinite ones included (hull vertices: the star is connected through them).
  // The cells seen are kept in a small hash table on the stack (a star has some 20 to 60 cells); a
  // larger star goes on with a linear search of the list.
  constexpr std::size_t                           slots = 256;
  std::array<const void *, slots>                 seen{};
  boost::container::small_vector<CellHandle, 128> star;
  auto                                            firstVisit = [&seen, &star](const CellHandle & c) {
    if (star.size() >= slots / 2)
    {
      return std::find(star.begin(), star.end(), c) == star.end();
    }
    const void *   key = &*c;
    const uint64_t hash = uint64_t(reinterpret_cast<std::uintptr_t>(key)) * 0x9E3779B97F4A7C15ull; // Fibonacci
    std::size_t    h = std::size_t(hash >> 56); // its top 8 bits: one of the 256 slots
    for (; seen[h] != nullptr; h = (h + 1) % slots)
    {
      if (seen[h] == key)
      {
        return false;
      }
    }
    seen[h] = key;
    return true;
  };
  firstVisit(v->cell());
  star.push_back(v->cell());
  for (std::size_t i = 0; i < star.size(); ++i)
  {
    const CellHandle c = star[i];
    const int        opposite = c->index(v);
    for (int j = 0; j < 4; ++j)
    {
      if (j != opposite)
      {
        const CellHandle n = c->neighbor(j);
        if (firstVisit(n))
        {
          // Read when its turn comes: its cache misses overlap the walk meanwhile (a cell is 72 bytes, on
          // two lines mostly).
          __builtin_prefetch(&*n);
          __builtin_prefetch(reinterpret_cast<const char *>(&*n) + 64);
          star.push_back(n);
        }
      }
    }
  }
  for (const CellHandle & c : star)
  {
    f(c);
  }
}

void
Tetrahedralization::IncidentCells(VertexId id, std::vector<Cell> & out) const
{
  out.clear();
  m_Impl->ForEachIncident(id, [&out](const CellHandle & c) {
    if (c->info().Id() != NoCell)
    {
      out.push_back(CellOf(c->info().Id(), c));
    }
  });
}

void
Tetrahedralization::IncidentVolumes(VertexId id, std::vector<std::pair<CellId, uint64_t>> & out) const
{
  out.clear();
  const Impl & d = *m_Impl;
  d.ForEachIncident(id, [&](const CellHandle & c) {
    if (c->info().Id() != NoCell)
    {
      const uint32_t kept = c->info().Volume6();
      out.emplace_back(c->info().Id(), kept != LargeVolume6 ? kept : d.Volume6(c));
    }
  });
}

std::vector<Tetrahedralization::CellId>
Tetrahedralization::CompactCellIds()
{
  Impl &              d = *m_Impl;
  std::vector<CellId> renumbered(d.cells.size(), NoCell);
  CellId              next = 0;
  for (CellId old = 0; old < d.cells.size(); ++old)
  {
    if (d.cells[old] != CellHandle())
    {
      renumbered[old] = next;
      d.cells[old]->info().SetId(next);
      d.cells[next++] = d.cells[old]; // next <= old: nothing unread is overwritten
    }
  }
  // Room for the ids to come up to the next compaction (at 1.5 times the live cells, see
  // RefinementEngine), not the doubling of push_back: 8 bytes an id.
  std::vector<CellHandle> kept;
  kept.reserve(std::size_t(next) + next / 2 + 8192);
  kept.assign(d.cells.begin(), d.cells.begin() + next);
  d.cells.swap(kept);
  return renumbered;
}

std::size_t
Tetrahedralization::NumberOfCellIds() const
{
  return m_Impl->cells.size();
}

std::vector<Tetrahedralization::Cell>
Tetrahedralization::FiniteCells() const
{
  std::vector<Cell> out;
  out.reserve(m_Impl->dt.number_of_finite_cells());
  FiniteCells(0, CellId(m_Impl->cells.size()), out);
  return out;
}

void
Tetrahedralization::FiniteCells(CellId first, CellId last, std::vector<Cell> & out) const
{
  // By id: an order that does not depend on memory addresses (see RegisterInOrder). Blocks of ids on
  // every thread, each written at the place the live cells before it leave (the cells' vertices miss the
  // cache one after the other: 4% of the encoder's main thread at 0.25 bpv when read on it alone).
  out.clear();
  const auto & cells = m_Impl->cells;
  const CellId end = CellId(std::min<std::size_t>(last, cells.size()));
  if (end <= first)
  {
    return;
  }
  constexpr std::size_t    block = 4096;
  const std::size_t        blocks = (std::size_t(end - first) + block - 1) / block;
  std::vector<std::size_t> start(blocks + 1, 0);
  auto                     range = [&](std::size_t b) {
    return std::make_pair(CellId(first + b * block), CellId(std::min<std::size_t>(end, first + (b + 1) * block)));
  };
  ParallelFor(blocks, 1, [&](std::size_t b) {
    const auto [from, to] = range(b);
    start[b + 1] = std::size_t(
      std::count_if(cells.begin() + from, cells.begin() + to, [](const CellHandle & c) { return c != CellHandle(); }));
  });
  for (std::size_t b = 0; b < blocks; ++b)
  {
    start[b + 1] += start[b];
  }
  out.resize(start[blocks]);
  ParallelFor(blocks, 1, [&](std::size_t b) {
    const auto [from, to] = range(b);
    std::size_t at = start[b];
    for (CellId id = from; id < to; ++id)
    {
      if (const CellHandle & c = cells[id]; c != CellHandle())
      {
        out[at++] = CellOf(id, c);
      }
    }
  });
}

void
Tetrahedralization::FiniteCells(const CellId * ids, std::size_t count, std::vector<Cell> & out) const
{
  const auto & cells = m_Impl->cells;
  out.resize(count);
  ParallelFor(count, 1024, [&](std::size_t i) {
    const CellHandle & c = cells.at(ids[i]);
    if (c == CellHandle())
    {
      throw std::invalid_argument("Tetrahedralization: no live cell " + std::to_string(ids[i]));
    }
    out[i] = CellOf(ids[i], c);
  });
}

const GridPoint &
Tetrahedralization::Point(VertexId v) const
{
  return m_Impl->points.at(v);
}

Tetrahedralization::VertexId
Tetrahedralization::NumberOfVertexIds() const
{
  return VertexId(m_Impl->points.size());
}

std::size_t
Tetrahedralization::NumberOfVertices() const
{
  return m_Impl->dt.number_of_vertices();
}

std::size_t
Tetrahedralization::NumberOfFiniteCells() const
{
  return m_Impl->dt.number_of_finite_cells();
}

bool
Tetrahedralization::IsValid() const
{
  return m_Impl->dt.is_valid();
}

} // namespace dcv
