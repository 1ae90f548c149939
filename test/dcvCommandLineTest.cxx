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
// dcv on the command line: the demo path, and a clear error with a non-zero exit for each bad input.
#include "dcvRateControl.h"
#include "dcvVideoLayer.h"
#include "dcvTestUtilities.h"

#include "itkConfigure.h"
#include "itkImageFileWriter.h"
#include "itkVectorImage.h"

#include <CGAL/version_macros.h>
#include <dcmtk/dcmdata/dcuid.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <thread>
#include <tuple>

namespace
{
namespace fs = std::filesystem;

using dcv::test::Result;
using dcv::test::RunDcv;

class CommandLine : public ::testing::Test
{
protected:
  void
  SetUp() override
  {
    std::string test = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    std::replace(test.begin(), test.end(), '/', '-'); // a parameterized test's name
    m_Directory = fs::temp_directory_path() / ("dcv-cli-" + std::to_string(::getpid()) + "-" + test);
    fs::remove_all(m_Directory);
    fs::create_directories(m_Directory);
  }
  void
  TearDown() override
  {
    fs::remove_all(m_Directory);
  }
  std::string
  Path(const std::string & name) const
  {
    return (m_Directory / name).string();
  }
  template <typename TImage>
  std::string
  Write(typename TImage::Pointer image, const std::string & name)
  {
    auto writer = itk::ImageFileWriter<TImage>::New();
    writer->SetInput(image);
    writer->SetFileName(Path(name));
    writer->Update();
    return Path(name);
  }
  template <unsigned int D>
  std::string
  WriteScalar(const std::string & name, unsigned int n)
  {
    using ImageType = itk::Image<uint8_t, D>;
    auto                         image = ImageType::New();
    typename ImageType::SizeType size;
    size.Fill(n);
    image->SetRegions(size);
    image->Allocate(true);
    return Write<ImageType>(image, name);
  }
  /** Runs `dcv approximate INPUT out.nrrd EXTRA` and expects a failure whose message has every phrase. */
  void
  ExpectRefused(const std::string & input, const std::vector<std::string> & phrases, const std::string & extra = "")
  {
    const Result r = RunDcv("approximate " + input + " " + Path("out.nrrd") + extra);
    EXPECT_NE(r.status, 0);
    for (const auto & phrase : phrases)
    {
      EXPECT_NE(r.output.find(phrase), std::string::npos) << "missing '" << phrase << "' in: " << r.output;
    }
  }
  fs::path m_Directory;
};

TEST_F(CommandLine, HelpDescribesTheCommands)
{
  const Result r = RunDcv("--help");
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.output.find("approximate"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("phantom"), std::string::npos) << r.output;
  const Result a = RunDcv("approximate --help");
  EXPECT_EQ(a.status, 0);
  EXPECT_NE(a.output.find("--points"), std::string::npos) << a.output;
  EXPECT_NE(a.output.find("--force"), std::string::npos) << a.output;
}

TEST_F(CommandLine, PhantomThenApproximate)
{
  const std::string phantom = Path("phantom.nrrd");
  const std::string output = Path("approximation.nrrd");
  Result            r = RunDcv("phantom " + phantom + " --size 32");
  ASSERT_EQ(r.status, 0) << r.output;
  r = RunDcv("approximate " + phantom + " " + output + " --points 500");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("points: 500"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("PSNR: "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("seconds: "), std::string::npos) << r.output;

  // The output has the input's geometry and pixel type, and the PSNR printed is the one it has.
  using ImageType = itk::Image<uint8_t, 3>;
  auto in = itk::ReadImage<ImageType>(phantom);
  auto reader = itk::ImageFileReader<ImageType>::New();
  reader->SetFileName(output);
  reader->Update();
  EXPECT_EQ(reader->GetImageIO()->GetComponentType(), itk::IOComponentEnum::UCHAR);
  auto out = reader->GetOutput();
  EXPECT_EQ(out->GetLargestPossibleRegion(), in->GetLargestPossibleRegion());
  const auto   n = in->GetLargestPossibleRegion().GetNumberOfPixels();
  const double psnr = dcv::PSNR(dcv::SquaredError(in->GetBufferPointer(), out->GetBufferPointer(), n), n, 255.0);
  const double printed = std::stod(r.output.substr(r.output.find("PSNR: ") + 6));
  EXPECT_NEAR(printed, psnr, 1e-3);
  EXPECT_GT(psnr, 15.0);
}

TEST_F(CommandLine, MissingInput)
{
  ExpectRefused(Path("nothing.nrrd"), { "nothing.nrrd", "no such file" });
  EXPECT_FALSE(fs::exists(Path("out.nrrd")));
}

TEST_F(CommandLine, NotAnImage)
{
  std::ofstream(Path("text.nrrd")) << "this is not a volume\n";
  ExpectRefused(Path("text.nrrd"), { "text.nrrd" });
  EXPECT_FALSE(fs::exists(Path("out.nrrd")));
}

TEST_F(CommandLine, TwoDimensionalImage)
{
  ExpectRefused(WriteScalar<2>("slice.nrrd", 16), { "is a 2D image", "slice.nrrd" });
}

TEST_F(CommandLine, FourDimensionalImage)
{
  ExpectRefused(WriteScalar<4>("series.nrrd", 4), { "is a 4D image" });
}

TEST_F(CommandLine, FlatVolume)
{
  using ImageType = itk::Image<uint8_t, 3>;
  auto                image = ImageType::New();
  ImageType::SizeType size{ { 8, 8, 1 } };
  image->SetRegions(size);
  image->Allocate(true);
  ExpectRefused(Write<ImageType>(image, "flat.nrrd"), { "at least 2 voxels along each axis" });
}

TEST_F(CommandLine, VectorPixels)
{
  using ImageType = itk::VectorImage<float, 3>;
  auto                image = ImageType::New();
  ImageType::SizeType size{ { 4, 4, 4 } };
  image->SetRegions(size);
  image->SetNumberOfComponentsPerPixel(3);
  image->Allocate(true);
  ExpectRefused(Write<ImageType>(image, "vectors.nrrd"), { "3 components per voxel", "scalar volume" });
}

TEST_F(CommandLine, TooFewPoints)
{
  ExpectRefused(WriteScalar<3>("volume.nrrd", 8), { "NumberOfPoints (--points) must be at least 8" }, " --points 7");
  EXPECT_FALSE(fs::exists(Path("out.nrrd")));
}

TEST_F(CommandLine, BadMethodParameters)
{
  const std::string input = WriteScalar<3>("volume.nrrd", 8);
  ExpectRefused(input, { "--mode", "unknown mode 'fast'", "silva, dec, dec+com or best" }, " --mode fast");
  ExpectRefused(input, { "Alpha (--alpha) must be positive" }, " --alpha 0");
  ExpectRefused(input, { "DomainSigma (--domain-sigma) must be positive" }, " --domain-sigma -1");
  ExpectRefused(input, { "RangeSigma (--range-sigma) must be positive, or 0" }, " --range-sigma -2");
  EXPECT_FALSE(fs::exists(Path("out.nrrd")));
}

TEST_F(CommandLine, ExistingOutputNeedsForce)
{
  const std::string input = WriteScalar<3>("volume.nrrd", 8);
  const std::string output = Path("precious.nrrd");
  std::ofstream(output) << "keep me";
  Result r = RunDcv("approximate " + input + " " + output + " --points 20");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("already exists"), std::string::npos) << r.output;
  std::ifstream     kept(output);
  const std::string content((std::istreambuf_iterator<char>(kept)), std::istreambuf_iterator<char>());
  EXPECT_EQ(content, "keep me");

  r = RunDcv("approximate " + input + " " + output + " --points 20 --force");
  EXPECT_EQ(r.status, 0) << r.output;
  using ImageType = itk::Image<uint8_t, 3>;
  EXPECT_NO_THROW(itk::ReadImage<ImageType>(output));
}

/** The whole file fits the bit budget of `voxels` at `bpv` and fills at least what the encoder promises,
 * 97% of it (dcv::MinimumFileBytes), or with an AV1 video layer, whose size moves by whole levels,
 * dcv::AV1MinimumFill; compress printed its size. */
void
ExpectTheFileFillsTheBudget(const std::string & file, double bpv, uint64_t voxels, const std::string & printed)
{
  const auto budget = std::size_t(std::floor(bpv * double(voxels) / 8.0));
  const auto bytes = std::size_t(fs::file_size(file));
  EXPECT_LE(bytes, budget);
  const bool av1 = printed.find("(an AV1 stream)") != std::string::npos;
  EXPECT_GE(bytes, av1 ? std::size_t(std::ceil(dcv::AV1MinimumFill * double(budget))) : dcv::MinimumFileBytes(budget))
    << "budget " << budget << ", " << 100.0 * double(bytes) / double(budget) << "% of it" << (av1 ? " (AV1)" : "");
  EXPECT_NE(printed.find("bytes: " + std::to_string(bytes)), std::string::npos) << printed;
}

TEST_F(CommandLine, CompressDecompressInfo)
{
  const std::string phantom = Path("phantom.nrrd");
  ASSERT_EQ(RunDcv("phantom " + phantom + " --size 40").status, 0);
  const std::string packed = Path("phantom.dcv");
  const Result      c = RunDcv("compress " + phantom + " " + packed + " --bpv 0.0625");
  ASSERT_EQ(c.status, 0) << c.output;
  ExpectTheFileFillsTheBudget(packed, 0.0625, 40 * 40 * 40, c.output);
  // The stages one after another: their seconds add up to the whole run's.
  {
    const double      seconds = std::stod(c.output.substr(c.output.find("\nseconds: ") + 10));
    const auto        from = c.output.find("seconds by stage: ");
    const std::string line = c.output.substr(from, c.output.find('\n', from) - from);
    const std::regex  stage("([a-z ]+) ([0-9.e+-]+) \\(([0-9.]+)%\\)");
    double            sum = 0.0;
    int               stages = 0;
    for (auto m = std::sregex_iterator(line.begin(), line.end(), stage); m != std::sregex_iterator(); ++m, ++stages)
      sum += std::stod((*m)[2]);
    EXPECT_EQ(stages, 7) << line;
    EXPECT_NEAR(sum, seconds, 1e-3 + 1e-4 * seconds) << line;
  }

  const Result info = RunDcv("info " + packed);
  ASSERT_EQ(info.status, 0) << info.output;
  EXPECT_NE(info.output.find("size: 40 40 40"), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("pixel type: uint8"), std::string::npos) << info.output;

  const std::string decoded = Path("decoded.nrrd");
  const Result      d = RunDcv("decompress " + packed + " " + decoded);
  ASSERT_EQ(d.status, 0) << d.output;
  // The PSNR compress printed is the one of what decompress wrote.
  using ImageType = itk::Image<uint8_t, 3>;
  auto         in = itk::ReadImage<ImageType>(phantom);
  auto         out = itk::ReadImage<ImageType>(decoded);
  const auto   n = in->GetLargestPossibleRegion().GetNumberOfPixels();
  const double psnr = dcv::PSNR(dcv::SquaredError(in->GetBufferPointer(), out->GetBufferPointer(), n), n, 255.0);
  const double printed = std::stod(c.output.substr(c.output.find("PSNR: ") + 6));
  EXPECT_NEAR(printed, psnr, 1e-3);
  EXPECT_EQ(out->GetLargestPossibleRegion(), in->GetLargestPossibleRegion());
}

/** The budget's promise on every dev volume (../shared/data) at 0.03125 bpv, the smallest files of the dev
 * runs: head-mr's is 488 bytes, of which its residual layer's steps left 19 unused (96.1%) before the fill
 * tried fewer 2D wavelet levels. */
class CommandLineBudget
  : public CommandLine
  , public ::testing::WithParamInterface<const char *>
{};

const char * const DevVolumes[] = { "avg152t1.nrrd", "ct-avm-4mm.nrrd",   "ct-avm.nrrd",   "flair-mr.nrrd",
                                    "head-mr.nrrd",  "headsq-ct.nrrd",    "ironprot.nrrd", "neghip.nrrd",
                                    "norm-256.nrrd", "dicom-ct-brain-5mm" };

TEST_P(CommandLineBudget, TheFileFillsTheBudgetAtAThirtySecondOfABitPerVoxel)
{
  DCV_REQUIRE_DATA(GetParam());
  const std::string packed = Path("volume.dcv");
  const Result      c = RunDcv("compress " + dcv::test::DataFile(GetParam()) + " " + packed + " --bpv 0.03125");
  ASSERT_EQ(c.status, 0) << c.output;
  const Result info = RunDcv("info " + packed);
  ASSERT_EQ(info.status, 0) << info.output;
  std::smatch size;
  ASSERT_TRUE(std::regex_search(info.output, size, std::regex("size: ([0-9]+) ([0-9]+) ([0-9]+)"))) << info.output;
  const uint64_t voxels = std::stoull(size[1]) * std::stoull(size[2]) * std::stoull(size[3]);
  ExpectTheFileFillsTheBudget(packed, 0.03125, voxels, c.output);
}

INSTANTIATE_TEST_SUITE_P(DevVolumes, CommandLineBudget, ::testing::ValuesIn(DevVolumes),
                         [](const ::testing::TestParamInfo<const char *> & info) {
                           std::string name = info.param;
                           name = name.substr(0, name.find('.'));
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

/** Every volume of ../shared/data is one of DevVolumes, so that a volume added there is tested too. */
TEST(CommandLineBudgetVolumes, AreEveryDevVolume)
{
  DCV_REQUIRE_DATA("");
  const std::set<std::string> listed(std::begin(DevVolumes), std::end(DevVolumes));
  for (const auto & entry : fs::directory_iterator(dcv::test::DataFile("")))
  {
    const std::string name = entry.path().filename().string();
    if (entry.path().extension() == ".nrrd" || (entry.is_directory() && name.rfind("dicom-", 0) == 0))
      EXPECT_EQ(listed.count(name), 1u) << name << " is not in DevVolumes";
  }
}

TEST_F(CommandLine, CompressOnMoreThreadsThanCoresIsQuietAndTheSame)
{
  const std::string phantom = Path("phantom.nrrd");
  ASSERT_EQ(RunDcv("phantom " + phantom + " --size 32").status, 0);
  const unsigned    many = 2 * std::max(1u, std::thread::hardware_concurrency()) + 1;
  const std::string one = Path("one.dcv"), more = Path("more.dcv");
  const Result      a = RunDcv("compress " + phantom + " " + one + " --bpv 0.125 --threads 1 --quiet");
  ASSERT_EQ(a.status, 0) << a.output;
  const Result b =
    RunDcv("compress " + phantom + " " + more + " --bpv 0.125 --quiet --threads " + std::to_string(many));
  ASSERT_EQ(b.status, 0) << b.output;
  EXPECT_EQ(b.output, "") << "--quiet prints nothing (TBB warned of workers beyond the cores)";
  EXPECT_EQ(dcv::test::FileBytes(one), dcv::test::FileBytes(more));
}

TEST_F(CommandLine, CompressRefusesABudgetTooSmallAndWritesNothing)
{
  const std::string phantom = Path("phantom.nrrd");
  ASSERT_EQ(RunDcv("phantom " + phantom + " --size 24").status, 0);
  const std::string packed = Path("tiny.dcv");
  const Result      r = RunDcv("compress " + phantom + " " + packed + " --bpv 0.01"); // 17 bytes
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("cannot compress"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("phantom.nrrd"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("too few"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("ITK ERROR"), std::string::npos) << r.output; // the user's words, not ITK's
  EXPECT_FALSE(fs::exists(packed));
}

TEST_F(CommandLine, CompressIsReproducible)
{
  const std::string phantom = Path("phantom.nrrd");
  ASSERT_EQ(RunDcv("phantom " + phantom + " --size 32").status, 0);
  ASSERT_EQ(RunDcv("compress " + phantom + " " + Path("a.dcv") + " --bpv 0.1").status, 0);
  ASSERT_EQ(RunDcv("compress " + phantom + " " + Path("b.dcv") + " --bpv 0.1").status, 0);
  std::ifstream     a(Path("a.dcv"), std::ios::binary), b(Path("b.dcv"), std::ios::binary);
  const std::string first((std::istreambuf_iterator<char>(a)), std::istreambuf_iterator<char>());
  const std::string second((std::istreambuf_iterator<char>(b)), std::istreambuf_iterator<char>());
  EXPECT_FALSE(first.empty());
  EXPECT_EQ(first, second); // CGAL's memory order must not leak into the result
}

TEST_F(CommandLine, CompressKeepsPixelTypeAndGeometryOfRealCT)
{
  DCV_REQUIRE_DATA("headsq-ct.nrrd");
  const std::string packed = Path("ct.dcv");
  const Result c = RunDcv("compress " + dcv::test::DataFile("headsq-ct.nrrd") + " " + packed + " --points 500 -m dec");
  ASSERT_EQ(c.status, 0) << c.output;
  ASSERT_EQ(RunDcv("decompress " + packed + " " + Path("ct.nrrd")).status, 0);
  using ImageType = itk::Image<int16_t, 3>;
  auto reader = itk::ImageFileReader<ImageType>::New();
  reader->SetFileName(Path("ct.nrrd"));
  reader->Update();
  auto original = itk::ReadImage<ImageType>(dcv::test::DataFile("headsq-ct.nrrd"));
  EXPECT_EQ(reader->GetImageIO()->GetComponentType(), itk::IOComponentEnum::SHORT);
  EXPECT_EQ(reader->GetOutput()->GetSpacing(), original->GetSpacing());
  EXPECT_EQ(reader->GetOutput()->GetOrigin(), original->GetOrigin());
  EXPECT_EQ(reader->GetOutput()->GetDirection(), original->GetDirection());
}

TEST_F(CommandLine, BadCompressedFiles)
{
  const std::string phantom = Path("phantom.nrrd");
  ASSERT_EQ(RunDcv("phantom " + phantom + " --size 24").status, 0);
  const std::string packed = Path("good.dcv");
  ASSERT_EQ(RunDcv("compress " + phantom + " " + packed + " --points 100").status, 0);
  std::ifstream     in(packed, std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto              write = [&](const std::string & name, const std::vector<char> & b) {
    std::ofstream(Path(name), std::ios::binary).write(b.data(), std::streamsize(b.size()));
    return Path(name);
  };
  std::vector<char> magic = bytes;
  magic[1] = 'X';
  std::vector<char> truncated(bytes.begin(), bytes.begin() + std::ptrdiff_t(bytes.size() / 2));
  std::vector<char> flipped = bytes;
  flipped[bytes.size() / 2] ^= 0x10;
  for (const auto & [name, content, phrase] :
       { std::make_tuple(std::string("magic.dcv"), magic, std::string("not a .dcv file")),
         std::make_tuple(std::string("cut.dcv"), truncated, std::string("CRC-32")),
         std::make_tuple(std::string("flip.dcv"), flipped, std::string("CRC-32")) })
  {
    const std::string file = write(name, content);
    for (const std::string command : { "decompress " + file + " " + Path("out.nrrd"), "info " + file })
    {
      const Result r = RunDcv(command);
      EXPECT_NE(r.status, 0) << command;
      EXPECT_NE(r.output.find(name), std::string::npos) << r.output;
      EXPECT_NE(r.output.find(phrase), std::string::npos) << r.output;
    }
    EXPECT_FALSE(fs::exists(Path("out.nrrd")));
  }
  // compress refuses a name that is not .dcv, and keeps an existing file without --force.
  EXPECT_NE(RunDcv("compress " + phantom + " " + Path("x.nrrd") + " -n 50").status, 0);
  const Result again = RunDcv("compress " + phantom + " " + packed + " -n 50");
  EXPECT_NE(again.status, 0);
  EXPECT_NE(again.output.find("already exists"), std::string::npos);
}

TEST_F(CommandLine, UnknownOutputFormat)
{
  const std::string input = WriteScalar<3>("volume.nrrd", 8);
  const Result      r = RunDcv("approximate " + input + " " + Path("out.unknown"));
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("no image format"), std::string::npos) << r.output;
}

TEST_F(CommandLine, ApproximatesRealCTWithItsPixelType)
{
  DCV_REQUIRE_DATA("headsq-ct.nrrd");
  const std::string output = Path("ct.nii.gz");
  const Result      r = RunDcv("approximate " + dcv::test::DataFile("headsq-ct.nrrd") + " " + output + " -n 2000");
  ASSERT_EQ(r.status, 0) << r.output;
  auto reader = itk::ImageFileReader<itk::Image<int16_t, 3>>::New();
  reader->SetFileName(output);
  reader->Update();
  EXPECT_EQ(reader->GetImageIO()->GetComponentType(), itk::IOComponentEnum::SHORT);
  EXPECT_EQ(reader->GetOutput()->GetLargestPossibleRegion().GetSize(), (itk::Size<3>{ { 64, 64, 93 } }));
}

TEST_F(CommandLine, UsageErrorsExitWithStatusTwo)
{
  EXPECT_EQ(RunDcv("--help").status, 0);
  EXPECT_EQ(RunDcv("--version").status, 0);
  EXPECT_EQ(RunDcv("").status, 2);
  EXPECT_EQ(RunDcv("compress").status, 2);
  EXPECT_EQ(RunDcv("compress a.nrrd b.dcv --bogus").status, 2);
  EXPECT_EQ(RunDcv("frobnicate").status, 2);
}

TEST_F(CommandLine, VersionNamesTheModuleAndTheLibrariesItWasBuiltWith)
{
  const Result r = RunDcv("--version");
  ASSERT_EQ(r.status, 0) << r.output;
  // The module's version as CMake's project() sets it (DCV_PROJECT_VERSION, test/CMakeLists.txt).
  EXPECT_EQ(r.output.rfind(std::string("dcv ") + DCV_PROJECT_VERSION + "\n", 0), 0u) << r.output;
  const std::string itk = "ITK " + std::to_string(ITK_VERSION_MAJOR) + "." + std::to_string(ITK_VERSION_MINOR) + "." +
                          std::to_string(ITK_VERSION_PATCH);
  // The libraries on one line: ITK, CGAL and DCMTK as this test was compiled against them, OpenJPEG, x265,
  // libde265, libaom and dav1d (as loaded at run time) with versions of numbers.
  const std::regex libraries(
    "\n" + itk + ", CGAL " + CGAL_VERSION_STR +
    ", OpenJPEG [0-9]+\\.[0-9]+\\.[0-9]+, x265 [0-9]+\\.[0-9][^,]*, libde265 [0-9]+\\.[0-9]+\\.[0-9]+, "
    "libaom [0-9]+\\.[0-9]+\\.[0-9]+, dav1d [0-9]+\\.[0-9]+\\.[0-9]+, DCMTK " +
    OFFIS_DCMTK_VERSION_STRING + "\n?$");
  EXPECT_TRUE(std::regex_search(r.output, libraries)) << r.output;
}

// --video-codec: the codec asked is the one in the file (a 16^3 phantom at 3.35 bpv, where the video layer
// wins); both: the closer of the two; another name: exit 2.
TEST_F(CommandLine, VideoCodecChoosesTheVideoLayersCodec)
{
  const std::string phantom = Path("phantom.nrrd");
  ASSERT_EQ(RunDcv("phantom " + phantom + " --size 16").status, 0);
  std::map<std::string, double> psnr;
  for (const std::string codec : { "hevc", "av1", "both" })
  {
    const Result r = RunDcv("compress " + phantom + " " + Path(codec + ".dcv") + " --bpv 3.35 --video-codec " + codec);
    ASSERT_EQ(r.status, 0) << r.output;
    const std::string stream = codec == "hevc" ? "(an HEVC stream)" : "(an AV1 stream)";
    EXPECT_NE(r.output.find(stream), std::string::npos) << codec << ": " << r.output;
    const Result info = RunDcv("info " + Path(codec + ".dcv"));
    EXPECT_NE(info.output.find(stream), std::string::npos) << codec << ": " << info.output;
    psnr[codec] = std::stod(r.output.substr(r.output.find("PSNR: ") + 6));
  }
  EXPECT_EQ(psnr["both"], std::max(psnr["hevc"], psnr["av1"]));
  const Result bad = RunDcv("compress " + phantom + " " + Path("x.dcv") + " --bpv 1 --video-codec vp9");
  EXPECT_EQ(bad.status, 2) << bad.output;
  EXPECT_NE(bad.output.find("--video-codec"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(Path("x.dcv")));
}

TEST_F(CommandLine, OneTargetAtATime)
{
  const std::string phantom = Path("phantom.nrrd");
  ASSERT_EQ(RunDcv("phantom " + phantom + " --size 16").status, 0);
  for (const std::string flags : { "--bpv 0.1 --points 50", "--bpv 0.1 --psnr 30", "--psnr 30 -n 50" })
  {
    const Result r = RunDcv("compress " + phantom + " " + Path("x.dcv") + " " + flags);
    EXPECT_EQ(r.status, 2) << flags;
    EXPECT_NE(r.output.find("excludes"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(Path("x.dcv")));
  }
}

TEST_F(CommandLine, CompressToAPSNRTarget)
{
  const std::string phantom = Path("phantom.nrrd");
  ASSERT_EQ(RunDcv("phantom " + phantom + " --size 40").status, 0);
  const Result r = RunDcv("compress " + phantom + " " + Path("q.dcv") + " --psnr 26");
  ASSERT_EQ(r.status, 0) << r.output;
  const double printed = std::stod(r.output.substr(r.output.find("PSNR: ") + 6));
  EXPECT_GE(printed, 26.0);
  EXPECT_LT(printed, 27.0);
}

TEST_F(CommandLine, DecompressWritesCompressedVolumes)
{
  const std::string phantom = Path("phantom.nrrd");
  ASSERT_EQ(RunDcv("phantom " + phantom + " --size 40").status, 0);
  EXPECT_NE(dcv::test::FileBytes(phantom).find("encoding: gzip"), std::string::npos);
  // Points only: a piecewise-linear volume, which gzip shrinks well below its raw size.
  ASSERT_EQ(RunDcv("compress " + phantom + " " + Path("p.dcv") + " --bpv 0.1 --no-residual-layer").status, 0);
  ASSERT_EQ(RunDcv("decompress " + Path("p.dcv") + " " + Path("d.nrrd")).status, 0);
  EXPECT_NE(dcv::test::FileBytes(Path("d.nrrd")).find("encoding: gzip"), std::string::npos);
  EXPECT_LT(fs::file_size(Path("d.nrrd")), 40u * 40 * 40 / 2);
  // --no-compression: raw, the same voxels.
  ASSERT_EQ(RunDcv("decompress " + Path("p.dcv") + " " + Path("r.nrrd") + " --no-compression").status, 0);
  EXPECT_NE(dcv::test::FileBytes(Path("r.nrrd")).find("encoding: raw"), std::string::npos);
  EXPECT_GT(fs::file_size(Path("r.nrrd")), 40u * 40 * 40);
  using ImageType = itk::Image<uint8_t, 3>;
  const auto gz = itk::ReadImage<ImageType>(Path("d.nrrd"));
  const auto raw = itk::ReadImage<ImageType>(Path("r.nrrd"));
  EXPECT_TRUE(std::equal(gz->GetBufferPointer(), gz->GetBufferPointer() + 40 * 40 * 40, raw->GetBufferPointer()));
}

TEST_F(CommandLine, AFailedWriteLeavesNoFile)
{
  const std::string phantom = Path("phantom.nrrd");
  ASSERT_EQ(RunDcv("phantom " + phantom + " --size 16").status, 0);
  ASSERT_EQ(RunDcv("compress " + phantom + " " + Path("p.dcv") + " -n 40").status, 0);
  // PNG holds 2D images: ITK's factory offers no writer of a 3D volume for the name, a usage error (the
  // writes that fail on the way, a full disk, are dcvRobustnessTest's Outputs.AFailedWriteLeavesNothing...).
  const Result r = RunDcv("decompress " + Path("p.dcv") + " " + Path("out.png"));
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("cannot write"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("out.png"), std::string::npos) << r.output;
  std::size_t files = 0;
  for (const auto & entry : fs::directory_iterator(m_Directory))
  {
    ++files;
    EXPECT_NE(entry.path().filename().string().substr(0, 5), ".dcv-") << entry.path();
  }
  EXPECT_EQ(files, 2u); // phantom.nrrd and p.dcv
}

TEST_F(CommandLine, PointCountsBeyondTheVolumeAreRefused)
{
  const std::string phantom = Path("phantom.nrrd");
  ASSERT_EQ(RunDcv("phantom " + phantom + " --size 16").status, 0);
  Result r = RunDcv("compress " + phantom + " " + Path("x.dcv") + " --points -1");
  EXPECT_EQ(r.status, 2) << r.output; // CLI11 refuses it: a usage error
  r = RunDcv("compress " + phantom + " " + Path("x.dcv") + " --points 10000000");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("at most the number of voxels, 4096"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(Path("x.dcv")));
}

} // namespace

TEST_F(CommandLine, MaximumErrorGivesLosslessAndBoundedFiles)
{
  const std::string phantom = Path("phantom.nrrd");
  ASSERT_EQ(RunDcv("phantom " + phantom + " --size 24").status, 0);
  using ImageType = itk::Image<uint8_t, 3>;
  const auto original = itk::ReadImage<ImageType>(phantom);
  for (const int bound : { 0, 3 })
  {
    const std::string packed = Path("bounded" + std::to_string(bound) + ".dcv");
    const Result      c = RunDcv("compress " + phantom + " " + packed + " --max-error " + std::to_string(bound));
    ASSERT_EQ(c.status, 0) << c.output;
    EXPECT_NE(c.output.find("mode: bounded error"), std::string::npos) << c.output;
    const std::string stated = bound == 0 ? "maximum error: 0 (lossless)" : "maximum error: 3 (every voxel";
    EXPECT_NE(c.output.find(stated), std::string::npos) << c.output;
    const Result info = RunDcv("info " + packed);
    EXPECT_NE(info.output.find(stated), std::string::npos) << info.output;
    EXPECT_NE(info.output.find("a bounded-error layer"), std::string::npos) << info.output;
    const std::string decoded = Path("bounded" + std::to_string(bound) + ".nrrd");
    ASSERT_EQ(RunDcv("decompress " + packed + " " + decoded).status, 0);
    const auto back = itk::ReadImage<ImageType>(decoded);
    const auto n = original->GetBufferedRegion().GetNumberOfPixels();
    int        worst = 0;
    for (std::size_t i = 0; i < n; ++i)
      worst = std::max(worst, std::abs(int(back->GetBufferPointer()[i]) - int(original->GetBufferPointer()[i])));
    EXPECT_LE(worst, bound);
  }
  // A lossy file states no bound.
  ASSERT_EQ(RunDcv("compress " + phantom + " " + Path("lossy.dcv") + " --bpv 0.5").status, 0);
  EXPECT_NE(RunDcv("info " + Path("lossy.dcv")).output.find("maximum error: none"), std::string::npos);
}

TEST_F(CommandLine, BadMaximumErrorsAreUsageErrors)
{
  const std::string phantom = Path("phantom.nrrd");
  ASSERT_EQ(RunDcv("phantom " + phantom + " --size 16").status, 0);
  for (const std::string flags : { "--max-error -1",
                                   "--max-error nan",
                                   "--max-error inf",
                                   "--max-error x",
                                   "--max-error 1 --bpv 0.1",
                                   "--max-error 1 --psnr 30",
                                   "--max-error 0 -n 50" })
  {
    const Result r = RunDcv("compress " + phantom + " " + Path("x.dcv") + " " + flags);
    EXPECT_EQ(r.status, 2) << flags << ": " << r.output;
    EXPECT_NE(r.output.find("max-error"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(Path("x.dcv")));
  }
}
