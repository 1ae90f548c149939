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
#include "dcvPositionCoder.h"

#include <algorithm>
#include <array>
#include <memory>
#include <stdexcept>
#include <tuple>

// Tuning constants (overridable for measurements).
#ifndef DCV_POSITION_SMALL_COUNT
#  define DCV_POSITION_SMALL_COUNT 16
#endif
#ifndef DCV_POSITION_DENSITY_BUCKETS
#  define DCV_POSITION_DENSITY_BUCKETS 24
#endif
#ifndef DCV_POSITION_SHIFT
#  define DCV_POSITION_SHIFT 7
#endif
#ifndef DCV_POSITION_COUNT_DIVISOR
#  define DCV_POSITION_COUNT_DIVISOR 2
#endif
#ifndef DCV_POSITION_PRIOR_COUNT
#  define DCV_POSITION_PRIOR_COUNT 16
#endif

namespace dcv
{
namespace
{

/** Points up to this count (after complementing dense boxes) code k through the symmetric unary
 * scheme; above, the deviation from the expected count. */
constexpr int SmallCount = DCV_POSITION_SMALL_COUNT;
constexpr int DensityBuckets = DCV_POSITION_DENSITY_BUCKETS;
constexpr int CountBuckets = 34; // bit length of n <= 2^33
constexpr int Shift = DCV_POSITION_SHIFT;
constexpr int PriorCount = DCV_POSITION_PRIOR_COUNT;

/** Number of bits of v (0 for 0). */
inline int
BitLength(uint64_t v)
{
  int b = 0;
  while (v != 0)
  {
    ++b;
    v >>= 1;
  }
  return b;
}

struct Box
{
  std::array<int32_t, 3> lo;
  std::array<int32_t, 3> hi; // exclusive

  uint64_t
  Voxels() const
  {
    return uint64_t(hi[0] - lo[0]) * uint64_t(hi[1] - lo[1]) * uint64_t(hi[2] - lo[2]);
  }
  int
  SplitAxis() const
  {
    int axis = 0;
    for (int c = 1; c < 3; ++c)
    {
      if (hi[c] - lo[c] > hi[axis] - lo[axis])
      {
        axis = c;
      }
    }
    return axis;
  }
};

/** The adaptive models of the split counts. */
class SplitModel
{
public:
  SplitModel()
  {
    // Priors: the distribution of a uniformly random set (k binomial with p = 1/2), computed with
    // correctly rounded double operations only, so every platform gets the same integers.
    for (int n = 1; n <= SmallCount; ++n)
    {
      std::array<double, SmallCount + 1> binomial{};
      binomial[0] = 1.0;
      for (int i = 1; i <= n; ++i)
        binomial[i] = binomial[i - 1] * double(n - i + 1) / double(i);
      std::array<double, SmallCount / 2 + 2> weight{}; // of m = i, i <= n / 2
      for (int i = 0; i <= n / 2; ++i)
        weight[i] = 2 * i == n ? binomial[i] : 2.0 * binomial[i];
      for (int i = 0; i < n / 2; ++i) // m = n / 2 is never coded (the last value is implied)
      {
        double rest = 0.0; // weight of m >= i
        for (int j = i; j <= n / 2; ++j)
          rest += weight[j];
        // The bit is (m == i): P(0) = P(m > i | m >= i).
        const double   p0 = (rest - weight[i]) / rest;
        const uint32_t probability = uint32_t(p0 * double(BitModel::One) + 0.5);
        for (auto & perDensity : m_Unary[n - 1])
          perDensity[i] = BitModel(Shift, probability, PriorCount);
      }
    }
    for (auto & row : m_Side)
      row.fill(BitModel(Shift));
    for (int c = 1; c < 9; ++c)
    {
      // One point, split axis of odd length L = 2c - 1 (c < 8): the bit is "in the first half",
      // of probability floor(L / 2) / L, so P(0) = c / (2c - 1).
      if (c < 8)
        m_Side[0][c] =
          BitModel(Shift, uint32_t(double(c) / double(2 * c - 1) * double(BitModel::One) + 0.5), PriorCount);
    }
    m_Zero.fill(BitModel(Shift));
    m_Sign.fill(BitModel(Shift));
    for (auto & m : m_Magnitude)
      m = std::make_unique<UIntModel>(Shift);
  }

  /** Codes (Io encodes) or decodes (Io decodes) the number k of the n points of a box of V voxels
   * that lie in its first half of V1 voxels; the split axis has `length` voxels. */
  template <typename Io>
  uint64_t
  Code(Io & io, uint64_t n, uint64_t V, uint64_t V1, int32_t length, uint64_t k)
  {
    const uint64_t V2 = V - V1;
    // Dense boxes code their empty voxels: n <= V / 2 below.
    const bool complement = 2 * n > V;
    if (complement)
    {
      n = V - n;
      k = V1 - k;
    }
    const uint64_t lo = n > V2 ? n - V2 : 0;
    const uint64_t hi = std::min(n, V1);
    uint64_t       result;
    if (n <= uint64_t(SmallCount))
    {
      result = CodeSmall(io, n, V, length, lo, hi, k);
    }
    else
    {
      result = CodeLarge(io, n, length, lo, hi, k);
    }
    return complement ? V1 - result : result;
  }

private:
  template <typename Io>
  uint64_t
  CodeSmall(Io & io, uint64_t n, uint64_t V, int32_t length, uint64_t lo, uint64_t hi, uint64_t k)
  {
    // m = distance of k from the nearer extreme, in unary over its feasible values, then the side.
    const int      density = std::min(BitLength(V / n) - 1, DensityBuckets - 1);
    auto &         unary = m_Unary[n - 1][density];
    auto           feasible = [lo, hi](uint64_t v) { return v >= lo && v <= hi; };
    const uint64_t half = n / 2;
    uint64_t       lastFeasible = 0;
    for (uint64_t i = 0; i <= half; ++i)
    {
      if (feasible(i) || feasible(n - i))
      {
        lastFeasible = i;
      }
    }
    const uint64_t m = io.Encoding() ? std::min(k, n - k) : 0;
    uint64_t       decoded = lastFeasible;
    for (uint64_t i = 0; i < lastFeasible; ++i)
    {
      if (!feasible(i) && !feasible(n - i))
      {
        continue;
      }
      if (io.Bit(unary[i], m == i))
      {
        decoded = i;
        break;
      }
    }
    // Side: k = m (first half, the bit is 0) or k = n - m (second half).
    if (decoded == n - decoded)
    {
      return decoded;
    }
    const bool first = feasible(decoded), second = feasible(n - decoded);
    int        side;
    if (first && second)
    {
      const int c = (length & 1) ? std::min((length + 1) / 2, 8) : 0;
      side = io.Bit(m_Side[n == 1 ? 0 : (decoded == 0 ? 1 : 2)][c], io.Encoding() && k != decoded);
    }
    else
    {
      side = first ? 0 : 1;
    }
    return side ? n - decoded : decoded;
  }

  template <typename Io>
  uint64_t
  CodeLarge(Io & io, uint64_t n, int32_t length, uint64_t lo, uint64_t hi, uint64_t k)
  {
    const uint64_t a = uint64_t(length / 2);
    const uint64_t expected = std::min(std::max((n * a + uint64_t(length) / 2) / uint64_t(length), lo), hi);
    const int      c = std::min(BitLength(n) / DCV_POSITION_COUNT_DIVISOR, CountBuckets - 1);
    const int64_t  d = io.Encoding() ? int64_t(k) - int64_t(expected) : 0;
    if (io.Bit(m_Zero[c], d == 0))
    {
      return expected;
    }
    const int      negative = io.Bit(m_Sign[c], d < 0);
    const uint64_t room = negative ? expected - lo : hi - expected; // >= 1 for the encoder
    const uint64_t magnitude = 1 + io.UInt(*m_Magnitude[c], uint32_t((d < 0 ? -d : d) - 1));
    const uint64_t step = std::min(magnitude, room); // garbage is clamped into [lo, hi]
    return negative ? expected - step : expected + step;
  }

  std::array<std::array<std::array<BitModel, SmallCount / 2 + 1>, DensityBuckets>, SmallCount> m_Unary;
  std::array<std::array<BitModel, 9>, 3>                                                       m_Side;
  std::array<BitModel, CountBuckets>                                                           m_Zero;
  std::array<BitModel, CountBuckets>                                                           m_Sign;
  std::array<std::unique_ptr<UIntModel>, CountBuckets>                                         m_Magnitude;
};

/** Io of the encoder: codes the given decisions and returns them. */
struct EncoderIo
{
  ArithmeticEncoder & encoder;
  static constexpr bool
  Encoding()
  {
    return true;
  }
  int
  Bit(BitModel & model, bool bit)
  {
    encoder.Encode(model, bit ? 1 : 0);
    return bit ? 1 : 0;
  }
  uint32_t
  UInt(UIntModel & model, uint32_t value)
  {
    model.Encode(encoder, value);
    return value;
  }
};

struct DecoderIo
{
  ArithmeticDecoder & decoder;
  static constexpr bool
  Encoding()
  {
    return false;
  }
  int
  Bit(BitModel & model, bool)
  {
    return decoder.Decode(model);
  }
  uint32_t
  UInt(UIntModel & model, uint32_t)
  {
    return model.Decode(decoder);
  }
};

void
SortRaster(std::vector<GridPoint>::iterator begin, std::vector<GridPoint>::iterator end)
{
  std::sort(begin, end, [](const GridPoint & a, const GridPoint & b) {
    return std::make_tuple(a[2], a[1], a[0]) < std::make_tuple(b[2], b[1], b[0]);
  });
}

/** Partitions [begin, end) into coding order, coding the splits through `code(n, V, V1, length, k)`. */
template <typename CodeFunction>
void
Traverse(const Box & box, std::vector<GridPoint>::iterator begin, std::vector<GridPoint>::iterator end,
         CodeFunction & code)
{
  const uint64_t n = uint64_t(end - begin);
  const uint64_t V = box.Voxels();
  if (n == 0)
  {
    return;
  }
  if (n >= V)
  {
    // Full (n == V) if the points are distinct, which the sort reveals.
    SortRaster(begin, end);
    if (n > V || std::adjacent_find(begin, end) != end)
    {
      throw std::invalid_argument("EncodePositions: duplicate points");
    }
    return;
  }
  const int      axis = box.SplitAxis();
  const int32_t  length = box.hi[axis] - box.lo[axis];
  const int32_t  middle = box.lo[axis] + length / 2;
  const auto     split = std::partition(begin, end, [axis, middle](const GridPoint & p) { return p[axis] < middle; });
  const uint64_t V1 = V / uint64_t(length) * uint64_t(length / 2);
  code(n, V, V1, length, uint64_t(split - begin));
  Box first = box, second = box;
  first.hi[axis] = middle;
  second.lo[axis] = middle;
  Traverse(first, begin, split, code);
  Traverse(second, split, end, code);
}

void
Decode(const Box & box, uint64_t n, SplitModel & model, DecoderIo & io, std::vector<GridPoint> & out)
{
  const uint64_t V = box.Voxels();
  if (n == 0 || io.decoder.Overrun())
  {
    return; // an overrun stream is damaged: no more work (or memory) for its garbage
  }
  if (n == V)
  {
    for (int32_t z = box.lo[2]; z < box.hi[2]; ++z)
      for (int32_t y = box.lo[1]; y < box.hi[1]; ++y)
        for (int32_t x = box.lo[0]; x < box.hi[0]; ++x)
          out.push_back({ x, y, z });
    return;
  }
  const int      axis = box.SplitAxis();
  const int32_t  length = box.hi[axis] - box.lo[axis];
  const int32_t  middle = box.lo[axis] + length / 2;
  const uint64_t V1 = V / uint64_t(length) * uint64_t(length / 2);
  const uint64_t k = model.Code(io, n, V, V1, length, 0);
  Box            first = box, second = box;
  first.hi[axis] = middle;
  second.lo[axis] = middle;
  Decode(first, k, model, io, out);
  Decode(second, n - k, model, io, out);
}

Box
GridBox(const GridSize & grid)
{
  return Box{ { 0, 0, 0 }, { grid.x, grid.y, grid.z } };
}

void
CheckInside(const GridSize & grid, const std::vector<GridPoint> & points)
{
  if (grid.x < 0 || grid.y < 0 || grid.z < 0)
  {
    throw std::invalid_argument("EncodePositions: negative grid size");
  }
  for (const GridPoint & p : points)
  {
    if (p[0] < 0 || p[1] < 0 || p[2] < 0 || p[0] >= grid.x || p[1] >= grid.y || p[2] >= grid.z)
    {
      throw std::invalid_argument("EncodePositions: point outside the grid");
    }
  }
}

} // namespace

void
EncodePositions(ArithmeticEncoder & encoder, const GridSize & grid, std::vector<GridPoint> points)
{
  CheckInside(grid, points);
  auto      model = std::make_unique<SplitModel>();
  EncoderIo io{ encoder };
  auto      code = [&model, &io](uint64_t n, uint64_t V, uint64_t V1, int32_t length, uint64_t k) {
    model->Code(io, n, V, V1, length, k);
  };
  Traverse(GridBox(grid), points.begin(), points.end(), code);
}

void
SortPositions(const GridSize & grid, std::vector<GridPoint> & points)
{
  CheckInside(grid, points);
  auto code = [](uint64_t, uint64_t, uint64_t, int32_t, uint64_t) {};
  Traverse(GridBox(grid), points.begin(), points.end(), code);
}

std::vector<GridPoint>
DecodePositions(ArithmeticDecoder & decoder, const GridSize & grid, uint32_t count)
{
  if (grid.x < 0 || grid.y < 0 || grid.z < 0 || uint64_t(count) > grid.NumberOfVoxels())
  {
    throw std::invalid_argument("DecodePositions: more points than voxels");
  }
  std::vector<GridPoint> out;
  out.reserve(std::min<uint32_t>(count, 1u << 22));
  auto      model = std::make_unique<SplitModel>();
  DecoderIo io{ decoder };
  Decode(GridBox(grid), count, *model, io, out);
  return out;
}

} // namespace dcv
