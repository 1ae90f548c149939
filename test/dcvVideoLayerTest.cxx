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
// The video layer: HEVC and AV1 streams of 8, 10 and 12 bits code and decode the slices of any size, the
// same stream whatever the threads; damaged streams are refused by name; the encoder keeps the layer only
// where it decodes closest, the file decodes to exactly what it reported, and the container refuses the
// form bits it cannot hold.
#include "dcvCodec.h"
#include "dcvParallel.h"
#include "dcvRateControl.h"
#include "dcvTestUtilities.h"
#include "dcvVideoLayer.h"
#include "itkDCVEncoder.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>
#include <zlib.h>

namespace
{
using dcv::GridSize;

/** Smooth slices with a little noise, 0 to `top`. */
std::vector<uint16_t>
Slices(const GridSize & g, int top, unsigned seed)
{
  std::mt19937          random(seed);
  std::vector<uint16_t> s(g.NumberOfVoxels());
  for (int32_t z = 0; z < g.z; ++z)
    for (int32_t y = 0; y < g.y; ++y)
      for (int32_t x = 0; x < g.x; ++x)
      {
        const double v =
          0.5 * top * (1.0 + 0.8 * std::sin(0.2 * x + 0.3 * z) * std::cos(0.15 * y)) + double(random() % 5) - 2.0;
        s[g.Offset(x, y, z)] = uint16_t(std::clamp(v, 0.0, double(top)));
      }
  return s;
}

double
PSNR(const std::vector<uint16_t> & a, const dcv::ResidualSamples & b, double peak)
{
  double e = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i)
    e += (double(a[i]) - double(b[i])) * (double(a[i]) - double(b[i]));
  return dcv::PSNR(e, a.size(), peak);
}

/** Each codec's tests run for both. */
class VideoCodecs : public ::testing::TestWithParam<dcv::VideoCodec>
{
protected:
  /** A quality of the codec's scale given as one of x265's rate factors (libaom's levels run to 63). */
  double
  Quality(double crf) const
  {
    return GetParam() == dcv::VideoCodec::AV1 ? std::round(crf * 63.0 / 51.0) : crf;
  }
  std::vector<uint8_t>
  Encode(const std::vector<uint16_t> & s, const GridSize & g, int32_t depth, double crf) const
  {
    return dcv::EncodeVideoLayer(GetParam(), s, g, depth, crf == dcv::VideoLossless ? crf : Quality(crf));
  }
  dcv::ResidualSamples
  Decode(const std::vector<uint8_t> & stream, const GridSize & g) const
  {
    return dcv::DecodeVideoLayer(GetParam(), stream, g, "'v.dcv'");
  }
};

/** Thick CT-like slices (int16, 5 mm over 0.5 mm pixels): texture that changes from slice to slice. */
itk::Image<int16_t, 3>::Pointer
ThickSlices(const GridSize & g)
{
  auto image = itk::Image<int16_t, 3>::New();
  image->SetRegions(itk::Size<3>{ { std::size_t(g.x), std::size_t(g.y), std::size_t(g.z) } });
  image->Allocate();
  int16_t * v = image->GetBufferPointer();
  for (int32_t z = 0; z < g.z; ++z)
    for (int32_t y = 0; y < g.y; ++y)
      for (int32_t x = 0; x < g.x; ++x)
      {
        const double r = std::hypot(x - 0.5 * g.x, y - 0.5 * g.y);
        const double inside = r < 0.4 * g.x ? 1.0 : 0.0;
        v[g.Offset(x, y, z)] =
          int16_t(std::lround(-1000.0 + inside * (1040.0 + 60.0 * std::sin(0.3 * x + 0.2 * z) * std::cos(0.25 * y))));
      }
  itk::Image<int16_t, 3>::SpacingType spacing;
  spacing[0] = spacing[1] = 0.5;
  spacing[2] = 5.0;
  image->SetSpacing(spacing);
  return image;
}
} // namespace

TEST(VideoLayer, DepthAndStep)
{
  EXPECT_EQ(dcv::VideoDepth(0.0), 8);
  EXPECT_EQ(dcv::VideoDepth(255.0), 8);
  EXPECT_EQ(dcv::VideoDepth(256.0), 10);
  EXPECT_EQ(dcv::VideoDepth(1023.0), 10);
  EXPECT_EQ(dcv::VideoDepth(4095.0), 12);
  EXPECT_EQ(dcv::VideoDepth(4096.0), 0);
  EXPECT_EQ(dcv::VideoStep(4095.0, true), 1.0);
  EXPECT_EQ(dcv::VideoStep(4096.0, true), 2.0);
  EXPECT_EQ(dcv::VideoStep(65535.0, true), 17.0);
  EXPECT_DOUBLE_EQ(dcv::VideoStep(8190.0, false), 2.0);
  EXPECT_DOUBLE_EQ(dcv::VideoStep(1.0, false), 1.0 / 4095.0);
}

// Every depth, and slices smaller than a coding tree unit, of odd sizes, and the 48 x 64 slices on which
// Debian's x265 aborts unless the pictures are whole coding tree units.
TEST_P(VideoCodecs, CodesAndDecodesEveryDepthAndSize)
{
  for (const GridSize g : { GridSize{ 40, 36, 6 }, GridSize{ 17, 23, 5 }, GridSize{ 48, 64, 4 }, GridSize{ 2, 2, 2 } })
    for (int32_t depth : { 8, 10, 12 })
    {
      const int                   top = (1 << depth) - 1;
      const std::vector<uint16_t> s = Slices(g, top, unsigned(depth));
      const std::vector<uint8_t>  stream = Encode(s, g, depth, 12.0);
      ASSERT_FALSE(stream.empty());
      const dcv::ResidualSamples decoded = Decode(stream, g);
      ASSERT_EQ(decoded.size(), s.size());
      EXPECT_GT(PSNR(s, decoded, top), 38.0) << g.x << "x" << g.y << "x" << g.z << ", " << depth << " bits";
      for (int32_t v : decoded)
        ASSERT_TRUE(v >= 0 && v <= top);
      // A larger rate factor: a smaller stream, decoded farther.
      const std::vector<uint8_t> small = Encode(s, g, depth, 40.0);
      EXPECT_LT(small.size(), stream.size());
      EXPECT_LT(PSNR(s, Decode(small, g), top), PSNR(s, decoded, top));
      // Lossless: exactly the samples.
      const dcv::ResidualSamples exact = Decode(Encode(s, g, depth, dcv::VideoLossless), g);
      EXPECT_TRUE(std::equal(s.begin(), s.end(), exact.begin()));
    }
}

TEST_P(VideoCodecs, SameStreamWhateverTheNumberOfThreads)
{
  const GridSize              g{ 96, 80, 24 };
  const std::vector<uint16_t> s = Slices(g, 1000, 3);
  std::vector<uint8_t>        streams[3];
  unsigned                    threads[3] = { 1, 2, 4 };
  for (int i = 0; i < 3; ++i)
    streams[i] = dcv::WithThreads(threads[i], [&] { return Encode(s, g, 10, 30.0); });
  EXPECT_EQ(streams[0], streams[1]);
  EXPECT_EQ(streams[0], streams[2]);
}

// The same stream every time, for slices narrower than the pictures (head-mr's 48 x 62 as 64 x 64), one
// encode after another in one process.
TEST_P(VideoCodecs, SameStreamEveryTime)
{
  const GridSize              g{ 48, 62, 42 };
  const std::vector<uint16_t> s = Slices(g, 255, 9);
  const std::vector<uint8_t>  first = Encode(s, g, 8, 30.0);
  for (int i = 0; i < 4; ++i)
    EXPECT_EQ(Encode(s, g, 8, 30.0), first) << i;
}

TEST_P(VideoCodecs, DamagedStreamsAreRefusedByName)
{
  const GridSize              g{ 40, 36, 6 };
  const std::vector<uint16_t> s = Slices(g, 255, 1);
  const std::vector<uint8_t>  stream = Encode(s, g, 8, 20.0);
  auto                        refused = [&](const std::vector<uint8_t> & bytes, const GridSize & grid) {
    try
    {
      Decode(bytes, grid);
      return std::string();
    }
    catch (const dcv::FormatError & e)
    {
      EXPECT_EQ(std::string(e.what()).rfind("'v.dcv': invalid video layer (", 0), 0u) << e.what();
      return std::string(e.what());
    }
  };
  // More slices than pictures, fewer, larger ones, a stream cut short, no stream.
  EXPECT_NE(refused(stream, GridSize{ 40, 36, 7 }).find("6 pictures for 7 slices"), std::string::npos);
  EXPECT_NE(refused(stream, GridSize{ 40, 36, 5 }).find("more pictures than"), std::string::npos);
  EXPECT_NE(refused(stream, GridSize{ 80, 36, 6 }).find("smaller than the slices"), std::string::npos);
  EXPECT_FALSE(
    refused(std::vector<uint8_t>(stream.begin(), stream.begin() + std::ptrdiff_t(stream.size() / 2)), g).empty());
  EXPECT_FALSE(refused({ 0, 0, 0, 1 }, g).empty());
  // Bytes changed anywhere: refused, or pictures of the grid; never a crash.
  std::mt19937 random(7);
  for (int trial = 0; trial < 200; ++trial)
  {
    std::vector<uint8_t> bad = stream;
    for (int k = 0; k < 1 + trial % 4; ++k)
      bad[random() % bad.size()] ^= uint8_t(1 + random() % 255);
    try
    {
      EXPECT_EQ(Decode(bad, g).size(), g.NumberOfVoxels());
    }
    catch (const dcv::FormatError &)
    {}
  }
}

// Thick-slice CT: the video layer wins, the file decodes to exactly what the encoder reported, whatever
// the threads; without the video layer the file holds none and decodes no closer.
TEST(VideoLayer, EncoderKeepsItWhereItDecodesClosest)
{
  const GridSize      g{ 96, 96, 12 };
  const auto          image = ThickSlices(g);
  const double        bpv = 0.125;
  dcv::EncoderOptions options;
  options.bitsPerVoxel = bpv;
  options.threads = 2;
  const auto video = itk::DCVEncode(image.GetPointer(), options);
  options.threads = 1;
  EXPECT_EQ(itk::DCVEncode(image.GetPointer(), options).bytes, video.bytes);
  options.videoLayer = false;
  const auto without = itk::DCVEncode(image.GetPointer(), options);
  std::cout << bpv << " bpv: " << video.psnr << " dB with the video layer, " << without.psnr << " dB without"
            << std::endl;
  ASSERT_TRUE(video.header.videoLayer);
  EXPECT_FALSE(without.header.videoLayer);
  EXPECT_GT(video.psnr, without.psnr);
  EXPECT_LE(video.bytes.size(), std::size_t(bpv * double(g.NumberOfVoxels()) / 8.0));
  // An HEVC stream grows in steps as its rate factor falls: on small volumes none may land in the last 3%
  // of the budget (here 96.7%).
  EXPECT_GE(double(video.bytes.size()), 0.95 * bpv * double(g.NumberOfVoxels()) / 8.0);

  dcv::test::TemporaryDirectory dir;
  const std::string             path = dir / "video.dcv";
  dcv::WriteFileAtomically(path, video.bytes);
  const dcv::CompressedFile file = dcv::ReadCompressedFile(path);
  EXPECT_TRUE(file.header.videoLayer);
  EXPECT_TRUE(file.header.constantSpline);
  std::vector<int16_t> decoded(g.NumberOfVoxels());
  dcv::Rasterize(dcv::Decode(file), decoded.data());
  const double peak = dcv::PSNRPeak(image->GetBufferPointer(), decoded.size());
  EXPECT_EQ(
    dcv::PSNR(dcv::SquaredError(image->GetBufferPointer(), decoded.data(), decoded.size()), decoded.size(), peak),
    video.psnr);
}

// Real data: 12 bits over the range, however small (the range 0 to 1 in steps of 1/4095, not 1).
TEST_P(VideoCodecs, RealDataTakeTwelveBitsOverTheirRange)
{
  const GridSize              g{ 64, 48, 8 };
  const std::vector<uint16_t> s = Slices(g, 4095, 5);
  std::vector<float>          voxels(s.size());
  for (std::size_t i = 0; i < s.size(); ++i)
    voxels[i] = float(s[i]) / 4095.0f;
  const double           step = dcv::VideoStep(1.0, false);
  const dcv::VideoChoice c =
    dcv::ChooseVideoLayer(GetParam(), voxels.data(), dcv::PixelType::Float32, g, 0.0, step, 8000);
  ASSERT_FALSE(c.stream.empty());
  EXPECT_LE(c.stream.size(), 8000u);
  EXPECT_EQ(c.codec, GetParam());
  EXPECT_GT(dcv::PSNR(c.squaredError, g.NumberOfVoxels(), 1.0), 40.0);
}

// The container: a video layer of either codec only over a constant spline, without the compact form or
// the inter-slice wavelet; read back as written.
TEST_P(VideoCodecs, ContainerCarriesIt)
{
  const GridSize  g{ 40, 36, 6 };
  dcv::FileHeader h;
  h.size = g;
  h.constantSpline = true;
  h.videoLayer = true;
  h.videoCodec = GetParam();
  h.quantizationOrigin = -1024.0;
  h.residualStep = 1.0;
  h.numberOfPoints = 8;
  h.residualLayer = Encode(Slices(g, 4095, 2), g, 12, 25.0);
  const std::vector<uint8_t> bytes = dcv::SerializeFile(h, {});
  dcv::FileHeader            back;
  std::vector<uint8_t>       payload;
  dcv::ParseFile(bytes, "'v.dcv'", back, payload);
  EXPECT_TRUE(back.videoLayer);
  EXPECT_EQ(back.videoCodec, GetParam());
  EXPECT_EQ(back.residualLayer, h.residualLayer);
  EXPECT_EQ(back.quantizationOrigin, -1024.0);
  dcv::FileHeader points = h;
  points.constantSpline = false;
  EXPECT_THROW(dcv::SerializeFile(points, { 1, 2, 3 }), std::invalid_argument);
  dcv::FileHeader wavelet = h;
  wavelet.residualLevels = 1;
  EXPECT_THROW(dcv::SerializeFile(wavelet, {}), std::invalid_argument);
}

INSTANTIATE_TEST_SUITE_P(VideoLayer, VideoCodecs, ::testing::Values(dcv::VideoCodec::HEVC, dcv::VideoCodec::AV1),
                         [](const auto & info) { return std::string(dcv::VideoCodecName(info.param)); });

// Form bit 4 (AV1) without form bit 3 (a video layer) is refused.
TEST(VideoLayer, AV1FormBitNeedsAVideoLayer)
{
  const GridSize  g{ 40, 36, 6 };
  dcv::FileHeader h;
  h.size = g;
  h.constantSpline = true;
  h.videoLayer = true;
  h.videoCodec = dcv::VideoCodec::AV1;
  h.quantizationOrigin = 0.0;
  h.residualStep = 1.0;
  h.numberOfPoints = 8;
  h.residualLayer = dcv::EncodeVideoLayer(dcv::VideoCodec::AV1, Slices(g, 255, 2), g, 8, 30.0);
  std::vector<uint8_t> bytes = dcv::SerializeFile(h, {});
  dcv::FileHeader      back;
  std::vector<uint8_t> payload;
  dcv::ParseFile(bytes, "'v.dcv'", back, payload);
  EXPECT_EQ(back.videoCodec, dcv::VideoCodec::AV1);
  // The form byte: the first byte that differs from the same file labelled HEVC.
  dcv::FileHeader hevc = h;
  hevc.videoCodec = dcv::VideoCodec::HEVC;
  const std::vector<uint8_t> other = dcv::SerializeFile(hevc, {});
  ASSERT_EQ(other.size(), bytes.size());
  const auto form = std::mismatch(bytes.begin(), bytes.end(), other.begin()).first;
  ASSERT_NE(form, bytes.end());
  EXPECT_EQ(*form, uint8_t(1 | 2 | 8 | 16)); // constant spline, unit step, video layer, AV1
  *form = uint8_t(1 | 2 | 16);
  const uint32_t crc = uint32_t(crc32(0L, bytes.data(), uInt(bytes.size() - 4)));
  for (int i = 0; i < 4; ++i)
    bytes[bytes.size() - 4 + std::size_t(i)] = uint8_t(crc >> (8 * i));
  try
  {
    dcv::ParseFile(bytes, "'v.dcv'", back, payload);
    ADD_FAILURE() << "form bit 4 alone was read";
  }
  catch (const dcv::FormatError & e)
  {
    EXPECT_NE(std::string(e.what()).find("form bit 4"), std::string::npos) << e.what();
  }
}
