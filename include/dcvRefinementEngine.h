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
#ifndef dcvRefinementEngine_h
#define dcvRefinementEngine_h

#include "DelaunayCompressionExport.h"
#include "dcvApproximation.h"

#include <functional>
#include <memory>

namespace dcv
{

/** Greedy refinement of a linear spline over an adaptive Delaunay tetrahedralization.
 *
 * Silva's method extended to tetrahedra (Jovanovic and Lorentz, "A combined image approach to
 * compression of volumetric data using Delaunay tetrahedralization", section 2): start from the 8
 * corners of the volume, then insert points alternately at the voxel of largest absolute error
 * (MaxErrorPosition) and at the worst voxel of the cell with the largest squared-error sum E(T) of
 * Eq. 1 (MaxTetrahedronErrorPosition). Vertex values are the image values.
 *
 * Each insertion rasterizes only the cells it creates (the Delaunay cavity); per-cell error sums and
 * worst voxels live in two max-heaps with lazy deletion (cell identifiers are never reused), so a
 * step costs the volume of the cavity, never a pass over the whole image.
 * \ingroup DelaunayCompression
 */
class DelaunayCompression_EXPORT RefinementEngine
{
public:
  /** Called with the fraction done, in [0, 1]; it may throw to abort. */
  using ProgressFunction = std::function<void(double)>;

  /** Error statistics of one live cell. */
  struct CellStatistics
  {
    uint32_t id;
    uint64_t voxels;
    double   squaredError;
  };

  /** `image` holds grid.NumberOfVoxels() values, x fastest; it must outlive the engine.
   * Throws std::invalid_argument when an axis has fewer than 2 or more than MaximumGridExtent voxels. */
  RefinementEngine(const float * image, const GridSize & grid);
  ~RefinementEngine();
  RefinementEngine(const RefinementEngine &) = delete;
  RefinementEngine &
  operator=(const RefinementEngine &) = delete;

  /** Inserts points until there are `numberOfPoints` (at least the 8 corners) or the approximation is
   * exact. Can be called again with a larger count to continue. */
  void
  Refine(std::size_t numberOfPoints, const ProgressFunction & progress = ProgressFunction());

  std::size_t
  GetNumberOfPoints() const;

  /** Sum over voxels of (I - L)^2, kept up to date cell by cell. */
  double
  GetSquaredError() const;

  /** Significant points and tetrahedra (indices into the points). */
  Approximation
  GetApproximation() const;

  /** Per-cell statistics of the live cells (for tests and diagnostics). */
  std::vector<CellStatistics>
  GetCellStatistics() const;

  const GridSize &
  GetGrid() const;

private:
  struct Impl;
  std::unique_ptr<Impl> m_Impl;
};

} // namespace dcv

#endif
