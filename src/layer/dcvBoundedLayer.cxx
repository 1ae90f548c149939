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
#include "dcvBoundedLayer.h"
#include "dcvArithmeticCoder.h"
#include "dcvFileFormat.h"
#include "dcvParallel.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>

namespace dcv
{
namespace
{
/** The predictors: four within the slice, three across slices (only where a previous slice of the slab
 * exists). docs/format.md, "Bounded-error layer", states them; the order is part of the format. */
constexpr int InSlice = 4;
constexpr int Predictors = 7;
/** Contexts of the residual's code (half octaves of the local activity) and of the bias correction. */
constexpr int CodingContexts = 32;
/** Classes of the prediction's place in the range: inside, or at, near or fairly near the low or high end. */
constexpr int EndClasses = 7;
constexpr int BiasContexts = 16 * 8;
/** A bias context's counts halve when they reach this (it follows a drifting mean, as JPEG-LS's do). */
constexpr int32_t BiasReset = 256;
/** Errors are kept capped: the weights' sums then never overflow. */
constexpr uint32_t ErrorCap = uint32_t(1) << 28;

constexpr std::size_t HeaderBytes = 8 + 4 + 4 + 4 + 4;

/** Half octaves of a non-negative activity: 0, 1, 2, 3, then two buckets per power of two. */
inline int
ActivityBucket(uint64_t a, int buckets)
{
  if (a < 4)
    return int(a);
  int       bits = 63 - __builtin_clzll(a); // floor(log2 a) >= 2
  const int b = 2 * bits + int((a >> (bits - 1)) & 1u);
  return std::min(b, buckets - 1);
}

inline int64_t
Clamp(int64_t v, int64_t hi)
{
  return v < 0 ? 0 : (v > hi ? hi : v);
}

/** floor(2^30 / x') for x >= 1, where x' is x with the bits below its 8 leading ones cleared: a table look-up
 * and a shift instead of a division (the weights' divisions were most of the coder's time). */
struct Reciprocals
{
  std::array<uint32_t, 256> table{};
  Reciprocals()
  {
    for (uint32_t m = 1; m < 256; ++m)
      table[m] = (uint32_t(1) << 30) / m;
  }
  uint64_t
  operator()(uint64_t x) const
  {
    // Keeps the 8 leading bits (none dropped below 256), without a branch: busy voxels' errors fall either side.
    const int shift = std::max(0, (63 - __builtin_clzll(x)) - 7);
    return table[x >> shift] >> shift;
  }
};
const Reciprocals Reciprocal;

/** Floor of a / b for b > 0. */
inline int64_t
FloorDivide(int64_t a, int64_t b)
{
  const int64_t q = a / b;
  return q - int64_t((a % b != 0) && (a < 0));
}

/** One slab, coded (TCoder: the arithmetic encoder) or decoded (the decoder): the same code both ways, so that
 * they cannot drift apart. `samples` points at the slab's first voxel; values are sample - minimum. */
template <bool Decoding, typename TCoder>
class SlabCoder
{
public:
  SlabCoder(int32_t * samples, const GridSize & grid, int64_t minimum, int64_t range, int64_t near, TCoder & coder,
            const std::string & name)
    : m_Samples(samples)
    , m_X(grid.x)
    , m_Y(grid.y)
    , m_Plane(std::size_t(grid.x) * std::size_t(grid.y))
    , m_Minimum(minimum)
    , m_Range(range)
    , m_Near(near)
    , m_Step(2 * near + 1)
    , m_Steps((range + 2 * near) / (2 * near + 1) + 1) // JPEG-LS's RANGE: the residual's modulus, in steps
    , m_Half(m_Steps / 2)
    , m_Errors(std::size_t(2) * m_Plane, Errors{})
    , m_Models(EndClasses * CodingContexts, SIntModel(6))
    , m_Coder(coder)
    , m_Name(name)
  {}

  void
  Code(int32_t slices)
  {
    for (int32_t z = 0; z < slices; ++z)
    {
      if (z == 0)
        Slice<false>(z);
      else
        Slice<true>(z);
    }
  }

private:
  // Errors of each predictor and of the final prediction, on this slice and the one before.
  // A voxel's errors side by side: the neighbours' errors of every predictor are then a cache line each.
  using Errors = std::array<uint32_t, Predictors + 1>;
  static constexpr int Final = Predictors; // the final prediction's lane of Errors

  int64_t
  Value(std::size_t i) const
  {
    return int64_t(m_Samples[i]) - m_Minimum;
  }

  /** The slice's voxels in order; HasPrevious: a slice of the slab before it (the across-slice predictors). */
  template <bool HasPrevious>
  void
  Slice(int32_t z)
  {
    Errors *          current = m_Errors.data() + std::size_t(z & 1) * m_Plane;
    const Errors *    previous = m_Errors.data() + std::size_t((z + 1) & 1) * m_Plane; // slice z - 1's
    const std::size_t sliceStart = std::size_t(z) * m_Plane;
    const int64_t     X = m_X;
    for (int64_t y = 0; y < m_Y; ++y)
    {
      // The voxel before was flat, decoded to its neighbours' value with a zero residual: of this voxel's
      // neighbourhood, only what lies ahead of that one's is new.
      bool run = false;
      for (int64_t x = 0; x < X; ++x)
      {
        const std::size_t j = std::size_t(y * X + x);
        const std::size_t i = sliceStart + j;
        // A flat neighbourhood (every neighbour the same value, no final error around): every predictor gives
        // that value and the activity is 0, so the general path below would find blended = that value,
        // activity 0 and texture 0. Most of a volume's background; the same result for far less work.
        if (y > 0 && x > 0 && x + 1 < X)
        {
          const int32_t *      s = m_Samples + i;
          const int32_t        c = s[-X];
          const Errors *       e = current + j;
          const std::ptrdiff_t P = std::ptrdiff_t(m_Plane);
          const bool           flat =
            run ? FlatAhead<HasPrevious>(s, c, current, previous, j)
                          : (s[-1] == c && s[-X - 1] == c && s[-X + 1] == c && e[-1][Final] == 0 && e[-X][Final] == 0 &&
                   e[-X - 1][Final] == 0 && e[-X + 1][Final] == 0 &&
                   (!HasPrevious || (s[-P] == c && s[-P - 1] == c && s[-P - X] == c && s[-P - X - 1] == c &&
                                     s[-P - X + 1] == c && previous[j][Final] == 0)));
          if (flat)
          {
            const int64_t  blended = int64_t(c) - m_Minimum;
            int64_t        residual;
            const int64_t  v = Voxel<true>(i, blended, 0, 0, residual);
            const uint32_t off = uint32_t(std::min<uint64_t>(uint64_t(std::abs(v - blended)), ErrorCap));
            Errors &       out = current[j];
            for (int k = 0; k < Predictors; ++k)
              out[k] = off;
            out[Final] = uint32_t(std::min<uint64_t>(uint64_t(std::abs(residual)), ErrorCap));
            run = off == 0 && residual == 0;
            if (run)
              x = Run<HasPrevious>(x + 1, y, sliceStart, current, previous) - 1; // the voxel before the next
            continue;
          }
        }
        run = false;
        if (y > 0 && x > 0 && x + 1 < X)
          General<HasPrevious, true>(x, y, sliceStart, current, previous);
        else
          General<HasPrevious, false>(x, y, sliceStart, current, previous);
      }
      // A damaged stream is refused at the row it runs out in, not after the whole slab.
      if constexpr (Decoding)
      {
        if (m_Coder.Overrun())
          throw FormatError(m_Name + ": the bounded-error layer ends inside a slab");
      }
    }
  }

  /** Voxel (x, y) of the slice at sliceStart, every predictor computed and blended. Interior: 0 < x < X - 1
   * and y > 0, every neighbour inside the slice (the compiler then drops the edges' cases). */
  template <bool HasPrevious, bool Interior>
  void
  General(int64_t x, int64_t y, std::size_t sliceStart, Errors * current, const Errors * previous)
  {
    constexpr int     count = HasPrevious ? Predictors : InSlice;
    const int64_t     X = m_X;
    const std::size_t j = std::size_t(y * X + x);
    const std::size_t i = sliceStart + j;
    // Neighbours within the slice (in-plane offsets), replicated where the slice ends: north from
    // the west on the first row, west from the north on the first column.
    const std::size_t jn = Interior ? j - X : y > 0 ? j - X : (x > 0 ? j - 1 : j);
    const std::size_t jw = Interior || x > 0 ? j - 1 : jn;
    const std::size_t jnw = Interior || (x > 0 && y > 0) ? j - X - 1 : jn;
    const std::size_t jne = Interior || (y > 0 && x + 1 < X) ? j - X + 1 : jn;
    const bool        first = !Interior && jn == j; // the slab's first voxel of a slice: nothing before it
    int64_t           w, n, nw, ne;
    if (first)
    {
      w = n = nw = ne = HasPrevious ? Value(i - m_Plane) : 0;
    }
    else
    {
      w = Value(sliceStart + jw);
      n = Value(sliceStart + jn);
      nw = Value(sliceStart + jnw);
      ne = Value(sliceStart + jne);
    }
    // The first voxel of a slice has no neighbour in it: its in-slice errors are 0.
    static const Errors             none{};
    const Errors &                  ew = first ? none : current[jw];
    const Errors &                  en = first ? none : current[jn];
    const Errors &                  enw = first ? none : current[jnw];
    const Errors &                  ene = first ? none : current[jne];
    std::array<int64_t, Predictors> p;
    p[0] = w + n - nw;
    p[1] = w + ne - n;
    p[2] = n;
    p[3] = w;
    if constexpr (HasPrevious)
    {
      const std::size_t q = i - m_Plane;
      const int64_t     pc = Value(q);
      const int64_t pw = Value(q - j + jw), pn = Value(q - j + jn), pnw = Value(q - j + jnw), pne = Value(q - j + jne);
      p[4] = pc + (w - pw) + (n - pn) - (nw - pnw);
      p[5] = pc + FloorDivide((w - pw) + (n - pn) + (ne - pne) + (nw - pnw) + 2, 4);
      p[6] = pc;
    }
    int64_t lo = std::numeric_limits<int64_t>::max(), hi = std::numeric_limits<int64_t>::min();
    for (int k = 0; k < count; ++k)
    {
      p[k] = Clamp(p[k], m_Range);
      lo = std::min(lo, p[k]);
      hi = std::max(hi, p[k]);
    }
    // Weights: the inverse square of each predictor's recent error around the voxel. Where every
    // predictor agrees (flat regions: most of a volume's background) any weights give that value.
    int64_t blended = lo;
    if (lo != hi)
    {
      uint64_t weightSum = 0;
      int64_t  weighted = 0;
      for (int k = 0; k < count; ++k)
      {
        uint64_t s = uint64_t(ew[k]) + en[k] + ((uint64_t(enw[k]) + ene[k]) >> 1);
        if constexpr (HasPrevious)
          s += previous[j][k];
        const uint64_t inverse = Reciprocal(s + 1);
        const uint64_t weight = std::max<uint64_t>(1, (inverse * inverse) >> 38);
        weightSum += weight;
        weighted += int64_t(weight) * p[k];
      }
      blended = (weighted + int64_t(weightSum / 2)) / int64_t(weightSum);
    }
    // Contexts: the final prediction's recent errors and how far the predictors disagree.
    uint64_t activity = uint64_t(ew[Final]) + en[Final] + ((uint64_t(enw[Final]) + ene[Final]) >> 1);
    activity += HasPrevious ? previous[j][Final] : ew[Final];
    activity += uint64_t(hi - lo) >> 1;
    const int     texture = int(w > blended) | (int(n > blended) << 1) | (HasPrevious ? int(p[6] > blended) << 2 : 0);
    int64_t       residual;
    const int64_t v = Voxel<false>(i, blended, activity, texture, residual);
    Errors &      out = current[j];
    for (int k = 0; k < count; ++k)
      out[k] = uint32_t(std::min<uint64_t>(uint64_t(std::abs(v - p[k])), ErrorCap));
    for (int k = count; k < Predictors; ++k)
      out[k] = out[0]; // the slab's first slice: across-slice predictors start as the gradient
    out[Final] = uint32_t(std::min<uint64_t>(uint64_t(std::abs(residual)), ErrorCap));
  }

  /** Voxel j (sample s) is flat on c, given that the voxel before it was flat on c with a zero residual: only
   * the neighbours ahead of that one's neighbourhood are new (north-east, and in the slice before the voxel
   * itself and its north-east). */
  template <bool HasPrevious>
  bool
  FlatAhead(const int32_t * s, int32_t c, const Errors * current, const Errors * previous, std::size_t j) const
  {
    const int64_t        X = m_X;
    const std::ptrdiff_t P = std::ptrdiff_t(m_Plane);
    return s[-X + 1] == c && current[j - X + 1][Final] == 0 &&
           (!HasPrevious || (s[-P] == c && s[-P - X + 1] == c && previous[j][Final] == 0));
  }

  /** Voxels x, x + 1, ... of row y (x > 0, y > 0) while each is flat on the value of the voxel before it, with a
   * zero residual and no bias correction: Voxel<true>'s decisions for each, with the coder, the zero flag's
   * model and the bias kept in registers (a model's and the coder's state otherwise went to memory and back
   * every voxel: most of the background's time). Returns the first voxel of the row not coded. */
  template <bool HasPrevious>
  int64_t
  Run(int64_t x, int64_t y, std::size_t sliceStart, Errors * current, const Errors * previous)
  {
    const int64_t X = m_X;
    const int32_t c = m_Samples[sliceStart + std::size_t(y * X + x - 1)];
    const int64_t value = int64_t(c) - m_Minimum;
    // Voxel<true>'s end class for the prediction `value` (activity 0).
    const uint64_t below = uint64_t(value), above = uint64_t(m_Range - value);
    const int      end = std::min(below, above) == 0 ? (below <= above ? 1 : 4) : 0;
    BitModel &     model = m_Models[std::size_t(end) * CodingContexts].ZeroFlag();
    BitModel       zero = model;
    TCoder         coder = m_Coder;
    int64_t        biasSum = m_BiasSum[0];
    int32_t        biasCount = m_BiasCount[0];
    for (; x + 1 < X; ++x)
    {
      const std::size_t j = std::size_t(y * X + x);
      const std::size_t i = sliceStart + j;
      const int32_t *   s = m_Samples + i;
      if (!FlatAhead<HasPrevious>(s, c, current, previous, j))
        break;
      if (biasCount > 0)
      {
        const int64_t a = 2 * biasSum + biasCount;
        if (a < 0 || a >= 2 * int64_t(biasCount))
          break; // a correction: Voxel<true> codes this one
      }
      if constexpr (Decoding)
      {
        TCoder   tried = coder;
        BitModel flag = zero;
        if (!tried.Decode(flag))
          break; // not zero: Voxel<true> decodes this one again from the state before it
        coder = tried;
        zero = flag;
      }
      else
      {
        if (std::abs(int64_t(m_Samples[i]) - int64_t(c)) > m_Near)
          break;
        coder.Encode(zero, 1);
      }
      m_Samples[i] = c;
      if (++biasCount == BiasReset)
      {
        biasSum = FloorDivide(biasSum, 2);
        biasCount = BiasReset / 2;
      }
      current[j] = Errors{};
    }
    model = zero;
    m_Coder = coder;
    m_BiasSum[0] = biasSum;
    m_BiasCount[0] = biasCount;
    return x;
  }

  /** Voxel i from its blended prediction and contexts: the bias correction, the residual coded or decoded,
   * the sample written (the encoder's too: what follows is predicted from decoded samples). Returns the
   * value (sample - minimum) and the residual, in the input's units. Flat: activity and texture 0, known
   * to the compiler. */
  template <bool Flat>
  int64_t
  Voxel(std::size_t i, int64_t blended, uint64_t activity, int texture, int64_t & residual)
  {
    if constexpr (Flat)
    {
      activity = 0;
      texture = 0;
    }
    const int b = ActivityBucket(activity, 16) * 8 + texture;
    int64_t   correction = 0;
    if (m_BiasCount[b] > 0)
    {
      // floor((2 S + c) / 2 c): without a division where the mean is below one step either way (most).
      const int64_t a = 2 * m_BiasSum[b] + m_BiasCount[b], d = 2 * int64_t(m_BiasCount[b]);
      correction = (a >= 0 && a < d) ? 0 : (a < 0 && a >= -d) ? -1 : FloorDivide(a, d);
    }
    const int64_t prediction = Clamp(blended + correction, m_Range);
    // Where the prediction is at or near an end of the range (air at 0, a window's clipped values), the
    // residual's distribution is one-sided: its own models (7 classes by side and distance).
    const uint64_t below = uint64_t(prediction), above = uint64_t(m_Range - prediction);
    const uint64_t nearest = std::min(below, above);
    const int      side = below <= above ? 0 : 3;
    const int      end = nearest == 0                 ? 1 + side
                         : nearest * 4 < activity + 4 ? 2 + side
                         : nearest < activity + 1     ? 3 + side
                                                      : 0;
    SIntModel &    model = m_Models[std::size_t(end) * CodingContexts + ActivityBucket(activity, CodingContexts)];
    // The residual in steps of 2 near + 1 (JPEG-LS's near-lossless quantization: the decoded sample is
    // within `near` of the input), modulo the steps the range spans,
    // folded around 0: it then fits 32 bits whatever the samples, and the sum wraps back into the range.
    int64_t q;
    if constexpr (Decoding)
    {
      q = model.Decode(m_Coder);
      if (q < -m_Half || q >= m_Steps - m_Half)
        throw FormatError(m_Name + ": damaged bounded-error layer (a sample outside its range)");
    }
    else
    {
      const int64_t e = Value(i) - prediction;
      q = m_Near == 0 ? e : (e >= 0 ? (e + m_Near) / m_Step : -((m_Near - e) / m_Step));
      q += q < -m_Half ? m_Steps : (q >= m_Steps - m_Half ? -m_Steps : 0);
      model.Encode(m_Coder, int32_t(q));
    }
    residual = q * m_Step;
    int64_t v = prediction + residual;
    v += v < -m_Near ? m_Steps * m_Step : (v > m_Range + m_Near ? -m_Steps * m_Step : 0);
    v = Clamp(v, m_Range);
    m_Samples[i] = int32_t(v + m_Minimum);
    m_BiasSum[b] += residual;
    if (++m_BiasCount[b] == BiasReset)
    {
      m_BiasSum[b] = FloorDivide(m_BiasSum[b], 2);
      m_BiasCount[b] = BiasReset / 2;
    }
    return v;
  }

  int32_t * const                                     m_Samples;
  const int64_t                                       m_X, m_Y;
  const std::size_t                                   m_Plane;
  const int64_t                                       m_Minimum, m_Range, m_Near, m_Step, m_Steps, m_Half;
  std::vector<Errors, UninitializedAllocator<Errors>> m_Errors; // huge pages: see UninitializedAllocator
  // Models that settle slower than the points' (shift 6, not 5): 1% smaller on the dev volumes, whose
  // contexts see many thousands of residuals each.
  std::vector<SIntModel>            m_Models;
  std::array<int64_t, BiasContexts> m_BiasSum{};
  std::array<int32_t, BiasContexts> m_BiasCount{};
  TCoder &                          m_Coder;
  const std::string &               m_Name;
};

void
PutU32(std::vector<uint8_t> & out, uint32_t v)
{
  for (int b = 0; b < 4; ++b)
    out.push_back(uint8_t(v >> (8 * b)));
}
uint32_t
GetU32(const uint8_t * p)
{
  return uint32_t(p[0]) | (uint32_t(p[1]) << 8) | (uint32_t(p[2]) << 16) | (uint32_t(p[3]) << 24);
}
} // namespace

uint32_t
BoundedLayerSlabSlices(const GridSize & grid)
{
  const uint64_t plane = uint64_t(grid.x) * uint64_t(grid.y);
  const uint64_t slices = std::max<uint64_t>(8, (uint64_t(1) << 22) / std::max<uint64_t>(1, plane));
  return uint32_t(std::min<uint64_t>(slices, uint64_t(std::max(grid.z, 1))));
}

std::vector<uint8_t>
EncodeBoundedLayer(int32_t * samples, const GridSize & grid, uint32_t near, double maximumError,
                   const std::function<void(double)> & progress)
{
  const uint64_t                    voxels = grid.NumberOfVoxels();
  const auto                        mm = ParallelMinMax(samples, voxels);
  const int64_t                     minimum = mm.first, range = int64_t(mm.second) - minimum;
  const uint32_t                    slabSlices = BoundedLayerSlabSlices(grid);
  const uint32_t                    slabs = uint32_t((uint32_t(grid.z) + slabSlices - 1) / slabSlices);
  const std::size_t                 plane = std::size_t(grid.x) * std::size_t(grid.y);
  std::vector<std::vector<uint8_t>> coded(slabs);
  // As many slabs at once as there are threads, the progress reported between them (from this thread).
  // Four slabs a thread in each batch: slabs differ in work (a head's background against its middle), and a
  // batch of one a thread waited for its busiest (norm-256 on 2 threads: 0.185 s against 0.14 s).
  const std::size_t together = 4 * std::max<std::size_t>(1, CurrentThreads());
  for (std::size_t first = 0; first < slabs; first += together)
  {
    ParallelFor(std::min<std::size_t>(together, slabs - first), 1, [&](std::size_t k) {
      const std::size_t s = first + k;
      const int32_t     z0 = int32_t(s * slabSlices);
      const int32_t     n = std::min<int32_t>(int32_t(slabSlices), grid.z - z0);
      ArithmeticEncoder encoder(coded[s]);
      const std::string none;
      SlabCoder<false, ArithmeticEncoder>(
        samples + std::size_t(z0) * plane, grid, minimum, range, int64_t(near), encoder, none)
        .Code(n);
      encoder.Finish();
    });
    if (progress)
      progress(double(std::min<std::size_t>(slabs, first + together)) / double(slabs));
  }
  std::vector<uint8_t> out(8);
  std::memcpy(out.data(), &maximumError, 8); // little-endian hosts only, as the rest of the container
  PutU32(out, uint32_t(int32_t(minimum)));
  PutU32(out, uint32_t(range));
  PutU32(out, slabSlices);
  PutU32(out, near);
  for (const auto & c : coded)
  {
    PutU32(out, uint32_t(c.size()));
    out.insert(out.end(), c.begin(), c.end());
  }
  return out;
}

BoundedLayerHeader
ReadBoundedLayerHeader(const std::vector<uint8_t> & layer, const GridSize & grid, const std::string & name)
{
  if (layer.size() < HeaderBytes)
    throw FormatError(name + ": damaged bounded-error layer (" + std::to_string(layer.size()) + " bytes)");
  BoundedLayerHeader h;
  std::memcpy(&h.maximumError, layer.data(), 8);
  h.minimum = int32_t(GetU32(layer.data() + 8));
  h.range = GetU32(layer.data() + 12);
  h.slabSlices = GetU32(layer.data() + 16);
  h.near = GetU32(layer.data() + 20);
  if (!std::isfinite(h.maximumError) || h.maximumError < 0.0)
    throw FormatError(name + ": damaged bounded-error layer (its bound is not a finite non-negative number)");
  if (int64_t(h.minimum) + int64_t(h.range) > std::numeric_limits<int32_t>::max())
    throw FormatError(name + ": damaged bounded-error layer (samples beyond 32 bits)");
  if (h.slabSlices != BoundedLayerSlabSlices(grid))
    throw FormatError(name + ": damaged bounded-error layer (slabs of " + std::to_string(h.slabSlices) +
                      " slices, not " + std::to_string(BoundedLayerSlabSlices(grid)) + ")");
  return h;
}

ResidualSamples
DecodeBoundedLayer(const std::vector<uint8_t> & layer, const GridSize & grid, const std::string & name)
{
  const BoundedLayerHeader h = ReadBoundedLayerHeader(layer, grid, name);
  const uint32_t           slabs = (uint32_t(grid.z) + h.slabSlices - 1) / h.slabSlices;
  // The slabs' places first: every length checked before anything is decoded.
  std::vector<std::size_t> start(slabs), length(slabs);
  std::size_t              at = HeaderBytes;
  for (uint32_t s = 0; s < slabs; ++s)
  {
    if (layer.size() - at < 4)
      throw FormatError(name + ": the bounded-error layer ends before slab " + std::to_string(s + 1) + " of " +
                        std::to_string(slabs));
    length[s] = GetU32(layer.data() + at);
    at += 4;
    if (layer.size() - at < length[s])
      throw FormatError(name + ": the bounded-error layer ends inside slab " + std::to_string(s + 1) + " of " +
                        std::to_string(slabs));
    start[s] = at;
    at += length[s];
  }
  if (at != layer.size())
    throw FormatError(name + ": " + std::to_string(layer.size() - at) + " bytes follow the bounded-error layer");
  const std::size_t plane = std::size_t(grid.x) * std::size_t(grid.y);
  ResidualSamples   samples(grid.NumberOfVoxels());
  ParallelFor(slabs, 1, [&](std::size_t s) {
    const int32_t     z0 = int32_t(s * h.slabSlices);
    const int32_t     n = std::min<int32_t>(int32_t(h.slabSlices), grid.z - z0);
    ArithmeticDecoder decoder(layer.data() + start[s], length[s]);
    SlabCoder<true, ArithmeticDecoder>(
      samples.data() + std::size_t(z0) * plane, grid, h.minimum, h.range, int64_t(h.near), decoder, name)
      .Code(n);
    if (decoder.GetPosition() != length[s])
      throw FormatError(name + ": damaged bounded-error layer (" + std::to_string(length[s] - decoder.GetPosition()) +
                        " bytes follow slab " + std::to_string(s + 1) + ")");
  });
  return samples;
}

} // namespace dcv
