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
// The bounded-error mode: the layer codes its samples without loss, and every file keeps its bound on every
// voxel, on random volumes of every pixel type and on the dev volumes.
#include "dcvBoundedLayer.h"
#include "dcvCodec.h"
#include "dcvTestUtilities.h"
#include "itkDCVEncoder.h"
#include "itkImageFileReader.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

namespace
{
using dcv::GridSize;

dcv::CompressedFile
Parse(const std::vector<uint8_t> & bytes, const std::string & name)
{
  dcv::CompressedFile file;
  file.name = name;
  file.size = bytes.size();
  dcv::ParseFile(bytes, name, file.header, file.payload);
  return file;
}

std::vector<int32_t>
RandomSamples(const GridSize & g, int64_t lo, int64_t hi, unsigned seed)
{
  std::mt19937_64                        random(seed);
  std::uniform_int_distribution<int64_t> value(lo, hi);
  std::vector<int32_t>                   s(g.NumberOfVoxels());
  for (auto & v : s)
    v = int32_t(value(random));
  return s;
}

/** Codes the samples within `near`: the decoder gives what the encoder left, each sample within `near`. */
void
ExpectLayerRoundTrip(const std::vector<int32_t> & s, const GridSize & g, uint32_t near = 0)
{
  auto       coded = s;
  const auto bytes = dcv::EncodeBoundedLayer(coded.data(), g, near, double(near));
  const auto decoded = dcv::DecodeBoundedLayer(bytes, g, "'layer'");
  ASSERT_EQ(decoded.size(), s.size());
  EXPECT_TRUE(std::equal(coded.begin(), coded.end(), decoded.begin()));
  int64_t worst = 0;
  for (std::size_t i = 0; i < s.size(); ++i)
    worst = std::max<int64_t>(worst, std::abs(int64_t(s[i]) - int64_t(decoded[i])));
  EXPECT_LE(worst, int64_t(near));
  if (near == 0)
    EXPECT_TRUE(std::equal(s.begin(), s.end(), decoded.begin()));
}

/** A random volume of pixel type T: noise over the whole type, a constant, a single bright voxel, or the
 * extremes of the type in a checkerboard. */
template <typename T>
typename itk::Image<T, 3>::Pointer
MakeImage(const GridSize & g, int kind, unsigned seed)
{
  auto                                image = itk::Image<T, 3>::New();
  typename itk::Image<T, 3>::SizeType size = { { std::size_t(g.x), std::size_t(g.y), std::size_t(g.z) } };
  image->SetRegions(size);
  image->Allocate();
  const double    lo = std::is_floating_point<T>::value ? -1000.0 : double(std::numeric_limits<T>::lowest());
  const double    hi = std::is_floating_point<T>::value ? 1000.0 : double(std::numeric_limits<T>::max());
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  T *                                    p = image->GetBufferPointer();
  for (uint64_t i = 0; i < g.NumberOfVoxels(); ++i)
  {
    double v = 0.0;
    if (kind == 0)
      v = lo + (hi - lo) * unit(random);
    else if (kind == 1)
      v = std::is_floating_point<T>::value ? 12.5 : std::floor(lo / 2 + hi / 2);
    else if (kind == 2)
      v = i == g.NumberOfVoxels() / 2 ? hi : lo;
    else
      v = ((i + i / g.x + i / (uint64_t(g.x) * g.y)) % 2) ? hi : lo;
    p[i] = std::is_floating_point<T>::value ? T(v) : T(std::floor(v));
  }
  return image;
}

template <typename T>
void
ExpectBoundHolds(const GridSize & g, double bound)
{
  for (int kind = 0; kind < 4; ++kind)
  {
    auto                image = MakeImage<T>(g, kind, 7u + unsigned(kind));
    dcv::EncoderOptions options;
    options.maximumError = bound;
    const auto r = itk::DCVEncode(image.GetPointer(), options);
    const auto file = Parse(r.bytes, "'bounded.dcv'");
    EXPECT_TRUE(file.header.boundedLayer);
    std::vector<T> decoded(g.NumberOfVoxels());
    dcv::DecodeVolume(file, decoded.data());
    const T * input = image->GetBufferPointer();
    double    worst = 0.0;
    for (uint64_t i = 0; i < decoded.size(); ++i)
      worst = std::max(worst, std::abs(double(decoded[i]) - double(input[i])));
    const double kept = std::is_floating_point<T>::value ? bound : std::floor(bound);
    EXPECT_LE(worst, kept) << dcv::PixelTypeName(dcv::PixelTypeOf<T>()) << " kind " << kind << " bound " << bound;
    EXPECT_EQ(r.maximumError, kept);
    EXPECT_EQ(dcv::ReadBoundedLayerHeader(file.header.residualLayer, g, "'bounded.dcv'").maximumError, kept);
  }
}
} // namespace

TEST(BoundedLayer, CodesEverySampleRangeWithoutLoss)
{
  const GridSize g{ 17, 13, 11 };
  ExpectLayerRoundTrip(RandomSamples(g, 0, 255, 1), g);
  ExpectLayerRoundTrip(RandomSamples(g, -1024, 3071, 2), g);
  ExpectLayerRoundTrip(RandomSamples(g, 5, 5, 3), g); // constant
  // The widest range the samples allow: the residuals wrap around it.
  ExpectLayerRoundTrip(
    RandomSamples(g, std::numeric_limits<int32_t>::min() + 1, std::numeric_limits<int32_t>::max(), 4), g);
  std::vector<int32_t> extremes(g.NumberOfVoxels());
  for (std::size_t i = 0; i < extremes.size(); ++i)
    extremes[i] = (i % 3) ? std::numeric_limits<int32_t>::max() : std::numeric_limits<int32_t>::min();
  ExpectLayerRoundTrip(extremes, g);
  const GridSize tiny{ 2, 2, 2 };
  ExpectLayerRoundTrip(RandomSamples(tiny, 0, 1, 5), tiny);
}

TEST(BoundedLayer, KeepsEverySampleWithinItsBound)
{
  const GridSize g{ 17, 13, 11 };
  for (uint32_t near : { 1u, 2u, 7u, 100u, 1000000u })
  {
    ExpectLayerRoundTrip(RandomSamples(g, 0, 255, 11), g, near);
    ExpectLayerRoundTrip(RandomSamples(g, -1024, 3071, 12), g, near);
    ExpectLayerRoundTrip(
      RandomSamples(g, std::numeric_limits<int32_t>::min() + 1, std::numeric_limits<int32_t>::max(), 13), g, near);
  }
}

TEST(BoundedLayer, SlabsAreIndependentAndTheFileTheSameWhateverTheThreads)
{
  // 512 x 512 slices: slabs of 16 slices, so 20 slices make two slabs, coded on two threads or one.
  const GridSize g{ 512, 512, 20 };
  ASSERT_EQ(dcv::BoundedLayerSlabSlices(g), 16u);
  std::vector<int32_t> s(g.NumberOfVoxels());
  for (uint64_t i = 0; i < s.size(); ++i)
    s[i] = int32_t((i * 2654435761u) % 97 + (i / 512) % 50);
  std::vector<uint8_t> one, two;
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
    auto                coded = s;
    one = dcv::EncodeBoundedLayer(coded.data(), g, 0, 0.0);
  }
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
    auto                coded = s;
    two = dcv::EncodeBoundedLayer(coded.data(), g, 0, 0.0);
  }
  EXPECT_EQ(one, two);
  const auto decoded = dcv::DecodeBoundedLayer(one, g, "'layer'");
  EXPECT_TRUE(std::equal(s.begin(), s.end(), decoded.begin()));
}

TEST(BoundedLayer, DamagedLayersAreRefusedByName)
{
  const GridSize g{ 24, 20, 18 };
  auto           s = RandomSamples(g, 0, 4095, 9);
  const auto     bytes = dcv::EncodeBoundedLayer(s.data(), g, 0, 0.0);
  auto           expectRefused = [&](std::vector<uint8_t> damaged, const std::string & what) {
    try
    {
      dcv::DecodeBoundedLayer(damaged, g, "'damaged.dcv'");
      ADD_FAILURE() << what << ": not refused";
    }
    catch (const dcv::FormatError & e)
    {
      EXPECT_NE(std::string(e.what()).find("'damaged.dcv'"), std::string::npos) << e.what();
    }
  };
  expectRefused({ bytes.begin(), bytes.begin() + 10 }, "header cut");
  expectRefused({ bytes.begin(), bytes.end() - 1 }, "last byte cut");
  auto longer = bytes;
  longer.push_back(0);
  expectRefused(longer, "a trailing byte");
  auto slabs = bytes;
  slabs[16] ^= 1; // the slab size
  expectRefused(slabs, "another slab size");
  auto         bound = bytes;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::memcpy(bound.data(), &nan, 8);
  expectRefused(bound, "a NaN bound");
  // Any flipped byte of the coded slab decodes to some samples or is refused, never beyond the buffer.
  for (std::size_t i = 28; i < bytes.size(); i += 97)
  {
    auto flipped = bytes;
    flipped[i] ^= 0x5A;
    try
    {
      dcv::DecodeBoundedLayer(flipped, g, "'damaged.dcv'");
    }
    catch (const dcv::FormatError &)
    {}
  }
}

TEST(BoundedError, EveryPixelTypeKeepsItsBound)
{
  const GridSize g{ 19, 14, 12 };
  for (double e : { 0.0, 1.0, 2.5, 10.0 })
  {
    ExpectBoundHolds<uint8_t>(g, e);
    ExpectBoundHolds<int8_t>(g, e);
    ExpectBoundHolds<uint16_t>(g, e);
    ExpectBoundHolds<int16_t>(g, e);
    ExpectBoundHolds<uint32_t>(g, e);
    ExpectBoundHolds<int32_t>(g, e);
  }
  for (double e : { 1e-3, 0.5, 7.0 })
  {
    ExpectBoundHolds<float>(g, e);
    ExpectBoundHolds<double>(g, e);
  }
}

TEST(BoundedError, LosslessIsBitForBitAndSmallerThanTheVolume)
{
  const auto          image = dcv::test::PhantomImage({ 40, 36, 32 });
  dcv::EncoderOptions options;
  options.maximumError = 0.0;
  const auto r = itk::DCVEncode(image.GetPointer(), options);
  EXPECT_TRUE(std::isinf(r.psnr));
  EXPECT_LT(r.bytes.size(), 40u * 36u * 32u / 4u); // a phantom is mostly flat: under 2 bits a voxel
  const auto           file = Parse(r.bytes, "'phantom.dcv'");
  std::vector<uint8_t> decoded(40 * 36 * 32);
  dcv::DecodeVolume(file, decoded.data());
  EXPECT_TRUE(std::equal(decoded.begin(), decoded.end(), image->GetBufferPointer()));
}

TEST(BoundedError, BadBoundsAreRefused)
{
  const auto          image = dcv::test::PhantomImage({ 16, 16, 16 });
  dcv::EncoderOptions options;
  options.maximumError = 1.0;
  options.bitsPerVoxel = 0.5;
  EXPECT_THROW(itk::DCVEncode(image.GetPointer(), options), std::invalid_argument);
  options.bitsPerVoxel = 0.0;
  options.maximumError = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(itk::DCVEncode(image.GetPointer(), options), std::invalid_argument);
  // Below the precision of float32 values near 1000.
  auto floats = MakeImage<float>({ 8, 8, 8 }, 0, 3);
  options.maximumError = 1e-30;
  try
  {
    itk::DCVEncode(floats.GetPointer(), options);
    ADD_FAILURE() << "a bound below float32's precision was accepted";
  }
  catch (const std::invalid_argument & e)
  {
    EXPECT_NE(std::string(e.what()).find("at least"), std::string::npos) << e.what();
  }
}

class BoundedDevVolumes : public ::testing::TestWithParam<std::string>
{};

TEST_P(BoundedDevVolumes, KeepTheBoundOnEveryVoxel)
{
  const std::string name = GetParam();
  DCV_REQUIRE_DATA(name);
  using ImageType = itk::Image<int16_t, 3>; // every dev volume's values fit int16
  auto reader = itk::ImageFileReader<ImageType>::New();
  reader->SetFileName(dcv::test::DataFile(name));
  reader->Update();
  ImageType::Pointer image = reader->GetOutput();
  for (double e : { 0.0, 2.0 })
  {
    dcv::EncoderOptions options;
    options.maximumError = e;
    const auto           r = itk::DCVEncode(image.GetPointer(), options);
    const auto           file = Parse(r.bytes, "'" + name + ".dcv'");
    std::vector<int16_t> decoded(file.header.size.NumberOfVoxels());
    dcv::DecodeVolume(file, decoded.data());
    const int16_t * input = image->GetBufferPointer();
    int             worst = 0;
    for (std::size_t i = 0; i < decoded.size(); ++i)
      worst = std::max(worst, std::abs(int(decoded[i]) - int(input[i])));
    EXPECT_LE(worst, int(e)) << name;
    if (e == 0.0)
      EXPECT_EQ(worst, 0) << name;
  }
}

INSTANTIATE_TEST_SUITE_P(DevVolumes, BoundedDevVolumes,
                         ::testing::Values("head-mr.nrrd", "headsq-ct.nrrd", "ironprot.nrrd", "neghip.nrrd",
                                           "avg152t1.nrrd", "flair-mr.nrrd", "ct-avm.nrrd", "ct-avm-4mm.nrrd",
                                           "norm-256.nrrd"),
                         [](const auto & info) {
                           std::string n = info.param.substr(0, info.param.find('.'));
                           std::replace(n.begin(), n.end(), '-', '_');
                           return n;
                         });
