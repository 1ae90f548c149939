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
// DICOM series in and out: dcv compress reads the dev CT series (Hounsfield units, its attributes kept),
// refuses, with a message that says which and why, series made from it that are not a volume on a grid,
// and dcv decompress --dicom gives back a valid derived series of the same study.
#include "dcvTestUtilities.h"

#include "itkGDCMImageIO.h"
#include "itkGDCMSeriesFileNames.h"
#include "itkImageSeriesReader.h"

#include <dcmtk/dcmdata/dctk.h>

#include <sstream>

namespace
{
namespace fs = std::filesystem;
using dcv::test::Result;
using dcv::test::RunDcv;

const char * const Series = "dicom-ct-brain-5mm";

/** A copy of the dev series in a fresh directory. */
class DicomInput : public ::testing::Test
{
protected:
  void
  SetUp() override
  {
    if (!dcv::test::HaveData(Series))
    {
      GTEST_SKIP() << "needs " << dcv::test::DataFile(Series) << " (../shared/data is absent)";
    }
    m_Directory = std::make_unique<dcv::test::TemporaryDirectory>();
    m_Series = *m_Directory / "series";
    fs::create_directories(m_Series);
    for (const auto & entry : fs::directory_iterator(dcv::test::DataFile(Series)))
    {
      fs::copy_file(entry.path(), m_Series + "/" + entry.path().filename().string());
      fs::permissions(m_Series + "/" + entry.path().filename().string(), fs::perms::owner_write, fs::perm_options::add);
    }
  }
  std::string
  Path(const std::string & name) const
  {
    return *m_Directory / name;
  }
  /** Sets a tag of one file of the copy. */
  void
  Edit(const std::string & file, const DcmTagKey & key, const std::string & value) const
  {
    DcmFileFormat dicom;
    ASSERT_TRUE(dicom.loadFile((m_Series + "/" + file).c_str()).good()) << file;
    // DCMTK reads pixel data lazily: load it before the file is written over itself.
    ASSERT_TRUE(dicom.loadAllDataIntoMemory().good()) << file;
    ASSERT_TRUE(dicom.getDataset()->putAndInsertString(key, value.c_str()).good());
    ASSERT_TRUE(dicom.saveFile((m_Series + "/" + file).c_str()).good()) << file;
  }
  std::string
  Get(const std::string & file, const DcmTagKey & key) const
  {
    DcmFileFormat dicom;
    EXPECT_TRUE(dicom.loadFile((m_Series + "/" + file).c_str()).good()) << file;
    OFString value;
    dicom.getDataset()->findAndGetOFStringArray(key, value);
    return value.c_str();
  }
  /** `dcv compress` of the copy; expects a refusal with every phrase and no output file. */
  void
  ExpectRefused(const std::vector<std::string> & phrases, const std::string & extra = "") const
  {
    const Result r = RunDcv("compress " + m_Series + " " + Path("out.dcv") + " --points 100" + extra);
    EXPECT_EQ(r.status, 1) << r.output;
    for (const auto & phrase : phrases)
    {
      EXPECT_NE(r.output.find(phrase), std::string::npos) << "missing '" << phrase << "' in: " << r.output;
    }
    EXPECT_FALSE(fs::exists(Path("out.dcv")));
  }
  std::unique_ptr<dcv::test::TemporaryDirectory> m_Directory;
  std::string                                    m_Series;
};

TEST_F(DicomInput, CompressesTheSeriesInHounsfieldUnitsWithItsAttributes)
{
  const Result c = RunDcv("compress " + m_Series + " " + Path("ct.dcv") + " --points 2000 -m dec");
  ASSERT_EQ(c.status, 0) << c.output;
  const Result info = RunDcv("info " + Path("ct.dcv"));
  EXPECT_NE(info.output.find("pixel type: int16"), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("size: 512 512 28"), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("DICOM Modality = CT"), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("DICOM FrameOfReferenceUID = 1.3.46."), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("DICOM StudyInstanceUID = 1.3.46."), std::string::npos) << info.output;
  // The PSNR printed is the one of the decoded volume against the series read by ITK, in HU.
  ASSERT_EQ(RunDcv("decompress " + Path("ct.dcv") + " " + Path("ct.nrrd")).status, 0);
  using ImageType = itk::Image<int16_t, 3>;
  auto names = itk::GDCMSeriesFileNames::New();
  names->SetDirectory(m_Series);
  auto reader = itk::ImageSeriesReader<ImageType>::New();
  reader->SetImageIO(itk::GDCMImageIO::New());
  reader->SetFileNames(names->GetInputFileNames());
  reader->Update();
  const auto * original = reader->GetOutput();
  const auto   decoded = itk::ReadImage<ImageType>(Path("ct.nrrd"));
  const auto   n = original->GetBufferedRegion().GetNumberOfPixels();
  const auto   range = std::minmax_element(original->GetBufferPointer(), original->GetBufferPointer() + n);
  EXPECT_LE(*range.first, -1000); // air, in Hounsfield units
  const double psnr = dcv::PSNR(dcv::SquaredError(original->GetBufferPointer(), decoded->GetBufferPointer(), n),
                                n,
                                double(*range.second) - double(*range.first));
  const double printed = std::stod(c.output.substr(c.output.find("PSNR: ") + 6));
  EXPECT_NEAR(printed, psnr, 1e-3);
  for (unsigned d = 0; d < 3; ++d)
  {
    EXPECT_NEAR(decoded->GetOrigin()[d], original->GetOrigin()[d], 1e-4);
    EXPECT_NEAR(decoded->GetSpacing()[d], original->GetSpacing()[d], 1e-4);
  }
}

TEST_F(DicomInput, OneFileStandsForItsSeriesAndOthersAreSkipped)
{
  std::ofstream(m_Series + "/README.txt") << "not DICOM";
  const Result r = RunDcv("compress " + m_Series + "/I140.dcm " + Path("ct.dcv") + " --points 200 -m silva");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("skipped 1 files"), std::string::npos) << r.output;
  EXPECT_NE(RunDcv("info " + Path("ct.dcv")).output.find("size: 512 512 28"), std::string::npos);
}

TEST_F(DicomInput, RefusesAMissingSlice)
{
  fs::remove(m_Series + "/I140.dcm");
  ExpectRefused({ "missing slice between slices", "a gap of 10 mm where slices are 5 mm apart" });
}

TEST_F(DicomInput, RefusesUnevenSpacing)
{
  std::string position = Get("I140.dcm", DCM_ImagePositionPatient);
  const auto  z = position.rfind('\\');
  position = position.substr(0, z + 1) + std::to_string(std::stod(position.substr(z + 1)) + 1.5);
  Edit("I140.dcm", DCM_ImagePositionPatient, position);
  ExpectRefused({ "uneven slice spacing", "5 mm elsewhere" });
}

TEST_F(DicomInput, RefusesATiltedSeries)
{
  // Rows tilted by 10 degrees about x, positions still stacked along z: gantry tilt.
  for (const auto & entry : fs::directory_iterator(m_Series))
  {
    Edit(entry.path().filename().string(), DCM_ImageOrientationPatient, "1\\0\\0\\0\\0.98480775\\0.17364818");
  }
  ExpectRefused({ "not stacked along the normal", "gantry tilt" });
}

TEST_F(DicomInput, ListsTheSeriesOfADirectoryThatHoldsSeveral)
{
  const std::string uid = Get("I10.dcm", DCM_SeriesInstanceUID);
  for (const std::string file : { "I10.dcm", "I20.dcm", "I30.dcm" })
  {
    fs::copy_file(m_Series + "/" + file, m_Series + "/other-" + file);
    Edit("other-" + file, DCM_SeriesInstanceUID, "1.2.826.0.1.3680043.2.1125.42");
    Edit("other-" + file, DCM_SOPInstanceUID, "1.2.826.0.1.3680043.2.1125.42." + file.substr(1, file.size() - 5));
    Edit("other-" + file, DCM_SeriesDescription, "THREE SLICES");
  }
  ExpectRefused({ "holds 2 DICOM series; choose one with --series UID",
                  uid,
                  "1.2.826.0.1.3680043.2.1125.42",
                  "28 slices",
                  "3 slices",
                  "THREE SLICES" });
  const Result r = RunDcv("compress " + m_Series + " " + Path("out.dcv") + " --points 100 -m silva --series " + uid);
  EXPECT_EQ(r.status, 0) << r.output;
}

TEST_F(DicomInput, RefusesADirectoryWithoutImages)
{
  const std::string empty = Path("empty");
  fs::create_directories(empty);
  Result r = RunDcv("compress " + empty + " " + Path("x.dcv") + " -n 50");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("no DICOM image in"), std::string::npos) << r.output;
  std::ofstream(empty + "/notes.txt") << "hello";
  r = RunDcv("compress " + empty + " " + Path("x.dcv") + " -n 50");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("1 files, none of them DICOM"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(Path("x.dcv")));
}

/** Reads a DICOM directory with ITK. */
itk::Image<int16_t, 3>::Pointer
ReadSeries(const std::string & directory)
{
  auto names = itk::GDCMSeriesFileNames::New();
  names->SetDirectory(directory);
  auto reader = itk::ImageSeriesReader<itk::Image<int16_t, 3>>::New();
  reader->SetImageIO(itk::GDCMImageIO::New());
  reader->SetFileNames(names->GetInputFileNames());
  reader->Update();
  return reader->GetOutput();
}

/** The errors dciodvfy reports on every file of a directory ("" when it is not installed). */
std::string
DciodvfyErrors(const std::string & directory, std::size_t & files)
{
  files = 0;
  std::string errors;
  for (const auto & entry : fs::directory_iterator(directory))
  {
    ++files;
    const Result       r = dcv::test::RunCommand("dciodvfy '" + entry.path().string() + "' 2>&1");
    std::istringstream lines(r.output);
    for (std::string line; std::getline(lines, line);)
    {
      if (line.rfind("Error", 0) == 0)
        errors += entry.path().filename().string() + ": " + line + "\n";
    }
  }
  return errors;
}

bool
HaveDciodvfy()
{
  return dcv::test::RunCommand("command -v dciodvfy").status == 0;
}

TEST_F(DicomInput, RoundTripsToAValidDerivedSeriesOfTheSameStudy)
{
  const Result c = RunDcv("compress " + m_Series + " " + Path("ct.dcv") + " --points 3000 -m dec");
  ASSERT_EQ(c.status, 0) << c.output;
  const std::string out = Path("returned");
  const Result      d = RunDcv("decompress " + Path("ct.dcv") + " " + out + " --dicom");
  ASSERT_EQ(d.status, 0) << d.output;
  std::size_t files = 0;
  if (HaveDciodvfy())
  {
    EXPECT_EQ(DciodvfyErrors(out, files), "");
    EXPECT_EQ(files, 28u);
  }
  else
  {
    std::cout << "dciodvfy (dicom3tools) is not installed: the files were not validated" << std::endl;
  }
  // Same study and frame of reference, a new series, a lossy derived image.
  DcmFileFormat original, returned;
  ASSERT_TRUE(original.loadFile((m_Series + "/I10.dcm").c_str()).good());
  ASSERT_TRUE(returned.loadFile((out + "/IM000001.dcm").c_str()).good());
  auto tag = [](DcmFileFormat & f, const DcmTagKey & key) {
    OFString v;
    f.getDataset()->findAndGetOFStringArray(key, v);
    return std::string(v.c_str());
  };
  EXPECT_EQ(tag(returned, DCM_StudyInstanceUID), tag(original, DCM_StudyInstanceUID));
  EXPECT_EQ(tag(returned, DCM_FrameOfReferenceUID), tag(original, DCM_FrameOfReferenceUID));
  EXPECT_EQ(tag(returned, DCM_PatientID), tag(original, DCM_PatientID));
  EXPECT_NE(tag(returned, DCM_SeriesInstanceUID), tag(original, DCM_SeriesInstanceUID));
  EXPECT_EQ(tag(returned, DCM_ImageType).rfind("DERIVED\\SECONDARY", 0), 0u) << tag(returned, DCM_ImageType);
  EXPECT_EQ(tag(returned, DCM_LossyImageCompression), "01");
  EXPECT_EQ(tag(returned, DCM_BitsStored), tag(original, DCM_BitsStored));
  EXPECT_EQ(tag(returned, DCM_RescaleIntercept), tag(original, DCM_RescaleIntercept));
  // Geometry within 1e-4 mm, values in HU, and the PSNR compress printed.
  const auto a = ReadSeries(m_Series);
  const auto b = ReadSeries(out);
  ASSERT_EQ(a->GetLargestPossibleRegion(), b->GetLargestPossibleRegion());
  for (unsigned i = 0; i < 3; ++i)
  {
    EXPECT_NEAR(a->GetOrigin()[i], b->GetOrigin()[i], 1e-4);
    EXPECT_NEAR(a->GetSpacing()[i], b->GetSpacing()[i], 1e-4);
    for (unsigned j = 0; j < 3; ++j)
      EXPECT_NEAR(a->GetDirection()(i, j), b->GetDirection()(i, j), 1e-6);
  }
  const auto   n = a->GetBufferedRegion().GetNumberOfPixels();
  const auto   range = std::minmax_element(a->GetBufferPointer(), a->GetBufferPointer() + n);
  const double psnr = dcv::PSNR(dcv::SquaredError(a->GetBufferPointer(), b->GetBufferPointer(), n),
                                n,
                                double(*range.second) - double(*range.first));
  EXPECT_NEAR(std::stod(c.output.substr(c.output.find("PSNR: ") + 6)), psnr, 1e-3);
  // A non-empty directory is kept without --force, replaced with it.
  EXPECT_EQ(RunDcv("decompress " + Path("ct.dcv") + " " + out + " --dicom").status, 1);
  EXPECT_EQ(RunDcv("decompress " + Path("ct.dcv") + " " + out + " --dicom --force").status, 0);
  EXPECT_EQ(std::distance(fs::directory_iterator(out), fs::directory_iterator()), 28);
}

TEST(DicomOutput, AVolumeNotFromDicomGetsAPlaceholderContext)
{
  const dcv::test::TemporaryDirectory directory;
  ASSERT_EQ(RunDcv("phantom " + (directory / "p.nrrd") + " --size 24").status, 0);
  ASSERT_EQ(RunDcv("compress " + (directory / "p.nrrd") + " " + (directory / "p.dcv") + " -n 300 -m dec").status, 0);
  const Result d = RunDcv("decompress " + (directory / "p.dcv") + " " + (directory / "series") + " --dicom");
  ASSERT_EQ(d.status, 0) << d.output;
  std::size_t files = 0;
  if (HaveDciodvfy())
  {
    EXPECT_EQ(DciodvfyErrors(directory / "series", files), "");
    EXPECT_EQ(files, 24u);
  }
  DcmFileFormat f;
  ASSERT_TRUE(f.loadFile((directory / "series/IM000001.dcm").c_str()).good());
  OFString name, description;
  f.getDataset()->findAndGetOFString(DCM_PatientName, name);
  f.getDataset()->findAndGetOFString(DCM_StudyDescription, description);
  EXPECT_EQ(std::string(name.c_str()), "DCV^PLACEHOLDER");
  EXPECT_NE(std::string(description.c_str()).find("Not from DICOM"), std::string::npos);
  // Its values come back (uint8 phantom stored in 16 bits).
  const auto a = itk::ReadImage<itk::Image<int16_t, 3>>(directory / "p.nrrd");
  const auto b = ReadSeries(directory / "series");
  const auto n = a->GetBufferedRegion().GetNumberOfPixels();
  EXPECT_GT(dcv::PSNR(dcv::SquaredError(a->GetBufferPointer(), b->GetBufferPointer(), n), n, 255.0), 15.0);
}

} // namespace
