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
#include <ostream>
#include <memory>
#include <string>

namespace dcv
{

/** The variants of the method, as columns of the paper's Table 1, plus ours.
 * - Silva: greedy refinement, vertex values from the image (paper, section 2);
 * - Dec: plus refinement/decimation with the approximate removal cost (sections 4, 5);
 * - DecCom: plus the combined image approach (section 3): positions chosen on the bilateral-filtered
 *   I* until PSNR(L) >= alpha PSNR(I*), each value the better of I(p) and I*(p);
 * - Best: decimation and least-squares values, what measurably helps (not I*: see ParametersForMode). */
enum class Mode
{
  Silva,
  Dec,
  DecCom,
  Best
};

/** "silva", "dec", "dec+com", "best": the names used by the CLI, the docs and the file format. */
DelaunayCompression_EXPORT const char *
ModeName(Mode mode);
/** Inverse of ModeName; throws std::invalid_argument naming the valid modes. */
DelaunayCompression_EXPORT Mode
ParseMode(const std::string & name);

/** What the engine does beyond Silva's refinement. */
struct RefinementParameters
{
  /** I*, the smoothed image on the same grid, or null: positions and values come from I only. */
  const float * smoothed{ nullptr };
  /** Selection switches from I* to I once PSNR(L) >= alpha * PSNR(I*) (paper, section 3). */
  double alpha{ 0.9 };
  /** Peak of the PSNR (255 for 8-bit data, else the range of I). */
  double peak{ 255.0 };
  /** Also consider, for each new vertex, the value that minimizes the error over its new cells. */
  bool localOptimalValue{ false };
  /** Refinement/decimation schedule of section 5 in Approximate(). */
  bool decimation{ false };
  /** Global least-squares vertex values at the end of Approximate(). */
  bool leastSquares{ false };
  /** Quantization of the vertex values: when the step is positive every value is
   * quantizationOrigin + k * quantizationStep (k integer), so that a decoder given the quantized values
   * reproduces the engine's approximation exactly. */
  double quantizationStep{ 0.0 };
  double quantizationOrigin{ 0.0 };
  /** Per-axis scale of the space the tetrahedralization is Delaunay in (GridScale). */
  GridScale scale{ { 1, 1, 1 } };
  /** Range of vertex values (the pixel type's), enforced on values that are not image values. */
  double valueMin{ -1e300 };
  double valueMax{ 1e300 };
};

/** The engine's parameters for a mode (smoothed image, peak and value range left to the caller). */
DelaunayCompression_EXPORT RefinementParameters
ParametersForMode(Mode mode);

/** Whether a mode needs the smoothed image I* (the combined image approach): dec+com only. */
DelaunayCompression_EXPORT bool
UsesSmoothedImage(Mode mode);

inline std::ostream &
operator<<(std::ostream & os, Mode mode)
{
  return os << ModeName(mode);
}

/** Greedy refinement of a linear spline over an adaptive Delaunay tetrahedralization.
 *
 * Silva's method extended to tetrahedra (Jovanovic and Lorentz, "A combined image approach to
 * compression of volumetric data using Delaunay tetrahedralization", section 2): start from the 8
 * corners of the volume, then insert points alternately at the voxel of largest absolute error
 * (MaxErrorPosition) and at the worst voxel of the cell with the largest squared-error sum E(T) of
 * Eq. 1 (MaxTetrahedronErrorPosition). Sections 3 to 5 and least-squares values come with
 * RefinementParameters.
 *
 * Each insertion or removal rasterizes only the cells it creates; per-cell error sums and worst voxels
 * live in two max-heaps with lazy deletion (cell identifiers are never reused), so a step costs the
 * volume of the cells it changes, never a pass over the whole image.
 * \ingroup DelaunayCompression
 */
class DelaunayCompression_EXPORT RefinementEngine
{
public:
  /** Called with the fraction done, in [0, 1]; it may throw to abort. */
  using ProgressFunction = std::function<void(double)>;
  using VertexId = uint32_t;

  /** A removal's time in insertions (its new cells scanned, CGAL's hole, its neighbours' costs: norm-256
   * at 0.03125 and 0.25 bpv), the weight progress gives it. */
  static constexpr double RemovalWork = 3.0;

  /** Error statistics of one live cell. */
  struct CellStatistics
  {
    uint32_t id;
    uint64_t voxels;
    double   squaredError;
  };

  /** `image` (and parameters.smoothed) hold grid.NumberOfVoxels() values, x fastest; they must
   * outlive the engine. Throws std::invalid_argument when an axis has fewer than 2 or more than
   * MaximumGridExtent voxels, or when a parameter is out of range (alpha <= 0). */
  RefinementEngine(const float * image, const GridSize & grid, const RefinementParameters & parameters = {});
  ~RefinementEngine();
  RefinementEngine(const RefinementEngine &) = delete;
  RefinementEngine &
  operator=(const RefinementEngine &) = delete;

  /** The whole method: Refine(numberOfPoints), then, with decimation, the schedule of section 5
   * (remove k = n/2 vertices, refine back to n, halve k, until k is 0), then least-squares values. */
  void
  Approximate(std::size_t numberOfPoints, const ProgressFunction & progress = ProgressFunction());

  /** Inserts points until there are `numberOfPoints` (at least the 8 corners) or the approximation is
   * exact. Can be called again with a larger count to continue. */
  void
  Refine(std::size_t numberOfPoints, const ProgressFunction & progress = ProgressFunction());

  /** Removes `count` vertices (never a corner), each time the one whose removal is estimated to raise
   * the error least (Eqs. 2-7: the error stored at its insertion, scaled by the change of its incident
   * volume, minus its current incident error). `progress` follows the removals (every 1%). */
  void
  Decimate(std::size_t count, const ProgressFunction & progress = ProgressFunction());

  /** Brings the point count to `numberOfPoints` on the current tetrahedralization: Decimate() when
   * there are more, Refine() when fewer, then least-squares values again when they are on. Rate
   * control uses it to adjust a finished approximation instead of running the method again. `progress`
   * follows the insertions or the removals (the solve is not counted). */
  void
  Resize(std::size_t numberOfPoints, const ProgressFunction & progress = ProgressFunction());

  /** Changes the quantization step of the vertex values: each value is quantized again, from the
   * least-squares solution of the current tetrahedralization when the mode has least squares and
   * OptimizeValues() solved this tetrahedralization, else from its source (I(p), or I*(p) when that is
   * nearer the current value; OptimizeValues() may follow). Rate control uses it to compare steps on
   * one mesh. Throws std::invalid_argument unless the step is positive. */
  void
  SetQuantizationStep(double step);

  /** What SetQuantizationStep(step) would give, the approximation and its squared error (into
   * `squaredError`), the engine left as it is: rate control's step trials, after which the engine is still
   * at its step, its cells' state in hand. Throws std::invalid_argument unless the step is positive. */
  Approximation
  GetApproximationAtStep(double step, double & squaredError) const;

  /** Replaces the vertex values by those minimizing the total squared error against the image on the
   * current tetrahedralization (clamped to the value range); keeps the old ones if that is not better.
   * Returns the squared error gained (>= 0). */
  double
  OptimizeValues();

  /** Estimated increase of the squared error if the vertex were removed (the decimation key). */
  double
  EstimateRemovalCost(VertexId v) const;
  /** Removes one vertex (not a corner). */
  void
  RemoveVertex(VertexId v);
  /** The vertex inserted last. */
  VertexId
  GetLastInsertedVertex() const;

  std::size_t
  GetNumberOfPoints() const;

  /** Sum over voxels of (I - L)^2, kept up to date cell by cell. */
  double
  GetSquaredError() const;

  /** Seconds spent by Approximate() in each phase (refinement includes refining back after removals). */
  struct Timings
  {
    double refinement{ 0.0 };
    double decimation{ 0.0 };
    double leastSquares{ 0.0 };
  };
  const Timings &
  GetTimings() const;

  /** PSNR(I*) against I (0 without a smoothed image), and whether selection has switched to I. */
  double
  GetSmoothedPSNR() const;
  bool
  GetSelectingOnImage() const;

  /** Significant points and tetrahedra (indices into the points). */
  Approximation
  GetApproximation() const;

  /** Per-cell statistics of the live cells (for tests and diagnostics). */
  std::vector<CellStatistics>
  GetCellStatistics() const;

  const GridSize &
  GetGrid() const;

  const RefinementParameters &
  GetParameters() const;

private:
  struct Impl;
  std::unique_ptr<Impl> m_Impl;
};

} // namespace dcv

#endif
