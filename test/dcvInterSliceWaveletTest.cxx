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
// The inter-slice wavelet of the residual layer: exactly invertible at every level count and slice count,
// empty high bands where slices are alike, bounded on any decoded input, and carried by the container.
#include "dcvFileFormat.h"
#include "dcvInterSliceWavelet.h"
#include "dcvResidualLayer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace
{
using dcv::GridSize;

std::vector<int32_t>
Random(const GridSize & g, int32_t amplitude, unsigned seed)
{
  std::mt19937                           random(seed);
  std::uniform_int_distribution<int32_t> value(-amplitude, amplitude);
  std::vector<int32_t>                   s(g.NumberOfVoxels());
  for (int32_t & v : s)
    v = value(random);
  return s;
}

/** Slices that change slowly along z, as in a near-isotropic volume. */
std::vector<int32_t>
SmoothAlongZ(const GridSize & g)
{
  std::vector<int32_t> s(g.NumberOfVoxels());
  for (int32_t z = 0; z < g.z; ++z)
    for (int32_t y = 0; y < g.y; ++y)
      for (int32_t x = 0; x < g.x; ++x)
        s[g.Offset(x, y, z)] =
          int32_t(std::lround(400.0 * std::sin(0.4 * x) * std::cos(0.3 * y) * (1.0 + 0.02 * z) + 3.0 * z));
  return s;
}
} // namespace

TEST(InterSliceWavelet, LevelsNeedTwoSlicesAtEveryLevel)
{
  EXPECT_EQ(dcv::InterSliceLevels(1), 0);
  EXPECT_EQ(dcv::InterSliceLevels(2), 1);
  EXPECT_EQ(dcv::InterSliceLevels(3), 2); // 3 -> 2 -> 1
  EXPECT_EQ(dcv::InterSliceLevels(4), 2);
  EXPECT_EQ(dcv::InterSliceLevels(5), 3); // 5 -> 3 -> 2 -> 1
  EXPECT_EQ(dcv::InterSliceLevels(28), 5);
  EXPECT_EQ(dcv::InterSliceLevels(33), 6);
  EXPECT_EQ(dcv::InterSliceLevels(65535), dcv::MaximumInterSliceLevels);
  // Every weight is at least 1, so that weighting loses nothing.
  for (int64_t w : dcv::LowBandWeight)
    EXPECT_GE(w, 4096);
  for (int64_t w : dcv::HighBandWeight)
    EXPECT_GE(w, 4096);
}

TEST(InterSliceWavelet, ForwardThenInverseIsExact)
{
  for (int32_t z : { 2, 3, 4, 5, 7, 8, 13, 28, 38, 64 })
  {
    const GridSize g{ 5, 3, z };
    for (int32_t levels = 0; levels <= dcv::InterSliceLevels(z); ++levels)
    {
      for (int32_t amplitude : { 1, 300, 32767 })
      {
        const std::vector<int32_t> original = Random(g, amplitude, unsigned(z * 100 + levels));
        std::vector<int32_t>       s = original;
        dcv::ForwardInterSlice(s, g, levels);
        if (levels > 0 && amplitude > 1)
          EXPECT_NE(s, original) << z << " slices, " << levels << " levels";
        dcv::InverseInterSlice(s, g, levels);
        EXPECT_EQ(s, original) << z << " slices, " << levels << " levels, amplitude " << amplitude;
      }
    }
  }
}

TEST(InterSliceWavelet, HighBandsOfEqualSlicesAreEmpty)
{
  const GridSize       g{ 4, 4, 13 };
  std::vector<int32_t> s(g.NumberOfVoxels());
  for (int32_t z = 0; z < g.z; ++z)
    for (int32_t i = 0; i < 16; ++i)
      s[std::size_t(z) * 16 + std::size_t(i)] = 100 + i; // every slice the same
  const int32_t levels = 3;
  dcv::ForwardInterSlice(s, g, levels);
  const int32_t lowSlices = 2; // ceil(13 / 8)
  for (int32_t z = 0; z < g.z; ++z)
  {
    for (int32_t i = 0; i < 16; ++i)
    {
      const int32_t v = s[std::size_t(z) * 16 + std::size_t(i)];
      if (z < lowSlices) // the low band: the slice times its weight
        EXPECT_EQ(v, int32_t(std::lround((100 + i) * double(dcv::LowBandWeight[levels - 1]) / 4096.0)));
      else
        EXPECT_EQ(v, 0) << "slice " << z;
    }
  }
  EXPECT_THROW(dcv::ForwardInterSlice(s, g, dcv::InterSliceLevels(13) + 1), std::invalid_argument);
  EXPECT_THROW(dcv::ForwardInterSlice(s, GridSize{ 4, 4, 12 }, 1), std::invalid_argument);
}

TEST(InterSliceWavelet, InverseOfAnyDecodedSamplesStaysInRange)
{
  // A damaged layer may decode to extreme samples: the synthesis must neither overflow nor wrap.
  const GridSize       g{ 3, 2, 64 };
  std::vector<int32_t> s(g.NumberOfVoxels());
  for (std::size_t i = 0; i < s.size(); ++i)
    s[i] = (i % 3 == 0) ? std::numeric_limits<int32_t>::max() : (i % 3 == 1 ? std::numeric_limits<int32_t>::min() : 0);
  dcv::InverseInterSlice(s, g, dcv::InterSliceLevels(64));
  for (int32_t v : s)
    EXPECT_GT(v, std::numeric_limits<int32_t>::min());
}

TEST(InterSliceWavelet, ResidualLayerIsLosslessWithTheReversibleWavelet)
{
  const GridSize             g{ 20, 18, 11 };
  const std::vector<int32_t> samples = Random(g, 2000, 7);
  for (dcv::Arrangement a : { dcv::Arrangement::Mosaic, dcv::Arrangement::Components })
  {
    for (int32_t levels = 1; levels <= dcv::InterSliceLevels(g.z); ++levels)
    {
      const auto codestream = dcv::EncodeResidualLayer(samples, g, 1 << 22, dcv::Wavelet::Reversible53, a, levels);
      ASSERT_FALSE(codestream.empty());
      EXPECT_EQ(dcv::DecodeResidualLayer(codestream, g, "x", levels),
                dcv::ResidualSamples(samples.begin(), samples.end()))
        << levels << " levels";
    }
  }
}

TEST(InterSliceWavelet, SlicesAlikeCodeCloserAtTheSameSize)
{
  // What the wavelet is for: at the same bytes, slices that change slowly along z decode closer with it.
  const GridSize             g{ 32, 32, 32 };
  const std::vector<int32_t> samples = SmoothAlongZ(g);
  auto                       error = [&](int32_t levels) {
    const auto codestream =
      dcv::EncodeResidualLayer(samples, g, 1500, dcv::Wavelet::Irreversible97, dcv::Arrangement::Components, levels);
    EXPECT_FALSE(codestream.empty());
    EXPECT_LE(codestream.size(), 1500u);
    const auto decoded = dcv::DecodeResidualLayer(codestream, g, "x", levels);
    double     e = 0.0;
    for (std::size_t i = 0; i < samples.size(); ++i)
      e += double(samples[i] - decoded[i]) * double(samples[i] - decoded[i]);
    return e;
  };
  const double without = error(0), with = error(4);
  std::cout << "squared error at 1500 bytes: " << without << " without, " << with << " with 4 levels\n";
  EXPECT_LT(with, 0.5 * without);
}

TEST(InterSliceWavelet, TheContainerCarriesTheLevels)
{
  dcv::FileHeader h;
  h.size = GridSize{ 4, 4, 9 };
  h.numberOfPoints = 8;
  h.residualStep = 1.0;
  h.residualLevels = 3;
  h.residualLayer = { 1, 2, 3 };
  const std::vector<uint8_t> payload(8, 0);
  std::vector<uint8_t>       bytes = dcv::SerializeFile(h, payload);
  dcv::FileHeader            back;
  std::vector<uint8_t>       p;
  dcv::ParseFile(bytes, "'f.dcv'", back, p);
  EXPECT_EQ(back.residualLevels, 3);
  EXPECT_EQ(back.residualLayer, h.residualLayer);
  // Without the wavelet the file is a byte shorter and has no level field.
  h.residualLevels = 0;
  EXPECT_EQ(dcv::SerializeFile(h, payload).size() + 1, bytes.size());
  // More levels than the slices take: refused when writing.
  h.residualLevels = 5; // 9 slices take 4: 9, 5, 3, 2
  EXPECT_THROW(dcv::SerializeFile(h, payload), std::invalid_argument);
}

namespace
{
int64_t
FloorDivide(int64_t a, int64_t b)
{
  const int64_t q = a / b;
  return (a % b != 0 && a < 0) ? q - 1 : q;
}

/** docs/format.md's inverse of one column of z samples, written as plainly as the text says it (true
 * divisions): what InverseInterSlice's faster arithmetic must equal. */
std::vector<int64_t>
PlainInverse(std::vector<int64_t> c, int32_t levels)
{
  const int32_t n = int32_t(c.size());
  auto          low = [](int32_t m, int32_t l) { return int32_t((int64_t(m) + (int64_t(1) << l) - 1) >> l); };
  for (int32_t i = 0; i < n; ++i)
  {
    int64_t w = dcv::LowBandWeight[std::size_t(levels - 1)];
    if (i >= low(n, levels))
    {
      int32_t k = levels;
      while (i >= low(n, k - 1))
        --k;
      w = dcv::HighBandWeight[std::size_t(k - 1)];
    }
    c[std::size_t(i)] = FloorDivide(c[std::size_t(i)] * 8192 + w, 2 * w);
  }
  for (int32_t l = levels - 1; l >= 0; --l)
  {
    const int32_t        m = low(n, l), lows = (m + 1) / 2, highs = m / 2;
    std::vector<int64_t> x(std::size_t(m), 0);
    auto                 h = [&](int32_t i) { return c[std::size_t(lows + std::clamp(i, 0, highs - 1))]; };
    for (int32_t i = 0; i < lows; ++i)
      x[std::size_t(2 * i)] = c[std::size_t(i)] - FloorDivide(h(i - 1) + h(i) + 2, 4);
    for (int32_t i = 0; i < highs; ++i)
      x[std::size_t(2 * i + 1)] =
        c[std::size_t(lows + i)] +
        FloorDivide(x[std::size_t(2 * i)] + x[std::size_t(2 * i + 2 < m ? 2 * i + 2 : 2 * i)], 2);
    std::copy(x.begin(), x.end(), c.begin());
  }
  for (int64_t & v : c)
    v = std::clamp<int64_t>(v, std::numeric_limits<int32_t>::min() + 1, std::numeric_limits<int32_t>::max());
  return c;
}
} // namespace

TEST(InterSliceWavelet, InverseEqualsThePlainArithmeticOfTheFormat)
{
  // The inverse divides by shifts and by a corrected floating-point quotient, in int32 where the samples
  // are small (up to 2^20) and in int64 otherwise: it must give what true floor divisions give, for any
  // samples, extremes and negative values included.
  for (const int32_t slices : { 2, 5, 16, 37, 64 })
    for (const int32_t amplitude : { 70000, 1 << 20, (1 << 20) + 1 })
      for (const bool extremes : { false, true })
      {
        const GridSize       g{ 7, 3, slices };
        std::vector<int32_t> samples = Random(g, amplitude, unsigned(slices));
        if (!extremes)
          samples[5] = amplitude; // the largest an int32 synthesis takes, or one past it
        for (std::size_t i = 0; extremes && i < samples.size(); i += 11)
          samples[i] = (i % 2) ? std::numeric_limits<int32_t>::max() : std::numeric_limits<int32_t>::min();
        for (int32_t levels = 1; levels <= dcv::InterSliceLevels(slices); ++levels)
        {
          SCOPED_TRACE("slices " + std::to_string(slices) + ", amplitude " + std::to_string(amplitude) +
                       (extremes ? ", extremes" : "") + ", levels " + std::to_string(levels));
          std::vector<int32_t> fast = samples;
          dcv::InverseInterSlice(fast, g, levels);
          for (int32_t y = 0; y < g.y; ++y)
            for (int32_t x = 0; x < g.x; ++x)
            {
              std::vector<int64_t> column;
              for (int32_t z = 0; z < g.z; ++z)
                column.push_back(samples[g.Offset(x, y, z)]);
              const std::vector<int64_t> plain = PlainInverse(column, levels);
              for (int32_t z = 0; z < g.z; ++z)
                ASSERT_EQ(fast[g.Offset(x, y, z)], plain[std::size_t(z)]) << "x " << x << " y " << y << " z " << z;
            }
        }
      }
}

TEST(InterSliceWavelet, InverseIsExactAtEveryRemainderOfTheLargestSmallSamples)
{
  // In int32 the division by a band's weight is a product in double, whose error grows with the sample:
  // every sample from 2^20 - 2^16 to 2^20 (the largest the int32 synthesis takes), of either sign, meets
  // every remainder of every weight (2 w < 2^16), the exact halves included.
  for (int32_t levels = 1; levels <= dcv::MaximumInterSliceLevels; ++levels)
    for (const int32_t sign : { 1, -1 })
    {
      const GridSize       g{ 1 << 16, 1, 1 << levels };
      std::vector<int32_t> samples(g.NumberOfVoxels());
      for (int32_t z = 0; z < g.z; ++z)
        for (int32_t x = 0; x < g.x; ++x)
          samples[g.Offset(x, 0, z)] = sign * ((1 << 20) - ((x + 4099 * z) & 0xffff));
      std::vector<int32_t> fast = samples;
      dcv::InverseInterSlice(fast, g, levels);
      for (int32_t x = 0; x < g.x; ++x)
      {
        std::vector<int64_t> column;
        for (int32_t z = 0; z < g.z; ++z)
          column.push_back(samples[g.Offset(x, 0, z)]);
        const std::vector<int64_t> plain = PlainInverse(column, levels);
        for (int32_t z = 0; z < g.z; ++z)
          ASSERT_EQ(fast[g.Offset(x, 0, z)], plain[std::size_t(z)])
            << "levels " << levels << " x " << x << " z " << z << " sample " << samples[g.Offset(x, 0, z)];
      }
    }
}

TEST(InterSliceWavelet, InverseFromElsewhereEqualsInPlace)
{
  // A decoder's inverse reads each row where it was decoded (a mosaic): the same samples as in place.
  const GridSize       g{ 9, 4, 21 };
  std::vector<int32_t> samples = Random(g, 3000, 5);
  std::vector<int32_t> shuffled(samples.size()); // the rows stored by (z, y) reversed
  auto at = [&](int32_t y, int32_t z) { return int64_t(g.z - 1 - z) * g.y * g.x + int64_t(g.y - 1 - y) * g.x; };
  for (int32_t z = 0; z < g.z; ++z)
    for (int32_t y = 0; y < g.y; ++y)
      std::copy_n(samples.data() + g.Offset(0, y, z), g.x, shuffled.data() + at(y, z));
  for (int32_t levels = 0; levels <= dcv::InterSliceLevels(g.z); ++levels)
  {
    std::vector<int32_t> inPlace = samples, fromElsewhere(samples.size(), -1);
    dcv::InverseInterSlice(inPlace, g, levels);
    dcv::InverseInterSlice(
      [&](int32_t y, int32_t z) { return shuffled.data() + at(y, z); }, fromElsewhere.data(), g, levels);
    EXPECT_EQ(fromElsewhere, inPlace) << levels << " levels";
  }
}

TEST(InterSliceWavelet, RowByRowEqualsTheVolume)
{
  // The encoder computes a layer's samples straight into JPEG 2000's planes, and sums a trial's error as
  // the rows are decoded: the rows they see are the volume's rows, each exactly once.
  const GridSize       g{ 7, 5, 19 };
  std::vector<int32_t> samples = Random(g, 30000, 9);
  // Extremes, where the int64 lifting and the clamp to int32 matter.
  samples[3] = std::numeric_limits<int32_t>::max();
  samples[g.Offset(1, 2, 3)] = std::numeric_limits<int32_t>::min() + 1;
  std::vector<int32_t> rows(samples.size());
  std::vector<int>     given(std::size_t(g.y) * std::size_t(g.z));
  // The sink of both directions: each row kept where it belongs, and counted.
  const auto collect = [&](int32_t y, int32_t z, const int32_t * row) {
    ++given[std::size_t(z) * std::size_t(g.y) + std::size_t(y)];
    std::copy_n(row, g.x, rows.data() + g.Offset(0, y, z));
  };
  const auto eachOnce = [&] { return std::all_of(given.begin(), given.end(), [](int n) { return n == 1; }); };
  for (int32_t levels = 0; levels <= dcv::InterSliceLevels(g.z); ++levels)
  {
    std::vector<int32_t> volume = samples;
    dcv::ForwardInterSlice(volume, g, levels);
    std::fill(rows.begin(), rows.end(), -1);
    std::fill(given.begin(), given.end(), 0);
    dcv::ForwardInterSlice(
      [&](int32_t y, int32_t z, int32_t * row) { std::copy_n(samples.data() + g.Offset(0, y, z), g.x, row); },
      collect,
      g,
      levels);
    EXPECT_EQ(rows, volume) << levels << " levels, forward";
    EXPECT_TRUE(eachOnce()) << levels << " levels";

    std::vector<int32_t> inverse = volume;
    dcv::InverseInterSlice(inverse, g, levels);
    std::fill(rows.begin(), rows.end(), -1);
    std::fill(given.begin(), given.end(), 0);
    dcv::InverseInterSlice([&](int32_t y, int32_t z) { return volume.data() + g.Offset(0, y, z); }, collect, g, levels);
    EXPECT_EQ(rows, inverse) << levels << " levels, inverse";
    EXPECT_TRUE(eachOnce()) << levels << " levels";
  }
}
