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
#include "dcvDicomTestUtilities.h"
#include "dcvFileFormat.h"
#include "dcvTestUtilities.h"

#include "itkGDCMImageIO.h"
#include "itkGDCMSeriesFileNames.h"
#include "itkImageFileWriter.h"
#include "itkImageSeriesReader.h"

#include <dcmtk/dcmdata/dctk.h>

#include <array>
#include <functional>
#include <map>
#include <sstream>

namespace
{
namespace fs = std::filesystem;
using dcv::test::Result;
using dcv::test::RunDcv;
using dcv::test::WriteCtSeries;
using dcv::test::AxialPositions;
using dcv::test::Axial;

const char * const Series = "dicom-ct-brain-5mm";

/** What `compress` printed after "key: ". */
std::string
Printed(const std::string & output, const std::string & key)
{
  const auto at = output.find(key + ": ");
  if (at == std::string::npos)
    return "";
  const auto end = output.find_first_of(" \n", at + key.size() + 2);
  return output.substr(at + key.size() + 2, end - at - key.size() - 2);
}

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
  const double       psnr = dcv::PSNR(dcv::SquaredError(original->GetBufferPointer(), decoded->GetBufferPointer(), n),
                                n,
                                double(*range.second) - double(*range.first));
  std::ostringstream measured;
  measured << psnr; // as compress prints it
  EXPECT_EQ(Printed(c.output, "PSNR"), measured.str());
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

/** The first `bytes` bytes of `file`, written over it. */
void
CutShort(const std::string & file, std::size_t bytes)
{
  const std::string whole = dcv::test::FileBytes(file);
  std::ofstream(file, std::ios::binary | std::ios::trunc) << whole.substr(0, std::min(bytes, whole.size()));
}

TEST_F(DicomInput, RefusesAFileWhosePixelDataIsCutShort)
{
  // 531932 bytes, the pixel data's 524288 from byte 7642: cut to 400000, 131930 of them are missing.
  CutShort(m_Series + "/I140.dcm", 400000);
  const std::vector<std::string> phrases{
    "I140.dcm", "it is cut short", "pixel data is 524288 bytes", "131930 bytes missing"
  };
  ExpectRefused(phrases);
  const Result r = RunDcv("convert " + m_Series + " " + Path("out.nrrd"));
  EXPECT_EQ(r.status, 1) << r.output;
  for (const auto & phrase : phrases)
    EXPECT_NE(r.output.find(phrase), std::string::npos) << "missing '" << phrase << "' in: " << r.output;
  EXPECT_FALSE(fs::exists(Path("out.nrrd")));
}

TEST_F(DicomInput, RefusesASeriesOfFilesCutToHalfTheirLength)
{
  for (const auto & entry : fs::directory_iterator(m_Series))
    CutShort(entry.path().string(), 531932 / 2);
  // 265966 bytes, about half of the pixel data's 524288 missing, whichever file is read first.
  ExpectRefused({ "cannot read the DICOM file", "it is cut short", "pixel data is 524288 bytes", "bytes missing" });
  const Result r = RunDcv("convert " + m_Series + " " + Path("out.nrrd"));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("it is cut short"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(Path("out.nrrd")));
}

TEST_F(DicomInput, RefusesUnevenSpacing)
{
  std::string position = Get("I140.dcm", DCM_ImagePositionPatient);
  const auto  z = position.rfind('\\');
  position = position.substr(0, z + 1) + std::to_string(std::stod(position.substr(z + 1)) + 1.5);
  Edit("I140.dcm", DCM_ImagePositionPatient, position);
  ExpectRefused({ "uneven slice spacing", "5 mm elsewhere", "--resample" });
  // With --resample: onto the smallest gap, 3.5 mm, as the 135 mm from the first slice to the last allow.
  const Result r = RunDcv("convert " + m_Series + " " + Path("resampled.nrrd") + " --resample");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("resampled: uneven slice spacing 3.5-6.5 mm -> 3.462 mm (the smallest gap, 3.5 mm, "
                          "fitted to the 135 mm from the first slice to the last), 40 slices"),
            std::string::npos)
    << r.output;
  const auto image = itk::ReadImage<itk::Image<int16_t, 3>>(Path("resampled.nrrd"));
  EXPECT_EQ(image->GetLargestPossibleRegion().GetSize()[2], 40u);
  EXPECT_NEAR(image->GetSpacing()[2], 135.0 / 39.0, 1e-9);
}

TEST_F(DicomInput, RefusesATiltedSeries)
{
  // Rows tilted by 10 degrees about x, positions still stacked along z: gantry tilt.
  for (const auto & entry : fs::directory_iterator(m_Series))
  {
    Edit(entry.path().filename().string(), DCM_ImageOrientationPatient, "1\\0\\0\\0\\0.98480775\\0.17364818");
  }
  ExpectRefused({ "not stacked along the normal", "gantry tilt", "--resample" });
  const Result r = RunDcv("convert " + m_Series + " " + Path("resampled.nrrd") + " --resample");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("resampled: gantry tilt 10 degrees -> slices along the normal of the orientation, 4.924 mm "
                          "apart, 28 slices"),
            std::string::npos)
    << r.output;
  const auto image = itk::ReadImage<itk::Image<int16_t, 3>>(Path("resampled.nrrd"));
  EXPECT_EQ(image->GetLargestPossibleRegion().GetSize()[2], 28u);
  EXPECT_NEAR(image->GetSpacing()[2], 5.0 * 0.98480775, 1e-5);
  EXPECT_NEAR(image->GetDirection()(1, 2), -0.17364818, 1e-6); // the normal of the tilted orientation
  EXPECT_NEAR(image->GetDirection()(2, 2), 0.98480775, 1e-6);
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
  // The original's software versions, then dcv's.
  const std::string versions = tag(original, DCM_SoftwareVersions);
  EXPECT_EQ(tag(returned, DCM_SoftwareVersions),
            (versions.empty() ? "" : versions + "\\") + std::string("dcv ") + DCV_PROJECT_VERSION);
  EXPECT_EQ(tag(returned, DCM_BitsStored), tag(original, DCM_BitsStored));
  // The original's intercept, or one below it where the decoding undershoots -1024 HU.
  EXPECT_LE(std::stod(tag(returned, DCM_RescaleIntercept)), std::stod(tag(original, DCM_RescaleIntercept)));
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
  const auto         n = a->GetBufferedRegion().GetNumberOfPixels();
  const auto         range = std::minmax_element(a->GetBufferPointer(), a->GetBufferPointer() + n);
  const double       psnr = dcv::PSNR(dcv::SquaredError(a->GetBufferPointer(), b->GetBufferPointer(), n),
                                n,
                                double(*range.second) - double(*range.first));
  std::ostringstream measured;
  measured << psnr; // as compress prints it
  EXPECT_EQ(Printed(c.output, "PSNR"), measured.str());
  // A non-empty directory is kept without --force, replaced with it.
  EXPECT_EQ(RunDcv("decompress " + Path("ct.dcv") + " " + out + " --dicom").status, 1);
  EXPECT_EQ(RunDcv("decompress " + Path("ct.dcv") + " " + out + " --dicom --force").status, 0);
  EXPECT_EQ(std::distance(fs::directory_iterator(out), fs::directory_iterator()), 28);
}

// Lossless files give a series not flagged lossy, identical in its values; near-lossless ones are flagged and
// state their bound; both pass dciodvfy.
TEST_F(DicomInput, BoundedFilesSayWhetherTheyAreLossless)
{
  const auto original = ReadSeries(m_Series);
  const auto n = original->GetBufferedRegion().GetNumberOfPixels();
  for (const int bound : { 0, 5 })
  {
    const std::string packed = Path("bounded" + std::to_string(bound) + ".dcv");
    const Result      c = RunDcv("compress " + m_Series + " " + packed + " --max-error " + std::to_string(bound));
    ASSERT_EQ(c.status, 0) << c.output;
    const std::string out = Path("bounded" + std::to_string(bound));
    const Result      d = RunDcv("decompress " + packed + " " + out + " --dicom");
    ASSERT_EQ(d.status, 0) << d.output;
    std::size_t files = 0;
    if (HaveDciodvfy())
      EXPECT_EQ(DciodvfyErrors(out, files), "");
    DcmFileFormat returned;
    ASSERT_TRUE(returned.loadFile((out + "/IM000001.dcm").c_str()).good());
    OFString lossy, description;
    returned.getDataset()->findAndGetOFString(DCM_LossyImageCompression, lossy);
    returned.getDataset()->findAndGetOFString(DCM_DerivationDescription, description);
    EXPECT_EQ(std::string(lossy.c_str()), bound == 0 ? "00" : "01");
    const std::string stated = bound == 0 ? "lossless" : "near-lossless, every value within 5";
    EXPECT_NE(std::string(description.c_str()).find(stated), std::string::npos) << description;
    const auto back = ReadSeries(out);
    double     worst = 0.0;
    for (std::size_t i = 0; i < n; ++i)
      worst = std::max(worst, std::abs(double(back->GetBufferPointer()[i]) - double(original->GetBufferPointer()[i])));
    EXPECT_LE(worst, double(bound));
  }
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


// GDCM reads no image plane in Secondary Capture images; dcv writes one into the series it makes from
// volumes that were not CT, and reads it back: the same grid and voxels as the decoded volume.
TEST(DicomOutput, ASecondaryCaptureSeriesReadsBackOnItsGrid)
{
  const dcv::test::TemporaryDirectory directory;
  ASSERT_EQ(RunDcv("phantom " + (directory / "p.nrrd") + " --size 20").status, 0);
  using ImageType = itk::Image<uint8_t, 3>;
  const auto               image = itk::ReadImage<ImageType>(directory / "p.nrrd");
  const double             spacing[3] = { 0.7, 0.8, 2.5 };
  const double             origin[3] = { 10.0, -20.0, 30.0 };
  ImageType::DirectionType direction; // the in-plane axes flipped, as in a supine CT series
  direction.Fill(0.0);
  direction[0][0] = -1.0;
  direction[1][1] = -1.0;
  direction[2][2] = 1.0;
  image->SetSpacing(spacing);
  image->SetOrigin(origin);
  image->SetDirection(direction);
  itk::WriteImage(image, directory / "g.nrrd");
  ASSERT_EQ(RunDcv("compress " + (directory / "g.nrrd") + " " + (directory / "g.dcv") + " -n 300 -q").status, 0);
  ASSERT_EQ(RunDcv("decompress " + (directory / "g.dcv") + " " + (directory / "decoded.nrrd") + " -q").status, 0);
  ASSERT_EQ(RunDcv("decompress " + (directory / "g.dcv") + " " + (directory / "series") + " --dicom -q").status, 0);
  const Result back = RunDcv("convert " + (directory / "series") + " " + (directory / "back.nrrd"));
  ASSERT_EQ(back.status, 0) << back.output;
  const auto a = itk::ReadImage<itk::Image<int16_t, 3>>(directory / "decoded.nrrd");
  const auto b = itk::ReadImage<itk::Image<int16_t, 3>>(directory / "back.nrrd");
  ASSERT_EQ(a->GetLargestPossibleRegion(), b->GetLargestPossibleRegion());
  for (unsigned i = 0; i < 3; ++i)
  {
    EXPECT_NEAR(b->GetSpacing()[i], spacing[i], 1e-6);
    EXPECT_NEAR(b->GetOrigin()[i], origin[i], 1e-6);
    for (unsigned j = 0; j < 3; ++j)
      EXPECT_NEAR(b->GetDirection()[i][j], direction[i][j], 1e-6);
  }
  const auto n = a->GetBufferedRegion().GetNumberOfPixels();
  EXPECT_TRUE(std::equal(a->GetBufferPointer(), a->GetBufferPointer() + n, b->GetBufferPointer()));
  // Secondary Capture images without a position (screen captures) have nothing to stack them by.
  for (const auto & entry : fs::directory_iterator(directory / "series"))
  {
    DcmFileFormat f;
    ASSERT_TRUE(f.loadFile(entry.path().c_str()).good());
    f.getDataset()->findAndDeleteElement(DCM_ImagePositionPatient);
    ASSERT_TRUE(f.saveFile(entry.path().c_str(), EXS_LittleEndianExplicit).good());
  }
  const Result unplaced = RunDcv("convert " + (directory / "series") + " " + (directory / "none.nrrd"));
  EXPECT_EQ(unplaced.status, 1) << unplaced.output;
  EXPECT_NE(unplaced.output.find("Secondary Capture image without Image Position (Patient)"), std::string::npos)
    << unplaced.output;
  EXPECT_FALSE(fs::exists(directory / "none.nrrd"));
}


class GeneratedSeries : public ::testing::Test
{
protected:
  std::string
  Path(const std::string & name) const
  {
    return m_Directory / name;
  }
  dcv::test::TemporaryDirectory m_Directory;
};

// The spline (and a residual layer) may undershoot the original's stored range: a 12-bit CT series
// stores nothing below -1024 HU. The series written back must still hold every decoded value, or it
// differs from what `decompress` writes elsewhere and from the PSNR `compress` printed.
TEST_F(GeneratedSeries, ReturnedSeriesHasExactlyThePsnrCompressPrinted)
{
  const int           n = 40;
  const auto          phantom = dcv::SheppLoganPhantom(dcv::GridSize{ n, n, 10 });
  std::vector<double> z;
  for (int k = 0; k < 10; ++k)
    z.push_back(2.0 * k);
  // Air (-1024 HU, stored 0) around a skull of 761 HU: the spline overshoots into air at its edges.
  WriteCtSeries(Path("series"), n, AxialPositions(z), Axial, [&](int i, int j, int k, const std::array<double, 3> &) {
    return -1024.0 + 7.0 * phantom[(std::size_t(k) * n + j) * n + i];
  });
  for (const std::string target : { "--points 400", "--bpv 0.5" })
  {
    SCOPED_TRACE(target);
    const Result c = RunDcv("compress " + Path("series") + " " + Path("ct.dcv") + " " + target + " --force");
    ASSERT_EQ(c.status, 0) << c.output;
    ASSERT_EQ(RunDcv("decompress " + Path("ct.dcv") + " " + Path("ct.nrrd") + " --force").status, 0);
    const Result d = RunDcv("decompress " + Path("ct.dcv") + " " + Path("returned") + " --dicom --force");
    ASSERT_EQ(d.status, 0) << d.output;
    using ImageType = itk::Image<int16_t, 3>;
    const auto original = ReadSeries(Path("series"));
    const auto decoded = itk::ReadImage<ImageType>(Path("ct.nrrd"));
    const auto returned = ReadSeries(Path("returned"));
    const auto voxels = original->GetBufferedRegion().GetNumberOfPixels();
    ASSERT_EQ(returned->GetBufferedRegion().GetNumberOfPixels(), voxels);
    const auto decodedRange = std::minmax_element(decoded->GetBufferPointer(), decoded->GetBufferPointer() + voxels);
    // The case this guards: decoded values below what the original's encoding stores. The points
    // undershoot; at --bpv 0.5 the encoder keeps a layer over the constant corners, whose decoder clips
    // at the original's minimum, so there the series must only be exact.
    if (target.rfind("--points", 0) == 0)
      EXPECT_LT(*decodedRange.first, -1024) << "the decoding no longer undershoots: the test guards nothing";
    std::size_t differ = 0;
    for (std::size_t i = 0; i < voxels; ++i)
      differ += decoded->GetBufferPointer()[i] != returned->GetBufferPointer()[i] ? 1 : 0;
    EXPECT_EQ(differ, 0u) << "voxels of the returned series differ from the decoded volume";
    const auto   range = std::minmax_element(original->GetBufferPointer(), original->GetBufferPointer() + voxels);
    const double psnr = dcv::PSNR(dcv::SquaredError(original->GetBufferPointer(), returned->GetBufferPointer(), voxels),
                                  voxels,
                                  double(*range.second) - double(*range.first));
    std::ostringstream measured;
    measured << psnr; // as compress prints it
    EXPECT_EQ(Printed(c.output, "PSNR"), measured.str());
    std::size_t files = 0;
    if (HaveDciodvfy())
    {
      EXPECT_EQ(DciodvfyErrors(Path("returned"), files), "");
      EXPECT_EQ(files, 10u);
    }
  }
}

/** An affine field of HU, which linear interpolation reproduces. */
double
Field(const std::array<double, 3> & p)
{
  return -300.0 + 4.0 * p[0] + 3.0 * p[1] + 10.0 * p[2];
}

TEST_F(GeneratedSeries, UnevenSpacingIsResampledOntoTheSmallestGapWhenAsked)
{
  WriteCtSeries(Path("series"), 16, AxialPositions({ 0, 2, 4, 6, 9, 12 }), Axial, [](int, int, int, const auto & p) {
    return Field(p);
  });
  Result r = RunDcv("compress " + Path("series") + " " + Path("ct.dcv") + " --points 100");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("uneven slice spacing: 3 mm between slices 4 and 5, 2 mm elsewhere; --resample"),
            std::string::npos)
    << r.output;
  EXPECT_FALSE(fs::exists(Path("ct.dcv")));
  r = RunDcv("compress " + Path("series") + " " + Path("ct.dcv") + " --points 100 --resample");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("resampled: uneven slice spacing 2-3 mm -> 2 mm (the smallest gap), 7 slices"),
            std::string::npos)
    << r.output;
  EXPECT_NE(RunDcv("info " + Path("ct.dcv")).output.find("size: 16 16 7"), std::string::npos);
  // The grid, and values where linear interpolation is exact (an affine field; stored values rounded).
  r = RunDcv("convert " + Path("series") + " " + Path("grid.nrrd") + " --resample");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto image = itk::ReadImage<itk::Image<int16_t, 3>>(Path("grid.nrrd"));
  EXPECT_EQ(image->GetLargestPossibleRegion().GetSize(), (itk::Size<3>{ { 16, 16, 7 } }));
  EXPECT_NEAR(image->GetSpacing()[2], 2.0, 1e-9);
  EXPECT_NEAR(image->GetOrigin()[2], 0.0, 1e-9);
  for (unsigned k = 0; k < 7; ++k)
  {
    itk::Index<3>         index{ { 5, 7, k } };
    itk::Point<double, 3> p;
    image->TransformIndexToPhysicalPoint(index, p);
    EXPECT_NEAR(image->GetPixel(index), Field({ { p[0], p[1], p[2] } }), 1.0) << "slice " << k;
  }
  // Gaps that do not divide the extent: the spacing is shortened to end on the last slice.
  fs::remove_all(Path("series"));
  WriteCtSeries(
    Path("series"), 16, AxialPositions({ 0, 2, 4, 7 }), Axial, [](int, int, int, const auto & p) { return Field(p); });
  r = RunDcv("convert " + Path("series") + " " + Path("grid.nrrd") + " --resample --force");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("2-3 mm -> 1.75 mm (the smallest gap, 2 mm, fitted to the 7 mm from the first slice to "
                          "the last), 5 slices"),
            std::string::npos)
    << r.output;
  using ImageType = itk::Image<int16_t, 3>;
  EXPECT_NEAR(itk::ReadImage<ImageType>(Path("grid.nrrd"))->GetSpacing()[2], 1.75, 1e-9);
}

TEST_F(GeneratedSeries, MissingSlicesAndNearDuplicatesStayRefusedWithResample)
{
  WriteCtSeries(Path("series"), 16, AxialPositions({ 0, 2, 4, 8, 10 }), Axial, [](int, int, int, const auto & p) {
    return Field(p);
  });
  Result r = RunDcv("compress " + Path("series") + " " + Path("ct.dcv") + " --points 100 --resample");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("missing slice between slices 3 and 4"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(Path("ct.dcv")));
  // A slice 0.1 mm from the next: its gap would make 151 slices of 5.
  fs::remove_all(Path("series"));
  WriteCtSeries(Path("series"), 16, AxialPositions({ 0, 0.1, 5, 10, 15 }), Axial, [](int, int, int, const auto & p) {
    return Field(p);
  });
  r = RunDcv("compress " + Path("series") + " " + Path("ct.dcv") + " --points 100 --resample");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("resampling onto the smallest gap would make 151 slices of 5, so not resampled"),
            std::string::npos)
    << r.output;
  EXPECT_FALSE(fs::exists(Path("ct.dcv")));
}

TEST_F(GeneratedSeries, GantryTiltIsResampledOntoTheNormalOfTheOrientationWhenAsked)
{
  // Rows along x, columns tilted by 15 degrees about x, slices 3 mm apart along z: gantry tilt.
  const double                       c = std::cos(15.0 * 3.14159265358979323846 / 180.0);
  const double                       s = std::sin(15.0 * 3.14159265358979323846 / 180.0);
  const std::array<double, 6>        tilted{ { 1, 0, 0, 0, c, s } };
  std::vector<std::array<double, 3>> positions;
  for (int k = 0; k < 8; ++k)
    positions.push_back({ { 0.0, 0.0, 3.0 * k } });
  WriteCtSeries(Path("series"), 32, positions, tilted, [](int, int, int, const auto & p) { return Field(p); });
  Result r = RunDcv("compress " + Path("series") + " " + Path("ct.dcv") + " --points 100");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("gantry tilt?); a tilted series is not a volume on a grid; --resample"), std::string::npos)
    << r.output;
  r = RunDcv("compress " + Path("series") + " " + Path("ct.dcv") + " --points 100 --resample");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(
    r.output.find("resampled: gantry tilt 15 degrees -> slices along the normal of the orientation, 2.898 mm apart, "
                  "8 slices"),
    std::string::npos)
    << r.output;
  r = RunDcv("convert " + Path("series") + " " + Path("grid.nrrd") + " --resample");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto image = itk::ReadImage<itk::Image<int16_t, 3>>(Path("grid.nrrd"));
  EXPECT_EQ(image->GetLargestPossibleRegion().GetSize(), (itk::Size<3>{ { 32, 32, 8 } }));
  EXPECT_NEAR(image->GetSpacing()[2], 3.0 * c, 1e-6);
  const double normal[3] = { 0.0, -s, c };
  for (unsigned i = 0; i < 3; ++i)
  {
    EXPECT_NEAR(image->GetOrigin()[i], 0.0, 1e-9);
    EXPECT_NEAR(image->GetDirection()(i, 0), tilted[i], 1e-6);
    EXPECT_NEAR(image->GetDirection()(i, 1), tilted[3 + i], 1e-6);
    EXPECT_NEAR(image->GetDirection()(i, 2), normal[i], 1e-6);
  }
  // Slice k of the series lies 3 k sin(15) mm down the columns from slice k of the grid: where a slice
  // covers a voxel, the affine field comes back; where none does, the series' minimum.
  const auto minimum = int16_t(std::round(Field({ { 0, 0, 0 } })));
  for (unsigned k = 0; k < 8; ++k)
  {
    for (unsigned j = 0; j < 32; ++j)
    {
      const itk::Index<3>   index{ { 9, j, k } };
      const double          row = double(j) - 3.0 * k * s; // in the series' slice k
      itk::Point<double, 3> p;
      image->TransformIndexToPhysicalPoint(index, p);
      if (row >= 0.0 && row <= 31.0)
        EXPECT_NEAR(image->GetPixel(index), Field({ { p[0], p[1], p[2] } }), 1.0) << "k " << k << " j " << j;
      else if (row < -0.5 - 1e-6)
        EXPECT_EQ(image->GetPixel(index), minimum) << "k " << k << " j " << j;
    }
  }
  // The series written back lies on the new grid, and says it was resampled.
  ASSERT_EQ(RunDcv("decompress " + Path("ct.dcv") + " " + Path("returned") + " --dicom").status, 0);
  DcmFileFormat last;
  ASSERT_TRUE(last.loadFile(Path("returned/IM000008.dcm").c_str()).good());
  OFString position, derivation;
  last.getDataset()->findAndGetOFStringArray(DCM_ImagePositionPatient, position);
  last.getDataset()->findAndGetOFString(DCM_DerivationDescription, derivation);
  std::istringstream    values(std::string(position.c_str()));
  std::array<double, 3> xyz{};
  char                  separator;
  values >> xyz[0] >> separator >> xyz[1] >> separator >> xyz[2];
  for (unsigned i = 0; i < 3; ++i)
    EXPECT_NEAR(xyz[i], 7.0 * 3.0 * c * normal[i], 1e-4);
  EXPECT_NE(std::string(derivation.c_str()).find("resampled onto a regular grid (gantry tilt 15 degrees"),
            std::string::npos)
    << derivation;
  std::size_t files = 0;
  if (HaveDciodvfy())
  {
    EXPECT_EQ(DciodvfyErrors(Path("returned"), files), "");
  }
}


/** The attributes a lossy derived file changes (docs/dicom.md); every other public attribute of the
 * original comes back with the same value. */
const std::vector<DcmTagKey> Changed{ DCM_SOPInstanceUID,
                                      DCM_SeriesInstanceUID,
                                      DCM_ImageType,
                                      DCM_LossyImageCompression,
                                      DCM_LossyImageCompressionRatio,
                                      DCM_LossyImageCompressionMethod,
                                      DCM_DerivationDescription,
                                      DCM_SourceImageSequence,
                                      DCM_DerivationCodeSequence,
                                      DCM_InstanceCreationDate,
                                      DCM_InstanceCreationTime,
                                      DCM_SeriesNumber,
                                      DCM_SeriesDescription,
                                      DCM_SoftwareVersions,
                                      DCM_BitsStored,
                                      DCM_HighBit,
                                      DCM_RescaleIntercept,
                                      DCM_SmallestImagePixelValue,
                                      DCM_LargestImagePixelValue,
                                      DCM_SmallestPixelValueInSeries,
                                      DCM_LargestPixelValueInSeries,
                                      DCM_PixelPaddingValue,
                                      DCM_PixelPaddingRangeLimit,
                                      DCM_PixelData };

/** The ISO 2022 bytes of PS3.5 Annex H's example name "Yamada^Tarou=山田^太郎=やまだ^たろう". */
const std::string Yamada = "Yamada^Tarou=\x1b$B;3ED\x1b(B^\x1b$BB@O:\x1b(B=\x1b$B$d$^$@\x1b(B^\x1b$B$?$m$&\x1b(B";

/** Copies of the dev series, few slices, edited per file; compressed, and returned as DICOM. */
class DicomHeaders : public DicomInput
{
protected:
  /** Keeps the `n` slices lowest in z (a shorter series, quicker to code), sorted: m_Files. */
  void
  KeepSlices(std::size_t n)
  {
    std::vector<std::pair<double, std::string>> byZ;
    for (const auto & entry : fs::directory_iterator(m_Series))
    {
      const std::string name = entry.path().filename().string();
      const std::string position = Get(name, DCM_ImagePositionPatient);
      byZ.emplace_back(std::stod(position.substr(position.rfind('\\') + 1)), name);
    }
    std::sort(byZ.begin(), byZ.end());
    m_Files.clear();
    for (std::size_t i = 0; i < byZ.size(); ++i)
    {
      if (i < n)
        m_Files.push_back(byZ[i].second);
      else
        fs::remove(m_Series + "/" + byZ[i].second);
    }
  }
  /** Sets tags of one file of the copy at once (raw bytes: no character set conversion). */
  void
  EditFile(const std::string & file, const std::vector<std::pair<DcmTagKey, std::string>> & edits) const
  {
    DcmFileFormat dicom;
    ASSERT_TRUE(dicom.loadFile((m_Series + "/" + file).c_str()).good()) << file;
    ASSERT_TRUE(dicom.loadAllDataIntoMemory().good()) << file;
    for (const auto & [key, value] : edits)
      ASSERT_TRUE(dicom.getDataset()->putAndInsertString(key, value.c_str()).good()) << value;
    ASSERT_TRUE(dicom.saveFile((m_Series + "/" + file).c_str()).good()) << file;
  }
  /** compress (at `bpv`), decompress --dicom into "returned"; the directory. */
  std::string
  RoundTrip(const std::string & extra = "", const std::string & bpv = "0.125")
  {
    const Result c = RunDcv("compress " + m_Series + " " + Path("ct.dcv") + " --bpv " + bpv + extra);
    EXPECT_EQ(c.status, 0) << c.output;
    m_Compressed = c.output;
    EXPECT_NE(c.output.find("DICOM header: "), std::string::npos) << c.output;
    const std::string out = Path("returned");
    const Result      d = RunDcv("decompress " + Path("ct.dcv") + " " + out + " --dicom");
    EXPECT_EQ(d.status, 0) << d.output;
    return out;
  }
  /** Every returned file: valid (dciodvfy), its original (same position) referenced as its source, every
   * public attribute of the original there with the same value (the changed ones apart), its private
   * ones too (`privates`), the text of `texts` byte for byte. */
  void
  ExpectTrueToTheOriginals(const std::string & out, const std::vector<DcmTagKey> & texts, bool privates = true)
  {
    std::size_t files = 0;
    if (HaveDciodvfy())
    {
      EXPECT_EQ(DciodvfyErrors(out, files), "");
    }
    else
    {
      std::cout << "dciodvfy (dicom3tools) is not installed: the files were not validated" << std::endl;
    }
    std::map<std::string, std::string> byPosition;
    for (const auto & f : m_Files)
      byPosition[Get(f, DCM_ImagePositionPatient)] = f;
    files = 0;
    for (const auto & entry : fs::directory_iterator(out))
    {
      ++files;
      const std::string name = entry.path().filename().string();
      DcmFileFormat     returned, original;
      ASSERT_TRUE(returned.loadFile(entry.path().string().c_str()).good()) << name;
      DcmDataset & r = *returned.getDataset();
      OFString     position;
      r.findAndGetOFStringArray(DCM_ImagePositionPatient, position);
      ASSERT_TRUE(byPosition.count(position.c_str())) << name << " at " << position;
      const std::string source = byPosition[position.c_str()];
      ASSERT_TRUE(original.loadFile((m_Series + "/" + source).c_str()).good()) << source;
      DcmDataset & o = *original.getDataset();
      std::size_t  originalPrivates = 0, returnedPrivates = 0;
      for (unsigned long i = 0; i < o.card(); ++i)
      {
        DcmElement *    e = o.getElement(i);
        const DcmTagKey t = e->getTag();
        if (t.getGroup() & 1)
        {
          ++originalPrivates;
          continue;
        }
        if (std::find(Changed.begin(), Changed.end(), t) != Changed.end())
          continue;
        DcmElement * same = nullptr;
        EXPECT_TRUE(r.findAndGetElement(t, same).good())
          << name << ": " << t.toString() << " " << DcmTag(t).getTagName() << " of " << source << " is missing";
        if (same)
          EXPECT_EQ(e->compare(*same), 0)
            << name << ": " << t.toString() << " " << DcmTag(t).getTagName() << " differs from " << source;
      }
      for (unsigned long i = 0; i < r.card(); ++i)
        returnedPrivates += (r.getElement(i)->getTag().getGroup() & 1) ? 1 : 0;
      if (privates)
        EXPECT_EQ(returnedPrivates, originalPrivates) << name;
      for (const auto & t : texts)
      {
        OFString a, b;
        o.findAndGetOFStringArray(t, a);
        r.findAndGetOFStringArray(t, b);
        EXPECT_EQ(std::string(b.c_str()), std::string(a.c_str())) << name << ": " << DcmTag(t).getTagName();
      }
      // Derived from its original, lossy.
      OFString value;
      r.findAndGetOFStringArray(DCM_ImageType, value);
      EXPECT_EQ(std::string(value.c_str()).rfind("DERIVED\\SECONDARY", 0), 0u) << value;
      r.findAndGetOFString(DCM_LossyImageCompression, value);
      EXPECT_EQ(value, "01");
      DcmItem * item = nullptr;
      ASSERT_TRUE(r.findAndGetSequenceItem(DCM_SourceImageSequence, item, 0).good()) << name;
      EXPECT_TRUE(item->findAndGetOFString(DCM_ReferencedSOPInstanceUID, value).good()) << name;
      OFString originalUid, originalClass;
      o.findAndGetOFString(DCM_SOPInstanceUID, originalUid);
      o.findAndGetOFString(DCM_SOPClassUID, originalClass);
      EXPECT_EQ(value, originalUid) << name << " should name " << source;
      item->findAndGetOFString(DCM_ReferencedSOPClassUID, value);
      EXPECT_EQ(value, originalClass) << name;
      DcmItem * code = nullptr;
      ASSERT_TRUE(item->findAndGetSequenceItem(DCM_PurposeOfReferenceCodeSequence, code, 0).good()) << name;
      code->findAndGetOFString(DCM_CodeValue, value);
      EXPECT_EQ(value, "121320");
      ASSERT_TRUE(r.findAndGetSequenceItem(DCM_DerivationCodeSequence, code, 0).good()) << name;
      code->findAndGetOFString(DCM_CodeValue, value);
      EXPECT_EQ(value, "113040");
      r.findAndGetOFString(DCM_SOPInstanceUID, value);
      EXPECT_NE(value, originalUid);
    }
    EXPECT_EQ(files, m_Files.size());
  }
  std::vector<std::string> m_Files;
  std::string              m_Compressed;
};

TEST_F(DicomHeaders, Latin1NamesComeBackByteForByteWithTheWholeHeader)
{
  KeepSlices(4);
  for (const auto & f : m_Files)
  {
    EditFile(f,
             { { DCM_SpecificCharacterSet, "ISO_IR 100" },
               { DCM_PatientName, "M\xfcller^J\xfcrgen" },
               { DCM_StudyDescription,
                 "Sch\xe4"
                 "del nativ" } });
  }
  const std::string out = RoundTrip();
  ExpectTrueToTheOriginals(out, { DCM_SpecificCharacterSet, DCM_PatientName, DCM_StudyDescription });
  // The header's cost, printed by info too.
  const Result info = RunDcv("info " + Path("ct.dcv"));
  EXPECT_NE(info.output.find("DICOM header: "), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("4 files, full"), std::string::npos) << info.output;
}

TEST_F(DicomHeaders, Utf8AndIso2022NamesComeBackByteForByte)
{
  KeepSlices(4);
  // Files of one series that disagree on their character set: each keeps its own.
  for (std::size_t i = 0; i < m_Files.size(); ++i)
  {
    if (i % 2 == 0)
      EditFile(m_Files[i],
               { { DCM_SpecificCharacterSet, "ISO_IR 192" },
                 { DCM_PatientName,
                   "\xe1\xbd\x88\xce\xb4\xcf\x85\xcf\x83\xcf\x83\xce\xb5\xcf\x8d\xcf\x82^"
                   "\xce\x9c\xe1\xbf\x86\xcf\x84\xce\xb9\xcf\x82=\xe7\x8e\x8b^\xe5\xb0\x8f\xe6\x98\x8e" } });
    else
      EditFile(m_Files[i], { { DCM_SpecificCharacterSet, "\\ISO 2022 IR 87" }, { DCM_PatientName, Yamada } });
  }
  const std::string out = RoundTrip();
  ExpectTrueToTheOriginals(out, { DCM_SpecificCharacterSet, DCM_PatientName });
}

TEST_F(DicomHeaders, TwoWindowsAndPerSliceValuesAreKept)
{
  KeepSlices(4);
  for (std::size_t i = 0; i < m_Files.size(); ++i)
  {
    EditFile(m_Files[i],
             { { DCM_WindowCenter, "40\\400" },
               { DCM_WindowWidth, "80\\2000" },
               { DCM_WindowCenterWidthExplanation, "BRAIN\\BONE" },
               { DCM_ImageComments, "slice " + std::to_string(i + 1) },
               { DCM_ExposureTime, std::to_string(1000 + 10 * i) } });
  }
  const std::string out = RoundTrip();
  ExpectTrueToTheOriginals(out,
                           { DCM_WindowCenter,
                             DCM_WindowWidth,
                             DCM_WindowCenterWidthExplanation,
                             DCM_ImageComments,
                             DCM_ExposureTime,
                             DCM_ConvolutionKernel,
                             DCM_ProtocolName });
}

TEST_F(DicomHeaders, EssentialKeepsAValidSeriesInFewerBytes)
{
  KeepSlices(4);
  const std::string out = RoundTrip(" --dicom-header essential");
  const auto        bytes = [](const std::string & printed) {
    const auto at = printed.find("DICOM header: ");
    return at == std::string::npos ? 0ul : std::stoul(printed.substr(at + 14));
  };
  const std::size_t essential = bytes(m_Compressed);
  std::size_t       files = 0;
  if (HaveDciodvfy())
    EXPECT_EQ(DciodvfyErrors(out, files), "");
  EXPECT_EQ(Get(m_Files[0], DCM_PatientName), [&] {
    DcmFileFormat f;
    EXPECT_TRUE(f.loadFile((out + "/IM000001.dcm").c_str()).good());
    OFString v;
    f.getDataset()->findAndGetOFStringArray(DCM_PatientName, v);
    return std::string(v.c_str());
  }());
  const Result full = RunDcv("compress " + m_Series + " " + Path("full.dcv") + " --bpv 0.125 -f");
  ASSERT_EQ(full.status, 0) << full.output;
  EXPECT_LT(essential, bytes(full.output));
  // A budget the header does not fit: refused before encoding, with what it needs and the option.
  const Result tiny = RunDcv("compress " + m_Series + " " + Path("tiny.dcv") + " --bpv 0.005");
  EXPECT_EQ(tiny.status, 1) << tiny.output;
  EXPECT_NE(tiny.output.find("its DICOM header (full) takes"), std::string::npos) << tiny.output;
  EXPECT_NE(tiny.output.find("--dicom-header essential needs"), std::string::npos) << tiny.output;
  EXPECT_FALSE(fs::exists(Path("tiny.dcv")));
}

TEST_F(DicomHeaders, AFileWithoutTheHeaderBlockStillGivesADerivedSeries)
{
  KeepSlices(4);
  const Result c = RunDcv("compress " + m_Series + " " + Path("ct.dcv") + " --bpv 0.125");
  ASSERT_EQ(c.status, 0) << c.output;
  // The file as it was before the header block: the fixed list of attributes alone.
  auto   file = dcv::ReadCompressedFile(Path("ct.dcv"));
  auto & metadata = file.header.metadata;
  metadata.erase(
    std::remove_if(metadata.begin(), metadata.end(), [](const auto & kv) { return kv.first == dcv::DicomHeaderKey; }),
    metadata.end());
  dcv::WriteFileAtomically(Path("old.dcv"), dcv::SerializeFile(file.header, file.payload));
  EXPECT_EQ(RunDcv("info " + Path("old.dcv")).output.find("DICOM header: "), std::string::npos);
  const Result d = RunDcv("decompress " + Path("old.dcv") + " " + Path("returned") + " --dicom");
  ASSERT_EQ(d.status, 0) << d.output;
  std::size_t files = 0;
  if (HaveDciodvfy())
    EXPECT_EQ(DciodvfyErrors(Path("returned"), files), "");
  EXPECT_EQ(std::distance(fs::directory_iterator(Path("returned")), fs::directory_iterator()), 4);
}

} // namespace

TEST_F(DicomHeaders, AFileCutShortInsideItsHeaderIsRefusedNamingIt)
{
  // GDCM's series scan aborted the program on such a file: it is refused before GDCM reads it.
  KeepSlices(3);
  std::ofstream(m_Series + "/README.txt") << "not DICOM"; // still skipped, not refused
  const std::string cut = m_Files[1];
  CutShort(m_Series + "/" + cut, 7600); // its pixel data starts after byte 7626 or later
  const std::vector<std::string> phrases{ "cannot read the DICOM file",
                                          cut,
                                          "it is cut short inside its header (the file ends at byte 7600)" };
  ExpectRefused(phrases);
  for (const std::string & command :
       { "convert " + m_Series + " " + Path("out.nrrd"),
         "compress " + m_Series + "/" + m_Files[0] + " " + Path("out.dcv") + " --points 100",
         "compress " + m_Series + "/" + cut + " " + Path("out.dcv") + " --points 100" })
  {
    const Result r = RunDcv(command);
    EXPECT_EQ(r.status, 1) << command << ": " << r.output;
    for (const auto & phrase : phrases)
      EXPECT_NE(r.output.find(phrase), std::string::npos) << "missing '" << phrase << "' in: " << r.output;
  }
  EXPECT_FALSE(fs::exists(Path("out.nrrd")));
  EXPECT_FALSE(fs::exists(Path("out.dcv")));
  // Cut inside its file meta information, or right after the "DICM" prefix.
  for (const std::size_t bytes : { std::size_t(300), std::size_t(132) })
  {
    CutShort(m_Series + "/" + cut, bytes);
    ExpectRefused({ cut, "it is cut short inside its header (the file ends at byte " + std::to_string(bytes) + ")" });
  }
}

TEST_F(DicomHeaders, AnImageWithoutPixelDataIsRefusedAtEitherEndOrInTheMiddle)
{
  // GDCM's series scan leaves such a file out: at either end of the series it went unseen.
  KeepSlices(3);
  const auto withoutPixelData = [&](const std::string & file) {
    DcmFileFormat dicom;
    ASSERT_TRUE(dicom.loadFile((m_Series + "/" + file).c_str()).good()) << file;
    ASSERT_TRUE(dicom.getDataset()->findAndDeleteElement(DCM_PixelData).good()) << file;
    ASSERT_TRUE(dicom.saveFile((m_Series + "/" + file + ".header").c_str()).good()) << file;
    fs::rename(m_Series + "/" + file, Path(file));
    fs::rename(m_Series + "/" + file + ".header", m_Series + "/" + file);
  };
  for (const std::string & file : { m_Files.front(), m_Files.back(), m_Files[1] })
  {
    withoutPixelData(file);
    ExpectRefused({ "cannot read the DICOM file", file, "it has no pixel data" });
    fs::rename(Path(file), m_Series + "/" + file); // the whole file back
  }
  // Of another series, or not an image: not the series' business.
  withoutPixelData(m_Files.back());
  Edit(m_Files.back(), DCM_SeriesInstanceUID, "1.2.826.0.1.3680043.2.1125.99.3");
  const Result r = RunDcv("compress " + m_Series + " " + Path("b.dcv") + " --points 100 --series " +
                          Get(m_Files.front(), DCM_SeriesInstanceUID));
  EXPECT_EQ(r.status, 0) << r.output;
}
