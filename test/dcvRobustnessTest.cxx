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
// What a careless user and an attacker would find: no partial outputs (a full disk,
// a race, the output given as the input, a signal), the exit status of each kind of error, and volumes
// with bad numbers (NaN, infinities, constant, tiny, one slice), each refused clearly or coded correctly.
#include "dcvTestUtilities.h"

#include "dcvEncoder.h"
#include "dcvTools.h"
#include "itkDCVEncoder.h"
#include "itkImageFileWriter.h"

#include <csignal>
#include <cmath>
#include <fstream>
#include <limits>

namespace
{
namespace fs = std::filesystem;

using dcv::test::Result;
using dcv::test::RunDcv;

/** The names in a directory, sorted. */
std::vector<std::string>
Names(const std::string & directory)
{
  std::vector<std::string> names;
  for (const auto & entry : fs::directory_iterator(directory))
  {
    names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

/** dcv with a file size limit of 1 KiB: every write beyond it fails (EFBIG) as on a full disk, the
 * signal that would kill the process ignored, as a full disk sends none. */
Result
RunDcvWithFullDisk(const std::string & arguments)
{
  return dcv::test::RunCommand("sh -c \"ulimit -f 1; trap '' XFSZ; exec '" + std::string(DCV_EXECUTABLE) + "' " +
                               arguments + "\" 2>&1");
}

template <typename T>
std::string
WriteVolume(const std::string & path, const itk::Size<3> & size, const std::function<T(std::size_t)> & value)
{
  using ImageType = itk::Image<T, 3>;
  auto image = ImageType::New();
  image->SetRegions(size);
  image->Allocate();
  for (std::size_t i = 0; i < image->GetBufferedRegion().GetNumberOfPixels(); ++i)
  {
    image->GetBufferPointer()[i] = value(i);
  }
  itk::WriteImage(image, path);
  return path;
}

/** A smooth float volume with `bad` at a few voxels. */
std::string
FloatVolumeWith(const std::string & path, float bad, std::size_t count)
{
  return WriteVolume<float>(path, { { 12, 12, 12 } }, [&](std::size_t i) {
    return i % (1728 / count) == 5 && i / (1728 / count) < count ? bad : float(i % 12) * 0.5f + float(i / 144);
  });
}

double
PrintedPSNR(const std::string & output)
{
  const auto at = output.find("PSNR: ");
  return at == std::string::npos ? -1.0 : std::stod(output.substr(at + 6));
}

TEST(Outputs, AFailedWriteLeavesNothingUnderAnyName)
{
  const dcv::test::TemporaryDirectory d;
  ASSERT_EQ(RunDcv("phantom " + d / "p.nrrd" + " --size 48").status, 0);
  ASSERT_EQ(RunDcv("compress " + d / "p.nrrd" + " " + d / "p.dcv" + " -n 3000 -q").status, 0);
  ASSERT_GT(fs::file_size(d / "p.dcv"), 1024u);
  const std::vector<std::string> before = Names(d / "");
  // MetaImage and NIfTI writers only print on a failed write; .mhd, .hdr and .nhdr are several files.
  for (const std::string & name :
       std::vector<std::string>{ "o.nrrd", "o.mha", "o.nii", "o.nii.gz", "o.mhd", "o.hdr", "o.nhdr" })
  {
    for (const std::string & command : std::vector<std::string>{ "decompress " + d / "p.dcv",
                                                                 "convert " + d / "p.nrrd",
                                                                 "approximate " + d / "p.nrrd" + " -n 50 --mode dec",
                                                                 "phantom" })
    {
      const std::string output = command == "phantom" ? " " + d / name + " --size 48" : " " + d / name;
      const Result      r = RunDcvWithFullDisk(command + output);
      EXPECT_EQ(r.status, 1) << command << output << ": " << r.output;
      EXPECT_NE(r.output.find("cannot write '" + d / name + "'"), std::string::npos) << r.output;
      EXPECT_NE(r.output.find("size limit of the process"), std::string::npos) << r.output;
      EXPECT_EQ(Names(d / ""), before) << command << output;
    }
  }
  const Result c = RunDcvWithFullDisk("compress " + d / "p.nrrd" + " " + d / "o.dcv" + " -n 3000");
  EXPECT_EQ(c.status, 1) << c.output;
  EXPECT_NE(c.output.find("cannot write '" + d / "o.dcv" + "': File too large"), std::string::npos) << c.output;
  const Result m = RunDcvWithFullDisk("mesh " + d / "p.dcv" + " " + d / "o.vtu");
  EXPECT_EQ(m.status, 1) << m.output;
  EXPECT_NE(m.output.find("cannot write '" + d / "o.vtu" + "'"), std::string::npos) << m.output;
  EXPECT_EQ(Names(d / ""), before);
  // The same writes succeed without the limit, the several files side by side.
  ASSERT_EQ(RunDcv("decompress " + d / "p.dcv" + " " + d / "o.mhd").status, 0);
  EXPECT_TRUE(fs::exists(d / "o.mhd"));
  EXPECT_TRUE(fs::exists(d / "o.zraw"));
  EXPECT_NO_THROW((itk::ReadImage<itk::Image<uint8_t, 3>>(d / "o.mhd")));
}

TEST(Outputs, TheOutputIsNeverTheInput)
{
  const dcv::test::TemporaryDirectory d;
  ASSERT_EQ(RunDcv("phantom " + d / "p.nrrd" + " --size 16").status, 0);
  ASSERT_EQ(RunDcv("compress " + d / "p.nrrd" + " " + d / "p.dcv" + " -n 40 -q").status, 0);
  fs::create_hard_link(d / "p.nrrd", d / "link.nrrd");
  const std::string nrrd = dcv::test::FileBytes(d / "p.nrrd");
  const std::string packed = dcv::test::FileBytes(d / "p.dcv");
  // The same file under its name, another spelling of it, and a hard link.
  for (const std::string & command :
       std::vector<std::string>{ "approximate " + d / "p.nrrd" + " " + d / "p.nrrd" + " --force -n 20",
                                 "approximate " + d / "p.nrrd" + " " + d / "" + "./p.nrrd" + " --force -n 20",
                                 "convert " + d / "p.nrrd" + " " + d / "link.nrrd" + " --force",
                                 "compress " + d / "p.dcv" + " " + d / "p.dcv" + " --force -n 20",
                                 "decompress " + d / "p.dcv" + " " + d / "p.dcv" + " --force" })
  {
    const Result r = RunDcv(command);
    EXPECT_EQ(r.status, 2) << command << ": " << r.output;
    EXPECT_NE(r.output.find("it is the input"), std::string::npos) << r.output;
  }
  EXPECT_EQ(dcv::test::FileBytes(d / "p.nrrd"), nrrd);
  EXPECT_EQ(dcv::test::FileBytes(d / "p.dcv"), packed);
  EXPECT_EQ(Names(d / ""), (std::vector<std::string>{ "link.nrrd", "p.dcv", "p.nrrd" }));
}

TEST(Outputs, AFileThatAppearedWhileWritingIsKept)
{
  const dcv::test::TemporaryDirectory d;
  const std::string                   output = d / "out.dcv";
  {
    dcv::tools::PendingOutput pending(output, false, false);
    std::ofstream(pending.Path()) << "new";
    std::ofstream(output) << "someone else's"; // another run, between the check and the rename
    try
    {
      pending.Commit();
      ADD_FAILURE() << "replaced a file that appeared meanwhile";
    }
    catch (const dcv::tools::Failure & e)
    {
      EXPECT_NE(std::string(e.what()).find("appeared while it was being written"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("--force"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(dcv::test::FileBytes(output), "someone else's");
  EXPECT_EQ(Names(d / ""), (std::vector<std::string>{ "out.dcv" })); // the temporary is gone
  {
    dcv::tools::PendingOutput pending(output, true, false); // --force
    std::ofstream(pending.Path()) << "new";
    pending.Commit();
  }
  EXPECT_EQ(dcv::test::FileBytes(output), "new");
  // Several files: none is moved when one of them would replace another's.
  std::ofstream(d / "v.zraw") << "another volume's data";
  EXPECT_THROW(
    {
      dcv::tools::PendingOutput pending(d / "v.mhd", false, true);
      std::ofstream(fs::path(pending.Path()).parent_path() / "v.zraw") << "data";
      std::ofstream(pending.Path()) << "header";
      pending.Commit();
    },
    dcv::tools::Failure);
  EXPECT_EQ(dcv::test::FileBytes(d / "v.zraw"), "another volume's data");
  EXPECT_EQ(Names(d / ""), (std::vector<std::string>{ "out.dcv", "v.zraw" }));
}

TEST(Outputs, ConcurrentRunsWithoutForceNeverOverwriteEachOther)
{
  const dcv::test::TemporaryDirectory d;
  ASSERT_EQ(RunDcv("phantom " + d / "p.nrrd" + " --size 24").status, 0);
  // Four runs at once to one output: one wins, the others fail (at the start or at the rename).
  const Result r =
    dcv::test::RunCommand("for i in 1 2 3 4; do ('" + std::string(DCV_EXECUTABLE) + "' compress " + d / "p.nrrd" + " " +
                          d / "o.dcv" + " -n 300 -q; echo \"status $?\") & done; wait");
  std::size_t succeeded = 0;
  for (std::size_t at = r.output.find("status 0"); at != std::string::npos; at = r.output.find("status 0", at + 1))
  {
    ++succeeded;
  }
  EXPECT_EQ(succeeded, 1u) << r.output;
  EXPECT_EQ(Names(d / ""), (std::vector<std::string>{ "o.dcv", "p.nrrd" }));
  EXPECT_NO_THROW(dcv::ReadCompressedFile(d / "o.dcv"));
}

TEST(Outputs, ASignalRemovesTheTemporaryFiles)
{
  const dcv::test::TemporaryDirectory d;
  const std::string                   directory = d / "";
  // The child registers a file and a directory of files, as a write in progress does, then is killed.
  EXPECT_EXIT(
    {
      dcv::tools::PendingOutput file(directory + "a.nrrd", false, true);
      std::ofstream(file.Path()) << "partial";
      dcv::tools::PendingOutput several(directory + "b.mhd", false, true);
      std::ofstream(several.Path()) << "header";
      std::ofstream(fs::path(several.Path()).parent_path() / "b.zraw") << "data";
      std::raise(SIGTERM);
    },
    ::testing::KilledBySignal(SIGTERM),
    "");
  EXPECT_TRUE(Names(directory).empty()) << Names(directory).front();
}

TEST(ExitStatus, UsageTwoFailureOneSuccessZero)
{
  const dcv::test::TemporaryDirectory d;
  ASSERT_EQ(RunDcv("phantom " + d / "p.nrrd" + " --size 16").status, 0);
  ASSERT_EQ(RunDcv("compress " + d / "p.nrrd" + " " + d / "p.dcv" + " -n 40 -q").status, 0);
  const std::string p = d / "p.nrrd";
  const std::string out = " " + d / "out";
  for (const std::string & usage :
       std::vector<std::string>{ "",
                                 "frobnicate",
                                 "compress",
                                 "compress " + p + out + ".dcv --bogus",
                                 "compress " + p + out + ".dcv --bpv 0.1 -n 50",
                                 "compress " + p + out + ".nrrd",
                                 "compress " + p + out + ".dcv --alpha 0",
                                 "compress " + p + out + ".dcv --mode x",
                                 "compress " + p + out + ".dcv -n 7",
                                 "compress " + p + out + ".dcv --bpv 1e300",
                                 "compress " + p + out + ".dcv --bpv inf",
                                 "compress " + p + out + ".dcv --points -1",
                                 "approximate " + p + out + ".unknown",
                                 "phantom" + out + ".nrrd --size 1",
                                 "decompress " + d / "p.dcv" + out + ".nrrd --max-memory lots",
                                 "mesh " + d / "p.dcv" + out + ".txt",
                                 "batch " + d / "" + out,
                                 "batch " + d / "" + out + " -n 20 --shard 3/2" })
  {
    const Result r = RunDcv(usage);
    EXPECT_EQ(r.status, 2) << usage << ": " << r.output;
    EXPECT_FALSE(fs::exists(d / "out.dcv") || fs::exists(d / "out.nrrd") || fs::exists(d / "out")) << usage;
  }
  std::ofstream(d / "text.nrrd") << "not a volume";
  for (const std::string & failure : std::vector<std::string>{ "compress " + d / "missing.nrrd" + out + ".dcv",
                                                               "compress " + d / "text.nrrd" + out + ".dcv",
                                                               "compress " + p + " " + d / "p.dcv",
                                                               "approximate " + p + " " + d / "text.nrrd",
                                                               "compress " + p + out + ".dcv --bpv 0.01",
                                                               "compress " + p + out + ".dcv -n 5000",
                                                               "decompress " + d / "text.nrrd" + out + ".nrrd",
                                                               "info " + d / "text.nrrd" })
  {
    const Result r = RunDcv(failure);
    EXPECT_EQ(r.status, 1) << failure << ": " << r.output;
  }
  EXPECT_EQ(RunDcv("--help").status, 0);
  EXPECT_EQ(RunDcv("--version").status, 0);
  EXPECT_EQ(RunDcv("info " + d / "p.dcv").status, 0);
}

TEST(BadNumbers, NonFiniteVoxelsAreRefusedBeforeAnyOutput)
{
  const dcv::test::TemporaryDirectory                    d;
  const float                                            nan = std::numeric_limits<float>::quiet_NaN();
  const float                                            inf = std::numeric_limits<float>::infinity();
  const std::vector<std::pair<std::string, std::string>> inputs{
    { FloatVolumeWith(d / "nan.nrrd", nan, 3), "3 non-finite voxels" },
    { FloatVolumeWith(d / "inf.nrrd", inf, 2), "2 non-finite voxels" },
    { FloatVolumeWith(d / "minus-inf.nrrd", -inf, 1), "1 non-finite voxels" },
    { WriteVolume<float>(d / "all-nan.nrrd", { { 4, 4, 4 } }, [&](std::size_t) { return nan; }), "64 non-finite" },
    { WriteVolume<double>(d / "huge.nrrd", { { 4, 4, 4 } }, [](std::size_t i) { return i == 9 ? 1e300 : 1.0; }),
      "1 voxels beyond the range of float" }
  };
  for (const auto & [input, phrase] : inputs)
  {
    for (const std::string & command :
         std::vector<std::string>{ "compress " + input + " " + d / "o.dcv" + " --bpv 1",
                                   "compress " + input + " " + d / "o.dcv" + " -n 20",
                                   "approximate " + input + " " + d / "o.nrrd" + " -n 20" })
    {
      const Result r = RunDcv(command);
      EXPECT_EQ(r.status, 1) << command << ": " << r.output;
      EXPECT_NE(r.output.find("'" + input + "' holds " + phrase), std::string::npos) << r.output;
      EXPECT_EQ(r.output.find("nan dB"), std::string::npos) << r.output;
      EXPECT_FALSE(fs::exists(d / "o.dcv") || fs::exists(d / "o.nrrd")) << command;
    }
  }
  EXPECT_NE(RunDcv("compress " + d / "nan.nrrd" + " " + d / "o.dcv").output.find("dcv codes finite values only"),
            std::string::npos);
  // The library refuses them too (ImageFileWriter to .dcv, the filters), without a file name.
  auto image = itk::ReadImage<itk::Image<float, 3>>(d / "inf.nrrd");
  try
  {
    itk::DCVEncode(image.GetPointer(), dcv::EncoderOptions());
    ADD_FAILURE() << "encoded infinities";
  }
  catch (const std::invalid_argument & e)
  {
    EXPECT_NE(std::string(e.what()).find("holds 2 non-finite voxels"), std::string::npos) << e.what();
  }
}

TEST(BadNumbers, ConstantVolumesDecodeExactly)
{
  const dcv::test::TemporaryDirectory d;
  const std::vector<std::string>      inputs{
    WriteVolume<uint8_t>(d / "u8.nrrd", { { 10, 9, 8 } }, [](std::size_t) { return uint8_t(77); }),
    WriteVolume<int16_t>(d / "i16.nrrd", { { 10, 9, 8 } }, [](std::size_t) { return int16_t(-1024); }),
    WriteVolume<float>(d / "f32.nrrd", { { 10, 9, 8 } }, [](std::size_t) { return 3.25f; }),
    WriteVolume<double>(d / "f64.nrrd", { { 10, 9, 8 } }, [](std::size_t) { return -0.125; })
  };
  for (const auto & input : inputs)
  {
    for (const std::string & target :
         std::vector<std::string>{ "--bpv 2 --no-residual-layer", "-n 8", "-n 100", "--psnr 40" })
    {
      const Result c = RunDcv("compress " + input + " " + d / "c.dcv" + " --force " + target);
      ASSERT_EQ(c.status, 0) << input << " " << target << ": " << c.output;
      EXPECT_NE(c.output.find("PSNR: inf dB (exact)"), std::string::npos) << c.output;
      ASSERT_EQ(RunDcv("decompress " + d / "c.dcv" + " " + d / "c.nrrd" + " --force").status, 0);
      auto       in = itk::ReadImage<itk::Image<double, 3>>(input);
      auto       out = itk::ReadImage<itk::Image<double, 3>>(d / "c.nrrd");
      const auto n = in->GetBufferedRegion().GetNumberOfPixels();
      EXPECT_EQ(dcv::SquaredError(in->GetBufferPointer(), out->GetBufferPointer(), n), 0.0) << input << " " << target;
    }
    const Result a = RunDcv("approximate " + input + " " + d / "a.nrrd" + " --force -n 30");
    ASSERT_EQ(a.status, 0) << a.output;
    EXPECT_NE(a.output.find("PSNR: inf dB (exact)"), std::string::npos) << a.output;
  }
}

// Found here, left to the owner of ChooseLayers (src/codec/dcvEncoder.cxx): a constant negative float volume
// with the residual layer tried (--bpv without --no-residual-layer) is refused with the internal
// "EncodePayload: value -0.125000 is not on the quantization lattice" (nothing is written). Enable
// when fixed.
TEST(BadNumbers, ANegativeConstantVolumeWithTheResidualLayer)
{
  const dcv::test::TemporaryDirectory d;
  const std::string input = WriteVolume<float>(d / "n.nrrd", { { 10, 9, 8 } }, [](std::size_t) { return -0.125f; });
  const Result      c = RunDcv("compress " + input + " " + d / "n.dcv" + " --bpv 2");
  EXPECT_EQ(c.status, 0) << c.output;
  EXPECT_NE(c.output.find("PSNR: inf dB (exact)"), std::string::npos) << c.output;
}

TEST(BadNumbers, TinyAndThinVolumes)
{
  const dcv::test::TemporaryDirectory d;
  // 2x2x2: its 8 voxels are the corners; the default point count is capped at the voxels.
  const std::string tiny =
    WriteVolume<int16_t>(d / "tiny.nrrd", { { 2, 2, 2 } }, [](std::size_t i) { return int16_t(100 * i); });
  for (const std::string & target : std::vector<std::string>{ "", "-n 8", "--psnr 30" })
  {
    const Result c = RunDcv("compress " + tiny + " " + d / "t.dcv" + " --force " + target);
    ASSERT_EQ(c.status, 0) << target << ": " << c.output;
    EXPECT_NE(c.output.find("points: 8"), std::string::npos) << c.output;
    EXPECT_GT(PrintedPSNR(c.output), 40.0) << c.output; // the corners, quantized with step 11
  }
  const Result a = RunDcv("approximate " + tiny + " " + d / "t.nrrd");
  EXPECT_EQ(a.status, 0) << a.output;
  const Result nine = RunDcv("compress " + tiny + " " + d / "nine.dcv" + " -n 9");
  EXPECT_EQ(nine.status, 1) << nine.output;
  EXPECT_NE(nine.output.find("at most the number of voxels, 8"), std::string::npos) << nine.output;
  // A budget below the header: refused, nothing written.
  const Result small = RunDcv("compress " + tiny + " " + d / "small.dcv" + " --bpv 8");
  EXPECT_EQ(small.status, 1) << small.output;
  EXPECT_NE(small.output.find("too few"), std::string::npos) << small.output;
  EXPECT_FALSE(fs::exists(d / "small.dcv"));
  // Two slices, thin as they come: coded and decoded.
  const std::string thin = WriteVolume<uint8_t>(
    d / "thin.nrrd", { { 40, 30, 2 } }, [](std::size_t i) { return uint8_t((i % 40) * 3 + (i / 1200) * 50); });
  const Result t = RunDcv("compress " + thin + " " + d / "thin.dcv" + " --bpv 0.5");
  ASSERT_EQ(t.status, 0) << t.output;
  EXPECT_GT(PrintedPSNR(t.output), 30.0) << t.output;
  EXPECT_EQ(RunDcv("decompress " + d / "thin.dcv" + " " + d / "thin-decoded.nrrd").status, 0);
  // One slice is an image, not a volume: refused with the reason, nothing written.
  const std::string flat =
    WriteVolume<float>(d / "flat.nrrd", { { 16, 16, 1 } }, [](std::size_t i) { return float(i); });
  for (const std::string & command : std::vector<std::string>{ "compress " + flat + " " + d / "flat.dcv",
                                                               "approximate " + flat + " " + d / "flat-a.nrrd" })
  {
    const Result r = RunDcv(command);
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find("'" + flat + "' is 16x16x1 voxels; at least 2 voxels along each axis"), std::string::npos)
      << r.output;
  }
  EXPECT_FALSE(fs::exists(d / "flat.dcv") || fs::exists(d / "flat-a.nrrd"));
}

TEST(Options, AStepTooSmallForTheValueCoderIsRefused)
{
  const dcv::test::TemporaryDirectory d;
  ASSERT_EQ(RunDcv("phantom " + d / "p.nrrd" + " --size 16").status, 0);
  const Result r = RunDcv("compress " + d / "p.nrrd" + " " + d / "o.dcv" + " -n 50 --step 1e-300");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("cannot compress '" + d / "p.nrrd" + "'"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("QuantizationStep (--step) must be at least"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("got 1e-300"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("lattice"), std::string::npos) << r.output; // not the internal message
  EXPECT_FALSE(fs::exists(d / "o.dcv"));

  // The limit is real: just above it the file is coded and decodes as the encoder said.
  const auto          image = dcv::test::PhantomImage({ 16, 16, 16 });
  dcv::EncoderOptions o;
  o.numberOfPoints = 50;
  const auto   extremes = std::minmax_element(image->GetBufferPointer(),
                                            image->GetBufferPointer() + image->GetBufferedRegion().GetNumberOfPixels());
  const double range = double(*extremes.second) - double(*extremes.first);
  o.quantizationStep = range / double(dcv::MaximumQuantizationIndex / 2) * 1.01;
  dcv::EncoderResult result;
  ASSERT_NO_THROW(result = itk::DCVEncode(image.GetPointer(), o));
  const auto file = dcv::tools::ParseCompressedBytes(result.bytes, "test");
  EXPECT_NO_THROW(dcv::Decode(file));
  o.quantizationStep = range / double(dcv::MaximumQuantizationIndex / 2) * 0.99;
  EXPECT_THROW(itk::DCVEncode(image.GetPointer(), o), std::invalid_argument);
}

TEST(Options, BudgetsBeyondTheFormatAreRefused)
{
  dcv::EncoderOptions o;
  o.bitsPerVoxel = 1e300;
  EXPECT_THROW(dcv::CheckOptions(o), std::invalid_argument);
  o.bitsPerVoxel = std::numeric_limits<double>::infinity();
  EXPECT_THROW(dcv::CheckOptions(o), std::invalid_argument);
  o.bitsPerVoxel = 64.0;
  EXPECT_NO_THROW(dcv::CheckOptions(o));
  // A budget the pixel type does not need, and one a uint32 payload length cannot state (the geometry
  // alone: 2048^3 float64 voxels).
  dcv::EncoderInput input;
  input.header.pixelType = dcv::PixelType::UInt8;
  input.header.size = { 64, 64, 64 };
  o.bitsPerVoxel = 9.0;
  try
  {
    dcv::CheckOptions(o, input);
    ADD_FAILURE() << "9 bits per uint8 voxel accepted";
  }
  catch (const std::invalid_argument & e)
  {
    EXPECT_NE(std::string(e.what()).find("BitsPerVoxel (--bpv) must be at most 8 for uint8 voxels"), std::string::npos)
      << e.what();
  }
  input.header.pixelType = dcv::PixelType::Float64;
  input.header.size = { 2048, 2048, 2048 };
  o.bitsPerVoxel = 8.0;
  try
  {
    dcv::CheckOptions(o, input);
    ADD_FAILURE() << "a budget of 8 GiB accepted";
  }
  catch (const std::invalid_argument & e)
  {
    EXPECT_NE(std::string(e.what()).find("a .dcv payload holds at most 4294967295"), std::string::npos) << e.what();
  }
  o.bitsPerVoxel = 0.0;
  o.numberOfPoints = 10000;
  input.header.size = { 8, 8, 8 };
  EXPECT_THROW(dcv::CheckOptions(o, input), std::invalid_argument); // 10000 points of 512 voxels
}

} // namespace
