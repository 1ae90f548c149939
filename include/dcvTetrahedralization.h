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
#ifndef dcvTetrahedralization_h
#define dcvTetrahedralization_h

#include "DelaunayCompressionExport.h"
#include "dcvRasterizer.h"

#include <array>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace dcv
{

/** A Delaunay tetrahedralization of grid points, with stable identifiers.
 *
 * A thin wrapper over CGAL's Delaunay_triangulation_3 (exact predicates; CGAL itself stays in the
 * compiled source). CGAL recycles its cell handles, so every finite cell gets an identifier that is
 * never reused; vertices are numbered in insertion order. Under CGAL's symbolic perturbation the
 * tetrahedralization of a point set is unique, whatever the insertion order, which is what lets a
 * decoder rebuild the encoder's mesh from the points alone.
 * \ingroup DelaunayCompression
 */
class DelaunayCompression_EXPORT Tetrahedralization
{
public:
  using CellId = uint32_t;
  using VertexId = uint32_t;
  static constexpr CellId NoCell = 0xffffffffu;

  /** A finite cell: its identifier and its four vertices. */
  struct Cell
  {
    CellId                  id;
    std::array<VertexId, 4> vertices;
  };

  Tetrahedralization();
  ~Tetrahedralization();
  Tetrahedralization(const Tetrahedralization &) = delete;
  Tetrahedralization &
  operator=(const Tetrahedralization &) = delete;

  /** Builds the tetrahedralization of the points scaled per axis (before any insertion; default 1, 1, 1).
   * Throws std::invalid_argument outside 1 .. MaximumGridScale. */
  void
  SetScale(const GridScale & scale);

  /** Inserts points in bulk (spatially sorted; vertex i is points[i] shifted by the current count). */
  void
  InsertMany(const std::vector<GridPoint> & points);

  /** Inserts one point that is not yet a vertex. `hint` is a live cell near p (or NoCell).
   * Reports the finite cells that died and the finite cells that were created. */
  VertexId
  Insert(const GridPoint & p, CellId hint, std::vector<CellId> & killed, std::vector<Cell> & created);

  /** Removes a vertex; reports the finite cells that died and those that fill the hole. */
  void
  Remove(VertexId v, std::vector<CellId> & killed, std::vector<Cell> & created);

  /** The finite cells incident to a vertex, in no fixed order. Reads only: several threads may call it at
   * once while nothing changes the tetrahedralization. */
  void
  IncidentCells(VertexId v, std::vector<Cell> & cells) const;

  /** The finite cells incident to a vertex with six times their volume in grid units (|SignedVolume6|
   * of their points), in no fixed order: what the decimation's removal costs read, without reading the
   * cells' vertices. Reads only, as IncidentCells(). */
  void
  IncidentVolumes(VertexId v, std::vector<std::pair<CellId, uint64_t>> & cells) const;

  /** Renumbers the live finite cells 0, 1, ... in the order of their current ids (ids are never reused,
   * so without this the per-id state of a long run grows with every cell ever created). Returns the
   * new id of every old id (NoCell for cells that died). */
  std::vector<CellId>
  CompactCellIds();
  /** Number of cell ids given so far (dead cells included): the size per-id state needs. */
  std::size_t
  NumberOfCellIds() const;
  /** All finite cells, by id. */
  std::vector<Cell>
  FiniteCells() const;
  /** The finite cells with ids first to last - 1, by id, into `out` (cleared first): a part of the cells
   * at a time, where a list of all of them (20 bytes a cell) would set a peak. */
  void
  FiniteCells(CellId first, CellId last, std::vector<Cell> & out) const;
  /** The finite cells of `ids` (live ones), in that order, into `out` (resized to ids.size()). */
  void
  FiniteCells(const CellId * ids, std::size_t count, std::vector<Cell> & out) const;

  /** Position of a vertex. */
  const GridPoint &
  Point(VertexId v) const;

  /** Number of vertices ever inserted (removed ones included) and currently present. */
  VertexId
  NumberOfVertexIds() const;
  std::size_t
  NumberOfVertices() const;
  std::size_t
  NumberOfFiniteCells() const;

  /** CGAL's own validity check (tests). */
  bool
  IsValid() const;

private:
  struct Impl;
  std::unique_ptr<Impl> m_Impl;
};

} // namespace dcv

#endif
