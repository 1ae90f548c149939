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
// The residual layer: the JPEG 2000 mosaic codes and decodes within its budget (exactly with 5/3 and
// room enough), damaged layers are refused by name, the container carries it, and the encoder keeps
// it only where it decodes closer than the points alone, with the decoder giving what it reported.
#include "dcvCodec.h"
#include "dcvResidualLayer.h"
#include "dcvTestUtilities.h"
#include "itkDCVEncoder.h"
#include "itkDCVImageIO.h"
#include "itkImageFileReader.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <random>
#include <zlib.h>

namespace
{
using dcv::GridSize;

std::vector<int32_t>
Samples(const GridSize & g, int amplitude, unsigned seed)
{
  std::mt19937         random(seed);
  std::vector<int32_t> s(g.NumberOfVoxels());
  for (int32_t z = 0; z < g.z; ++z)
    for (int32_t y = 0; y < g.y; ++y)
      for (int32_t x = 0; x < g.x; ++x)
        s[g.Offset(x, y, z)] =
          int32_t(std::lround(amplitude * std::sin(0.3 * x + z) * std::cos(0.2 * y))) + int32_t(random() % 7) - 3;
  return s;
}

template <typename B>
double
SquaredError(const std::vector<int32_t> & a, const B & b)
{
  double e = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i)
    e += double(a[i] - b[i]) * double(a[i] - b[i]);
  return e;
}

/** A volume whose slices have little in common (thick slices): texture a spline cannot follow. */
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
        v[g.Offset(x, y, z)] = int16_t(std::lround(900.0 * std::sin(0.15 * x + 1.7 * z) * std::cos(0.1 * y + z)));
  itk::Image<int16_t, 3>::SpacingType spacing;
  spacing[0] = spacing[1] = 0.5;
  spacing[2] = 5.0;
  image->SetSpacing(spacing);
  return image;
}
} // namespace

TEST(ResidualLayer, MosaicIsNearSquareWithFewEmptyTiles)
{
  EXPECT_EQ(dcv::MosaicColumns({ 256, 242, 38 }), 6); // 6 x 7 tiles, as the benchmark's j2k-mosaic
  EXPECT_EQ(dcv::MosaicColumns({ 64, 64, 1 }), 1);
  EXPECT_EQ(dcv::MosaicColumns({ 10, 10, 16 }), 4);
  EXPECT_EQ(dcv::MosaicColumns({ 100, 10, 4 }), 1); // wide slices stack in one column
}

TEST(ResidualLayer, ReversibleWithRoomIsExact)
{
  for (const GridSize g : { GridSize{ 20, 12, 7 }, GridSize{ 9, 33, 2 }, GridSize{ 2, 2, 2 } })
  {
    const auto samples = Samples(g, 300, 1);
    for (dcv::Arrangement a : { dcv::Arrangement::Mosaic, dcv::Arrangement::Components })
    {
      const auto codestream = dcv::EncodeResidualLayer(samples, g, 1 << 20, dcv::Wavelet::Reversible53, a);
      ASSERT_FALSE(codestream.empty());
      EXPECT_EQ(dcv::DecodeResidualLayer(codestream, g, "x"), dcv::ResidualSamples(samples.begin(), samples.end()))
        << g.x << "x" << g.y << "x" << g.z;
    }
  }
}

TEST(ResidualLayer, StaysWithinItsBudgetAndImprovesWithIt)
{
  const GridSize g{ 48, 40, 9 };
  const auto     samples = Samples(g, 2000, 2);
  for (const dcv::ResidualCoding c :
       { dcv::ResidualCoding{ dcv::Wavelet::Irreversible97, dcv::Arrangement::Mosaic },
         dcv::ResidualCoding{ dcv::Wavelet::Reversible53, dcv::Arrangement::Mosaic },
         dcv::ResidualCoding{ dcv::Wavelet::Irreversible97, dcv::Arrangement::Components } })
  {
    const dcv::Wavelet w = c.wavelet;
    double             previous = std::numeric_limits<double>::infinity();
    for (std::size_t budget : { 400, 1600, 6400 })
    {
      const auto codestream = dcv::EncodeResidualLayer(samples, g, budget, w, c.arrangement);
      ASSERT_FALSE(codestream.empty()) << budget;
      EXPECT_LE(codestream.size(), budget);
      EXPECT_GE(codestream.size(), budget * 9 / 10) << "the budget is not used";
      const double error = SquaredError(samples, dcv::DecodeResidualLayer(codestream, g, "x"));
      EXPECT_LT(error, previous) << budget;
      previous = error;
    }
    // Deterministic: the same bytes again (OpenJPEG runs threaded).
    EXPECT_EQ(dcv::EncodeResidualLayer(samples, g, 1600, w, c.arrangement),
              dcv::EncodeResidualLayer(samples, g, 1600, w, c.arrangement));
  }
  EXPECT_TRUE(dcv::EncodeResidualLayer(samples, g, 10, dcv::Wavelet::Irreversible97).empty());
  EXPECT_THROW(dcv::EncodeResidualLayer(std::vector<int32_t>(10, 0), g, 100, dcv::Wavelet::Reversible53),
               std::invalid_argument);
}

TEST(ResidualLayer, DamagedLayersAreRefusedByName)
{
  const GridSize g{ 24, 20, 6 };
  const auto     codestream = dcv::EncodeResidualLayer(Samples(g, 100, 3), g, 800, dcv::Wavelet::Irreversible97);
  ASSERT_FALSE(codestream.empty());
  auto expectRefused = [&](const std::vector<uint8_t> & bytes, const GridSize & grid, const std::string & why) {
    try
    {
      dcv::DecodeResidualLayer(bytes, grid, "'f.dcv'");
      ADD_FAILURE() << "accepted: " << why;
    }
    catch (const dcv::FormatError & e)
    {
      EXPECT_NE(std::string(e.what()).find("'f.dcv': damaged residual layer"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
  };
  expectRefused(std::vector<uint8_t>(codestream.begin(), codestream.begin() + 20), g, "");
  expectRefused(std::vector<uint8_t>(64, 0x5a), g, "unreadable");
  expectRefused(codestream, { 24, 20, 13 }, "neither a mosaic of 13 slices");
  expectRefused(codestream, { 12, 20, 6 }, "nor one component per slice");
  // Any damage past the header decodes to something or is refused, never a crash.
  std::mt19937 random(5);
  for (int i = 0; i < 200; ++i)
  {
    auto damaged = codestream;
    damaged[std::size_t(random() % damaged.size())] ^= uint8_t(1 + random() % 255);
    try
    {
      EXPECT_EQ(dcv::DecodeResidualLayer(damaged, g, "x").size(), g.NumberOfVoxels());
    }
    catch (const dcv::FormatError &)
    {}
  }
}

TEST(ResidualLayer, ContainerCarriesIt)
{
  dcv::FileHeader h;
  h.size = { 4, 3, 2 };
  h.numberOfPoints = 8;
  h.residualStep = 2.0;
  h.residualLayer = { 1, 2, 3, 4, 5 };
  h.metadata = { { "k", "v" } };
  const auto           bytes = dcv::SerializeFile(h, { 7, 7 });
  dcv::FileHeader      back;
  std::vector<uint8_t> payload;
  dcv::ParseFile(bytes, "x", back, payload);
  EXPECT_EQ(back.residualStep, 2.0);
  EXPECT_EQ(back.residualLayer, h.residualLayer);
  EXPECT_EQ(back.metadata, h.metadata);
  EXPECT_EQ(payload, (std::vector<uint8_t>{ 7, 7 }));
  h.residualStep = 0.0;
  EXPECT_EQ(dcv::SerializeFile(h, { 7, 7 }).size() + 1 + 8 + 4 + 5, bytes.size()); // form, step, length, layer
  h.residualStep = -1.0;
  EXPECT_THROW(dcv::SerializeFile(h, { 7, 7 }), std::invalid_argument);
}

TEST(ResidualLayer, EncoderKeepsItOnlyWhereItDecodesCloser)
{
  const GridSize g{ 64, 60, 8 };
  const auto     image = ThickSlices(g);
  for (double bpv : { 0.25, 1.0 })
  {
    dcv::EncoderOptions options;
    options.bitsPerVoxel = bpv;
    const auto layered = itk::DCVEncode(image.GetPointer(), options);
    options.residualLayer = false;
    const auto pointsOnly = itk::DCVEncode(image.GetPointer(), options);
    EXPECT_TRUE(pointsOnly.header.residualLayer.empty());
    EXPECT_GE(layered.psnr, pointsOnly.psnr) << bpv;
    // Texture across thick slices: the transform layer wins here.
    EXPECT_FALSE(layered.header.residualLayer.empty()) << bpv;
    EXPECT_GT(layered.psnr, pointsOnly.psnr + 1.0) << bpv;
    std::cout << bpv << " bpv: " << layered.psnr << " dB with the residual layer, " << pointsOnly.psnr
              << " dB points only" << std::endl;
    EXPECT_LE(layered.bytes.size(), std::size_t(bpv * g.NumberOfVoxels() / 8));

    // The decoder (the library's and ITK's reader) gives exactly what the encoder reported.
    dcv::test::TemporaryDirectory dir;
    const std::string             path = dir / "layered.dcv";
    dcv::WriteFileAtomically(path, layered.bytes);
    std::vector<int16_t> decoded(g.NumberOfVoxels());
    dcv::Rasterize(dcv::Decode(dcv::ReadCompressedFile(path)), decoded.data());
    const double peak = dcv::PSNRPeak(image->GetBufferPointer(), decoded.size());
    EXPECT_EQ(
      dcv::PSNR(dcv::SquaredError(image->GetBufferPointer(), decoded.data(), decoded.size()), decoded.size(), peak),
      layered.psnr);
    auto reader = itk::ImageFileReader<itk::Image<int16_t, 3>>::New();
    reader->SetFileName(path);
    reader->Update();
    EXPECT_TRUE(std::equal(decoded.begin(), decoded.end(), reader->GetOutput()->GetBufferPointer()));
  }
}

TEST(ResidualLayer, RegionDecodeAddsTheLayer)
{
  const GridSize      g{ 40, 36, 6 };
  const auto          image = ThickSlices(g);
  dcv::EncoderOptions options;
  options.bitsPerVoxel = 1.0;
  const auto r = itk::DCVEncode(image.GetPointer(), options);
  ASSERT_FALSE(r.header.residualLayer.empty());
  dcv::CompressedFile file;
  file.name = "x";
  dcv::ParseFile(r.bytes, file.name, file.header, file.payload);
  const dcv::Approximation a = dcv::Decode(file);
  std::vector<int16_t>     whole(g.NumberOfVoxels());
  dcv::Rasterize(a, whole.data());
  const dcv::GridPoint first{ 3, 5, 1 }, last{ 20, 17, 4 };
  std::vector<int16_t> box(18 * 13 * 4);
  dcv::RasterizeBox(a, first, last, box.data());
  std::size_t i = 0;
  for (int32_t z = first[2]; z <= last[2]; ++z)
    for (int32_t y = first[1]; y <= last[1]; ++y)
      for (int32_t x = first[0]; x <= last[0]; ++x)
        EXPECT_EQ(box[i++], whole[g.Offset(x, y, z)]);
}

// DecodeVolume adds the layer row by row as it is decoded (and writes a constant spline with it): the
// voxels of Decode() then Rasterize(), for integers (the clamping loop) and reals, with and without points.
TEST(ResidualLayer, DecodeVolumeEqualsDecodeThenRasterize)
{
  const GridSize g{ 40, 36, 6 };
  const auto     image = ThickSlices(g);
  using Real = itk::Image<float, 3>;
  auto real = Real::New();
  real->SetRegions(image->GetLargestPossibleRegion());
  real->SetSpacing(image->GetSpacing());
  real->Allocate();
  for (std::size_t i = 0; i < g.NumberOfVoxels(); ++i)
    real->GetBufferPointer()[i] = 0.37f * float(image->GetBufferPointer()[i]);
  int constant = 0, points = 0;
  for (double bpv : { 0.25, 1.0 })
  {
    dcv::EncoderOptions options;
    options.bitsPerVoxel = bpv;
    std::vector<std::vector<uint8_t>> files;
    for (const auto & r : { itk::DCVEncode(image.GetPointer(), options), itk::DCVEncode(real.GetPointer(), options) })
      files.push_back(r.bytes);
    // Points under a layer of their own, with and without the inter-slice wavelet.
    options.residualLayer = false;
    for (const auto & r : { itk::DCVEncode(image.GetPointer(), options), itk::DCVEncode(real.GetPointer(), options) })
    {
      dcv::CompressedFile file;
      dcv::ParseFile(r.bytes, "x", file.header, file.payload);
      const int32_t levels = bpv < 0.5 ? 0 : 1;
      file.header.residualStep = bpv < 0.5 ? 1.0 : 0.37;
      file.header.residualLevels = levels;
      file.header.residualLayer = dcv::EncodeResidualLayer(
        Samples(g, 40, 3), g, 3000, dcv::Wavelet::Irreversible97, dcv::Arrangement::Mosaic, levels);
      files.push_back(dcv::SerializeFile(file.header, file.payload));
    }
    for (const std::vector<uint8_t> & bytes : files)
    {
      dcv::CompressedFile file;
      file.name = "x";
      dcv::ParseFile(bytes, file.name, file.header, file.payload);
      if (file.header.residualLayer.empty())
        continue;
      (file.header.constantSpline ? constant : points) += 1;
      dcv::VisitPixelType(file.header.pixelType, [&](auto pixel) {
        using T = decltype(pixel);
        std::vector<T> expected(g.NumberOfVoxels()), rows(g.NumberOfVoxels());
        dcv::Rasterize(dcv::Decode(file), expected.data());
        dcv::DecodeVolume(file, rows.data());
        EXPECT_TRUE(std::equal(expected.begin(), expected.end(), rows.begin()))
          << bpv << " bpv, " << (file.header.constantSpline ? "constant spline" : "points");
      });
    }
  }
  EXPECT_GT(constant, 0);
  EXPECT_GT(points, 0);
}

// The compact form leaves out SOC, SIZ, COD, SOT, SOD, EOC and (9/7, up to 5 levels) the QCD, and gives
// the very codestream back, for both arrangements, both wavelets and every number of resolutions.
TEST(ResidualLayer, CompactFormGivesTheCodestreamBack)
{
  int compacted = 0;
  for (const GridSize g : { GridSize{ 40, 36, 6 }, GridSize{ 7, 5, 3 }, GridSize{ 3, 2, 2 }, GridSize{ 130, 70, 5 } })
    for (dcv::Arrangement a : { dcv::Arrangement::Mosaic, dcv::Arrangement::Components })
      for (dcv::Wavelet w : { dcv::Wavelet::Irreversible97, dcv::Wavelet::Reversible53 })
        for (int amplitude : { 3, 300, 20000 }) // precisions 4 to 16
        {
          SCOPED_TRACE(std::to_string(g.x) + "x" + std::to_string(g.y) + "x" + std::to_string(g.z) + " amplitude " +
                       std::to_string(amplitude) + (a == dcv::Arrangement::Mosaic ? " mosaic" : " components") +
                       (w == dcv::Wavelet::Reversible53 ? " 5/3" : " 9/7"));
          const auto codestream = dcv::EncodeResidualLayer(Samples(g, amplitude, 5), g, 1 << 20, w, a);
          ASSERT_FALSE(codestream.empty());
          std::vector<uint8_t> stored;
          ASSERT_TRUE(dcv::CompactLayer(codestream, g, stored));
          EXPECT_EQ(dcv::ExpandLayer(stored, g, "x"), codestream);
          EXPECT_EQ(dcv::StoredLayerBytes(codestream, g), stored.size());
          // The QCD is implicit too: the saving the encoder counts on (9/7 at 6 resolutions; 5/3 has a
          // shorter QCD, fewer resolutions fewer bands).
          const bool sixResolutions = std::min(g.x, g.y) >= 32;
          if (w == dcv::Wavelet::Irreversible97 && sixResolutions)
            EXPECT_EQ(codestream.size() - stored.size(), dcv::CompactLayerSaving(g, a));
          EXPECT_EQ(stored[2] & 0x40, 0x40) << "QCD not implicit";
          ++compacted;
        }
  EXPECT_EQ(compacted, 4 * 2 * 2 * 3);

  // What is not OpenJPEG's layout stays whole, and a compact layer with bad fields is refused by name.
  const GridSize       g{ 40, 36, 6 };
  auto                 codestream = dcv::EncodeResidualLayer(Samples(g, 300, 5), g, 4000, dcv::Wavelet::Irreversible97);
  std::vector<uint8_t> stored;
  ASSERT_TRUE(dcv::CompactLayer(codestream, g, stored));
  auto other = codestream;
  other[other.size() - 1] = 0xd8; // not EOC
  EXPECT_FALSE(dcv::CompactLayer(other, g, stored));
  EXPECT_TRUE(stored.empty());
  EXPECT_FALSE(dcv::CompactLayer(codestream, GridSize{ 40, 36, 7 }, stored)) << "another grid's mosaic";
  ASSERT_TRUE(dcv::CompactLayer(codestream, g, stored));
  for (auto damage : std::vector<std::pair<std::size_t, uint8_t>>{ { 1, 7 },    // more columns than slices
                                                                   { 2, 0x7f }, // precision 64
                                                                   { 3, 33 },   // levels
                                                                   { 3, 6 } })  // implicit QCD past 5 levels
  {
    auto bad = stored;
    bad[damage.first] = damage.second;
    try
    {
      dcv::ExpandLayer(bad, g, "'bad.dcv'");
      ADD_FAILURE() << "byte " << damage.first << " = " << int(damage.second) << " accepted";
    }
    catch (const dcv::FormatError & e)
    {
      EXPECT_NE(std::string(e.what()).find("'bad.dcv': damaged residual layer"), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(dcv::ExpandLayer({ 0, 1, 7 }, g, "x"), dcv::FormatError);
}

// The constant spline under a layer that takes the whole budget is filled, not rasterized: the same
// voxels as Rasterize() gives, for integer and floating types and values off the integers.
TEST(ResidualLayer, ConstantSplineIsFilled)
{
  const GridSize g{ 9, 7, 5 };
  for (double value : { 128.0, -1023.5, 0.3, 70000.7 })
  {
    for (const dcv::GridScale scale : { dcv::GridScale{ { 1, 1, 1 } }, dcv::GridScale{ { 1, 1, 7 } } })
    {
      const dcv::Approximation a = dcv::ConstantSpline(g, scale, value);
      ASSERT_EQ(a.points.size(), 8u);
      std::vector<int16_t> i16(g.NumberOfVoxels(), 1);
      std::vector<float>   f32(g.NumberOfVoxels(), 1.0f);
      std::vector<uint8_t> u8(g.NumberOfVoxels(), 1);
      dcv::Rasterize(a, i16.data());
      dcv::Rasterize(a, f32.data());
      dcv::Rasterize(a, u8.data());
      for (std::size_t i = 0; i < i16.size(); ++i)
      {
        ASSERT_EQ(i16[i], dcv::ConvertValue<int16_t>(value)) << value << " voxel " << i;
        ASSERT_EQ(f32[i], dcv::ConvertValue<float>(value)) << value << " voxel " << i;
        ASSERT_EQ(u8[i], dcv::ConvertValue<uint8_t>(value)) << value << " voxel " << i;
      }
    }
    // And the search measures the same error from its filled spline as from the rasterized one.
    std::vector<float> voxels(g.NumberOfVoxels());
    for (std::size_t i = 0; i < voxels.size(); ++i)
      voxels[i] = float(int(i % 13) * 10);
    const dcv::Approximation a = dcv::ConstantSpline(g, dcv::GridScale{ { 1, 1, 7 } }, value);
    std::vector<int16_t>     decoded(g.NumberOfVoxels());
    dcv::Rasterize(a, decoded.data());
    const dcv::ResidualSearch search(voxels.data(), dcv::PixelType::Int16, a, 1.0, 1000);
    EXPECT_EQ(search.SplineError(), dcv::SquaredError(voxels.data(), decoded.data(), decoded.size())) << value;
  }
}

/** The 8 corners of the grid at value 0: a constant spline, the residual is the volume. */
dcv::Approximation
CornersAtZero(const GridSize & g)
{
  return dcv::ConstantSpline(g, dcv::GridScale{ { 1, 1, 1 } }, 0.0);
}

// Filling the budget never takes more than it, never decodes worse, and stops at once where the whole
// image fits (6100 and 9000 bytes here: more target, no more bytes).
TEST(ResidualLayer, FillStaysWithinTheBudgetAndDecodesNoWorse)
{
  const GridSize           g{ 64, 60, 8 };
  const auto               image = ThickSlices(g);
  std::vector<float>       voxels(image->GetBufferPointer(), image->GetBufferPointer() + g.NumberOfVoxels());
  const dcv::Approximation corners = CornersAtZero(g);
  int                      filled = 0;
  for (std::size_t budget : { 1500, 2500, 4000, 6100, 9000 })
  {
    dcv::ResidualSearch search(voxels.data(), dcv::PixelType::Int16, corners, 1.0, budget);
    const double        first = search.Try({ dcv::Wavelet::Irreversible97, dcv::Arrangement::Mosaic, 0 });
    const std::size_t   unused = search.Unused();
    ASSERT_LE(unused, budget);
    const std::size_t encodes = search.Fill(0, 6);
    EXPECT_LE(search.BestError(), first) << budget;
    EXPECT_LE(search.Unused(), unused) << budget;
    EXPECT_EQ(encodes > 0, unused > 0) << budget;
    if (budget >= 6100)
      EXPECT_EQ(encodes, 1u) << budget;
    filled += search.Unused() < unused ? 1 : 0;
    const dcv::ResidualChoice best = std::move(search).Best();
    EXPECT_LE(dcv::StoredLayerBytes(best.codestream, g), budget);
    // What it kept decodes to what it measured.
    EXPECT_EQ(dcv::DecodeResidualLayer(best.codestream, g, "x", best.levels), best.samples);
  }
  std::cout << filled << " of 5 budgets filled further" << std::endl;
}

/** The 2D wavelet levels of a codestream: SPcod's first byte in its COD marker segment. */
int
DecompositionLevels(const std::vector<uint8_t> & codestream)
{
  for (std::size_t i = 0; i + 10 < codestream.size(); ++i)
    if (codestream[i] == 0xff && codestream[i + 1] == 0x52)
      return codestream[i + 9]; // marker 2, Lcod 2, Scod 1, progression 1, layers 2, MCT 1
  return -1;
}

// Fewer 2D wavelet levels than the image takes (the encoder's corners' layer searches them) code and
// decode as the decoder decodes them, one level fewer each; none at all left is no coding.
TEST(ResidualLayer, FewerResolutionsCodeFewerLevelsAndDecodeExactly)
{
  const GridSize           g{ 64, 60, 8 };
  const auto               image = ThickSlices(g);
  std::vector<float>       voxels(image->GetBufferPointer(), image->GetBufferPointer() + g.NumberOfVoxels());
  const dcv::Approximation corners = CornersAtZero(g);
  int                      most = -1;
  for (int32_t fewer = 0; fewer <= 3; ++fewer)
  {
    dcv::ResidualSearch search(voxels.data(), dcv::PixelType::Int16, corners, 1.0, 3000);
    const double        error = search.Try({ dcv::Wavelet::Irreversible97, dcv::Arrangement::Mosaic, 1, fewer });
    ASSERT_TRUE(std::isfinite(error)) << fewer;
    const dcv::ResidualChoice best = std::move(search).Best();
    const int                 levels = DecompositionLevels(best.codestream);
    if (fewer == 0)
      most = levels;
    EXPECT_EQ(levels, most - fewer);
    EXPECT_EQ(dcv::DecodeResidualLayer(best.codestream, g, "x", best.levels), best.samples);
    EXPECT_EQ(best.squaredError, error);
  }
  dcv::ResidualSearch search(voxels.data(), dcv::PixelType::Int16, corners, 1.0, 3000);
  EXPECT_TRUE(std::isinf(search.Try({ dcv::Wavelet::Irreversible97, dcv::Arrangement::Mosaic, 1, most + 1 })));
}

// Restore() undoes the trials since Save(): the best coding and its codestream are the saved ones, and
// the next trial starts where it would have.
TEST(ResidualLayer, RestoreUndoesTheTrialsSinceSave)
{
  const GridSize            g{ 64, 60, 8 };
  const auto                image = ThickSlices(g);
  std::vector<float>        voxels(image->GetBufferPointer(), image->GetBufferPointer() + g.NumberOfVoxels());
  const dcv::Approximation  corners = CornersAtZero(g);
  const dcv::ResidualCoding finer{ dcv::Wavelet::Irreversible97, dcv::Arrangement::Mosaic, 1 };
  const dcv::ResidualCoding coarser{ dcv::Wavelet::Irreversible97, dcv::Arrangement::Mosaic, 1, 2 };
  dcv::ResidualSearch       reference(voxels.data(), dcv::PixelType::Int16, corners, 1.0, 2000);
  reference.Try(finer);
  dcv::ResidualSearch search(voxels.data(), dcv::PixelType::Int16, corners, 1.0, 2000);
  search.Try(finer);
  dcv::ResidualSearch::State saved = search.Save();
  const double               first = search.BestError();
  const std::size_t          unused = search.Unused();
  search.Try(coarser);
  search.Try({ dcv::Wavelet::Reversible53, dcv::Arrangement::Mosaic, 1 });
  search.Restore(std::move(saved));
  EXPECT_EQ(search.BestError(), first);
  EXPECT_EQ(search.Unused(), unused);
  search.Fill(0, 3);
  reference.Fill(0, 3);
  EXPECT_EQ(search.BestError(), reference.BestError());
  EXPECT_EQ(std::move(search).Best().codestream, std::move(reference).Best().codestream);
}

// The search keeps no volume of samples between its encodes: each encode after a coding's first (a
// target that overshot, a fill) computes them again and transforms them again. Its codestreams must
// decode as close as EncodeResidualLayer()'s from the residual given whole, in the same bytes.
TEST(ResidualLayer, SamplesComputedAgainCodeTheSameImage)
{
  // Texture that needs every byte (a smooth volume fits whole before the budget).
  const GridSize     g{ 64, 60, 8 };
  const auto         image = ThickSlices(g);
  std::vector<float> voxels(image->GetBufferPointer(), image->GetBufferPointer() + g.NumberOfVoxels());
  std::mt19937       random(5);
  for (float & v : voxels)
    v += float(int(random() % 201) - 100);
  std::vector<int32_t> residual(voxels.begin(), voxels.end()); // the corners at 0, a step of 1
  dcv::Approximation   corners;
  corners.grid = g;
  for (int32_t z : { 0, g.z - 1 })
    for (int32_t y : { 0, g.y - 1 })
      for (int32_t x : { 0, g.x - 1 })
        corners.points.push_back({ x, y, z });
  corners.values.assign(8, 0.0);
  corners.tetrahedra = dcv::Tetrahedralize(corners.points);
  using dcv::Arrangement;
  using dcv::Wavelet;
  for (const dcv::ResidualCoding coding : { dcv::ResidualCoding{ Wavelet::Irreversible97, Arrangement::Mosaic, 0 },
                                            dcv::ResidualCoding{ Wavelet::Irreversible97, Arrangement::Mosaic, 2 },
                                            dcv::ResidualCoding{ Wavelet::Reversible53, Arrangement::Components, 1 } })
  {
    for (std::size_t budget : { 1500, 2500, 4000 })
    {
      dcv::ResidualSearch search(voxels.data(), dcv::PixelType::Int16, corners, 1.0, budget);
      search.Try(coding);
      search.Try(coding); // a second time: its first encode aims where the first ended
      search.Fill(0, 3);
      const double              error = search.BestError();
      const dcv::ResidualChoice best = std::move(search).Best();
      ASSERT_FALSE(best.codestream.empty());
      EXPECT_EQ(best.squaredError, error);
      EXPECT_EQ(best.levels, coding.levels);
      const auto decoded = dcv::DecodeResidualLayer(best.codestream, g, "x", best.levels);
      EXPECT_EQ(best.samples, decoded);
      const auto direct = dcv::DecodeResidualLayer(
        dcv::EncodeResidualLayer(
          residual, g, dcv::StoredLayerBytes(best.codestream, g), coding.wavelet, coding.arrangement, coding.levels),
        g,
        "y",
        coding.levels);
      double searchError = 0.0, directError = 0.0;
      for (std::size_t i = 0; i < residual.size(); ++i)
      {
        searchError += double(residual[i] - decoded[i]) * double(residual[i] - decoded[i]);
        directError += double(residual[i] - direct[i]) * double(residual[i] - direct[i]);
      }
      EXPECT_EQ(searchError, error) << budget;
      EXPECT_LT(searchError, 1.1 * directError) << budget << " levels " << coding.levels;
    }
    // EncodeResidualLayer() keeps the first codestream that fits, often from a second target (its
    // samples computed again): more bytes, never a worse decode than a little fewer.
    double previous = std::numeric_limits<double>::infinity();
    for (std::size_t budget = 1200; budget <= 4200; budget += 150)
    {
      const auto decoded = dcv::DecodeResidualLayer(
        dcv::EncodeResidualLayer(residual, g, budget, coding.wavelet, coding.arrangement, coding.levels),
        g,
        "z",
        coding.levels);
      double error = 0.0;
      for (std::size_t i = 0; i < residual.size(); ++i)
        error += double(residual[i] - decoded[i]) * double(residual[i] - decoded[i]);
      EXPECT_LT(error, 1.02 * previous) << budget << " levels " << coding.levels;
      previous = error;
    }
  }
}

// Form bits: a constant spline takes no q, n, L or payload; a unit step is not stored; unknown form bits,
// a form byte without a layer and a constant spline with a payload are refused.
TEST(ResidualLayer, FormByteShortensTheContainer)
{
  const GridSize  g{ 40, 36, 6 };
  dcv::FileHeader h;
  h.size = g;
  h.numberOfPoints = 8;
  h.quantizationOrigin = 128.0;
  h.quantizationStep = 4.0;
  h.residualStep = 1.0;
  h.residualLayer = dcv::EncodeResidualLayer(Samples(g, 300, 5), g, 3000, dcv::Wavelet::Irreversible97);
  const std::vector<uint8_t> payload{ 1, 2, 3, 4, 5, 6 };
  const auto                 points = dcv::SerializeFile(h, payload);
  h.constantSpline = true;
  EXPECT_THROW(dcv::SerializeFile(h, payload), std::invalid_argument);
  const auto constant = dcv::SerializeFile(h, {});
  EXPECT_EQ(points.size() - constant.size(), 8 + 4 + 4 + payload.size()); // q, n, L, payload
  dcv::FileHeader      back;
  std::vector<uint8_t> backPayload{ 9 };
  dcv::ParseFile(constant, "c", back, backPayload);
  EXPECT_TRUE(back.constantSpline);
  EXPECT_EQ(back.quantizationOrigin, 128.0);
  EXPECT_EQ(back.numberOfPoints, 8u);
  EXPECT_TRUE(backPayload.empty());
  EXPECT_EQ(back.residualStep, 1.0);
  EXPECT_EQ(back.residualLayer, h.residualLayer);
  // The decoder's spline: the 8 corners at q0.
  dcv::CompressedFile      file{ "c", back, backPayload, constant.size() };
  const dcv::Approximation a = dcv::Decode(file);
  EXPECT_EQ(a.points.size(), 8u);
  EXPECT_EQ(a.values, std::vector<double>(8, 128.0));
  EXPECT_EQ(a.residual.samples, dcv::DecodeResidualLayer(h.residualLayer, g, "c"));

  // A step other than 1 is stored (8 bytes); a codestream not in OpenJPEG's layout is stored whole.
  h.residualStep = 2.0;
  EXPECT_EQ(dcv::SerializeFile(h, {}).size(), constant.size() + 8);
  auto whole = h;
  whole.residualLayer.back() = 0xd8;
  EXPECT_EQ(dcv::SerializeFile(whole, {}).size(),
            dcv::SerializeFile(h, {}).size() + dcv::CompactLayerSaving(g, dcv::Arrangement::Mosaic));
  dcv::ParseFile(dcv::SerializeFile(whole, {}), "w", back, backPayload);
  EXPECT_EQ(back.residualLayer, whole.residualLayer);

  // Damaged forms, with their CRC made right so that the form itself is what is refused.
  auto refuse = [](std::vector<uint8_t> bytes, std::size_t at, uint8_t value, const std::string & what) {
    bytes[at] = value;
    const uint32_t crc = uint32_t(crc32(0L, bytes.data(), uInt(bytes.size() - 4)));
    for (int i = 0; i < 4; ++i)
      bytes[bytes.size() - 4 + std::size_t(i)] = uint8_t(crc >> (8 * i));
    dcv::FileHeader      x;
    std::vector<uint8_t> p;
    try
    {
      dcv::ParseFile(bytes, "'d.dcv'", x, p);
      ADD_FAILURE() << what << " accepted";
    }
    catch (const dcv::FormatError & e)
    {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  const std::size_t form = 62; // no direction, no scale: the form byte follows the origin
  ASSERT_EQ(constant[6] & 128, 128);
  ASSERT_EQ(constant[form], 1 | 2 | 4);
  refuse(constant, form, 1 | 2 | 4 | 64, "unknown form bits 71");
  refuse(constant, form, 1 | 2 | 4 | 32, "a bounded-error layer (form bit 5) needs");
  refuse(constant, form, 2 | 32, "a bounded-error layer (form bit 5) needs");
  refuse(constant, form, 1 | 2 | 16, "form bit 4 (AV1) without a video layer");
  refuse(constant, form, 1 | 2 | 4 | 8, "a video layer (form bit 3) needs");
  refuse(constant, form, 2 | 8, "a video layer (form bit 3) needs");
  refuse(constant, 6, uint8_t(constant[6] & ~8), "unknown header flags");
}

// The decoders' row loop (int32 where the step is whole) against the one rule, AddResidual, at the ends
// of every small integer type, every kind of step, and samples up to the ends of int32.
template <typename T>
void
ExpectRowsAsAddResidual()
{
  const double         lo = double(std::numeric_limits<T>::lowest()), hi = double(std::numeric_limits<T>::max());
  std::vector<T>       spline{ T(lo), T(lo + 1), T(0), T(1), T(hi / 2), T(hi - 1), T(hi) };
  std::vector<int32_t> samples{ std::numeric_limits<int32_t>::min(), std::numeric_limits<int32_t>::max(), 0, 1, -1 };
  for (int32_t b : { 1 << 16, 1 << 17, 65535, 65536, 131071, 131072, 131073 })
    for (int32_t d : { -1, 0, 1 })
    {
      samples.push_back(b + d);
      samples.push_back(-(b + d));
    }
  std::mt19937 random(7);
  for (int i = 0; i < 200; ++i)
    samples.push_back(int32_t(random() % 300000) - 150000);
  int checked = 0;
  for (double step : { 1.0, 2.0, 3.0, 7.0, 255.0, 1000.0, 65536.0, 131072.0, 262144.0, 1048576.0, 1048577.0, 0.5, 2.5 })
  {
    for (T voxel : spline)
    {
      std::vector<T> row(samples.size(), voxel);
      dcv::detail::AddResidualToRow(step, samples.data(), row.data(), row.size());
      for (std::size_t i = 0; i < samples.size(); ++i)
      {
        ASSERT_EQ(double(row[i]), double(dcv::AddResidual(voxel, step, samples[i])))
          << "step " << step << ", voxel " << double(voxel) << ", sample " << samples[i];
        ++checked;
      }
    }
  }
  EXPECT_EQ(checked, 13 * 7 * int(samples.size()));
}

TEST(ResidualLayer, AddResidualToRowIsAddResidual)
{
  ExpectRowsAsAddResidual<uint8_t>();
  ExpectRowsAsAddResidual<int8_t>();
  ExpectRowsAsAddResidual<uint16_t>();
  ExpectRowsAsAddResidual<int16_t>();
  ExpectRowsAsAddResidual<float>();
}
