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
// The engine's view of the image: a narrow copy where the voxels allow it, read as the very floats.
#include "dcvParallel.h"
#include "dcvPixelSource.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace
{
using dcv::PixelSource;

/** Every voxel read through the source, as a row of the whole image, against the double of its float
 * (bit for bit: -0 reads as +0 only where the float is -0 and the copy holds 0). */
void
ExpectReadsTheFloats(const std::vector<float> & image, unsigned bytes, const std::string & what)
{
  const PixelSource source(image.data(), image.size());
  EXPECT_EQ(source.BytesPerVoxel(), bytes) << what;
  std::size_t differ = 0;
  source.Visit([&](const auto * row) {
    for (std::size_t i = 0; i < image.size(); ++i)
      differ += source(row, int64_t(i)) == double(image[i]) ? 0 : 1;
  });
  EXPECT_EQ(differ, 0u) << what;
}

std::vector<float>
Integers(double lowest, double span, std::size_t n, double stride = 1.0)
{
  std::mt19937       random(7);
  std::vector<float> image(n);
  const auto         steps = uint64_t(span / stride);
  for (auto & v : image)
    v = float(lowest + stride * double(random() % (steps + 1)));
  image[0] = float(lowest); // both ends present: the span is exactly `span`
  image[1] = float(lowest + stride * double(steps));
  return image;
}

TEST(PixelSource, CopiesEightBitIntegers)
{
  ExpectReadsTheFloats(Integers(0, 255, 5000), 1, "uint8 values");
  ExpectReadsTheFloats(Integers(-128, 255, 5000), 1, "int8 values");
  ExpectReadsTheFloats(Integers(-1000, 255, 5000), 1, "256 values below zero");
  ExpectReadsTheFloats(Integers(0, 256, 5000), 0, "257 values");
  ExpectReadsTheFloats(Integers(-1024, 3071 + 1024, 5000), 0, "CT values");
  ExpectReadsTheFloats(Integers(-32768, 65535, 5000), 0, "int16 values");
  ExpectReadsTheFloats(Integers(-2147483648.0, 4294967295.0, 5000), 0, "int32 values");
  // Large integers, far apart in float (128 at 2^30) but within 256 of each other.
  ExpectReadsTheFloats(Integers(1073741824.0, 128.0, 5000, 128.0), 1, "integers near 2^30");
  ExpectReadsTheFloats(Integers(-1073741824.0 - 128.0, 128.0, 5000, 128.0), 1, "integers near -2^30");
}

TEST(PixelSource, ReadsOtherVolumesAsTheirFloats)
{
  std::vector<float> image = Integers(0, 100, 5000);
  image[4321] = 17.5f;
  ExpectReadsTheFloats(image, 0, "one half");
  image[4321] = std::nextafter(17.0f, 18.0f);
  ExpectReadsTheFloats(image, 0, "one float just above an integer");
  image[4321] = std::numeric_limits<float>::quiet_NaN();
  {
    const PixelSource source(image.data(), image.size());
    EXPECT_EQ(source.BytesPerVoxel(), 0u) << "a NaN";
  }
  image[4321] = std::numeric_limits<float>::infinity();
  ExpectReadsTheFloats(image, 0, "an infinity");
  image[4321] = 3e38f;
  ExpectReadsTheFloats(image, 0, "a huge value");
  ExpectReadsTheFloats(std::vector<float>(10, -0.0f), 1, "negative zeros");
  ExpectReadsTheFloats(std::vector<float>(10, 1e20f), 0, "a constant beyond int64");
  ExpectReadsTheFloats(std::vector<float>(1, 5.0f), 1, "one voxel");
  const PixelSource none(nullptr, 0);
  EXPECT_EQ(none.BytesPerVoxel(), 0u);
}

/** A row's sums, as the least squares read them, against adding each voxel's double in order: the same
 * bits, on the copy (integer sums; offsets of either sign, 0, and one too large for them) and on floats. */
TEST(PixelSource, RowSumsAreTheVoxelByVoxelSums)
{
  const std::size_t n = 3000;
  for (const double lowest : { 0.0, -1024.0, 37.0, -1048000.0, 3.0e6, 1.5 })
  {
    const std::vector<float> image = Integers(lowest, lowest == 1.5 ? 300.0 : 255.0, n);
    const PixelSource        source(image.data(), image.size());
    std::mt19937             random(11);
    std::size_t              differ = 0;
    source.Visit([&](const auto * row) {
      for (int trial = 0; trial < 2000; ++trial)
      {
        const int32_t x0 = int32_t(random() % n);
        const int32_t x1 = std::min<int32_t>(int32_t(n) - 1, x0 + int32_t(random() % (trial < 1000 ? 16 : 2500)));
        double        sumI = 0.0, sumUI = 0.0;
        for (int32_t x = x0; x <= x1; ++x)
        {
          sumI += double(image[std::size_t(x)]);
          sumUI += double(x - x0) * double(image[std::size_t(x)]);
        }
        double rowI = -1.0, rowUI = -1.0;
        source.RowSums(row, x0, x1, rowI, rowUI);
        differ +=
          std::memcmp(&rowI, &sumI, sizeof(double)) == 0 && std::memcmp(&rowUI, &sumUI, sizeof(double)) == 0 ? 0 : 1;
      }
    });
    EXPECT_EQ(differ, 0u) << "smallest value " << lowest << ", " << source.BytesPerVoxel() << " byte(s) a voxel";
  }
}


/** The passes over the voxels before the encoder's first point, on every thread: std::minmax_element's
 * values (the first smallest, the last largest: -0 against +0 decides the quantization origin's bits) and
 * std::count_if's count, whatever the threads, over several blocks and a short last one. */
TEST(Parallel, MinMaxAndCountAreTheSerialOnes)
{
  const std::size_t  n = 3 * dcv::PassBlock + 12345;
  std::mt19937       random(5);
  std::vector<float> data(n);
  for (auto & v : data)
    v = float(int(random() % 2001) - 1000);
  // The smallest ties across blocks as -0 and +0, where the first one's sign must show; the largest ties too.
  for (const float zero : { -0.0f, 0.0f })
  {
    std::vector<float> z(data.size());
    for (std::size_t i = 0; i < z.size(); ++i)
      z[i] = std::fabs(data[i]) + 1.0f;
    z[7] = zero;
    z[dcv::PassBlock + 3] = -zero;
    z[2 * dcv::PassBlock] = 2001.0f;
    z[n - 1] = 2001.0f;
    for (unsigned threads : { 1u, 2u, 3u })
    {
      const auto got = dcv::WithThreads(threads, [&] { return dcv::ParallelMinMax(z.data(), z.size()); });
      const auto want = std::minmax_element(z.begin(), z.end());
      EXPECT_EQ(std::signbit(got.first), std::signbit(*want.first)) << threads << " threads";
      EXPECT_EQ(got.first, *want.first);
      EXPECT_EQ(got.second, *want.second);
    }
  }
  data[n - 1] = -5000.0f;
  data[dcv::PassBlock] = 5000.0f;
  const auto got = dcv::ParallelMinMax(data.data(), n);
  EXPECT_EQ(got.first, -5000.0f);
  EXPECT_EQ(got.second, 5000.0f);
  const auto odd = [](float v) { return int(v) % 2 != 0; };
  EXPECT_EQ(dcv::ParallelCount(data.data(), n, odd), std::size_t(std::count_if(data.begin(), data.end(), odd)));
  EXPECT_EQ(dcv::ParallelCount(data.data(), 1, odd), std::size_t(odd(data[0])));
}

} // namespace
