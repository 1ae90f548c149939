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
// The encoder in the library: itk::ImageFileWriter writes .dcv files byte for byte as `dcv compress`
// does, the PSNR it reports is the decoder's, a quality target is met, and a pipeline runs the
// approximation filter once.
#include "dcvCodec.h"
#include "dcvInterSliceWavelet.h"
#include "dcvPhantom.h"
#include "dcvTestUtilities.h"
#include "itkDCVEncoder.h"
#include "itkDCVImageIO.h"
#include "itkDelaunayApproximationImageToMeshFilter.h"
#include "itkTetrahedralMeshToImageFilter.h"

#include "itkCommand.h"
#include "itkImageFileReader.h"
#include "itkImageFileWriter.h"
#include "itkImageRegionIteratorWithIndex.h"
#include "itkMesh.h"

#include <random>

namespace
{
using ImageType = itk::Image<uint8_t, 3>;
using MeshType = itk::Mesh<double, 3>;

ImageType::Pointer
Phantom(const dcv::GridSize & grid)
{
  return dcv::test::PhantomImage(grid, true);
}

template <typename TImage>
void
Write(const TImage * image, const std::string & path, itk::ImageIOBase * io = nullptr)
{
  auto writer = itk::ImageFileWriter<TImage>::New();
  writer->SetInput(image);
  writer->SetFileName(path);
  if (io)
    writer->SetImageIO(io);
  writer->Update();
}

TEST(DCVImageIO, ImageFileWriterWritesWhatTheToolWrites)
{
  const dcv::test::TemporaryDirectory directory;
  const auto                          image = Phantom({ 36, 32, 20 });
  const std::string                   input = directory / "phantom.nrrd";
  Write(image.GetPointer(), input);
  struct Case
  {
    std::string                            flags;
    std::function<void(itk::DCVImageIO &)> set;
  };
  const std::vector<Case> cases{
    { "--bpv 0.125", nullptr }, // the IO's default
    { "--bpv 0.07", [](itk::DCVImageIO & io) { io.SetBitsPerVoxel(0.07); } },
    { "--psnr 27", [](itk::DCVImageIO & io) { io.SetPSNR(27.0); } },
    { "--max-error 0", [](itk::DCVImageIO & io) { io.SetMaximumError(0.0); } },
    { "--max-error 2", [](itk::DCVImageIO & io) { io.SetMaximumError(2.0); } },
    { "--points 300 -m dec",
      [](itk::DCVImageIO & io) {
        io.SetNumberOfPoints(300);
        io.SetMode(dcv::Mode::Dec);
      } },
  };
  for (const auto & c : cases)
  {
    const std::string tool = directory / "tool.dcv";
    const std::string itk = directory / "itk.dcv";
    const auto        r = dcv::test::RunDcv("compress " + input + " " + tool + " --force " + c.flags);
    ASSERT_EQ(r.status, 0) << r.output;
    auto io = itk::DCVImageIO::New();
    if (c.set)
    {
      c.set(*io);
      Write(image.GetPointer(), itk, io);
    }
    else
    {
      Write(image.GetPointer(), itk); // through the factory, with the IO's defaults
    }
    EXPECT_EQ(dcv::test::FileBytes(itk), dcv::test::FileBytes(tool)) << c.flags;
  }
}

TEST(DCVImageIO, ImageFileWriterWritesRealCTAsTheToolDoes)
{
  DCV_REQUIRE_DATA("headsq-ct.nrrd");
  const dcv::test::TemporaryDirectory directory;
  const std::string                   input = dcv::test::DataFile("headsq-ct.nrrd");
  const auto r = dcv::test::RunDcv("compress " + input + " " + (directory / "tool.dcv") + " --bpv 0.03125");
  ASSERT_EQ(r.status, 0) << r.output;
  using CTImage = itk::Image<int16_t, 3>;
  auto io = itk::DCVImageIO::New();
  io->SetBitsPerVoxel(0.03125);
  Write(itk::ReadImage<CTImage>(input).GetPointer(), directory / "itk.dcv", io);
  EXPECT_EQ(dcv::test::FileBytes(directory / "itk.dcv"), dcv::test::FileBytes(directory / "tool.dcv"));
  EXPECT_EQ(io->GetLastEncoderResult().header.pixelType, dcv::PixelType::Int16);
}

TEST(DCVImageIO, ReadsTheFileOnce)
{
  const dcv::test::TemporaryDirectory directory;
  const std::string                   path = directory / "phantom.dcv";
  const auto                          image = Phantom({ 40, 36, 16 });
  Write(image.GetPointer(), path);
  auto io = itk::DCVImageIO::New();
  io->SetFileName(path);
  io->ReadImageInformation();
  EXPECT_EQ(io->GetComponentType(), itk::IOComponentEnum::UCHAR);
  EXPECT_EQ(io->GetDimensions(0), 40u);
  EXPECT_EQ(io->GetDimensions(2), 16u);
  EXPECT_EQ(io->GetSpacing(2), 2.5);
  std::filesystem::rename(path, directory / "moved.dcv"); // Read() needs what was read already
  std::vector<uint8_t> voxels(40 * 36 * 16);
  ASSERT_NO_THROW(io->Read(voxels.data()));
  auto reader = itk::ImageFileReader<ImageType>::New();
  reader->SetFileName(directory / "moved.dcv");
  reader->Update();
  EXPECT_TRUE(std::equal(voxels.begin(), voxels.end(), reader->GetOutput()->GetBufferPointer()));
  EXPECT_EQ(reader->GetOutput()->GetDirection(), image->GetDirection());
  EXPECT_EQ(reader->GetOutput()->GetOrigin(), image->GetOrigin());
}

TEST(DCVImageIO, WriterRefusesWhatADcvFileCannotHoldAndWritesNothing)
{
  const dcv::test::TemporaryDirectory directory;
  const std::string                   path = directory / "out.dcv";
  auto expectRefused = [&](auto image, const std::string & phrase, itk::ImageIOBase * io = nullptr) {
    try
    {
      Write(image.GetPointer(), path, io);
      FAIL() << "written: " << phrase;
    }
    catch (const itk::ExceptionObject & e)
    {
      EXPECT_NE(std::string(e.GetDescription()).find(phrase), std::string::npos) << e.GetDescription();
      EXPECT_NE(std::string(e.GetDescription()).find("out.dcv"), std::string::npos) << e.GetDescription();
    }
    EXPECT_FALSE(std::filesystem::exists(path)) << phrase;
  };
  using LongImage = itk::Image<int64_t, 3>;
  auto wide = LongImage::New();
  wide->SetRegions(LongImage::SizeType{ { 8, 8, 8 } });
  wide->Allocate(true);
  expectRefused(wide, "voxels; .dcv holds 8, 16 and 32-bit integers", itk::DCVImageIO::New());
  using FlatImage = itk::Image<uint8_t, 2>;
  auto flat = FlatImage::New();
  flat->SetRegions(FlatImage::SizeType{ { 8, 8 } });
  flat->Allocate(true);
  expectRefused(flat, "scalar 3D volumes", itk::DCVImageIO::New());
  auto tiny = itk::DCVImageIO::New();
  tiny->SetBitsPerVoxel(0.01);
  expectRefused(Phantom({ 20, 20, 20 }), "too few", tiny);
  auto both = itk::DCVImageIO::New();
  both->SetQuantizationStep(-1.0);
  expectRefused(Phantom({ 20, 20, 20 }), "QuantizationStep (--step) must be positive", both);
}

TEST(Encoder, ReportsThePSNRTheDecoderGives)
{
  const auto          image = Phantom({ 32, 30, 24 });
  dcv::EncoderOptions options;
  options.bitsPerVoxel = 0.1;
  const auto          r = itk::DCVEncode(image.GetPointer(), options);
  dcv::CompressedFile file;
  file.name = "encoded";
  dcv::ParseFile(r.bytes, file.name, file.header, file.payload);
  std::vector<uint8_t> decoded(image->GetBufferedRegion().GetNumberOfPixels());
  dcv::Rasterize(dcv::Decode(file), decoded.data());
  const double psnr =
    dcv::PSNR(dcv::SquaredError(image->GetBufferPointer(), decoded.data(), decoded.size()), decoded.size(), 255.0);
  EXPECT_EQ(r.psnr, psnr);
  EXPECT_EQ(r.header.numberOfPoints, file.header.numberOfPoints);
  EXPECT_LE(r.bytes.size(), std::size_t(0.1 * decoded.size() / 8));
  EXPECT_GT(r.timings.total, 0.0);
}

TEST(Encoder, MeetsAPSNRTargetWithFewPoints)
{
  const auto image = Phantom({ 40, 36, 28 });
  for (double target : { 24.0, 30.0 })
  {
    dcv::EncoderOptions options;
    options.psnr = target;
    const auto r = itk::DCVEncode(image.GetPointer(), options);
    EXPECT_GE(r.psnr, target);
    EXPECT_LT(r.psnr, target + 1.0) << "many more points than the target needs";
    // Fewer points by the point-count path reach less.
    options.psnr = 0.0;
    options.numberOfPoints = std::size_t(0.8 * r.header.numberOfPoints);
    options.quantizationStep = r.header.quantizationStep;
    EXPECT_LT(itk::DCVEncode(image.GetPointer(), options).psnr, target) << r.header.numberOfPoints;
  }
  dcv::EncoderOptions impossible; // values in steps of 64 cannot reach 60 dB
  impossible.psnr = 60.0;
  impossible.quantizationStep = 64.0;
  impossible.mode = dcv::Mode::Silva;
  EXPECT_THROW(itk::DCVEncode(Phantom({ 8, 8, 8 }).GetPointer(), impossible), std::range_error);
}

TEST(Encoder, ScaleFollowsTheVoxelSpacing)
{
  using S = dcv::GridScale;
  EXPECT_EQ(dcv::AutomaticScale({ 1.0, 1.0, 1.0 }), (S{ { 1, 1, 1 } }));
  EXPECT_EQ(dcv::AutomaticScale({ 2.0, 2.0, 2.0 }), (S{ { 1, 1, 1 } }));
  EXPECT_EQ(dcv::AutomaticScale({ 0.72, 0.72, 1.0 }), (S{ { 3, 3, 4 } }));
  EXPECT_EQ(dcv::AutomaticScale({ 0.72, 0.72, 4.0 }), (S{ { 2, 2, 11 } }));
  EXPECT_EQ(dcv::AutomaticScale({ 0.45, 0.45, 5.0 }), (S{ { 1, 1, 11 } }));
  EXPECT_EQ(dcv::AutomaticScale({ 5.0, 0.5, 0.5 }), (S{ { 10, 1, 1 } })); // thick along x: sagittal slices
  EXPECT_EQ(dcv::AutomaticScale({ 0.3, 0.3, 9.0 }), (S{ { 1, 1, 16 } })); // at most 16
  // The encoder takes it from the image and stores it; given explicitly, it is used as given.
  auto                image = dcv::test::PhantomImage({ 30, 30, 12 }, true); // spacing 0.5, 1, 2.5
  dcv::EncoderOptions options;
  options.numberOfPoints = 200;
  EXPECT_EQ(itk::DCVEncode(image.GetPointer(), options).header.scale, (S{ { 1, 2, 5 } }));
  options.scale = { { 1, 1, 1 } };
  EXPECT_EQ(itk::DCVEncode(image.GetPointer(), options).header.scale, (S{ { 1, 1, 1 } }));
  options.scale = { { 1, 0, 1 } };
  EXPECT_THROW(itk::DCVEncode(image.GetPointer(), options), std::invalid_argument);
}

TEST(DelaunayApproximationImageToMeshFilter, RunsOnceForManyConsumers)
{
  const dcv::test::TemporaryDirectory directory;
  const std::string                   input = directory / "phantom.nrrd";
  Write(Phantom({ 28, 24, 20 }).GetPointer(), input);
  auto reader = itk::ImageFileReader<ImageType>::New();
  reader->SetFileName(input);
  auto filter = itk::DelaunayApproximationImageToMeshFilter<ImageType, MeshType>::New();
  filter->SetInput(reader->GetOutput());
  filter->SetNumberOfPoints(200);
  unsigned starts = 0;
  auto     counter = itk::CStyleCommand::New();
  counter->SetClientData(&starts);
  counter->SetCallback([](itk::Object *, const itk::EventObject &, void * n) { ++*static_cast<unsigned *>(n); });
  filter->AddObserver(itk::StartEvent(), counter);
  std::vector<itk::TetrahedralMeshToImageFilter<MeshType, ImageType>::Pointer> consumers;
  for (int i = 0; i < 3; ++i)
  {
    auto rasterize = itk::TetrahedralMeshToImageFilter<MeshType, ImageType>::New();
    rasterize->SetInput(filter->GetOutput());
    rasterize->SetReferenceImage(reader->GetOutput());
    consumers.push_back(rasterize);
  }
  for (auto & c : consumers)
    c->Update();
  for (auto & c : consumers)
    c->Update();
  EXPECT_EQ(starts, 1u);
  EXPECT_EQ(filter->GetOutput()->GetNumberOfPoints(), 200u);
  filter->SetNumberOfPoints(150); // a change of parameters runs it again, once
  for (auto & c : consumers)
    c->Update();
  EXPECT_EQ(starts, 2u);
  EXPECT_EQ(filter->GetOutput()->GetNumberOfPoints(), 150u);
}

} // namespace

TEST(Encoder, OnlyModeDecComMakesIStar)
{
  // Mode best does not use I* (dcv::ParametersForMode): no bilateral filter runs; dec+com filters the
  // whole volume.
  auto image = ImageType::New();
  image->SetRegions(itk::Size<3>{ { 40, 36, 24 } });
  image->Allocate();
  std::mt19937 random(3);
  for (itk::ImageRegionIteratorWithIndex<ImageType> it(image, image->GetBufferedRegion()); !it.IsAtEnd(); ++it)
  {
    const auto i = it.GetIndex();
    const int  smooth =
      int(128 + 100 * std::sin(0.05 * double(i[0]) + 0.03 * double(i[2])) * std::cos(0.04 * double(i[1])));
    it.Set(uint8_t(std::clamp(smooth + int(random() % 61) - 30, 0, 255)));
  }
  dcv::EncoderOptions options;
  options.bitsPerVoxel = 0.25;
  const itk::DCVEncoderInput<ImageType> best(image.GetPointer(), options);
  EXPECT_EQ(best.Get().smoothed, nullptr) << "I* was computed for mode best";
  EXPECT_EQ(best.GetSmoothingSeconds(), 0.0);
  EXPECT_FALSE(dcv::Encode(best.Get(), options).bytes.empty());

  options.mode = dcv::Mode::DecCom;
  itk::DCVEncoderInput<ImageType> used(image.GetPointer(), options);
  ASSERT_NE(used.Get().smoothed, nullptr);
  EXPECT_NE(used.Get().smoothed, used.Get().voxels);

  // I* freed once the points are done (for the residual layers' buffers): the same file, and an input
  // whose I* is gone is refused, not read.
  const std::vector<uint8_t> kept = dcv::Encode(used.Get(), options).bytes;
  used.ReleaseSmoothedWhenDone();
  EXPECT_EQ(dcv::Encode(used.Get(), options).bytes, kept);
  EXPECT_EQ(used.Get().smoothed, nullptr);
  EXPECT_THROW(dcv::Encode(used.Get(), options), std::invalid_argument);
}

// DCVEncode taking the caller's reference frees the image once the encoder has its copy and I*, before
// the method runs, and writes the same file.
TEST(Encoder, FreesTheImageItWasHandedOnceCopied)
{
  auto image = ImageType::New();
  image->SetRegions(itk::Size<3>{ { 32, 30, 12 } });
  image->Allocate();
  std::mt19937 random(7);
  for (itk::ImageRegionIteratorWithIndex<ImageType> it(image, image->GetBufferedRegion()); !it.IsAtEnd(); ++it)
    it.Set(uint8_t(100 + 60 * std::sin(0.2 * double(it.GetIndex()[0] + it.GetIndex()[2])) + int(random() % 9)));
  dcv::EncoderOptions options;
  options.bitsPerVoxel = 0.25;
  const std::vector<uint8_t> kept = itk::DCVEncode(image.GetPointer(), options).bytes;
  bool                       freed = false, freedBeforeTheMethod = false;
  auto                       deleted = itk::CStyleCommand::New();
  // Deletion calls the const callback (UnRegister is const).
  deleted->SetConstCallback(
    [](const itk::Object *, const itk::EventObject &, void * flag) { *static_cast<bool *>(flag) = true; });
  deleted->SetClientData(&freed);
  image->AddObserver(itk::DeleteEvent(), deleted);
  options.progress = [&](double) { freedBeforeTheMethod = freedBeforeTheMethod || freed; };
  const std::vector<uint8_t> handed = itk::DCVEncode(std::move(image), options).bytes;
  EXPECT_TRUE(freed);
  EXPECT_TRUE(freedBeforeTheMethod) << "the image lived through the encoding";
  EXPECT_EQ(image, nullptr);
  EXPECT_EQ(handed, kept);
}

TEST(Encoder, AbandonsThePointsWhereTheResidualLayerWinsByFar)
{
  // Every slice the same fine texture: the inter-slice wavelet leaves one slice to code, the points
  // would need thousands of vertices per slice. The corners' layer is coded beside them, and the points
  // stop before their count is fitted: at the check on their first refinement, made when the corners'
  // layer is done (how far their schedule got by then depends on the threads' timing, not the file).
  auto image = ImageType::New();
  image->SetRegions(itk::Size<3>{ { 48, 48, 32 } });
  image->Allocate();
  std::mt19937         random(11);
  std::vector<uint8_t> slice(48 * 48);
  for (auto & v : slice)
    v = uint8_t(random() % 200);
  for (itk::ImageRegionIteratorWithIndex<ImageType> it(image, image->GetBufferedRegion()); !it.IsAtEnd(); ++it)
    it.Set(slice[std::size_t(it.GetIndex()[1] * 48 + it.GetIndex()[0])]);
  dcv::EncoderOptions options;
  options.bitsPerVoxel = 0.5;
  options.videoLayer = false; // the JPEG 2000 layer's levels are what this checks
  const auto r = itk::DCVEncode(image.GetPointer(), options);
  EXPECT_EQ(r.header.numberOfPoints, 8u);
  // Each level halves the slices left to code, so the corners' layer's descent over the levels goes on to
  // the most the 32 slices take (the earlier choice among 0, 2 and 4 levels stopped at 4).
  EXPECT_EQ(r.header.residualLevels, dcv::InterSliceLevels(32));
  EXPECT_EQ(r.adjustments, 0u) << "the points' count was fitted";
  EXPECT_GT(r.psnr, 30.0);
  // At 1/8 bit a voxel or less the descent tries more levels first: the same choice.
  options.bitsPerVoxel = 0.125;
  const auto low = itk::DCVEncode(image.GetPointer(), options);
  EXPECT_EQ(low.header.numberOfPoints, 8u);
  EXPECT_EQ(low.header.residualLevels, dcv::InterSliceLevels(32));
  // With the video layer too: the points abandoned as early.
  options.videoLayer = true;
  const auto video = itk::DCVEncode(image.GetPointer(), options);
  EXPECT_EQ(video.header.numberOfPoints, 8u);
  EXPECT_EQ(video.adjustments, 0u) << "the points' count was fitted";
  EXPECT_GE(video.psnr, low.psnr);
  options.videoLayer = false;
  options.bitsPerVoxel = 0.5;
  // The phantom at a low rate: the points beat the JPEG 2000 layers, and are not abandoned (the video
  // layer, which decodes it closer still, left out).
  const auto phantom = itk::DCVEncode(Phantom({ 56, 48, 40 }).GetPointer(), options);
  EXPECT_GT(phantom.header.numberOfPoints, 8u);
  EXPECT_GT(phantom.timings.decimation, 0.0);
}

TEST(Encoder, SameFileWhateverTheNumberOfThreads)
{
  // Large enough that the rescans and the least-squares assembly split over threads (thousands of
  // cells), with noise for I* to smooth, and a budget that leaves room for a residual layer.
  auto         image = Phantom({ 56, 48, 40 });
  std::mt19937 random(7);
  for (itk::ImageRegionIteratorWithIndex<ImageType> it(image, image->GetBufferedRegion()); !it.IsAtEnd(); ++it)
    it.Set(uint8_t(std::clamp(int(it.Get()) + int(random() % 41) - 20, 0, 255)));
  // The points alone in mode dec+com (I*: the bilateral filter runs on threads), and with the residual
  // layer in mode best (its inter-slice wavelet runs on threads too).
  for (bool layer : { false, true })
  {
    dcv::EncoderOptions options;
    options.bitsPerVoxel = 0.15;
    options.residualLayer = layer;
    options.mode = layer ? dcv::Mode::Best : dcv::Mode::DecCom;
    options.threads = 1;
    const auto one = itk::DCVEncode(image.GetPointer(), options);
    if (layer)
      EXPECT_GT(one.header.residualLayer.size(), 0u);
    else
      EXPECT_GT(one.header.numberOfPoints, 1000u);
    for (unsigned threads : { 2u, 3u, 0u })
    {
      options.threads = threads;
      const auto r = itk::DCVEncode(image.GetPointer(), options);
      EXPECT_EQ(r.bytes, one.bytes) << threads << " threads, layer " << layer;
      EXPECT_EQ(r.psnr, one.psnr) << threads << " threads, layer " << layer;
    }
  }
}
