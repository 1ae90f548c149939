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
#ifndef dcvApproximation_h
#define dcvApproximation_h

#include "DelaunayCompressionExport.h"
#include "dcvRasterizer.h"

#include <array>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <new>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>
#if defined(__linux__)
#  include <sys/mman.h>
#endif

/** \file dcvApproximation.h
 * The product of the method: significant points (grid position and value) and the linear spline
 * over their Delaunay tetrahedralization. Decoding is Tetrahedralize() followed by Rasterize().
 * \ingroup DelaunayCompression
 */
namespace dcv
{

/** Four indices into the point list. */
using Tetrahedron = std::array<uint32_t, 4>;

/** std::allocator, except that the elements a resize or the size constructor adds are left
 * uninitialized: a decoder's volume-sized buffer, which its threads then write whole, is not first
 * zeroed by one thread (norm-256: 67 MB of page faults and zeros, some 40 ms). Blocks of 4 MiB and more are
 * aligned to 2 MiB and, on Linux, asked for transparent huge pages: with a page fault per 4 KiB written, the
 * bounded-error layer decoded norm-256 in 0.39 s on one thread instead of 0.22 to 0.26. */
template <typename T>
struct UninitializedAllocator : std::allocator<T>
{
  using value_type = T;
  template <typename U>
  struct rebind
  {
    using other = UninitializedAllocator<U>;
  };
  UninitializedAllocator() = default;
  template <typename U>
  UninitializedAllocator(const UninitializedAllocator<U> &) noexcept
  {}
  static constexpr std::size_t HugePage = std::size_t(1) << 21;
  static constexpr std::size_t HugeBlock = std::size_t(1) << 22;
  T *
  allocate(std::size_t n)
  {
    if (n > std::size_t(-1) / sizeof(T))
      throw std::bad_array_new_length();
    const std::size_t bytes = n * sizeof(T);
    if (bytes < HugeBlock)
      return std::allocator<T>::allocate(n);
    void * p = ::operator new(bytes, std::align_val_t(HugePage));
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    madvise(p, bytes, MADV_HUGEPAGE); // advice only: without huge pages the block works as any other
#endif
    return static_cast<T *>(p);
  }
  void
  deallocate(T * p, std::size_t n) noexcept
  {
    if (n * sizeof(T) < HugeBlock)
      std::allocator<T>::deallocate(p, n);
    else
      ::operator delete(p, std::align_val_t(HugePage));
  }
  template <typename U>
  void
  construct(U * p) noexcept(std::is_nothrow_default_constructible<U>::value)
  {
    ::new (static_cast<void *>(p)) U;
  }
  template <typename U, typename... A>
  void
  construct(U * p, A &&... a)
  {
    ::new (static_cast<void *>(p)) U(std::forward<A>(a)...);
  }
};
template <typename T, typename U>
bool
operator==(const UninitializedAllocator<T> &, const UninitializedAllocator<U> &)
{
  return true;
}
template <typename T, typename U>
bool
operator!=(const UninitializedAllocator<T> &, const UninitializedAllocator<U> &)
{
  return false;
}

/** The samples of a decoded residual layer, laid out as the grid. */
using ResidualSamples = std::vector<int32_t, UninitializedAllocator<int32_t>>;

/** The residual layer of a decoded file (dcvResidualLayer.h): a voxel is the spline's voxel plus
 * `step` times its sample, converted to the pixel type again. None when `samples` is empty. */
struct Residual
{
  double          step{ 0.0 };
  ResidualSamples samples; // laid out as the grid
};

/** Significant points and the tetrahedra over them, on a voxel grid; and the residual layer of a
 * decoded file that has one. */
struct Approximation
{
  GridSize                 grid;
  GridScale                scale{ { 1, 1, 1 } }; // of the space the tetrahedra are Delaunay in
  std::vector<GridPoint>   points;
  std::vector<double>      values;
  std::vector<Tetrahedron> tetrahedra;
  Residual                 residual;
};

/** Adds the residual layer to a voxel the spline gave: the one rule of every decoder. */
template <typename T>
inline T
AddResidual(T splineVoxel, double step, int32_t sample)
{
  return ConvertValue<T>(double(splineVoxel) + step * double(sample));
}
template <typename T>
inline T
AddResidual(T splineVoxel, const Residual & r, uint64_t voxel)
{
  return AddResidual(splineVoxel, r.step, r.samples[voxel]);
}

/** The Delaunay tetrahedralization of grid points (CGAL, exact predicates, symbolic perturbation),
 * listed in a spatially coherent order:
 * unique for a point set, so it equals the encoder's mesh whatever the insertion order. Each cell is
 * positively oriented, its vertex ids ascending but for the last two; the listing is the same whatever
 * the threads (from 20,000 points they build it together).
 * Throws std::invalid_argument on duplicate points. */
DelaunayCompression_EXPORT std::vector<Tetrahedron>
Tetrahedralize(const std::vector<GridPoint> & points, const GridScale & scale = { { 1, 1, 1 } });

/** Checks that points lie on the grid and include its 8 corners; throws std::invalid_argument. */
DelaunayCompression_EXPORT void
CheckPoints(const GridSize & grid, const std::vector<GridPoint> & points);

namespace detail
{
/** Runs work() on `threads` threads (this one included) and waits for them. */
template <typename F>
void
OnThreads(unsigned int threads, F && work)
{
  std::vector<std::thread> pool;
  for (unsigned int i = 1; i < threads; ++i)
  {
    pool.emplace_back(std::ref(work));
  }
  work();
  for (auto & t : pool)
  {
    t.join();
  }
}

/** Calls f(z0, z1) for slabs of slices [z0, z1] that cover the grid, taken by the threads from a shared
 * counter. */
template <typename F>
void
ForEachSlab(const GridSize & grid, unsigned int threads, F && f)
{
  // Eight slabs a thread: even when some are slower (more cells, more residual).
  const int32_t        thickness = std::max<int32_t>(1, grid.z / int32_t(8 * threads));
  std::atomic<int32_t> next{ 0 };
  OnThreads(threads, [&]() {
    for (int32_t z0 = next.fetch_add(thickness); z0 < grid.z; z0 = next.fetch_add(thickness))
    {
      f(z0, std::min(grid.z - 1, z0 + thickness - 1));
    }
  });
}

/** AddResidual for the n voxels of `out` and their samples. For integers of 16 bits or less and a whole
 * step from 1 to 2^20 (integer layers always have one) the sum is a whole number, so converting it is
 * clamping it, and it is done in int32 (4 voxels an instruction, not 2 in double): a sample beyond
 * `bound` puts any voxel of 16 bits past the end it points to, and so does `bound` itself, whose
 * product stays below 2^21. The same voxels as AddResidual (test ResidualLayer.AddResidualToRowIsAddResidual). */
template <typename T>
void
AddResidualToRow(double step, const int32_t * samples, T * out, uint64_t n)
{
  if constexpr (std::is_integral<T>::value && sizeof(T) <= 2)
  {
    if (step == std::floor(step) && step >= 1.0 && step <= double(1 << 20))
    {
      const int32_t s = int32_t(step);
      const int32_t bound = (int32_t(1) << 17) / s + 1;
      const int32_t lowest = std::numeric_limits<T>::lowest(), highest = std::numeric_limits<T>::max();
      for (uint64_t i = 0; i < n; ++i)
      {
        const int32_t r = std::min(std::max(samples[i], -bound), bound);
        const int32_t v = int32_t(out[i]) + s * r;
        out[i] = T(std::min(std::max(v, lowest), highest));
      }
      return;
    }
  }
  for (uint64_t i = 0; i < n; ++i)
    out[i] = AddResidual(out[i], step, samples[i]);
}

/** AddResidual for the voxels [first, end). */
template <typename T>
void
AddResidualToVoxels(const Residual & r, T * out, uint64_t first, uint64_t end)
{
  AddResidualToRow(r.step, r.samples.data() + first, out + first, end - first);
}

template <typename T>
void
AddResidualToSlices(const Approximation & a, T * out, int32_t z0, int32_t z1)
{
  const uint64_t plane = uint64_t(a.grid.x) * uint64_t(a.grid.y);
  AddResidualToVoxels(a.residual, out, uint64_t(z0) * plane, (uint64_t(z1) + 1) * plane);
}

/** Whether the spline is one value over the whole grid (the corners under a residual layer that took the
 * whole budget), and which: every value equal, and the cells filling the box (their vertices in it and
 * their volumes adding up to its volume: cells never overlap). Every voxel is then that value converted,
 * as the cells give it (their gradients are 0); but a zero of a real type would take its sign from the
 * cell's arithmetic, so it is left to the cells. */
template <typename T>
bool
IsConstantSpline(const Approximation & a, double & value)
{
  if (a.values.empty() || a.tetrahedra.empty() || a.grid.x < 2 || a.grid.y < 2 || a.grid.z < 2)
    return false;
  value = a.values.front();
  if (!std::is_integral<T>::value && value == 0.0)
    return false;
  for (const double v : a.values)
    if (!(v == value))
      return false;
  for (const GridPoint & p : a.points)
    if (p[0] < 0 || p[1] < 0 || p[2] < 0 || p[0] >= a.grid.x || p[1] >= a.grid.y || p[2] >= a.grid.z)
      return false;
  uint64_t volume6 = 0;
  for (const Tetrahedron & t : a.tetrahedra)
  {
    if (t[0] >= a.points.size() || t[1] >= a.points.size() || t[2] >= a.points.size() || t[3] >= a.points.size())
      return false;
    const int64_t v = SignedVolume6({ a.points[t[0]], a.points[t[1]], a.points[t[2]], a.points[t[3]] });
    volume6 += uint64_t(v < 0 ? -v : v);
  }
  return volume6 == 6 * uint64_t(a.grid.x - 1) * uint64_t(a.grid.y - 1) * uint64_t(a.grid.z - 1);
}
} // namespace detail

/** Rasterizes every tetrahedron into `out` (laid out as the grid; voxels no cell owns are left as
 * they are), then adds the residual layer if there is one. Cells own disjoint voxels, so `threads` threads (0: one per
 * core) share them without locks, and the result does not depend on the order. */
template <typename T>
void
Rasterize(const Approximation & a, T * out, unsigned int threads = 0)
{
  if (threads == 0)
  {
    threads = std::max(1u, std::thread::hardware_concurrency());
  }
  constexpr std::size_t chunk = 512;
  const std::size_t     n = a.tetrahedra.size();
  if (n < 4 * chunk * threads && a.grid.NumberOfVoxels() < (uint64_t(1) << 18))
  {
    threads = 1; // a small volume of few cells: not worth a thread
  }
  const bool residual = !a.residual.samples.empty();
  double     one = 0.0;
  if (detail::IsConstantSpline<T>(a, one))
  {
    // One pass over the voxels instead of two (the cells, then the layer).
    const T        value = ConvertValue<T>(one);
    const uint64_t plane = uint64_t(a.grid.x) * uint64_t(a.grid.y);
    detail::ForEachSlab(a.grid, threads, [&](int32_t z0, int32_t z1) {
      const uint64_t first = uint64_t(z0) * plane, end = (uint64_t(z1) + 1) * plane;
      std::fill(out + first, out + end, value);
      if (residual)
        detail::AddResidualToVoxels(a.residual, out, first, end);
    });
    return;
  }
  auto cell = [&a, out](std::size_t c, int32_t z0, int32_t z1) {
    const Tetrahedron & t = a.tetrahedra[c];
    RasterizeTetrahedron(a.grid,
                         { a.points[t[0]], a.points[t[1]], a.points[t[2]], a.points[t[3]] },
                         { a.values[t[0]], a.values[t[1]], a.values[t[2]], a.values[t[3]] },
                         out,
                         z0,
                         z1);
  };
  if (n >= 4 * chunk * threads || threads == 1)
  {
    // Threads take chunks of consecutive (spatially close) cells from a shared counter, so that a
    // thread that drew large cells does not hold the others up.
    std::atomic<std::size_t> next{ 0 };
    detail::OnThreads(threads, [&]() {
      for (std::size_t begin = next.fetch_add(chunk); begin < n; begin = next.fetch_add(chunk))
      {
        for (std::size_t c = begin, end = std::min(n, begin + chunk); c < end; ++c)
          cell(c, 0, std::numeric_limits<int32_t>::max());
      }
    });
    if (residual)
      detail::ForEachSlab(
        a.grid, threads, [&](int32_t z0, int32_t z1) { detail::AddResidualToSlices(a, out, z0, z1); });
    return;
  }
  // Few cells, each over many voxels (a coarse spline, or the corners under a residual layer): the
  // threads share slabs of slices instead, each rasterizing the part of every cell in its slab, then
  // adding the residual layer there while the slab is in cache.
  std::vector<std::array<int32_t, 2>> extent(n);
  for (std::size_t c = 0; c < n; ++c)
  {
    const Tetrahedron & t = a.tetrahedra[c];
    extent[c] = {
      std::min(std::min(a.points[t[0]][2], a.points[t[1]][2]), std::min(a.points[t[2]][2], a.points[t[3]][2])),
      std::max(std::max(a.points[t[0]][2], a.points[t[1]][2]), std::max(a.points[t[2]][2], a.points[t[3]][2]))
    };
  }
  detail::ForEachSlab(a.grid, threads, [&](int32_t z0, int32_t z1) {
    for (std::size_t c = 0; c < n; ++c)
    {
      if (extent[c][1] >= z0 && extent[c][0] <= z1)
        cell(c, z0, z1);
    }
    if (residual)
      detail::AddResidualToSlices(a, out, z0, z1);
  });
}

/** Rasterizes only the voxels of the box [first, last] (inclusive grid coordinates) into `out`, laid
 * out as that box (x fastest); cells whose bounding box misses the box are skipped. The values are
 * the very ones Rasterize() gives, residual layer included. Returns the number of cells rasterized. */
template <typename T>
std::size_t
RasterizeBox(const Approximation & a, const GridPoint & first, const GridPoint & last, T * out)
{
  const int64_t sx = int64_t(last[0]) - first[0] + 1;
  const int64_t sy = int64_t(last[1]) - first[1] + 1;
  std::size_t   cells = 0;
  for (const Tetrahedron & t : a.tetrahedra)
  {
    const std::array<GridPoint, 4> p{ a.points[t[0]], a.points[t[1]], a.points[t[2]], a.points[t[3]] };
    bool                           misses = false;
    for (int d = 0; d < 3 && !misses; ++d)
    {
      const int32_t lo = std::min(std::min(p[0][d], p[1][d]), std::min(p[2][d], p[3][d]));
      const int32_t hi = std::max(std::max(p[0][d], p[1][d]), std::max(p[2][d], p[3][d]));
      misses = hi < first[d] || lo > last[d];
    }
    if (misses)
    {
      continue;
    }
    ++cells;
    const CanonicalTetrahedron c(p, { a.values[t[0]], a.values[t[1]], a.values[t[2]], a.values[t[3]] });
    const LinearFunction       L(c);
    ForEachSpan(a.grid, c.p, [&](int32_t y, int32_t z, int32_t x0, int32_t x1) {
      if (y < first[1] || y > last[1] || z < first[2] || z > last[2])
      {
        return;
      }
      const double base = L.RowBase(y, z);
      T *          row = out + (int64_t(z) - first[2]) * sx * sy + (int64_t(y) - first[1]) * sx - first[0];
      for (int32_t x = std::max(x0, first[0]); x <= std::min(x1, last[0]); ++x)
      {
        row[x] = ConvertValue<T>(base + L.gx * double(x - L.origin[0]));
      }
    });
  }
  if (!a.residual.samples.empty())
  {
    T * voxel = out;
    for (int32_t z = first[2]; z <= last[2]; ++z)
      for (int32_t y = first[1]; y <= last[1]; ++y)
        for (int32_t x = first[0]; x <= last[0]; ++x, ++voxel)
          *voxel = AddResidual(*voxel, a.residual, a.grid.Offset(x, y, z));
  }
  return cells;
}

/** Rebuilds the tetrahedra of an approximation from its points, then rasterizes it. */
template <typename T>
void
Decode(Approximation & a, T * out)
{
  CheckPoints(a.grid, a.points);
  a.tetrahedra = Tetrahedralize(a.points, a.scale);
  Rasterize(a, out);
}

/** Peak signal-to-noise ratio in dB: 10 log10(peak^2 / (squaredError / voxels)); +inf when exact. */
DelaunayCompression_EXPORT double
PSNR(double squaredError, uint64_t voxels, double peak);

/** The PSNR peak used throughout: 255 for 8-bit data, else the range max - min of the original. */
inline double
PSNRPeak(double minimum, double maximum, bool eightBit)
{
  return eightBit ? 255.0 : std::max(1e-12, maximum - minimum);
}

/** PSNRPeak of a buffer of n values of type T (8-bit when T is a one-byte integer). */
template <typename T>
double
PSNRPeak(const T * data, uint64_t n)
{
  const auto range = std::minmax_element(data, data + n);
  return PSNRPeak(double(*range.first), double(*range.second), sizeof(T) == 1 && std::is_integral<T>::value);
}

/** Sum of squared differences between two buffers of n values. */
template <typename A, typename B>
double
SquaredError(const A * a, const B * b, uint64_t n)
{
  double s = 0.0;
  for (uint64_t i = 0; i < n; ++i)
  {
    const double e = double(a[i]) - double(b[i]);
    s += e * e;
  }
  return s;
}

} // namespace dcv

#endif
