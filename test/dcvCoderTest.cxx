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
// The entropy coder of the .dcv format: arithmetic coder, integer codes, point positions.
#include "dcvArithmeticCoder.h"
#include "dcvPositionCoder.h"
#include "dcvRefinementEngine.h"
#include "dcvTestUtilities.h"

#include <chrono>
#include <cmath>
#include <iostream>
#include <limits>
#include <set>

namespace
{
using namespace dcv;

double
Log2Binomial(double N, double n)
{
  return (std::lgamma(N + 1) - std::lgamma(n + 1) - std::lgamma(N - n + 1)) / std::log(2.0);
}

std::vector<uint8_t>
EncodeToBytes(const GridSize & grid, const std::vector<GridPoint> & points)
{
  std::vector<uint8_t> bytes;
  ArithmeticEncoder    encoder(bytes);
  EncodePositions(encoder, grid, points);
  encoder.Finish();
  return bytes;
}

/** Encodes, decodes and checks the decoded points are the input in coding order, and that the
 * decoder read exactly the stream. Returns the stream size in bytes. */
std::size_t
CheckPositionRoundTrip(const GridSize & grid, const std::vector<GridPoint> & points)
{
  const std::vector<uint8_t> bytes = EncodeToBytes(grid, points);
  ArithmeticDecoder          decoder(bytes.data(), bytes.size());
  const auto                 decoded = DecodePositions(decoder, grid, uint32_t(points.size()));
  std::vector<GridPoint>     expected = points;
  SortPositions(grid, expected);
  EXPECT_EQ(decoded, expected) << grid.x << "x" << grid.y << "x" << grid.z << ", " << points.size() << " points";
  EXPECT_FALSE(decoder.Overrun());
  EXPECT_EQ(decoder.GetPosition(), bytes.size());
  // Coding order is a permutation of the input.
  std::set<GridPoint> a(points.begin(), points.end()), b(expected.begin(), expected.end());
  EXPECT_EQ(a, b);
  return bytes.size();
}

/** Every voxel of the grid with probability `density`. */
std::vector<GridPoint>
BernoulliPoints(const GridSize & grid, double density, unsigned seed)
{
  std::mt19937                           random(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<GridPoint>                 out;
  for (int32_t z = 0; z < grid.z; ++z)
    for (int32_t y = 0; y < grid.y; ++y)
      for (int32_t x = 0; x < grid.x; ++x)
        if (u(random) < density)
          out.push_back({ x, y, z });
  std::shuffle(out.begin(), out.end(), random);
  return out;
}

TEST(ArithmeticCoder, RandomBitsRoundTripNearTheEntropy)
{
  const std::vector<double> probabilities{ 0.5, 0.7, 0.9, 0.99, 0.999, 0.01, 0.0001, 1.0, 0.0 };
  for (double p1 : probabilities)
  {
    std::mt19937                random(12345);
    std::bernoulli_distribution bit(p1);
    std::vector<int>            bits(100000);
    for (int & b : bits)
      b = bit(random);
    for (int shift : { 4, 5, 7 })
    {
      std::vector<uint8_t> bytes{ 0xAB, 0xCD }; // a header already there: the coder appends
      {
        ArithmeticEncoder encoder(bytes);
        BitModel          model(shift);
        for (int b : bits)
          encoder.Encode(model, b);
        encoder.Finish();
        encoder.Finish(); // idempotent
      }
      ArithmeticDecoder decoder(bytes.data() + 2, bytes.size() - 2);
      BitModel          model(shift);
      for (std::size_t i = 0; i < bits.size(); ++i)
      {
        ASSERT_EQ(decoder.Decode(model), bits[i]) << "p1 " << p1 << " bit " << i;
      }
      EXPECT_FALSE(decoder.Overrun());
      EXPECT_EQ(decoder.GetPosition(), bytes.size() - 2);
      // Size against the empirical entropy (p = 0 or 1 cost the floor of the adaptive model). A
      // model adapting by 2^-shift pays for its noise, more on skewed bits and small shifts.
      const double ones = double(std::count(bits.begin(), bits.end(), 1)), n = double(bits.size());
      const double q = ones / n;
      const double entropy = (q > 0 && q < 1) ? -n * (q * std::log2(q) + (1 - q) * std::log2(1 - q)) : 0.0;
      const double factor = shift == 4 ? 1.35 : shift == 5 ? 1.2 : 1.05;
      const double floor = 1.5 * double(1 << shift) / 65536.0; // bits per bit at p = 0 or 1
      EXPECT_LE(8.0 * double(bytes.size() - 2), factor * entropy + floor * n + 64) << "p1 " << p1 << " shift " << shift;
    }
  }
}

TEST(ArithmeticCoder, InterleavedModelsAndEquiprobableValues)
{
  std::mt19937                       random(7);
  const int                          count = 50000;
  std::vector<int>                   kind(count), bits(count), widths(count);
  std::vector<uint32_t>              values(count);
  std::uniform_int_distribution<int> width(0, 32);
  for (int i = 0; i < count; ++i)
  {
    kind[i] = int(random() % 4); // model 0..2, or equiprobable
    bits[i] = int(random() % 100 < (kind[i] == 0 ? 3 : kind[i] == 1 ? 50 : 97));
    widths[i] = width(random);
    values[i] = widths[i] == 32 ? uint32_t(random()) : uint32_t(random()) & ((1u << widths[i]) - 1u);
  }
  values[0] = 0xFFFFFFFFu;
  widths[0] = 32;
  kind[0] = 3;
  std::vector<uint8_t> bytes;
  {
    ArithmeticEncoder       encoder(bytes);
    std::array<BitModel, 3> models{ BitModel(4), BitModel(5), BitModel(7) };
    for (int i = 0; i < count; ++i)
    {
      if (kind[i] == 3)
        encoder.EncodeEquiprobable(values[i], widths[i]);
      else
        encoder.Encode(models[kind[i]], bits[i]);
    }
    encoder.Finish();
    EXPECT_NEAR(encoder.GetBitCount(), 8.0 * bytes.size(), 0.5);
  }
  ArithmeticDecoder       decoder(bytes.data(), bytes.size());
  std::array<BitModel, 3> models{ BitModel(4), BitModel(5), BitModel(7) };
  for (int i = 0; i < count; ++i)
  {
    if (kind[i] == 3)
      ASSERT_EQ(decoder.DecodeEquiprobable(widths[i]), values[i]) << i;
    else
      ASSERT_EQ(decoder.Decode(models[kind[i]]), bits[i]) << i;
  }
  EXPECT_FALSE(decoder.Overrun());
  EXPECT_EQ(decoder.GetPosition(), bytes.size());
}

TEST(ArithmeticCoder, EmptyStreamAndEmptyInput)
{
  std::vector<uint8_t> bytes;
  ArithmeticEncoder    encoder(bytes);
  encoder.Finish();
  EXPECT_EQ(bytes.size(), 4u);
  ArithmeticDecoder decoder(bytes.data(), bytes.size());
  EXPECT_FALSE(decoder.Overrun());
  ArithmeticDecoder nothing(nullptr, 0); // reads zeros, flags the overrun, does not crash
  BitModel          model;
  nothing.Decode(model);
  nothing.DecodeEquiprobable(32);
  EXPECT_TRUE(nothing.Overrun());
}

TEST(ArithmeticCoder, IntegersOfAllMagnitudes)
{
  std::vector<uint32_t> unsignedValues{ 0,   1,   2,     3,     4,           5,           7,           8,          100,
                                        255, 256, 65535, 65536, 0x7FFFFFFFu, 0x80000000u, 0xFFFFFFFEu, 0xFFFFFFFFu };
  for (int b = 0; b < 32; ++b)
  {
    unsignedValues.push_back(1u << b);
    unsignedValues.push_back((1u << b) - 1u);
    unsignedValues.push_back((1u << b) + 1u);
  }
  std::vector<int32_t> signedValues{ 0,
                                     1,
                                     -1,
                                     2,
                                     -2,
                                     1000,
                                     -1000,
                                     std::numeric_limits<int32_t>::max(),
                                     std::numeric_limits<int32_t>::min(),
                                     std::numeric_limits<int32_t>::min() + 1 };
  std::mt19937         random(99);
  for (int i = 0; i < 20000; ++i)
  {
    const int      bits = int(random() % 33);
    const uint32_t v = bits == 0 ? 0u : uint32_t(random()) >> (32 - bits);
    unsignedValues.push_back(v);
    signedValues.push_back(int32_t(v));
    signedValues.push_back(int32_t(random() % 7) - 3); // many small ones
  }
  std::vector<uint8_t> bytes;
  {
    ArithmeticEncoder encoder(bytes);
    UIntModel         u;
    SIntModel         s;
    for (uint32_t v : unsignedValues)
      u.Encode(encoder, v);
    for (int32_t v : signedValues)
      s.Encode(encoder, v);
    encoder.Finish();
  }
  ArithmeticDecoder decoder(bytes.data(), bytes.size());
  UIntModel         u;
  SIntModel         s;
  for (uint32_t v : unsignedValues)
    ASSERT_EQ(u.Decode(decoder), v);
  for (int32_t v : signedValues)
    ASSERT_EQ(s.Decode(decoder), v);
  EXPECT_FALSE(decoder.Overrun());
  EXPECT_EQ(decoder.GetPosition(), bytes.size());

  // Small values cost little once learned.
  std::vector<uint8_t> zeros;
  {
    ArithmeticEncoder encoder(zeros);
    UIntModel         model;
    for (int i = 0; i < 10000; ++i)
      model.Encode(encoder, 0);
    encoder.Finish();
  }
  EXPECT_LT(zeros.size(), 40u);
}

TEST(ArithmeticCoder, TruncatedIntegerStreamsAreDetected)
{
  std::vector<int32_t> values;
  std::mt19937         random(5);
  for (int i = 0; i < 300; ++i)
    values.push_back(int32_t(random()) >> int(random() % 31));
  std::vector<uint8_t> bytes;
  {
    ArithmeticEncoder encoder(bytes);
    SIntModel         model;
    for (int32_t v : values)
      model.Encode(encoder, v);
    encoder.Finish();
  }
  for (std::size_t length = 0; length < bytes.size(); ++length)
  {
    const std::vector<uint8_t> prefix(bytes.begin(), bytes.begin() + std::ptrdiff_t(length));
    ArithmeticDecoder          decoder(prefix.data(), prefix.size());
    SIntModel                  model;
    bool                       same = true;
    for (int32_t v : values)
      same = (model.Decode(decoder) == v) && same;
    EXPECT_TRUE(decoder.Overrun() || !same) << "prefix " << length << " of " << bytes.size();
    EXPECT_LE(decoder.GetPosition(), prefix.size());
  }
}

TEST(PositionCoder, SmallBoxesEveryCase)
{
  // Every subset of the voxels of small boxes, including 1x1x1 and the 2x2x2 cube.
  for (const GridSize grid : { GridSize{ 1, 1, 1 },
                               GridSize{ 2, 1, 1 },
                               GridSize{ 1, 3, 1 },
                               GridSize{ 1, 1, 5 },
                               GridSize{ 2, 2, 2 },
                               GridSize{ 3, 2, 2 },
                               GridSize{ 1, 3, 4 } })
  {
    const uint32_t voxels = uint32_t(grid.NumberOfVoxels());
    for (uint32_t mask = 0; mask < (1u << voxels); ++mask)
    {
      std::vector<GridPoint> points;
      for (uint32_t v = 0; v < voxels; ++v)
        if (mask & (1u << v))
          points.push_back({ int32_t(v % grid.x), int32_t(v / grid.x % grid.y), int32_t(v / grid.x / grid.y) });
      CheckPositionRoundTrip(grid, points);
      if (HasFailure())
        return;
    }
  }
}

TEST(PositionCoder, EmptyFullAndDegenerateGrids)
{
  for (const GridSize grid : { GridSize{ 1, 1, 1 },
                               GridSize{ 17, 9, 4 },
                               GridSize{ 300, 2, 2 },
                               GridSize{ 1, 1, 1000 },
                               GridSize{ 2, 1000, 1 },
                               GridSize{ 64, 64, 64 } })
  {
    CheckPositionRoundTrip(grid, {});
    const auto full = BernoulliPoints(grid, 2.0, 1); // every voxel
    ASSERT_EQ(full.size(), grid.NumberOfVoxels());
    EXPECT_LE(CheckPositionRoundTrip(grid, full), 4u); // nothing but the flush
    CheckPositionRoundTrip(grid,
                           test::Corners(grid).size() <= grid.NumberOfVoxels() && grid.x > 1 && grid.y > 1 && grid.z > 1
                             ? test::Corners(grid)
                             : std::vector<GridPoint>{ { grid.x - 1, grid.y - 1, grid.z - 1 } });
  }
  // A grid with an empty axis holds no point.
  CheckPositionRoundTrip(GridSize{ 0, 5, 5 }, {});
  CheckPositionRoundTrip(GridSize{ 0, 0, 0 }, {});
}

TEST(PositionCoder, RandomSetsOfManyDensities)
{
  unsigned seed = 1;
  for (const GridSize grid : { GridSize{ 300, 2, 2 },
                               GridSize{ 2, 3, 300 },
                               GridSize{ 31, 17, 9 },
                               GridSize{ 64, 64, 64 },
                               GridSize{ 5, 200, 7 } })
  {
    for (double density : { 0.0005, 0.003, 0.02, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 0.9995 })
    {
      const auto   points = BernoulliPoints(grid, density, seed++);
      const double bits = 8.0 * double(CheckPositionRoundTrip(grid, points));
      // Near log2 C(N, n) for random sets: adaptive models cost a little, plus the 4-byte flush.
      const double bound = Log2Binomial(double(grid.NumberOfVoxels()), double(points.size()));
      EXPECT_LE(bits, 1.12 * bound + 64 + 2.0 * std::sqrt(double(points.size())))
        << grid.x << "x" << grid.y << "x" << grid.z << " density " << density;
    }
  }
  // The corners plus random points, the shape of a real point set.
  const GridSize grid{ 120, 90, 60 };
  CheckPositionRoundTrip(grid, test::RandomPoints(grid, 5000, 3));
}

TEST(PositionCoder, PointsOnTheFacesAndClusters)
{
  const GridSize         grid{ 40, 33, 21 };
  std::vector<GridPoint> faces;
  for (int32_t z = 0; z < grid.z; ++z)
    for (int32_t y = 0; y < grid.y; ++y)
      for (int32_t x = 0; x < grid.x; ++x)
        if (x == 0 || y == 0 || z == 0 || x == grid.x - 1 || y == grid.y - 1 || z == grid.z - 1)
          if ((x + 2 * y + 3 * z) % 3 == 0)
            faces.push_back({ x, y, z });
  CheckPositionRoundTrip(grid, faces);
  // A dense ball in a large empty box: clustered sets cost far less than log2 C(N, n).
  const GridSize         big{ 512, 512, 512 };
  std::vector<GridPoint> ball;
  for (int32_t z = -8; z <= 8; ++z)
    for (int32_t y = -8; y <= 8; ++y)
      for (int32_t x = -8; x <= 8; ++x)
        if (x * x + y * y + z * z <= 64 && (x + y + z) % 2 == 0)
          ball.push_back({ 300 + x, 100 + y, 50 + z });
  const double bits = 8.0 * double(CheckPositionRoundTrip(big, ball));
  EXPECT_LT(bits, 0.5 * Log2Binomial(double(big.NumberOfVoxels()), double(ball.size())));
}

TEST(PositionCoder, DeterministicAndIndependentOfTheInputOrder)
{
  const GridSize grid{ 50, 40, 30 };
  auto           points = test::RandomPoints(grid, 2000, 11);
  const auto     first = EncodeToBytes(grid, points);
  EXPECT_EQ(EncodeToBytes(grid, points), first);
  std::mt19937 random(3);
  std::shuffle(points.begin(), points.end(), random);
  EXPECT_EQ(EncodeToBytes(grid, points), first);
  SortPositions(grid, points);
  EXPECT_EQ(EncodeToBytes(grid, points), first);
}

TEST(PositionCoder, InvalidInputThrows)
{
  const GridSize       grid{ 10, 10, 10 };
  std::vector<uint8_t> bytes;
  ArithmeticEncoder    encoder(bytes);
  EXPECT_THROW(EncodePositions(encoder, grid, { { 10, 0, 0 } }), std::invalid_argument);
  EXPECT_THROW(EncodePositions(encoder, grid, { { 0, -1, 0 } }), std::invalid_argument);
  EXPECT_THROW(EncodePositions(encoder, grid, { { 1, 2, 3 }, { 4, 5, 6 }, { 1, 2, 3 } }), std::invalid_argument);
  ArithmeticDecoder decoder(bytes.data(), bytes.size());
  EXPECT_THROW(DecodePositions(decoder, grid, 1001), std::invalid_argument);
}

TEST(PositionCoder, TruncatedStreamsAreDetectedWithoutCrashing)
{
  const GridSize         grid{ 40, 30, 20 };
  const auto             points = test::RandomPoints(grid, 300, 21);
  const auto             bytes = EncodeToBytes(grid, points);
  std::vector<GridPoint> expected = points;
  SortPositions(grid, expected);
  for (std::size_t length = 0; length < bytes.size(); ++length)
  {
    // A copy of exactly `length` bytes, so that a read past it would be caught by sanitizers.
    const std::unique_ptr<uint8_t[]> prefix(new uint8_t[std::max<std::size_t>(length, 1)]);
    std::copy(bytes.begin(), bytes.begin() + std::ptrdiff_t(length), prefix.get());
    ArithmeticDecoder decoder(prefix.get(), length);
    const auto        decoded = DecodePositions(decoder, grid, uint32_t(points.size()));
    EXPECT_TRUE(decoder.Overrun() || decoded != expected) << "prefix " << length << " of " << bytes.size();
    EXPECT_LE(decoder.GetPosition(), length);
    // Whatever the stream, the result is distinct points of the grid: `count` of them, or fewer where
    // the decoder stopped at the end of the stream (an overrun: no more work for garbage).
    if (!decoder.Overrun())
      ASSERT_EQ(decoded.size(), points.size());
    ASSERT_LE(decoded.size(), points.size());
    std::set<GridPoint> distinct(decoded.begin(), decoded.end());
    EXPECT_EQ(distinct.size(), decoded.size());
    for (const GridPoint & p : decoded)
      ASSERT_TRUE(p[0] >= 0 && p[1] >= 0 && p[2] >= 0 && p[0] < grid.x && p[1] < grid.y && p[2] < grid.z);
  }
}

TEST(PositionCoder, GarbageDecodesToValidPoints)
{
  std::mt19937 random(77);
  for (int trial = 0; trial < 200; ++trial)
  {
    const GridSize       grid{ int32_t(1 + random() % 60), int32_t(1 + random() % 60), int32_t(1 + random() % 60) };
    std::vector<uint8_t> garbage(random() % 300);
    for (auto & b : garbage)
      b = uint8_t(trial % 3 == 0 ? 0xFF : random());
    const uint32_t    count = uint32_t(random() % (grid.NumberOfVoxels() + 1));
    ArithmeticDecoder decoder(garbage.data(), garbage.size());
    const auto        decoded = DecodePositions(decoder, grid, count);
    // `count` points, or fewer when the garbage ran out first (decoding stops there).
    if (!decoder.Overrun())
      ASSERT_EQ(decoded.size(), count);
    ASSERT_LE(decoded.size(), count);
    std::set<GridPoint> distinct(decoded.begin(), decoded.end());
    EXPECT_EQ(distinct.size(), decoded.size());
    for (const GridPoint & p : decoded)
      ASSERT_TRUE(p[0] >= 0 && p[1] >= 0 && p[2] >= 0 && p[0] < grid.x && p[1] < grid.y && p[2] < grid.z);
  }
}

/** Real point sets (silva refinement to voxels / 600 points) cluster: they must cost less than
 * log2 C(N, n), the cost of a uniformly random set of the same size. */
void
CheckRealPointSet(const std::string & name)
{
  const test::Volume volume = test::ReadVolume(name);
  RefinementEngine   engine(volume.voxels.data(), volume.grid);
  engine.Refine(volume.grid.NumberOfVoxels() / 600);
  const auto points = engine.GetApproximation().points;

  const auto             t0 = std::chrono::steady_clock::now();
  const auto             bytes = EncodeToBytes(volume.grid, points);
  const auto             t1 = std::chrono::steady_clock::now();
  ArithmeticDecoder      decoder(bytes.data(), bytes.size());
  const auto             decoded = DecodePositions(decoder, volume.grid, uint32_t(points.size()));
  const auto             t2 = std::chrono::steady_clock::now();
  std::vector<GridPoint> expected = points;
  SortPositions(volume.grid, expected);
  EXPECT_EQ(decoded, expected);
  EXPECT_FALSE(decoder.Overrun());

  const double n = double(points.size());
  const double bitsPerPoint = 8.0 * double(bytes.size()) / n;
  const double bound = Log2Binomial(double(volume.grid.NumberOfVoxels()), n) / n;
  const auto   random = test::RandomPoints(volume.grid, points.size() - 8, 1);
  const double randomBitsPerPoint = 8.0 * double(EncodeToBytes(volume.grid, random).size()) / n;
  std::cout << name << ": " << points.size() << " points, " << bitsPerPoint
            << " bits/point (random set: " << randomBitsPerPoint << "), log2 C(N, n) / n = " << bound << "; encode "
            << std::chrono::duration<double, std::milli>(t1 - t0).count() << " ms, decode "
            << std::chrono::duration<double, std::milli>(t2 - t1).count() << " ms" << std::endl;
  EXPECT_LT(bitsPerPoint, bound) << name;
  EXPECT_LT(randomBitsPerPoint, 1.05 * bound) << name;
}

TEST(PositionCoder, RealPointSetsCostLessThanRandomOnes)
{
  for (const char * name : { "head-mr.nrrd", "flair-mr.nrrd", "norm-256.nrrd" })
  {
    DCV_REQUIRE_DATA(name);
    CheckRealPointSet(name);
  }
}

} // namespace
