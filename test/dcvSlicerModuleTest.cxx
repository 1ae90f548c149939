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
// The 3D Slicer CLI modules (slicer/): their descriptions against Slicer's schema, and runs as Slicer runs
// them (test/dcvSlicerHarness.py builds the command line from the description) compared with the dcv
// tool: same file bytes, same voxels, same PSNR; DCVApproximate's two outputs; bad inputs.
#include "dcvTestUtilities.h"

#include "itkImageFileWriter.h"

#include <cmath>
#include <map>
#include <regex>
#include <set>
#include <sstream>

namespace
{
namespace fs = std::filesystem;
using dcv::test::RunCommand;
using dcv::test::TemporaryDirectory;

const std::vector<std::string> &
Modules()
{
  static const std::vector<std::string> modules{ DCV_SLICER_COMPRESS, DCV_SLICER_DECOMPRESS, DCV_SLICER_APPROXIMATE };
  return modules;
}

std::string
ModuleName(const std::string & path)
{
  return fs::path(path).filename().string();
}

bool
HaveHarness()
{
  return std::string(DCV_PYTHON3).size() > 0 && fs::exists(DCV_PYTHON3);
}

#define DCV_REQUIRE_HARNESS()                                                                                          \
  if (!HaveHarness())                                                                                                  \
  {                                                                                                                    \
    GTEST_SKIP() << "needs python3 for test/dcvSlicerHarness.py (not found at configure time)";                        \
  }

std::string
Shell(const std::string & s)
{
  std::string out = "'";
  for (char c : s)
    out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

/** What a run through the harness gave: the report's `key = value` lines. */
struct SlicerRun
{
  std::map<std::string, std::string> report;
  std::string                        harnessOutput;

  int
  Status() const
  {
    const auto it = report.find("status");
    return it == report.end() ? -1 : std::stoi(it->second);
  }
  std::string
  Get(const std::string & key) const
  {
    const auto it = report.find(key);
    return it == report.end() ? std::string() : it->second;
  }
  std::vector<double>
  Progress() const
  {
    std::vector<double> values;
    std::istringstream  in(Get("progress"));
    double              v;
    while (in >> v)
      values.push_back(v);
    return values;
  }
};

/** Runs a module as Slicer runs it, with NAME=VALUE parameters (the others take their defaults). */
SlicerRun
RunAsSlicer(const std::string & module, const std::string & reportPath, const std::vector<std::string> & values)
{
  std::string command =
    Shell(DCV_PYTHON3) + " " + Shell(DCV_SLICER_HARNESS) + " " + Shell(module) + " " + Shell(reportPath);
  for (const auto & v : values)
    command += " " + Shell(v);
  SlicerRun  run;
  const auto r = RunCommand(command + " 2>&1");
  run.harnessOutput = r.output;
  std::ifstream in(reportPath);
  std::string   line;
  while (std::getline(in, line))
  {
    const auto at = line.find(" = ");
    if (at != std::string::npos)
      run.report[line.substr(0, at)] = line.substr(at + 3);
  }
  fs::remove(reportPath);
  fs::remove(reportPath + ".params");
  return run;
}

/** The progress Slicer shows: from 0, never falling, to 1, with a filter-start and a filter-end. */
void
ExpectSlicerProgress(const SlicerRun & run)
{
  const auto p = run.Progress();
  ASSERT_GE(p.size(), 3u) << run.Get("progress");
  EXPECT_EQ(p.front(), 0.0);
  EXPECT_EQ(p.back(), 1.0);
  for (std::size_t i = 1; i < p.size(); ++i)
    EXPECT_LE(p[i - 1], p[i]) << "progress falls at value " << i << ": " << run.Get("progress");
  EXPECT_EQ(run.Get("filter-start"), "1");
  EXPECT_EQ(run.Get("filter-end"), "1");
}

/** A value of `dcv compress`'s output ("name: value"). */
std::string
Printed(const std::string & output, const std::string & name)
{
  std::smatch m;
  if (std::regex_search(output, m, std::regex("(^|\n)" + name + ": ([^ \n]+)")))
    return m[2];
  return {};
}

/** A number as `dcv compress` prints it (ostream defaults: 6 significant digits). */
std::string
AsPrinted(const std::string & value)
{
  std::ostringstream out;
  out << std::stod(value);
  return out.str();
}

using VolumeType = itk::Image<double, 3>;

VolumeType::Pointer
ReadAsDouble(const std::string & path)
{
  return itk::ReadImage<VolumeType>(path);
}

itk::ImageIOBase::IOComponentEnum
ComponentType(const std::string & path)
{
  auto io = itk::ImageIOFactory::CreateImageIO(path.c_str(), itk::IOFileModeEnum::ReadMode);
  io->SetFileName(path);
  io->ReadImageInformation();
  return io->GetComponentType();
}

void
ExpectSameGeometry(const VolumeType * a, const VolumeType * b)
{
  EXPECT_EQ(a->GetLargestPossibleRegion(), b->GetLargestPossibleRegion());
  EXPECT_EQ(a->GetSpacing(), b->GetSpacing());
  EXPECT_EQ(a->GetOrigin(), b->GetOrigin());
  EXPECT_EQ(a->GetDirection(), b->GetDirection());
}

/** How many voxels differ. */
std::size_t
DifferingVoxels(const VolumeType * a, const VolumeType * b)
{
  const std::size_t n = a->GetLargestPossibleRegion().GetNumberOfPixels();
  if (b->GetLargestPossibleRegion().GetNumberOfPixels() != n)
    return n;
  std::size_t differ = 0;
  for (std::size_t i = 0; i < n; ++i)
    differ += a->GetBufferPointer()[i] != b->GetBufferPointer()[i];
  return differ;
}

/** The files of a directory (names). */
std::set<std::string>
Files(const std::string & directory)
{
  std::set<std::string> names;
  for (const auto & entry : fs::directory_iterator(directory))
    names.insert(entry.path().filename().string());
  return names;
}

/** The description as each schema takes a returned value (a scalar output with neither flag nor index, which
 * Slicer writes back from the return parameter file). Slicer's parser reads a <channel> on any parameter,
 * but ModuleDescription.xsd (SlicerExecutionModel's too) declares <channel> only for indexed parameters:
 * for `slicer` the channel is removed. CTK's schema needs a flag or an index on every parameter and marks a
 * returned value with index 1000, which Slicer would take for a positional argument (ModuleParameter::
 * IsReturnParameter): for CTK <index>1000</index> is added after the name. Nothing else is changed.
 * Throws when a <channel> is on a scalar that is not a returned value. */
std::string
WithReturnedValuesFor(const std::string & xml, bool slicer, int & changed)
{
  const std::regex scalar("<(integer|double|float)>([\\s\\S]*?)</\\1>");
  std::string      out;
  auto             last = xml.cbegin();
  for (std::sregex_iterator it(xml.begin(), xml.end(), scalar), end; it != end; ++it)
  {
    const std::smatch & m = *it;
    std::string         body = m[2];
    if (body.find("<channel>") != std::string::npos)
    {
      if (body.find("<flag>") != std::string::npos || body.find("<longflag") != std::string::npos ||
          body.find("<index>") != std::string::npos || body.find("<channel>output</channel>") == std::string::npos)
        throw std::runtime_error("a <channel> on a scalar that is not a returned value: " + m.str());
      if (slicer)
        body = std::regex_replace(body, std::regex("[ \t]*<channel>output</channel>\n?"), "");
      else
        body = std::regex_replace(body, std::regex("(</name>\n?)([ \t]*)"), "$1$2<index>1000</index>\n$2");
      ++changed;
    }
    out.append(last, m[0].first);
    out += "<" + m[1].str() + ">" + body + "</" + m[1].str() + ">";
    last = m[0].second;
  }
  out.append(last, xml.cend());
  return out;
}

std::string
ModuleXML(const std::string & module)
{
  const auto r = RunCommand(Shell(module) + " --xml");
  EXPECT_EQ(r.status, 0);
  return r.output;
}

/** Each module's --xml output against Slicer's schema and CTK's: the element order of the two differs
 * (CTK: name, flag, longflag or index, description, label, default, channel, constraints), and CTK allows
 * only letters, digits and underscores in a longflag and no `reference` on an image. */
TEST(SlicerModule, DescriptionsValidateAgainstTheSlicerAndTheCTKSchemas)
{
  if (std::string(DCV_XMLLINT).empty() || !fs::exists(DCV_XMLLINT))
    GTEST_SKIP() << "needs xmllint (Debian package libxml2-utils; not found at configure time)";
  for (const char * schema : { DCV_SLICER_SCHEMA, DCV_CTK_SCHEMA })
  {
    if (!fs::exists(schema))
      GTEST_SKIP() << "needs the schema " << schema << " (../shared/slicer is absent)";
  }
  TemporaryDirectory directory;
  for (const std::string & module : Modules())
  {
    SCOPED_TRACE(ModuleName(module));
    const std::string xml = ModuleXML(module);
    for (const bool slicer : { true, false })
    {
      const std::string schema = slicer ? DCV_SLICER_SCHEMA : DCV_CTK_SCHEMA;
      SCOPED_TRACE(schema);
      int               changed = 0;
      const std::string checked = WithReturnedValuesFor(xml, slicer, changed);
      const std::string path = directory / (ModuleName(module) + (slicer ? "-slicer.xml" : "-ctk.xml"));
      std::ofstream(path) << checked;
      const auto r =
        RunCommand(Shell(DCV_XMLLINT) + " --noout --schema " + Shell(schema) + " " + Shell(path) + " 2>&1");
      EXPECT_EQ(r.status, 0) << r.output;
      EXPECT_NE(r.output.find("validates"), std::string::npos) << r.output;
      // Every returned value is such a scalar: 4 for Compress and Approximate, 2 for Decompress.
      EXPECT_EQ(changed, ModuleName(module) == "DCVDecompress" ? 2 : 4);
    }
  }
}

TEST(SlicerModule, EveryParameterHasALabelADescriptionAndADefault)
{
  const std::regex parameter(
    "<(integer|double|float|boolean|string|integer-vector|file|image)( [^>]*)?>([\\s\\S]*?)</\\1>");
  for (const std::string & module : Modules())
  {
    SCOPED_TRACE(ModuleName(module));
    const std::string xml = ModuleXML(module);
    int               count = 0;
    for (std::sregex_iterator it(xml.begin(), xml.end(), parameter), end; it != end; ++it, ++count)
    {
      const std::string tag = (*it)[1];
      const std::string body = (*it)[3];
      SCOPED_TRACE(body.substr(0, 60));
      EXPECT_NE(body.find("<label>"), std::string::npos);
      EXPECT_NE(body.find("<description>"), std::string::npos);
      // The schema allows no default on indexed parameters (the volumes and files Slicer passes).
      if (tag != "file" && tag != "image")
        EXPECT_NE(body.find("<default>"), std::string::npos);
    }
    EXPECT_GE(count, 4);
    // The version is CMake's project version (DCV_PROJECT_VERSION, test/CMakeLists.txt).
    for (const std::string header : { std::string("<category>"),
                                      std::string("<title>"),
                                      std::string("<description>"),
                                      "<version>" + std::string(DCV_PROJECT_VERSION) + "</version>",
                                      std::string("<documentation-url>http"),
                                      std::string("<license>"),
                                      std::string("<contributor>") })
      EXPECT_NE(xml.find(header), std::string::npos) << header;
  }
}

TEST(SlicerModule, TheParserHasExactlyTheFlagsOfTheDescription)
{
  // The parser is built from the description; --help lists what it accepts.
  const std::set<std::string> own{ "--help", "--xml", "--returnparameterfile", "--processinformationaddress" };
  for (const std::string & module : Modules())
  {
    SCOPED_TRACE(ModuleName(module));
    const std::string     xml = ModuleXML(module);
    std::set<std::string> declared = own;
    // A long flag and its aliases (the hyphenated spellings of earlier versions, which CTK's schema refuses
    // as a longflag, are deprecated aliases).
    const std::regex longflag("<longflag( [^>]*)?>-*([^<]+)</longflag>");
    const std::regex alias("alias=\"([^\"]*)\"");
    for (std::sregex_iterator it(xml.begin(), xml.end(), longflag), end; it != end; ++it)
    {
      declared.insert("--" + (*it)[2].str());
      const std::string attributes = (*it)[1];
      for (std::sregex_iterator a(attributes.begin(), attributes.end(), alias); a != end; ++a)
        declared.insert("--" + (*a)[1].str());
    }
    const auto help = RunCommand(Shell(module) + " --help");
    EXPECT_EQ(help.status, 0);
    std::set<std::string> accepted;
    const std::regex      option("(^|[ ,])(--[a-zA-Z][a-zA-Z0-9_-]*)");
    for (std::sregex_iterator it(help.output.begin(), help.output.end(), option), end; it != end; ++it)
      accepted.insert((*it)[2]);
    EXPECT_EQ(accepted, declared) << help.output;
  }
}

/** The phantom of `dcv phantom` (48^3, uint8). */
std::string
WritePhantom(const TemporaryDirectory & directory)
{
  const std::string path = directory / "phantom.nrrd";
  const auto        r = dcv::test::RunDcv("phantom " + Shell(path) + " --size 48 --force");
  EXPECT_EQ(r.status, 0) << r.output;
  return path;
}

/** DCVCompress then DCVDecompress as Slicer runs them, against dcv compress / decompress with the same
 * options: same file, same voxels, the same PSNR, bytes and points returned as printed. */
void
ExpectModulesAgreeWithTheTool(const std::string & input, const TemporaryDirectory & directory,
                              const std::vector<std::string> & parameters, const std::string & dcvOptions)
{
  std::vector<std::string> compressValues{ "inputVolume=" + input, "outputFile=" + (directory / "slicer.dcv") };
  compressValues.insert(compressValues.end(), parameters.begin(), parameters.end());
  const SlicerRun compress = RunAsSlicer(DCV_SLICER_COMPRESS, directory / "compress.report", compressValues);
  ASSERT_EQ(compress.Status(), 0) << compress.Get("stderr") << compress.harnessOutput;
  ExpectSlicerProgress(compress);
  const SlicerRun decompress =
    RunAsSlicer(DCV_SLICER_DECOMPRESS,
                directory / "decompress.report",
                { "inputFile=" + (directory / "slicer.dcv"), "outputVolume=" + (directory / "slicer-decoded.nrrd") });
  ASSERT_EQ(decompress.Status(), 0) << decompress.Get("stderr") << decompress.harnessOutput;
  ExpectSlicerProgress(decompress);

  const auto tool =
    dcv::test::RunDcv("compress " + Shell(input) + " " + Shell(directory / "dcv.dcv") + " " + dcvOptions + " --force");
  ASSERT_EQ(tool.status, 0) << tool.output;
  const auto toolDecoded =
    dcv::test::RunDcv("decompress " + Shell(directory / "dcv.dcv") + " " + Shell(directory / "dcv-decoded.nrrd"));
  ASSERT_EQ(toolDecoded.status, 0) << toolDecoded.output;

  EXPECT_EQ(dcv::test::FileBytes(directory / "slicer.dcv"), dcv::test::FileBytes(directory / "dcv.dcv"));
  const auto slicerVolume = ReadAsDouble(directory / "slicer-decoded.nrrd");
  const auto toolVolume = ReadAsDouble(directory / "dcv-decoded.nrrd");
  ExpectSameGeometry(slicerVolume, toolVolume);
  EXPECT_EQ(ComponentType(directory / "slicer-decoded.nrrd"), ComponentType(directory / "dcv-decoded.nrrd"));
  const std::size_t differ = DifferingVoxels(slicerVolume, toolVolume);
  EXPECT_EQ(differ, 0u);

  const std::string printedPSNR = Printed(tool.output, "PSNR");
  ASSERT_FALSE(printedPSNR.empty()) << tool.output;
  const std::string returnedPSNR = compress.Get("return.outputPSNR");
  ASSERT_FALSE(returnedPSNR.empty());
  EXPECT_EQ(AsPrinted(returnedPSNR), printedPSNR);
  EXPECT_EQ(compress.Get("return.outputBytes"), Printed(tool.output, "bytes"));
  EXPECT_EQ(AsPrinted(compress.Get("return.outputBitsPerVoxel")), Printed(tool.output, "bpv"));
  EXPECT_EQ(compress.Get("return.outputPoints"), Printed(tool.output, "points"));
  EXPECT_EQ(decompress.Get("return.outputPoints"), Printed(tool.output, "points"));
  EXPECT_EQ(compress.Get("return-unknown"), "");
  std::cout << "  " << fs::path(input).filename().string() << " (" << dcvOptions << "): DCVCompress returned PSNR "
            << returnedPSNR << " dB, " << compress.Get("return.outputBytes") << " bytes, "
            << compress.Get("return.outputBitsPerVoxel") << " bpv, " << compress.Get("return.outputPoints")
            << " points; dcv compress printed PSNR " << printedPSNR << " dB, " << Printed(tool.output, "bytes")
            << " bytes; voxels differing from dcv decompress: " << differ << " of "
            << slicerVolume->GetLargestPossibleRegion().GetNumberOfPixels() << "; progress values "
            << compress.Progress().size() << std::endl;
}

TEST(SlicerModule, CompressAndDecompressAsSlicerGiveWhatTheToolGivesOnAPhantom)
{
  DCV_REQUIRE_HARNESS();
  TemporaryDirectory directory;
  const std::string  phantom = WritePhantom(directory);
  ExpectModulesAgreeWithTheTool(phantom, directory, {}, "--bpv 0.0625");
}

TEST(SlicerModule, ThePSNRTargetModeAndPointsOnlyReachTheEncoderAsTheToolsOptionsDo)
{
  DCV_REQUIRE_HARNESS();
  TemporaryDirectory directory;
  const std::string  phantom = WritePhantom(directory);
  ExpectModulesAgreeWithTheTool(phantom,
                                directory,
                                { "psnr=21", "mode=dec", "noResidualLayer=true", "alpha=0.8", "scale=1,1,2" },
                                "--psnr 21 --mode dec --no-residual-layer --alpha 0.8 --scale 1,1,2");
}

TEST(SlicerModule, CompressAndDecompressAsSlicerGiveWhatTheToolGivesOnAvg152t1)
{
  DCV_REQUIRE_HARNESS();
  DCV_REQUIRE_DATA("avg152t1.nrrd");
  TemporaryDirectory directory;
  ExpectModulesAgreeWithTheTool(dcv::test::DataFile("avg152t1.nrrd"), directory, {}, "--bpv 0.0625");
}

TEST(SlicerModule, ApproximateWritesTheDecodedVolumeAndItsAbsoluteError)
{
  DCV_REQUIRE_HARNESS();
  TemporaryDirectory directory;
  // A phantom on an oblique, anisotropic, shifted grid, so that geometry errors show.
  const std::string input = directory / "oblique.nrrd";
  itk::WriteImage(dcv::test::PhantomImage({ 40, 36, 24 }, true), input);
  const SlicerRun run = RunAsSlicer(DCV_SLICER_APPROXIMATE,
                                    directory / "approximate.report",
                                    { "inputVolume=" + input,
                                      "outputVolume=" + (directory / "approximation.nrrd"),
                                      "errorVolume=" + (directory / "error.nrrd"),
                                      "bitsPerVoxel=0.1" });
  ASSERT_EQ(run.Status(), 0) << run.Get("stderr") << run.harnessOutput;
  ExpectSlicerProgress(run);

  const auto original = ReadAsDouble(input);
  const auto approximation = ReadAsDouble(directory / "approximation.nrrd");
  const auto error = ReadAsDouble(directory / "error.nrrd");
  ExpectSameGeometry(approximation, original);
  ExpectSameGeometry(error, original);
  EXPECT_EQ(ComponentType(directory / "approximation.nrrd"), itk::IOComponentEnum::UCHAR);
  EXPECT_EQ(ComponentType(directory / "error.nrrd"), itk::IOComponentEnum::FLOAT);
  const std::size_t n = original->GetLargestPossibleRegion().GetNumberOfPixels();
  std::size_t       wrong = 0;
  double            squared = 0.0;
  for (std::size_t i = 0; i < n; ++i)
  {
    const double e = std::abs(original->GetBufferPointer()[i] - approximation->GetBufferPointer()[i]);
    wrong += error->GetBufferPointer()[i] != e;
    squared += e * e;
  }
  EXPECT_EQ(wrong, 0u);
  EXPECT_GT(squared, 0.0);
  const double psnr = 10.0 * std::log10(255.0 * 255.0 / (squared / double(n)));
  EXPECT_NEAR(std::stod(run.Get("return.outputPSNR")), psnr, 1e-6);

  // The approximation is what compressing with the same options and decoding gives.
  const auto tool = dcv::test::RunDcv("compress " + Shell(input) + " " + Shell(directory / "dcv.dcv") + " --bpv 0.1");
  ASSERT_EQ(tool.status, 0) << tool.output;
  ASSERT_EQ(
    dcv::test::RunDcv("decompress " + Shell(directory / "dcv.dcv") + " " + Shell(directory / "dcv.nrrd")).status, 0);
  EXPECT_EQ(DifferingVoxels(approximation, ReadAsDouble(directory / "dcv.nrrd")), 0u);
  EXPECT_EQ(AsPrinted(run.Get("return.outputPSNR")), Printed(tool.output, "PSNR"));
  EXPECT_EQ(run.Get("return.outputBytes"), Printed(tool.output, "bytes"));
}

TEST(SlicerModule, BadInputGivesAClearErrorAndLeavesNoFile)
{
  DCV_REQUIRE_HARNESS();
  TemporaryDirectory directory;
  const std::string  phantom = WritePhantom(directory);
  {
    auto image = itk::Image<uint8_t, 2>::New();
    image->SetRegions(itk::Size<2>{ { 8, 8 } });
    image->Allocate(true);
    itk::WriteImage(image, directory / "flat.nrrd");
  }
  std::ofstream(directory / "text.dcv") << "not a compressed volume\n";
  const std::set<std::string> before = Files(directory / "");

  struct Case
  {
    std::string              module;
    std::vector<std::string> values;
    std::string              phrase;
  };
  const std::string       dcvOut = "outputFile=" + (directory / "out.dcv");
  const std::string       volumeOut = "outputVolume=" + (directory / "out.nrrd");
  const std::string       errorOut = "errorVolume=" + (directory / "error.nrrd");
  const std::vector<Case> cases{
    { DCV_SLICER_COMPRESS, { "inputVolume=" + (directory / "missing.nrrd"), dcvOut }, "no such file" },
    { DCV_SLICER_COMPRESS, { "inputVolume=" + (directory / "flat.nrrd"), dcvOut }, "2D image" },
    { DCV_SLICER_COMPRESS, { "inputVolume=" + (directory / "text.dcv"), dcvOut }, "cannot read" },
    { DCV_SLICER_COMPRESS, { "inputVolume=" + phantom, "outputFile=" + (directory / "out.nrrd") }, "ends in .dcv" },
    { DCV_SLICER_COMPRESS, { "inputVolume=" + phantom, dcvOut, "mode=fast" }, "--mode" },
    { DCV_SLICER_COMPRESS, { "inputVolume=" + phantom, dcvOut, "bitsPerVoxel=lots" }, "not a number" },
    { DCV_SLICER_COMPRESS, { "inputVolume=" + phantom, dcvOut, "bitsPerVoxel=-1" }, "BitsPerVoxel (--bpv)" },
    { DCV_SLICER_COMPRESS, { "inputVolume=" + phantom, dcvOut, "bitsPerVoxel=0.0005" }, "cannot compress" },
    { DCV_SLICER_COMPRESS, { "inputVolume=" + phantom, dcvOut, "scale=1,2" }, "Scale (--scale)" },
    { DCV_SLICER_COMPRESS,
      { "inputVolume=" + phantom, "outputFile=" + (directory / "nowhere/out.dcv") },
      "does not exist" },
    { DCV_SLICER_DECOMPRESS, { "inputFile=" + (directory / "text.dcv"), volumeOut }, "text.dcv" },
    { DCV_SLICER_DECOMPRESS, { "inputFile=" + (directory / "missing.dcv"), volumeOut }, "missing.dcv" },
    { DCV_SLICER_APPROXIMATE,
      { "inputVolume=" + phantom, volumeOut, "errorVolume=" + (directory / "out.nrrd") },
      "two files" },
    { DCV_SLICER_APPROXIMATE,
      { "inputVolume=" + phantom, volumeOut, "errorVolume=" + (directory / "error.xyz") },
      "no image format" },
    { DCV_SLICER_APPROXIMATE, { "inputVolume=" + (directory / "flat.nrrd"), volumeOut, errorOut }, "2D image" },
  };
  for (const Case & c : cases)
  {
    SCOPED_TRACE(ModuleName(c.module) + " " + c.values.back());
    const SlicerRun run = RunAsSlicer(c.module, directory / "run.report", c.values);
    EXPECT_EQ(run.Status(), 1) << run.harnessOutput;
    EXPECT_NE(run.Get("stderr").find(c.phrase), std::string::npos) << run.Get("stderr");
    EXPECT_EQ(run.Get("return.outputPSNR"), ""); // no return parameter file after a failure
    EXPECT_EQ(Files(directory / ""), before);    // no output, no temporary file
  }
}

} // namespace
