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
#ifndef dcvVertexRemoval_h
#define dcvVertexRemoval_h

// Internal to dcvTetrahedralization.cxx: the removal of a vertex from a 3D Delaunay triangulation of
// CGAL's, the hole filled with the cells CGAL's own removal gives (the same cells, their vertices in the
// same order), without its hash maps.
#include <array>
#include <cstdint>
#include <iterator>
#include <type_traits>
#include <vector>

namespace dcv
{

/** What RemoveByLink keeps between calls (its lists, sized once). */
template <typename TDelaunay>
struct VertexRemovalScratch
{
  using VertexHandle = typename TDelaunay::Vertex_handle;
  using CellHandle = typename TDelaunay::Cell_handle;
  struct Boundary // a facet of the hole: the star cell inside, the cell outside and its index there
  {
    uint64_t   key;
    CellHandle outside;
    int        outsideIndex;
    bool       glued;
  };
  std::vector<VertexHandle>       link;      // the vertices adjacent to the removed one, in CGAL's order
  std::vector<uint16_t>           linkIndex; // by vertex id (info): the position in `link`
  std::vector<VertexHandle>       linked;    // by position in `link`: the vertex of the small triangulation
  std::vector<Boundary>           boundary;
  std::vector<int32_t>            slots;  // open addressing over `boundary` by key (index + 1, 0: free)
  std::vector<CellHandle>         inside; // the small triangulation's cells that fill the hole
  std::vector<std::array<int, 4>> glue;   // per inside cell and facet: the boundary facet, or -1
};

namespace detail
{
/** The three link positions of facet i of c, as seen from c, rotated to start at the smallest: equal
 * for the two views of one triangle from the same side. */
template <typename TDelaunay, typename TCell, typename TPosition>
uint64_t
FacetKey(const TCell & c, int i, TPosition && position)
{
  uint64_t p[3];
  for (int k = 0; k < 3; ++k)
  {
    p[k] = position(c->vertex(TDelaunay::vertex_triple_index(i, k)));
  }
  const int first = p[0] < p[1] ? (p[0] < p[2] ? 0 : 2) : (p[1] < p[2] ? 1 : 2);
  return p[first] | p[(first + 1) % 3] << 16 | p[(first + 2) % 3] << 32;
}

inline std::size_t
KeySlot(uint64_t key, std::size_t mask)
{
  return std::size_t((key * 0x9E3779B97F4A7C15ull) >> 32) & mask;
}
} // namespace detail

/** Removes v from dt: where it returns true, dt is what dt.remove(v) leaves, and `created` holds the
 * cells that fill the hole. `hole` is v's star as dt.incident_cells(v) lists it. Like CGAL (Triangulation_3::
 * remove_3D), it triangulates v's link on its own (inserted in the same order, so with the same cells and
 * vertex orders) and keeps the cells of that triangulation inside the hole; CGAL finds them through two
 * hash maps of vertex triples (one node allocated per facet: some 300 a removal, 40% of its time on
 * norm-256), this walks the small triangulation from one facet of the hole across its cells, a facet of
 * the hole being looked up in a flat table. Returns false, dt untouched, where the link is not plainly
 * three-dimensional (the caller then asks CGAL). */
template <typename TDelaunay>
bool
RemoveByLink(TDelaunay & dt, typename TDelaunay::Vertex_handle v,
             const std::vector<typename TDelaunay::Cell_handle> & hole,
             std::vector<typename TDelaunay::Cell_handle> & created, VertexRemovalScratch<TDelaunay> & s,
             uint32_t noCell)
{
  using VertexHandle = typename TDelaunay::Vertex_handle;
  using CellHandle = typename TDelaunay::Cell_handle;
  if (dt.dimension() != 3)
    return false;
  s.link.clear();
  dt.adjacent_vertices(v, std::back_inserter(s.link));
  if (s.link.size() >= 0xffff || s.link.size() < 4)
    return false;
  const uint64_t infinite = uint64_t(s.link.size()); // the position the infinite vertex stands for
  bool           onHull = false;
  TDelaunay      small;
  s.linked.assign(s.link.size(), VertexHandle());
  CellHandle hint;
  for (std::size_t i = 0; i < s.link.size(); ++i)
  {
    const VertexHandle & u = s.link[i];
    if (dt.is_infinite(u))
    {
      onHull = true;
      continue;
    }
    if (s.linkIndex.size() <= u->info())
      s.linkIndex.resize(std::size_t(u->info()) + 1);
    s.linkIndex[u->info()] = uint16_t(i);
    const VertexHandle w = small.insert(u->point(), hint);
    hint = w->cell();
    w->info() = static_cast<std::remove_reference_t<decltype(w->info())>>(i);
    s.linked[i] = w;
  }
  if (small.dimension() != 3)
    return false;
  auto position = [&](const VertexHandle & u) {
    return dt.is_infinite(u) ? infinite : uint64_t(s.linkIndex[u->info()]);
  };
  auto smallPosition = [&](const VertexHandle & u) { return small.is_infinite(u) ? infinite : uint64_t(u->info()); };

  // The facets of the hole, seen from inside, in a table by key.
  s.boundary.clear();
  for (const CellHandle & c : hole)
  {
    const int        iv = c->index(v);
    const CellHandle outside = c->neighbor(iv);
    s.boundary.push_back({ detail::FacetKey<TDelaunay>(c, iv, position), outside, outside->index(c), false });
  }
  std::size_t capacity = 64;
  while (capacity < 2 * s.boundary.size())
    capacity *= 2;
  const std::size_t mask = capacity - 1;
  s.slots.assign(capacity, 0);
  for (std::size_t b = 0; b < s.boundary.size(); ++b)
  {
    std::size_t h = detail::KeySlot(s.boundary[b].key, mask);
    while (s.slots[h] != 0)
    {
      if (s.boundary[std::size_t(s.slots[h] - 1)].key == s.boundary[b].key)
        return false; // a triangle twice: not a simple star
      h = (h + 1) & mask;
    }
    s.slots[h] = int32_t(b + 1);
  }
  auto find = [&](uint64_t key) -> int {
    for (std::size_t h = detail::KeySlot(key, mask); s.slots[h] != 0; h = (h + 1) & mask)
    {
      if (s.boundary[std::size_t(s.slots[h] - 1)].key == key)
        return s.slots[h] - 1;
    }
    return -1;
  };

  // The cell of the small triangulation inside the hole at one finite facet of the hole.
  std::size_t seed = 0;
  for (; seed < hole.size(); ++seed)
  {
    const uint64_t key = s.boundary[seed].key;
    if ((key & 0xffff) != infinite && ((key >> 16) & 0xffff) != infinite && (key >> 32) != infinite)
      break;
  }
  if (seed == hole.size())
    return false;
  const uint64_t key = s.boundary[seed].key;
  CellHandle     start;
  int            i0 = 0, i1 = 0, i2 = 0;
  if (!small.tds().is_facet(
        s.linked[key & 0xffff], s.linked[(key >> 16) & 0xffff], s.linked[key >> 32], start, i0, i1, i2))
    return false;
  int facet = 6 - i0 - i1 - i2;
  if (detail::FacetKey<TDelaunay>(start, facet, smallPosition) != key)
  {
    const CellHandle other = start->neighbor(facet);
    facet = other->index(start);
    start = other;
    if (detail::FacetKey<TDelaunay>(start, facet, smallPosition) != key)
      return false;
  }

  // Every cell of the small triangulation reached from it without crossing the hole's surface, each
  // facet glued to the outside or to another such cell. (A cell's id in the small triangulation is its
  // position in `inside`; its cells start with none.)
  s.inside.clear();
  s.glue.clear();
  start->info().SetId(0);
  s.inside.push_back(start);
  std::size_t glued = 0;
  for (std::size_t k = 0; k < s.inside.size(); ++k)
  {
    const CellHandle t = s.inside[k];
    if (!onHull && small.is_infinite(t))
      return false;
    std::array<int, 4> g{ -1, -1, -1, -1 };
    for (int f = 0; f < 4; ++f)
    {
      const int b = find(detail::FacetKey<TDelaunay>(t, f, smallPosition));
      if (b >= 0)
      {
        if (s.boundary[std::size_t(b)].glued)
          return false;
        s.boundary[std::size_t(b)].glued = true;
        ++glued;
        g[f] = b;
      }
      else
      {
        const CellHandle n = t->neighbor(f);
        if (n->info().Id() == noCell)
        {
          n->info().SetId(uint32_t(s.inside.size()));
          s.inside.push_back(n);
        }
      }
    }
    s.glue.push_back(g);
    if (s.inside.size() > 16 * hole.size() + 64)
      return false;
  }
  if (glued != s.boundary.size())
    return false;

  // From here dt changes. As CGAL's make_hole_3D: each vertex of the link points at a cell outside.
  for (const CellHandle & c : hole)
  {
    const int        iv = c->index(v);
    const CellHandle outside = c->neighbor(iv);
    for (int i = 0; i < 4; ++i)
    {
      if (i != iv)
        c->vertex(i)->set_cell(outside);
    }
  }
  auto ours = [&](const VertexHandle & u) { return small.is_infinite(u) ? dt.infinite_vertex() : s.link[u->info()]; };
  created.clear();
  for (const CellHandle & t : s.inside)
  {
    CellHandle c = dt.tds().create_cell();
    c->set_vertices(ours(t->vertex(0)), ours(t->vertex(1)), ours(t->vertex(2)), ours(t->vertex(3)));
    created.push_back(c);
  }
  for (std::size_t k = 0; k < s.inside.size(); ++k)
  {
    const CellHandle & t = s.inside[k];
    const CellHandle & c = created[k];
    for (int f = 0; f < 4; ++f)
    {
      if (s.glue[k][f] >= 0)
      {
        const auto & b = s.boundary[std::size_t(s.glue[k][f])];
        c->set_neighbor(f, b.outside);
        b.outside->set_neighbor(b.outsideIndex, c);
      }
      else
      {
        c->set_neighbor(f, created[t->neighbor(f)->info().Id()]);
      }
    }
  }
  dt.tds().delete_vertex(v);
  dt.tds().delete_cells(hole.begin(), hole.end());
  return true;
}

} // namespace dcv

#endif
