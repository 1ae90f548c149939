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
// dcv batch: a tree of small volumes (one of them broken, one file to skip) and, when ../shared is
// there, DICOM series; a failure named while the others complete, resume, --jobs and --shard.
#include "dcvDicomTestUtilities.h"
#include "dcvFileFormat.h"
#include "dcvTestUtilities.h"

#include "itkImageFileWriter.h"

#include <dcmtk/dcmdata/dctk.h>

#include <map>
#include <set>

namespace
{
namespace fs = std::filesystem;
using dcv::test::FileBytes;
using dcv::test::Result;
using dcv::test::RunDcv;

using Rows = std::vector<std::vector<std::string>>;

/** The rows of a CSV file (quoted fields with doubled quotes, as the summary writes them). */
Rows
ReadCsv(const std::string & path)
{
  Rows                     rows;
  const std::string        text = FileBytes(path);
  std::vector<std::string> row;
  std::string              field;
  bool                     quoted = false;
  for (std::size_t i = 0; i < text.size(); ++i)
  {
    const char c = text[i];
    if (quoted)
    {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"')
      {
        field += '"';
        ++i;
      }
      else if (c == '"')
        quoted = false;
      else
        field += c;
    }
    else if (c == '"')
      quoted = true;
    else if (c == ',')
    {
      row.push_back(field);
      field.clear();
    }
    else if (c == '\n')
    {
      row.push_back(field);
      field.clear();
      rows.push_back(row);
      row.clear();
    }
    else
      field += c;
  }
  return rows;
}

/** item -> row of a summary (header checked, 7 cells each). */
std::map<std::string, std::vector<std::string>>
Summary(const std::string & path)
{
  const Rows rows = ReadCsv(path);
  EXPECT_FALSE(rows.empty()) << path;
  std::map<std::string, std::vector<std::string>> items;
  for (std::size_t i = 0; i < rows.size(); ++i)
  {
    EXPECT_EQ(rows[i].size(), 7u) << path << " row " << i;
    if (i == 0)
    {
      EXPECT_EQ(rows[i], (std::vector<std::string>{ "item", "slices", "bytes", "ratio", "PSNR", "seconds", "status" }));
    }
    else if (rows[i].size() == 7)
    {
      EXPECT_TRUE(items.emplace(rows[i][0], rows[i]).second) << "twice: " << rows[i][0];
    }
  }
  return items;
}

/** The .dcv files of a directory, by name, with their bytes. */
std::map<std::string, std::string>
DcvFiles(const std::string & directory)
{
  std::map<std::string, std::string> files;
  for (const auto & entry : fs::directory_iterator(directory))
  {
    if (entry.path().extension() == ".dcv")
    {
      files[entry.path().filename().string()] = FileBytes(entry.path().string());
    }
  }
  return files;
}

bool
Contains(const std::string & text, const std::string & part)
{
  return text.find(part) != std::string::npos;
}

class Batch : public ::testing::Test
{
protected:
  void
  SetUp() override
  {
    m_Directory = std::make_unique<dcv::test::TemporaryDirectory>();
    m_Tree = Path("tree");
    using ImageType = itk::Image<uint8_t, 3>;
    const auto write = [&](ImageType::Pointer image, const std::string & name) {
      fs::create_directories(fs::path(m_Tree + "/" + name).parent_path());
      auto writer = itk::ImageFileWriter<ImageType>::New();
      writer->SetInput(image);
      writer->SetFileName(m_Tree + "/" + name);
      writer->Update();
    };
    write(dcv::test::PhantomImage({ 24, 24, 24 }), "a/p.nrrd");
    write(dcv::test::PhantomImage({ 20, 24, 16 }, true), "a/b/q.mha");
    write(dcv::test::PhantomImage({ 16, 16, 16 }), "c/r.nii.gz");
    write(dcv::test::PhantomImage({ 16, 20, 16 }), "c/s.mhd"); // and its s.raw, not counted as skipped
    // A NRRD cut in its data: the header reads, the voxels do not.
    const std::string nrrd = FileBytes(m_Tree + "/a/p.nrrd");
    std::ofstream(m_Tree + "/c/broken.nrrd", std::ios::binary) << nrrd.substr(0, nrrd.size() / 2);
    std::ofstream(m_Tree + "/notes.txt") << "not a volume\n";
  }
  std::string
  Path(const std::string & name) const
  {
    return *m_Directory / name;
  }
  Result
  RunBatch(const std::string & output, const std::string & extra = "") const
  {
    return RunDcv("batch " + m_Tree + " " + Path(output) + " --bpv 0.25" + extra);
  }

  const std::set<std::string>                    m_Good{ "a_p.nrrd", "a_b_q.mha", "c_r.nii.gz", "c_s.mhd" };
  std::unique_ptr<dcv::test::TemporaryDirectory> m_Directory;
  std::string                                    m_Tree;
};

TEST_F(Batch, CompressesEveryItemNamesTheBrokenOneAndResumes)
{
  const Result r = RunBatch("out");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_TRUE(Contains(r.output, "1 of 5 items failed")) << r.output;
  EXPECT_TRUE(Contains(r.output, "c_broken.nrrd ('" + m_Tree + "/c/broken.nrrd'): cannot read")) << r.output;
  EXPECT_TRUE(Contains(r.output, "skipped 1 file that is neither DICOM nor a volume file")) << r.output;
  EXPECT_TRUE(Contains(r.output, "batch: [5/5] ")) << r.output; // a line per item: stderr is not a terminal

  // Every other item is a valid .dcv file; the broken one left nothing, and no temporary is left.
  for (const auto & name : m_Good)
  {
    const auto file = dcv::ReadCompressedFile(Path("out/" + name + ".dcv"));
    EXPECT_LE(file.size, std::size_t(file.header.size.NumberOfVoxels() * 0.25 / 8)) << name;
  }
  std::set<std::string> files;
  for (const auto & entry : fs::directory_iterator(Path("out")))
  {
    files.insert(entry.path().filename().string());
  }
  std::set<std::string> expected{ "batch-summary.csv" };
  for (const auto & name : m_Good)
  {
    expected.insert(name + ".dcv");
  }
  EXPECT_EQ(files, expected);

  auto summary = Summary(Path("out/batch-summary.csv"));
  ASSERT_EQ(summary.size(), 5u);
  EXPECT_EQ(summary["a_p.nrrd"][1], "24");
  EXPECT_EQ(summary["a_b_q.mha"][1], "16");
  const auto before = DcvFiles(Path("out"));
  for (const auto & name : m_Good)
  {
    const auto & row = summary[name];
    EXPECT_EQ(row[6], "ok") << name;
    EXPECT_EQ(row[2], std::to_string(before.at(name + ".dcv").size())) << name;
    EXPECT_FALSE(row[3].empty() || row[4].empty()) << name; // ratio and PSNR
  }
  EXPECT_NEAR(std::stod(summary["a_p.nrrd"][3]), 24.0 * 24 * 24 / std::stod(summary["a_p.nrrd"][2]), 0.01);
  EXPECT_EQ(summary["c_broken.nrrd"][6].rfind("failed: cannot read '", 0), 0u) << summary["c_broken.nrrd"][6];
  EXPECT_TRUE(summary["c_broken.nrrd"][2].empty());

  // A rerun keeps the valid files (bytes and ratio from them, no PSNR) and tries the broken one again.
  const Result again = RunBatch("out");
  EXPECT_EQ(again.status, 1) << again.output;
  EXPECT_TRUE(Contains(again.output, "skipped (exists)")) << again.output;
  EXPECT_EQ(DcvFiles(Path("out")), before);
  const auto resumed = Summary(Path("out/batch-summary.csv"));
  for (const auto & name : m_Good)
  {
    const auto & row = resumed.at(name);
    EXPECT_EQ(row[6], "skipped (exists)") << name;
    EXPECT_EQ(row[1], summary[name][1]) << name;
    EXPECT_EQ(row[2], summary[name][2]) << name;
    EXPECT_EQ(row[3], summary[name][3]) << name;
    EXPECT_TRUE(row[4].empty()) << name;
  }
  EXPECT_EQ(resumed.at("c_broken.nrrd")[6].rfind("failed: ", 0), 0u);

  // A damaged output (a killed copy, a flipped bit) is not valid: made again, the same bytes.
  const std::string damaged = Path("out/a_p.nrrd.dcv");
  std::ofstream(damaged, std::ios::binary) << before.at("a_p.nrrd.dcv").substr(0, 40);
  ASSERT_EQ(RunBatch("out").status, 1);
  EXPECT_EQ(Summary(Path("out/batch-summary.csv")).at("a_p.nrrd")[6], "ok");
  EXPECT_EQ(DcvFiles(Path("out")), before);

  // --force redoes them all, to the same bytes (the encoder is deterministic).
  ASSERT_EQ(RunBatch("out", " --force").status, 1);
  for (const auto & [name, row] : Summary(Path("out/batch-summary.csv")))
  {
    EXPECT_EQ(row[6].substr(0, 2), name == "c_broken.nrrd" ? "fa" : "ok") << name;
  }
  EXPECT_EQ(DcvFiles(Path("out")), before);
}

TEST_F(Batch, SucceedsQuietlyWithoutTheBrokenItemAndSkipsItsOwnOutputs)
{
  fs::remove(m_Tree + "/c/broken.nrrd");
  // OUTPUT_DIR inside the tree: its files are not items of the run.
  const Result r = RunDcv("batch " + m_Tree + " " + m_Tree + "/out --points 30 -q");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output, "");
  EXPECT_EQ(Summary(m_Tree + "/out/batch-summary.csv").size(), 4u);
  const Result again = RunDcv("batch " + m_Tree + " " + m_Tree + "/out --points 30");
  EXPECT_EQ(again.status, 0) << again.output;
  EXPECT_TRUE(Contains(again.output, "batch: 4 items in")) << again.output;
  EXPECT_EQ(Summary(m_Tree + "/out/batch-summary.csv").size(), 4u);
}

TEST_F(Batch, JobsDoNotChangeTheOutputs)
{
  ASSERT_EQ(RunBatch("one", " --jobs 1").status, 1);
  const Result two = RunBatch("two", " --jobs 2");
  ASSERT_EQ(two.status, 1) << two.output;
  EXPECT_TRUE(Contains(two.output, "2 jobs")) << two.output;
  const auto one = DcvFiles(Path("one"));
  EXPECT_EQ(one.size(), m_Good.size());
  EXPECT_EQ(DcvFiles(Path("two")), one);
  // The same rows in the same order (the seconds aside).
  const Rows a = ReadCsv(Path("one/batch-summary.csv")), b = ReadCsv(Path("two/batch-summary.csv"));
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i)
  {
    for (std::size_t c : { 0, 1, 2, 3, 4, 6 })
    {
      EXPECT_EQ(a[i].at(c), b[i].at(c)) << "row " << i << " column " << c;
    }
  }
}

TEST_F(Batch, ShardsCoverEveryItemExactlyOnce)
{
  ASSERT_EQ(RunBatch("all").status, 1);
  const auto            all = Summary(Path("all/batch-summary.csv"));
  std::set<std::string> covered;
  for (int k = 1; k <= 3; ++k)
  {
    const std::string shard = std::to_string(k) + "/3";
    const Result      r = RunBatch("sharded", " --jobs 2 --shard " + shard);
    // The broken item is in one shard only: that one fails.
    EXPECT_TRUE(r.status == 0 || r.status == 1) << r.output;
    EXPECT_TRUE(Contains(r.output, "shard " + shard + ": ")) << r.output;
    const auto part = Summary(Path("sharded/batch-summary-" + std::to_string(k) + "-of-3.csv"));
    EXPECT_FALSE(part.empty()) << shard;
    EXPECT_EQ(r.status, part.count("c_broken.nrrd") ? 1 : 0) << r.output;
    for (const auto & [name, row] : part)
    {
      EXPECT_TRUE(covered.insert(name).second) << name << " is in two shards";
      EXPECT_EQ(row[2], all.at(name)[2]) << name;
    }
  }
  std::set<std::string> names;
  for (const auto & [name, row] : all)
  {
    names.insert(name);
  }
  EXPECT_EQ(covered, names);
  EXPECT_EQ(DcvFiles(Path("sharded")), DcvFiles(Path("all")));
}

TEST_F(Batch, RefusesBadArgumentsWithAMessage)
{
  for (const std::string shard : { "0/3", "4/3", "3", "a/3", "1/0", "1/3x", "-1/3", "2/+3", "" })
  {
    const Result r = RunBatch("out", " '--shard=" + shard + "'");
    EXPECT_EQ(r.status, 2) << shard << ": " << r.output; // a usage error
    EXPECT_TRUE(Contains(r.output, "--shard")) << shard << ": " << r.output;
    if (!shard.empty()) // CLI11 refuses an empty value itself
    {
      EXPECT_TRUE(Contains(r.output, "expected K/N with 1 <= K <= N")) << shard << ": " << r.output;
    }
  }
  EXPECT_FALSE(fs::exists(Path("out"))); // refused before anything was written
  const Result noTarget = RunDcv("batch " + m_Tree + " " + Path("out"));
  EXPECT_EQ(noTarget.status, 2);
  EXPECT_TRUE(Contains(noTarget.output, "batch needs a target: --bpv R, --psnr DB or --points N")) << noTarget.output;
  const Result noTree = RunDcv("batch " + Path("missing") + " " + Path("out") + " --bpv 0.25");
  EXPECT_EQ(noTree.status, 1);
  EXPECT_TRUE(Contains(noTree.output, "no such directory")) << noTree.output;
  const Result badMode = RunDcv("batch " + m_Tree + " " + Path("out") + " --bpv 0.25 --mode nonsense");
  EXPECT_EQ(badMode.status, 2);
  EXPECT_TRUE(Contains(badMode.output, "--mode")) << badMode.output;
  EXPECT_FALSE(fs::exists(Path("out")));
}

TEST_F(Batch, RefusesBothItemsOfAnOutputNameTheyWouldShare)
{
  // x/y_z.nrrd and x_y/z.nrrd both map to x_y_z.nrrd.dcv: neither may overwrite the other.
  fs::create_directories(m_Tree + "/x");
  fs::create_directories(m_Tree + "/x_y");
  fs::copy_file(m_Tree + "/a/p.nrrd", m_Tree + "/x/y_z.nrrd");
  fs::copy_file(m_Tree + "/a/p.nrrd", m_Tree + "/x_y/z.nrrd");
  const Result r = RunDcv("batch " + m_Tree + " " + Path("out") + " --points 30 --jobs 0");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_TRUE(Contains(r.output, "3 of 7 items failed")) << r.output;
  EXPECT_TRUE(Contains(r.output, "its output name 'x_y_z.nrrd.dcv' is also that of '" + m_Tree + "/x_y/z.nrrd'"))
    << r.output;
  EXPECT_TRUE(Contains(r.output, "its output name 'x_y_z.nrrd.dcv' is also that of '" + m_Tree + "/x/y_z.nrrd'"))
    << r.output;
  EXPECT_FALSE(fs::exists(Path("out/x_y_z.nrrd.dcv")));
  EXPECT_EQ(DcvFiles(Path("out")).size(), m_Good.size());
}

/** The Series Instance UID of a DICOM file; sets it when `value` is given. */
std::string
SeriesUid(const std::string & file, const std::string & value = "")
{
  DcmFileFormat dicom;
  EXPECT_TRUE(dicom.loadFile(file.c_str()).good()) << file;
  if (!value.empty())
  {
    dicom.loadAllDataIntoMemory(); // DCMTK reads the pixel data lazily, from the file being overwritten
    EXPECT_TRUE(dicom.getDataset()->putAndInsertString(DCM_SeriesInstanceUID, value.c_str()).good());
    EXPECT_TRUE(dicom.saveFile(file.c_str()).good()) << file;
    return value;
  }
  OFString uid;
  dicom.getDataset()->findAndGetOFString(DCM_SeriesInstanceUID, uid);
  return uid.c_str();
}

TEST_F(Batch, DicomSeriesAreItemsNamedByDirectoryAndSeriesInstanceUid)
{
  const std::string series = "dicom-ct-brain-5mm";
  if (!dcv::test::HaveData(series))
  {
    GTEST_SKIP() << "needs " << dcv::test::DataFile(series) << " (../shared/data is absent)";
  }
  fs::remove(m_Tree + "/c/broken.nrrd");
  // ct/: the dev series and a file that is not DICOM; mixed/: the dev series and a copy of it under
  // another Series Instance UID, two items of one directory.
  fs::create_directories(m_Tree + "/dicom/ct");
  fs::create_directories(m_Tree + "/dicom/mixed");
  std::string       uid;
  const std::string other = "1.2.826.0.1.3680043.2.1125.99.1";
  for (const auto & entry : fs::directory_iterator(dcv::test::DataFile(series)))
  {
    const std::string name = entry.path().filename().string();
    for (const std::string & copy :
         { m_Tree + "/dicom/ct/" + name, m_Tree + "/dicom/mixed/" + name, m_Tree + "/dicom/mixed/copy-" + name })
    {
      fs::copy_file(entry.path(), copy);
      fs::permissions(copy, fs::perms::owner_write, fs::perm_options::add);
    }
    uid = SeriesUid(entry.path().string());
    SeriesUid(m_Tree + "/dicom/mixed/copy-" + name, other);
  }
  std::ofstream(m_Tree + "/dicom/ct/README") << "not DICOM\n";

  // Three series of 512 x 512 x 28 at a few points, two at a time (GDCM in two threads at once).
  const Result r = RunDcv("batch " + m_Tree + " " + Path("out") + " --points 500 --mode silva --jobs 2");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(Contains(r.output, "skipped 2 files")) << r.output; // notes.txt and README
  const auto summary = Summary(Path("out/batch-summary.csv"));
  EXPECT_EQ(summary.size(), 7u);
  for (const std::string & name : { "dicom_ct_" + uid, "dicom_mixed_" + uid, "dicom_mixed_" + other })
  {
    ASSERT_TRUE(summary.count(name)) << name << " in " << r.output;
    EXPECT_EQ(summary.at(name)[1], "28") << name;
    EXPECT_EQ(summary.at(name)[6], "ok") << name;
    const auto file = dcv::ReadCompressedFile(Path("out/" + name + ".dcv"));
    EXPECT_EQ(file.header.pixelType, dcv::PixelType::Int16) << name;
    EXPECT_EQ(file.header.size.z, 28) << name;
    // 512 x 512 x 28 int16 voxels over the file's bytes.
    EXPECT_NEAR(std::stod(summary.at(name)[3]), 512.0 * 512 * 28 * 2 / double(file.size), 0.01);
    const auto stored =
      std::find(file.header.metadata.begin(),
                file.header.metadata.end(),
                std::make_pair(std::string("DICOM SeriesInstanceUID"), name.substr(name.rfind('_') + 1)));
    EXPECT_NE(stored, file.header.metadata.end()) << name;
    // Every file's header, as compress keeps it (the 28 files, all of each).
    const auto header = std::find_if(file.header.metadata.begin(), file.header.metadata.end(), [](const auto & kv) {
      return kv.first == dcv::DicomHeaderKey;
    });
    ASSERT_NE(header, file.header.metadata.end()) << name;
    const auto block = dcv::SplitDicomHeader(header->second, name);
    EXPECT_EQ(block.mode, 0) << name;
    EXPECT_EQ(block.files.size(), 28u) << name;
  }
}

TEST_F(Batch, DicomSeriesWithPixelDataCutShortFailAndTheOthersGoOn)
{
  const std::string series = "dicom-ct-brain-5mm";
  if (!dcv::test::HaveData(series))
  {
    GTEST_SKIP() << "needs " << dcv::test::DataFile(series) << " (../shared/data is absent)";
  }
  fs::remove(m_Tree + "/c/broken.nrrd");
  // cut/: one file cut to 400000 of its 531932 bytes; halved/: every file cut to half its length (a
  // series of its own: another Series Instance UID).
  fs::create_directories(m_Tree + "/dicom/cut");
  fs::create_directories(m_Tree + "/dicom/halved");
  std::string       uid;
  const std::string other = "1.2.826.0.1.3680043.2.1125.99.2";
  for (const auto & entry : fs::directory_iterator(dcv::test::DataFile(series)))
  {
    const std::string name = entry.path().filename().string();
    for (const std::string & copy : { m_Tree + "/dicom/cut/" + name, m_Tree + "/dicom/halved/" + name })
    {
      fs::copy_file(entry.path(), copy);
      fs::permissions(copy, fs::perms::owner_write, fs::perm_options::add);
    }
    uid = SeriesUid(entry.path().string());
    SeriesUid(m_Tree + "/dicom/halved/" + name, other);
    const std::string halved = FileBytes(m_Tree + "/dicom/halved/" + name);
    std::ofstream(m_Tree + "/dicom/halved/" + name, std::ios::binary | std::ios::trunc)
      << halved.substr(0, halved.size() / 2);
  }
  const std::string cut = FileBytes(m_Tree + "/dicom/cut/I140.dcm");
  std::ofstream(m_Tree + "/dicom/cut/I140.dcm", std::ios::binary | std::ios::trunc) << cut.substr(0, 400000);

  const Result r = RunDcv("batch " + m_Tree + " " + Path("out") + " --points 100 --jobs 2");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_TRUE(Contains(r.output, "2 of 6 items failed")) << r.output;
  const auto summary = Summary(Path("out/batch-summary.csv"));
  ASSERT_TRUE(summary.count("dicom_cut_" + uid)) << r.output;
  ASSERT_TRUE(summary.count("dicom_halved_" + other)) << r.output;
  const std::string cutStatus = summary.at("dicom_cut_" + uid)[6];
  EXPECT_TRUE(Contains(cutStatus, "failed")) << cutStatus;
  EXPECT_TRUE(Contains(cutStatus, "I140.dcm")) << cutStatus;
  EXPECT_TRUE(Contains(cutStatus, "131930 bytes missing")) << cutStatus;
  const std::string halvedStatus = summary.at("dicom_halved_" + other)[6];
  EXPECT_TRUE(Contains(halvedStatus, "failed")) << halvedStatus;
  EXPECT_TRUE(Contains(halvedStatus, "it is cut short")) << halvedStatus;
  EXPECT_TRUE(Contains(halvedStatus, "bytes missing")) << halvedStatus;
  EXPECT_FALSE(fs::exists(Path("out/dicom_cut_" + uid + ".dcv")));
  EXPECT_FALSE(fs::exists(Path("out/dicom_halved_" + other + ".dcv")));
  for (const auto & name : m_Good)
    EXPECT_EQ(summary.at(name)[6], "ok") << name;
}

TEST_F(Batch, ADicomFileCutShortInsideItsHeaderFailsItsDirectoryAndTheOthersGoOn)
{
  const std::string series = "dicom-ct-brain-5mm";
  if (!dcv::test::HaveData(series))
  {
    GTEST_SKIP() << "needs " << dcv::test::DataFile(series) << " (../shared/data is absent)";
  }
  fs::remove(m_Tree + "/c/broken.nrrd");
  // GDCM's series scan aborted the whole run on such a file.
  fs::create_directories(m_Tree + "/dicom/cut");
  for (const std::string name : { "I130.dcm", "I140.dcm", "I150.dcm" })
  {
    fs::copy_file(dcv::test::DataFile(series) + "/" + name, m_Tree + "/dicom/cut/" + name);
    fs::permissions(m_Tree + "/dicom/cut/" + name, fs::perms::owner_write, fs::perm_options::add);
  }
  const std::string cut = FileBytes(m_Tree + "/dicom/cut/I140.dcm");
  std::ofstream(m_Tree + "/dicom/cut/I140.dcm", std::ios::binary | std::ios::trunc) << cut.substr(0, 7600);

  const Result r = RunDcv("batch " + m_Tree + " " + Path("out") + " --points 100 --jobs 2");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_TRUE(Contains(r.output, "1 of 5 items failed")) << r.output;
  EXPECT_TRUE(Contains(r.output, "I140.dcm': it is cut short inside its header (the file ends at byte 7600)"))
    << r.output;
  const auto summary = Summary(Path("out/batch-summary.csv"));
  ASSERT_TRUE(summary.count("dicom_cut")) << r.output;
  const std::string status = summary.at("dicom_cut")[6];
  EXPECT_TRUE(Contains(status, "failed")) << status;
  EXPECT_TRUE(Contains(status, "I140.dcm")) << status;
  EXPECT_TRUE(Contains(status, "cut short inside its header")) << status;
  EXPECT_FALSE(fs::exists(Path("out/dicom_cut.dcv")));
  for (const auto & name : m_Good)
    EXPECT_EQ(summary.at(name)[6], "ok") << name;
}

TEST(BatchResample, ATiltedSeriesFailsNamingTheOptionAndIsResampledWithIt)
{
  const dcv::test::TemporaryDirectory directory;
  const std::string                   tree = directory / "tree";
  const double                        c = std::cos(15.0 * 3.14159265358979323846 / 180.0);
  const double                        s = std::sin(15.0 * 3.14159265358979323846 / 180.0);
  std::vector<std::array<double, 3>>  positions;
  std::vector<double>                 z;
  for (int k = 0; k < 8; ++k)
  {
    positions.push_back({ { 0.0, 0.0, 3.0 * k } });
    z.push_back(3.0 * k);
  }
  const auto field = [](int i, int j, int k, const std::array<double, 3> &) { return -500.0 + 20.0 * (i + j + k); };
  dcv::test::WriteCtSeries(tree + "/tilted", 24, positions, { { 1, 0, 0, 0, c, s } }, field);
  dcv::test::WriteCtSeries(tree + "/axial", 24, dcv::test::AxialPositions(z), dcv::test::Axial, field);
  const std::string uid = "1.2.826.0.1.3680043.2.1125.77.2"; // WriteCtSeries' series
  Result            r = RunDcv("batch " + tree + " " + (directory / "out") + " --points 100");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_TRUE(Contains(r.output, "tilted_" + uid)) << r.output;
  EXPECT_TRUE(Contains(r.output, "gantry tilt?)")) << r.output;
  EXPECT_TRUE(Contains(r.output, "--resample resamples it onto a regular grid instead")) << r.output;
  EXPECT_EQ(Summary(directory / "out/batch-summary.csv").at("axial_" + uid)[6], "ok");

  r = RunDcv("batch " + tree + " " + (directory / "out") + " --points 100 --resample");
  EXPECT_EQ(r.status, 0) << r.output;
  const auto summary = Summary(directory / "out/batch-summary.csv");
  EXPECT_EQ(summary.at("axial_" + uid)[6], "skipped (exists)");
  EXPECT_EQ(summary.at("tilted_" + uid)[6],
            "ok (resampled: gantry tilt 15 degrees -> slices along the normal of the orientation, 2.898 mm apart, 8 "
            "slices)");
  EXPECT_EQ(dcv::ReadCompressedFile(directory / ("out/tilted_" + uid + ".dcv")).header.size.z, 8);
}

} // namespace
