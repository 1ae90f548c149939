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
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>

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

/** round(c 4096 / w), halves up: the inverse of Weigh for w >= 4096, with `inverse` = 1 / (2 w). Exact:
 * the quotient is estimated in double (a product: a 64-bit division per sample would cost more than the
 * rest of the synthesis) and corrected with integers to the floor. */
int64_t
Unweigh(int64_t c, int64_t w, double inverse)
{
  const int64_t num = c * 8192 + w, den = 2 * w;
  int64_t       q = int64_t(double(num) * inverse);
  int64_t       r = num - q * den;
  while (r < 0)
  {
    --q;
    r += den;
  }
  while (r >= den)
  {
    ++q;
    r -= den;
  }
  return q;
}

/** Unweigh for |c| <= SmallSample (InverseRows in int32), without integers of 64 bits nor a branch, so
 * that it vectorizes (it was half of the synthesis). The floor of c 4096 / w + 1/2, whose fraction is a
 * multiple of 1 / (2 w) > 2^-16, is computed in double within 2^-29 (|c 4096 / w| <= 2^20, a sum below
 * 2^23, with or without a fused multiply-add); a bias of 2^-20 then keeps it inside the same integer, and
 * an offset of 2^22 makes the truncation the floor. */
int32_t
UnweighSmall(int32_t c, double scale)
{
  constexpr double offset = 4194304.0;                  // 2^22
  constexpr double bias = 0.5 + offset + 1.0 / 1048576; // exact: 2^22 to 2^-20 fit a double's 53 bits
  return int32_t(double(c) * scale + bias) - int32_t(offset);
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

/** The inverse of Analyze, in S = int64_t for any samples, or in int32_t where they are small enough
 * (InverseRows): the same integers, and the loops vectorize. Shifts are floor divisions, as in FloorShift. */
template <typename S>
void
Synthesize(S * rows, S * scratch, int32_t m, int64_t width)
{
  const int32_t lows = (m + 1) / 2, highs = m / 2;
  const S *     low = rows;
  const S *     high = rows + int64_t(lows) * width;
  auto          x = [&](int32_t i) { return scratch + int64_t(i) * width; };
  for (int32_t i = 0; i < lows; ++i)
  {
    const S * before = high + int64_t(std::clamp(i - 1, 0, highs - 1)) * width;
    const S * after = high + int64_t(std::min(i, highs - 1)) * width;
    const S * s = low + int64_t(i) * width;
    S *       even = x(2 * i);
    for (int64_t c = 0; c < width; ++c)
      even[c] = s[c] - S((before[c] + after[c] + 2) >> 2);
  }
  for (int32_t i = 0; i < highs; ++i)
  {
    const S * left = x(2 * i);
    const S * right = x(2 * i + 2 < m ? 2 * i + 2 : 2 * i);
    const S * d = high + int64_t(i) * width;
    S *       odd = x(2 * i + 1);
    for (int64_t c = 0; c < width; ++c)
      odd[c] = d[c] + S((left[c] + right[c]) >> 1);
  }
  std::copy_n(scratch, int64_t(m) * width, rows);
}

void
CheckLevels(const GridSize & grid, int32_t levels)
{
  if (levels < 0 || levels > InterSliceLevels(grid.z))
  {
    throw std::invalid_argument("inter-slice wavelet: " + std::to_string(grid.z) + " slices take at most " +
                                std::to_string(InterSliceLevels(grid.z)) + " levels, not " + std::to_string(levels));
  }
}

void
CheckLevels(const std::vector<int32_t> & samples, const GridSize & grid, int32_t levels)
{
  if (samples.size() != grid.NumberOfVoxels())
    throw std::invalid_argument("inter-slice wavelet: one sample per voxel");
  CheckLevels(grid, levels);
}

/** Decoded samples at most this large in magnitude take the synthesis in int32: each level at most
 * multiplies the magnitudes by 2.5 (plus 3), so after MaximumInterSliceLevels they and the sums of two of
 * them stay below 2^30. */
constexpr int32_t SmallSample = int32_t(1) << 20;

/** Divides each slice's samples by its band weight (the finest high band's is 1: left as they are), then
 * synthesizes `levels` levels. */
template <typename S>
void
InverseRows(S * rows, S * scratch, const GridSize & grid, int32_t levels, const std::vector<int64_t> & weight,
            const std::vector<double> & inverse)
{
  for (int32_t z = 0; z < grid.z; ++z)
  {
    const int64_t w = weight[std::size_t(z)];
    if (w == HighBandWeight[0])
      continue;
    S * row = rows + int64_t(z) * grid.x;
    if constexpr (std::is_same_v<S, int32_t>)
    {
      // (The width in a local: an int32 store might change grid.x, which keeps the loop from vectorizing.)
      const double  scale = 4096.0 / double(w);
      const int64_t width = grid.x;
      for (int64_t c = 0; c < width; ++c)
        row[c] = UnweighSmall(row[c], scale);
    }
    else
    {
      for (int64_t c = 0; c < grid.x; ++c)
        row[c] = S(Unweigh(row[c], w, inverse[std::size_t(z)]));
    }
  }
  for (int32_t l = levels - 1; l >= 0; --l)
    Synthesize(rows, scratch, LowLength(grid.z, l), grid.x);
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
  // In place: each image row's slices are all read before any is written.
  ForwardInterSlice(
    [&](int32_t y, int32_t z, int32_t * row) { std::copy_n(samples.data() + grid.Offset(0, y, z), grid.x, row); },
    [&](int32_t y, int32_t z, const int32_t * row) { std::copy_n(row, grid.x, samples.data() + grid.Offset(0, y, z)); },
    grid,
    levels);
}

void
ForwardInterSlice(const std::function<void(int32_t y, int32_t z, int32_t * row)> &       source,
                  const std::function<void(int32_t y, int32_t z, const int32_t * row)> & sink, const GridSize & grid,
                  int32_t levels)
{
  CheckLevels(grid, levels);
  const int64_t     width = grid.x;
  const std::size_t n = std::size_t(width * grid.z);
  ParallelFor(std::size_t(grid.y), 1, [&](std::size_t row) {
    const int32_t y = int32_t(row);
    // Buffers a thread, kept between rows: allocating them per row costs more in page faults than the
    // lifting itself. The lifting runs in int64, so that no level overflows.
    thread_local std::vector<int32_t> narrow;
    thread_local std::vector<int64_t> rows, scratch;
    narrow.resize(n);
    for (int32_t z = 0; z < grid.z; ++z)
      source(y, z, narrow.data() + int64_t(z) * width);
    if (levels > 0)
    {
      rows.assign(narrow.begin(), narrow.end());
      scratch.resize(n);
      for (int32_t l = 0; l < levels; ++l)
        Analyze(rows.data(), scratch.data(), LowLength(grid.z, l), width);
      constexpr int64_t lowest = std::numeric_limits<int32_t>::min() + 1, highest = std::numeric_limits<int32_t>::max();
      for (int32_t z = 0; z < grid.z; ++z)
      {
        const int64_t w = SliceWeight(grid.z, levels, z);
        for (int64_t c = z * width; c < (z + 1) * width; ++c)
          narrow[std::size_t(c)] = int32_t(std::clamp(Weigh(rows[std::size_t(c)], w), lowest, highest));
      }
    }
    for (int32_t z = 0; z < grid.z; ++z)
      sink(y, z, narrow.data() + int64_t(z) * width);
  });
}

void
InverseInterSlice(std::vector<int32_t> & samples, const GridSize & grid, int32_t levels)
{
  CheckLevels(samples, grid, levels);
  InverseInterSlice(
    [&](int32_t y, int32_t z) { return samples.data() + grid.Offset(0, y, z); }, samples.data(), grid, levels);
}

void
InverseInterSlice(const std::function<const int32_t *(int32_t y, int32_t z)> & source, int32_t * out,
                  const GridSize & grid, int32_t levels)
{
  InverseInterSlice(
    source,
    [&](int32_t y, int32_t z, const int32_t * row) { std::copy_n(row, grid.x, out + grid.Offset(0, y, z)); },
    grid,
    levels);
}

void
InverseInterSlice(const std::function<const int32_t *(int32_t y, int32_t z)> &           source,
                  const std::function<void(int32_t y, int32_t z, const int32_t * row)> & sink, const GridSize & grid,
                  int32_t levels)
{
  CheckLevels(grid, levels);
  std::vector<int64_t> weight(std::size_t(grid.z), HighBandWeight[0]);
  std::vector<double>  inverse(weight.size(), 0.0);
  for (int32_t z = 0; levels > 0 && z < grid.z; ++z)
  {
    weight[std::size_t(z)] = SliceWeight(grid.z, levels, z);
    inverse[std::size_t(z)] = 1.0 / double(2 * weight[std::size_t(z)]);
  }
  const int64_t     width = grid.x;
  const std::size_t n = std::size_t(width * grid.z);
  ParallelFor(std::size_t(grid.y), 1, [&](std::size_t row) {
    const int32_t y = int32_t(row);
    // Buffers a thread, kept between rows: allocating them per row costs more in page faults than the
    // lifting itself.
    thread_local std::vector<int32_t> narrow, narrowScratch;
    thread_local std::vector<int64_t> wide, wideScratch;
    narrow.resize(n);
    int32_t lowest = 0, highest = 0;
    for (int32_t z = 0; z < grid.z; ++z)
    {
      const int32_t * in = source(y, z);
      int32_t *       to = narrow.data() + int64_t(z) * width;
      for (int64_t c = 0; c < width; ++c)
      {
        to[c] = in[c];
        lowest = std::min(lowest, in[c]);
        highest = std::max(highest, in[c]);
      }
    }
    if (levels > 0 && lowest >= -SmallSample && highest <= SmallSample)
    {
      narrowScratch.resize(n);
      InverseRows(narrow.data(), narrowScratch.data(), grid, levels, weight, inverse);
    }
    else if (levels > 0)
    {
      // Any samples (a damaged layer): in int64, clamped back to int32.
      wide.assign(narrow.begin(), narrow.end());
      wideScratch.resize(n);
      InverseRows(wide.data(), wideScratch.data(), grid, levels, weight, inverse);
      constexpr int64_t least = std::numeric_limits<int32_t>::min() + 1, most = std::numeric_limits<int32_t>::max();
      for (std::size_t i = 0; i < n; ++i)
        narrow[i] = int32_t(std::clamp(wide[i], least, most));
    }
    for (int32_t z = 0; z < grid.z; ++z)
      sink(y, z, narrow.data() + int64_t(z) * width);
  });
}

} // namespace dcv
