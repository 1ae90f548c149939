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
#include "dcvInterSliceWavelet.h"
#include "dcvParallel.h"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>

namespace dcv
{
namespace
{
/** floor(a / 2^shift): an arithmetic shift (what gcc and clang do with signed integers, and C++20
 * requires), not a division: the lifting below does one or two per sample. */
int64_t
FloorShift(int64_t a, int shift)
{
  return a >> shift;
}

/** round(c w / 4096), halves up. */
int64_t
Weigh(int64_t c, int64_t w)
{
  return FloorShift(2 * c * w + 4096, 13);
}

/** round(c 4096 / w), halves up: the inverse of Weigh for w >= 4096. Exact: the quotient is taken in
 * double and truncated (numerator and denominator are below 2^53, so that is at most one from the
 * floor), then corrected with integers: several times faster than a 64-bit division per sample. */
int64_t
Unweigh(int64_t c, int64_t w)
{
  const int64_t num = c * 8192 + w, den = 2 * w;
  int64_t       q = int64_t(double(num) / double(den));
  const int64_t r = num - q * den;
  q += int64_t(r >= den) - int64_t(r < 0);
  return q;
}

/** Length of the low band after `level` levels of a signal of n samples: ceil(n / 2^level). */
int32_t
LowLength(int32_t n, int32_t level)
{
  return int32_t((int64_t(n) + (int64_t(1) << level) - 1) >> level);
}

/** The band weight of slice i of the transformed layout. */
int64_t
SliceWeight(int32_t slices, int32_t levels, int32_t i)
{
  if (i < LowLength(slices, levels))
    return LowBandWeight[std::size_t(levels - 1)];
  int32_t k = levels;
  while (i >= LowLength(slices, k - 1))
    --k;
  return HighBandWeight[std::size_t(k - 1)];
}

/** One analysis level of the reversible 5/3 lifting (ISO/IEC 15444-1 Annex F, symmetric extension) on the
 * first m rows of `rows` (each `width` samples): low band to rows [0, ceil(m/2)), high band after it.
 * `scratch` holds m rows. */
void
Analyze(int64_t * rows, int64_t * scratch, int32_t m, int64_t width)
{
  const int32_t lows = (m + 1) / 2, highs = m / 2;
  auto          x = [&](int32_t i) { return rows + int64_t(i) * width; };
  int64_t *     low = scratch;
  int64_t *     high = scratch + int64_t(lows) * width;
  for (int32_t i = 0; i < highs; ++i)
  {
    const int64_t * left = x(2 * i);
    const int64_t * odd = x(2 * i + 1);
    const int64_t * right = x(2 * i + 2 < m ? 2 * i + 2 : 2 * i); // x[m] mirrors to x[m - 2]
    int64_t *       d = high + int64_t(i) * width;
    for (int64_t c = 0; c < width; ++c)
      d[c] = odd[c] - FloorShift(left[c] + right[c], 1);
  }
  for (int32_t i = 0; i < lows; ++i)
  {
    const int64_t * even = x(2 * i);
    // d[-1] mirrors to d[0], d[highs] (odd m) to d[highs - 1]
    const int64_t * before = high + int64_t(std::clamp(i - 1, 0, highs - 1)) * width;
    const int64_t * after = high + int64_t(std::min(i, highs - 1)) * width;
    int64_t *       s = low + int64_t(i) * width;
    for (int64_t c = 0; c < width; ++c)
      s[c] = even[c] + FloorShift(before[c] + after[c] + 2, 2);
  }
  std::copy_n(scratch, int64_t(m) * width, rows);
}

/** The inverse of Analyze. */
void
Synthesize(int64_t * rows, int64_t * scratch, int32_t m, int64_t width)
{
  const int32_t   lows = (m + 1) / 2, highs = m / 2;
  const int64_t * low = rows;
  const int64_t * high = rows + int64_t(lows) * width;
  auto            x = [&](int32_t i) { return scratch + int64_t(i) * width; };
  for (int32_t i = 0; i < lows; ++i)
  {
    const int64_t * before = high + int64_t(std::clamp(i - 1, 0, highs - 1)) * width;
    const int64_t * after = high + int64_t(std::min(i, highs - 1)) * width;
    const int64_t * s = low + int64_t(i) * width;
    int64_t *       even = x(2 * i);
    for (int64_t c = 0; c < width; ++c)
      even[c] = s[c] - FloorShift(before[c] + after[c] + 2, 2);
  }
  for (int32_t i = 0; i < highs; ++i)
  {
    const int64_t * left = x(2 * i);
    const int64_t * right = x(2 * i + 2 < m ? 2 * i + 2 : 2 * i);
    const int64_t * d = high + int64_t(i) * width;
    int64_t *       odd = x(2 * i + 1);
    for (int64_t c = 0; c < width; ++c)
      odd[c] = d[c] + FloorShift(left[c] + right[c], 1);
  }
  std::copy_n(scratch, int64_t(m) * width, rows);
}

void
CheckLevels(const std::vector<int32_t> & samples, const GridSize & grid, int32_t levels)
{
  if (samples.size() != grid.NumberOfVoxels())
    throw std::invalid_argument("inter-slice wavelet: one sample per voxel");
  if (levels < 0 || levels > InterSliceLevels(grid.z))
  {
    throw std::invalid_argument("inter-slice wavelet: " + std::to_string(grid.z) + " slices take at most " +
                                std::to_string(InterSliceLevels(grid.z)) + " levels, not " + std::to_string(levels));
  }
}

/** Runs `f(rows, scratch)` on each image row y of the volume gathered as z rows of x samples (int64, so
 * that no level overflows), then scatters the rows back, clamped to int32. Rows are independent. */
template <typename F>
void
ForEachRow(std::vector<int32_t> & samples, const GridSize & grid, F && f)
{
  const int64_t width = grid.x;
  ParallelFor(std::size_t(grid.y), 1, [&](std::size_t y) {
    // One pair of buffers a thread, kept between rows: allocating them per row costs more in page
    // faults than the lifting itself.
    thread_local std::vector<int64_t> rows, scratch;
    rows.resize(std::size_t(width * grid.z));
    scratch.resize(rows.size());
    for (int32_t z = 0; z < grid.z; ++z)
      std::copy_n(samples.data() + grid.Offset(0, int32_t(y), z), width, rows.data() + int64_t(z) * width);
    f(rows.data(), scratch.data());
    constexpr int64_t lowest = std::numeric_limits<int32_t>::min() + 1, highest = std::numeric_limits<int32_t>::max();
    for (int32_t z = 0; z < grid.z; ++z)
    {
      const int64_t * row = rows.data() + int64_t(z) * width;
      int32_t *       out = samples.data() + grid.Offset(0, int32_t(y), z);
      for (int64_t c = 0; c < width; ++c)
        out[c] = int32_t(std::clamp(row[c], lowest, highest));
    }
  });
}
} // namespace

int32_t
InterSliceLevels(int32_t slices)
{
  int32_t levels = 0;
  while (levels < MaximumInterSliceLevels && LowLength(slices, levels) >= 2)
    ++levels;
  return levels;
}

void
ForwardInterSlice(std::vector<int32_t> & samples, const GridSize & grid, int32_t levels)
{
  CheckLevels(samples, grid, levels);
  if (levels == 0)
    return;
  ForEachRow(samples, grid, [&](int64_t * rows, int64_t * scratch) {
    for (int32_t l = 0; l < levels; ++l)
      Analyze(rows, scratch, LowLength(grid.z, l), grid.x);
    for (int32_t z = 0; z < grid.z; ++z)
    {
      const int64_t w = SliceWeight(grid.z, levels, z);
      for (int64_t c = 0; c < grid.x; ++c)
        rows[z * int64_t(grid.x) + c] = Weigh(rows[z * int64_t(grid.x) + c], w);
    }
  });
}

void
InverseInterSlice(std::vector<int32_t> & samples, const GridSize & grid, int32_t levels)
{
  CheckLevels(samples, grid, levels);
  if (levels == 0)
    return;
  ForEachRow(samples, grid, [&](int64_t * rows, int64_t * scratch) {
    for (int32_t z = 0; z < grid.z; ++z)
    {
      const int64_t w = SliceWeight(grid.z, levels, z);
      for (int64_t c = 0; c < grid.x; ++c)
        rows[z * int64_t(grid.x) + c] = Unweigh(rows[z * int64_t(grid.x) + c], w);
    }
    for (int32_t l = levels - 1; l >= 0; --l)
      Synthesize(rows, scratch, LowLength(grid.z, l), grid.x);
  });
}

} // namespace dcv
