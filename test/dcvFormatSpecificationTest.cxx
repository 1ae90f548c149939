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
// docs/format.md against the code: scripts/dcv_reference_decoder.py, a decoder written from the document
// alone, must read every file the C++ encoder writes into exactly what the C++ decoder gives (header fields,
// points in decoding order, values given the neighbours), and refuse the damaged ones.
#include "dcvBoundedLayer.h"
#include "dcvCodec.h"
#include "dcvEncoder.h"
#include "dcvResidualLayer.h"
#include "dcvVideoLayer.h"
#include "dcvFileFormat.h"
#include "dcvInterSliceWavelet.h"
#include "dcvPhantom.h"
#include "dcvRefinementEngine.h"
#include "dcvTestUtilities.h"
#include "itkDCVEncoder.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

namespace
{
namespace fs = std::filesystem;
using namespace dcv;

struct Result
{
  int         status;
  std::string output; // stdout
  std::string errors; // stderr
};

std::string
Quote(const std::string & s)
{
  std::string q = "'";
  for (char c : s)
    q += (c == '\'') ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

/** A string as Python's json.dumps(s, ensure_ascii=False) writes it. */
std::string
Json(const std::string & s)
{
  std::string out = "\"";
  for (unsigned char c : s)
  {
    switch (c)
    {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\b':
        out += "\\b";
        break;
      case '\f':
        out += "\\f";
        break;
      default:
        if (c < 0x20)
        {
          char buffer[8];
          std::snprintf(buffer, sizeof(buffer), "\\u%04x", c);
          out += buffer;
        }
        else
        {
          out += char(c);
        }
    }
  }
  return out + "\"";
}

/** What the C++ reader makes of a file: ParseFile, then DecodePayload. */
struct Decoded
{
  std::vector<uint8_t> bytes;
  FileHeader           header;
  std::vector<uint8_t> payload;
  Approximation        approximation;
};

Decoded
DecodeWithTheLibrary(const std::string & path)
{
  Decoded d;
  d.bytes = ReadWholeFile(path);
  ParseFile(d.bytes, path, d.header, d.payload);
  const FileHeader & h = d.header;
  d.approximation =
    h.constantSpline
      ? DecodeMesh(CompressedFile{ path, h, d.payload, d.bytes.size() })
      : DecodePayload(d.payload, h.size, h.numberOfPoints, h.quantizationOrigin, h.quantizationStep, path, h.scale);
  return d;
}

/** The reference decoder's output, split into header fields and point lines. */
struct Reference
{
  std::map<std::string, std::vector<std::string>> fields;   // name -> tokens
  std::vector<std::string>                        metadata; // the text after "metadata ", per pair
  std::vector<std::vector<std::string>>           points;   // tokens per point line
};

Reference
ParseReference(const std::string & output)
{
  Reference          r;
  std::istringstream lines(output);
  std::string        line;
  while (std::getline(lines, line))
  {
    std::istringstream       tokens(line);
    std::vector<std::string> t;
    for (std::string s; tokens >> s;)
      t.push_back(s);
    if (t.empty())
      continue;
    if (t[0] == "metadata")
      r.metadata.push_back(line.substr(9));
    else if (std::isalpha(static_cast<unsigned char>(t[0][0])))
      r.fields[t[0]] = std::vector<std::string>(t.begin() + 1, t.end());
    else
      r.points.push_back(t);
  }
  return r;
}

double
ToDouble(const std::string & s)
{
  char *       end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  EXPECT_TRUE(end && *end == '\0' && !s.empty()) << "not a number: '" << s << "'";
  return v;
}

class FormatSpecification : public ::testing::Test
{
protected:
  void
  SetUp() override
  {
    if (std::string(DCV_PYTHON3).empty() || !fs::exists(DCV_PYTHON3))
    {
      GTEST_SKIP() << "python3 was not found (CMake find_program: '" << DCV_PYTHON3
                   << "'): cannot run the reference decoder " << DCV_REFERENCE_DECODER
                   << "; install python3 (scripts/setup.sh) and reconfigure";
    }
    m_Directory = fs::temp_directory_path() / ("dcv-spec-" + std::to_string(::getpid()) + "-" +
                                               ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(m_Directory);
    fs::create_directories(m_Directory);
  }
  void
  TearDown() override
  {
    if (!m_Directory.empty())
      fs::remove_all(m_Directory);
  }
  std::string
  Path(const std::string & name) const
  {
    return (m_Directory / name).string();
  }

  /** python3 dcv_reference_decoder.py FILE [--neighbours NEIGHBOURS]. */
  Result
  RunReference(const std::string & file, const std::string & neighbours = "") const
  {
    const std::string errors = Path("stderr.txt");
    std::string       command = Quote(DCV_PYTHON3) + " " + Quote(DCV_REFERENCE_DECODER) + " " + Quote(file);
    if (!neighbours.empty())
      command += " --neighbours " + Quote(neighbours);
    command += " 2>" + Quote(errors);
    const dcv::test::Result run = dcv::test::RunCommand(command);
    Result                  r{ run.status, run.output, "" };
    std::ifstream           in(errors);
    r.errors.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    return r;
  }

  /** The neighbour lists of the Delaunay tetrahedralization of the points, one line per vertex. */
  std::string
  WriteNeighbours(const std::vector<GridPoint> & points, const GridScale & scale, const std::string & name) const
  {
    std::vector<std::set<uint32_t>> around(points.size());
    for (const Tetrahedron & t : Tetrahedralize(points, scale))
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j)
          if (i != j)
            around[t[i]].insert(t[j]);
    std::ofstream out(Path(name));
    for (const auto & a : around)
    {
      const char * separator = "";
      for (uint32_t j : a)
      {
        out << separator << j;
        separator = " ";
      }
      out << '\n';
    }
    return Path(name);
  }

  /** Codes `a` (values on q0 + k q) into a file with header `h`. */
  std::string
  WriteDcv(const std::string & name, FileHeader h, const Approximation & a) const
  {
    h.size = a.grid;
    h.numberOfPoints = uint32_t(a.points.size());
    WriteFileAtomically(Path(name), SerializeFile(h, EncodePayload(a, h.quantizationOrigin, h.quantizationStep)));
    return Path(name);
  }

  /** The reference decoder agrees with the library on `path`: header, points in order, and values. */
  void
  ExpectAgreement(const std::string & path, bool alsoWithoutValues = false) const
  {
    const Decoded         d = DecodeWithTheLibrary(path);
    const FileHeader &    h = d.header;
    const Approximation & a = d.approximation;
    const std::string     neighbours = WriteNeighbours(a.points, h.scale, "neighbours.txt");
    const Result          run = RunReference(path, neighbours);
    ASSERT_EQ(run.status, 0) << run.errors;
    const Reference r = ParseReference(run.output);

    using Tokens = std::vector<std::string>;
    auto numbers = [](const Tokens & t) {
      std::vector<double> v;
      for (const auto & s : t)
        v.push_back(ToDouble(s));
      return v;
    };
    auto field = [&r](const std::string & name) {
      const auto it = r.fields.find(name);
      EXPECT_NE(it, r.fields.end()) << "the reference decoder printed no '" << name << "'";
      return it == r.fields.end() ? Tokens() : it->second;
    };
    const bool direction = h.direction != std::array<double, 9>{ 1, 0, 0, 0, 1, 0, 0, 0, 1 };
    const bool scaled = h.scale != GridScale{ { 1, 1, 1 } };
    const bool residual = h.residualStep > 0.0;
    const int  deflated = d.bytes[6] & 16;      // the writer's choice; the pairs below check the inflated block
    const int  axisDirection = d.bytes[6] & 64; // the writer's choice; the matrix is checked below
    const int  flags = (direction ? 1 : 0) | axisDirection | (h.metadata.empty() ? 0 : 2) | (scaled ? 4 : 0) |
                      (residual ? 8 : 0) | deflated | (h.residualLevels > 0 ? 32 : 0) | (residual ? 128 : 0);
    const Tokens type = field("pixel_type");
    const Tokens mode = field("mode");
    EXPECT_EQ(field("version"), Tokens{ std::to_string(FileHeader::Version) });
    EXPECT_EQ(type.empty() ? "" : type[0], std::to_string(int(h.pixelType)));
    EXPECT_EQ(field("flags"), Tokens{ std::to_string(flags) });
    EXPECT_EQ(mode.empty() ? "" : mode[0], std::to_string(int(h.mode)));
    EXPECT_EQ(field("size"), (Tokens{ std::to_string(h.size.x), std::to_string(h.size.y), std::to_string(h.size.z) }));
    EXPECT_EQ(numbers(field("spacing")), std::vector<double>(h.spacing.begin(), h.spacing.end()));
    EXPECT_EQ(numbers(field("origin")), std::vector<double>(h.origin.begin(), h.origin.end()));
    EXPECT_EQ(numbers(field("direction")), std::vector<double>(h.direction.begin(), h.direction.end()));
    EXPECT_EQ(numbers(field("scale")),
              (std::vector<double>{ double(h.scale[0]), double(h.scale[1]), double(h.scale[2]) }));
    EXPECT_EQ(numbers(field("quantization_origin")), std::vector<double>{ h.quantizationOrigin });
    EXPECT_EQ(numbers(field("quantization_step")), std::vector<double>{ h.quantizationStep });
    EXPECT_EQ(field("points"), Tokens{ std::to_string(h.numberOfPoints) });
    EXPECT_EQ(field("payload_bytes"), Tokens{ std::to_string(d.payload.size()) });
    if (residual)
    {
      std::vector<uint8_t> compact;
      const int            form = (h.constantSpline ? 1 : 0) | (h.residualStep == 1.0 ? 2 : 0) |
                       (!h.videoLayer && !h.boundedLayer && CompactLayer(h.residualLayer, h.size, compact) ? 4 : 0) |
                       (h.videoLayer ? 8 : 0) | (h.videoLayer && h.videoCodec == VideoCodec::AV1 ? 16 : 0) |
                       (h.boundedLayer ? 32 : 0);
      EXPECT_EQ(field("form"), Tokens{ std::to_string(form) });
      EXPECT_EQ(numbers(field("residual_step")), std::vector<double>{ h.residualStep });
      EXPECT_EQ(field("residual_levels"), Tokens{ std::to_string(h.residualLevels) });
      EXPECT_EQ(field("residual_bytes"), Tokens{ std::to_string(h.residualLayer.size()) });
      const ResidualSamples samples = h.boundedLayer ? DecodeBoundedLayer(h.residualLayer, h.size, path)
                                      : h.videoLayer
                                        ? DecodeVideoLayer(h.videoCodec, h.residualLayer, h.size, path)
                                        : DecodeResidualLayer(h.residualLayer, h.size, path, h.residualLevels);
      std::vector<uint8_t>  le;
      for (int32_t v : samples)
        for (int b = 0; b < 4; ++b)
          le.push_back(uint8_t(uint32_t(v) >> (8 * b)));
      EXPECT_EQ(field("residual_crc"), Tokens{ std::to_string(crc32(0L, le.data(), uInt(le.size()))) });
      if (h.boundedLayer) // the bound the layer states
        EXPECT_EQ(numbers(field("maximum_error")),
                  std::vector<double>{ ReadBoundedLayerHeader(h.residualLayer, h.size, path).maximumError });
      else
        EXPECT_EQ(r.fields.count("maximum_error"), 0u);
    }
    std::vector<std::string> metadata;
    for (const auto & kv : h.metadata)
    {
      if (kv.first == DicomHeaderKey)
      {
        // Bytes: the reference decoder checks the block's structure and prints its mode and counts.
        const DicomHeaderBlock block = SplitDicomHeader(kv.second, path);
        std::size_t            own = 0;
        for (const auto & f : block.files)
          own += f.size();
        metadata.push_back(Json(kv.first) + " " +
                           Json(std::string(block.mode == 0 ? "full" : "essential") + ", " +
                                std::to_string(block.files.size()) + " files, " + std::to_string(block.common.size()) +
                                " bytes common, " + std::to_string(own) + " per file in all"));
      }
      else
        metadata.push_back(Json(kv.first) + " " + Json(kv.second));
    }
    EXPECT_EQ(r.metadata, metadata);

    ASSERT_EQ(r.points.size(), a.points.size());
    for (std::size_t i = 0; i < a.points.size(); ++i)
    {
      const Tokens expected{ std::to_string(a.points[i][0]),
                             std::to_string(a.points[i][1]),
                             std::to_string(a.points[i][2]) };
      ASSERT_EQ(r.points[i].size(), 4u) << "point " << i;
      ASSERT_EQ(Tokens(r.points[i].begin(), r.points[i].begin() + 3), expected) << "point " << i << " of " << path;
      ASSERT_EQ(ToDouble(r.points[i][3]), a.values[i]) << "value of point " << i << " of " << path;
    }

    if (alsoWithoutValues) // positions only: the same lines without the values
    {
      const Result positions = RunReference(path);
      ASSERT_EQ(positions.status, 0) << positions.errors;
      const Reference p = ParseReference(positions.output);
      EXPECT_EQ(p.fields, r.fields);
      ASSERT_EQ(p.points.size(), r.points.size());
      for (std::size_t i = 0; i < p.points.size(); ++i)
        ASSERT_EQ(p.points[i], Tokens(r.points[i].begin(), r.points[i].begin() + 3)) << "point " << i;
    }
  }

  fs::path m_Directory;
};

/** The engine's approximation of the Shepp-Logan phantom with n points, values on k q. */
Approximation
Phantom(const GridSize & grid, Mode mode, std::size_t n, double q0, double q)
{
  const auto               bytes = SheppLoganPhantom(grid);
  const std::vector<float> image(bytes.begin(), bytes.end());
  RefinementParameters     p = ParametersForMode(mode);
  p.quantizationStep = q;
  p.quantizationOrigin = q0;
  p.valueMin = 0.0;
  p.valueMax = 255.0;
  RefinementEngine engine(image.data(), grid, p);
  engine.Approximate(n);
  return engine.GetApproximation();
}

TEST_F(FormatSpecification, PhantomEvenGrid)
{
  FileHeader h;
  h.mode = uint8_t(Mode::Dec);
  h.quantizationStep = 4.0;
  ExpectAgreement(WriteDcv("even.dcv", h, Phantom(GridSize{ 40, 36, 30 }, Mode::Dec, 700, 0.0, 4.0)), true);
}

TEST_F(FormatSpecification, PhantomOddGrid)
{
  FileHeader h;
  h.mode = uint8_t(Mode::Silva);
  h.quantizationStep = 3.0;
  ExpectAgreement(WriteDcv("odd.dcv", h, Phantom(GridSize{ 33, 27, 19 }, Mode::Silva, 600, 0.0, 3.0)));
}

TEST_F(FormatSpecification, DirectionAndMetadata)
{
  FileHeader h;
  h.pixelType = PixelType::Float32;
  h.mode = uint8_t(Mode::Best);
  h.spacing = { 0.7, 1.3, 2.25 };
  h.origin = { -12.5, 3.0, 1e-3 };
  h.direction = { 0.6, -0.8, 0, 0.8, 0.6, 0, 0, 0, -1 };
  h.quantizationOrigin = -3.5;
  h.quantizationStep = 0.5;
  h.metadata = { { "PatientID", "anon-7" },
                 { "Note", "é ü 中文, \"quoted\" \\ and\ta tab" },
                 { "", "an empty key" },
                 { "empty value", "" } };
  ExpectAgreement(WriteDcv("oriented.dcv", h, Phantom(GridSize{ 24, 30, 21 }, Mode::Best, 300, -3.5, 0.5)));
  // A DICOM header block (bytes: a NUL, a quote, a byte that is not UTF-8) among the pairs.
  DicomHeaderBlock block;
  block.common = std::string("\x08\x00\x60\x00"
                             "CS\x02\x00"
                             "CT",
                             10);
  block.files = { std::string("\x10\x00\x10\x00"
                              "PN\x04\x00"
                              "\xe4\"^ ",
                              12),
                  "" };
  h.metadata.emplace_back(DicomHeaderKey, JoinDicomHeader(block));
  ExpectAgreement(WriteDcv("dicom.dcv", h, Phantom(GridSize{ 24, 30, 21 }, Mode::Best, 300, -3.5, 0.5)));
  h.metadata.pop_back();
  // Flipped and swapped axes (LPS against RAS): the one-byte direction code.
  h.direction = { 0, -1, 0, -1, 0, 0, 0, 0, 1 };
  ExpectAgreement(WriteDcv("flipped.dcv", h, Phantom(GridSize{ 24, 30, 21 }, Mode::Best, 300, -3.5, 0.5)));
}

TEST_F(FormatSpecification, ScaledDelaunaySpace)
{
  // Thick slices: the tetrahedralization of (x, y, 5 z); the value prediction follows its neighbours.
  FileHeader h;
  h.spacing = { 0.5, 0.5, 2.5 };
  h.quantizationStep = 4.0;
  Approximation a = Phantom(GridSize{ 30, 28, 12 }, Mode::Dec, 400, 0.0, 4.0);
  a.scale = { { 1, 1, 5 } };
  h.scale = a.scale;
  ExpectAgreement(WriteDcv("scaled.dcv", h, a));
}

TEST_F(FormatSpecification, OnlyTheCorners)
{
  // A large, flat grid (every split is of a box with 8 points or fewer), then a grid that is all corners.
  for (const GridSize grid : { GridSize{ 300, 2, 65535 }, GridSize{ 2, 2, 2 } })
  {
    Approximation a;
    a.grid = grid;
    a.points = test::Corners(grid);
    for (std::size_t i = 0; i < a.points.size(); ++i)
      a.values.push_back(10.0 + 2.0 * double((i * 37) % 11) - 7.0 * double(i % 2));
    FileHeader h;
    h.pixelType = PixelType::Int16;
    h.quantizationOrigin = 10.0;
    h.quantizationStep = 1.0;
    ExpectAgreement(WriteDcv("corners.dcv", h, a));
  }
}

TEST_F(FormatSpecification, DenseRandomPointsWithLargeValues)
{
  // More points than half the voxels (the complement coding), values up to the encoder's 2^30 limit.
  const GridSize grid{ 6, 5, 4 };
  Approximation  a;
  a.grid = grid;
  a.points = test::RandomPoints(grid, 92, 7);
  std::mt19937                           random(11);
  std::uniform_int_distribution<int64_t> k(-(int64_t(1) << 30) + 1, (int64_t(1) << 30) - 1);
  for (std::size_t i = 0; i < a.points.size(); ++i)
    a.values.push_back(0.5 + 0.25 * double(i % 3 == 0 ? k(random) : k(random) % 100));
  FileHeader h;
  h.pixelType = PixelType::Float64;
  h.quantizationOrigin = 0.5;
  h.quantizationStep = 0.25;
  ExpectAgreement(WriteDcv("dense.dcv", h, a));
}

TEST_F(FormatSpecification, RealVolumeThroughTheCommandLine)
{
  DCV_REQUIRE_DATA("headsq-ct.nrrd");
  const std::string file = Path("headsq.dcv");
  const std::string command = Quote(DCV_EXECUTABLE) + " compress -q -m silva -n 3000 " +
                              Quote(test::DataFile("headsq-ct.nrrd")) + " " + Quote(file) + " 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
  ExpectAgreement(file);
}

TEST_F(FormatSpecification, ResidualLayer)
{
  // Slices with little in common (thick slices): the encoder keeps a residual layer, with both wavelets.
  const GridSize     grid{ 40, 36, 6 };
  std::vector<float> voxels(grid.NumberOfVoxels());
  for (int32_t z = 0; z < grid.z; ++z)
    for (int32_t y = 0; y < grid.y; ++y)
      for (int32_t x = 0; x < grid.x; ++x)
        voxels[grid.Offset(x, y, z)] = float(std::lround(900.0 * std::sin(0.15 * x + 1.7 * z) * std::cos(0.1 * y + z)));
  EncoderInput input;
  input.voxels = voxels.data();
  input.header.pixelType = PixelType::Int16;
  input.header.size = grid;
  input.header.spacing = { 0.5, 0.5, 5.0 };
  std::vector<float> smoothed = voxels;
  input.smoothed = smoothed.data();
  for (double bpv : { 1.0, 4.0 })
  {
    EncoderOptions options;
    options.bitsPerVoxel = bpv;
    options.videoLayer = false;  // the JPEG 2000 layers (the video layer: the next test)
    for (int i = 0; i < 12; ++i) // as DICOM attributes are: deflated (flag bit 4)
      options.metadata.emplace_back("DICOM Attribute" + std::to_string(i), "1.3.46.670589.33.1." + std::to_string(i));
    const EncoderResult r = Encode(input, options);
    ASSERT_GT(r.header.residualStep, 0.0) << bpv;
    ASSERT_EQ(r.bytes[6] & 16, 16) << "the metadata is not deflated";
    const std::string path = Path("residual.dcv");
    WriteFileAtomically(path, r.bytes);
    ExpectAgreement(path);
    // Both arrangements of the slices, whichever the encoder chose.
    FileHeader           h;
    std::vector<uint8_t> payload;
    ParseFile(r.bytes, path, h, payload);
    const auto                 decoded = DecodeResidualLayer(h.residualLayer, h.size, path, h.residualLevels);
    const std::vector<int32_t> samples(decoded.begin(), decoded.end());
    const std::size_t          bytes = h.residualLayer.size();
    for (Arrangement a : { Arrangement::Mosaic, Arrangement::Components })
    {
      // Without and with the inter-slice wavelet: the reference's inverse must give the library's samples.
      for (int32_t levels : { 0, 2, InterSliceLevels(h.size.z) })
      {
        h.residualLevels = levels;
        h.residualLayer = EncodeResidualLayer(samples, h.size, bytes, Wavelet::Irreversible97, a, levels);
        ASSERT_FALSE(h.residualLayer.empty());
        WriteFileAtomically(path, SerializeFile(h, payload));
        ExpectAgreement(path);
      }
    }
  }
}

// The video layer: the reference decoder (libde265's dec265) gives the library's samples, at 8, 10 and 12
// bits, on slices that are not whole coding tree units, and in the file the encoder chose.
TEST_F(FormatSpecification, VideoLayer)
{
  const GridSize grid{ 40, 36, 6 };
  for (const VideoCodec codec : { VideoCodec::HEVC, VideoCodec::AV1 })
    for (int32_t depth : { 8, 10, 12 })
    {
      std::vector<uint16_t> samples(grid.NumberOfVoxels());
      for (int32_t z = 0; z < grid.z; ++z)
        for (int32_t y = 0; y < grid.y; ++y)
          for (int32_t x = 0; x < grid.x; ++x)
            samples[grid.Offset(x, y, z)] = uint16_t(
              std::lround(((1 << depth) - 1) * (0.5 + 0.45 * std::sin(0.15 * x + 1.7 * z) * std::cos(0.1 * y))));
      FileHeader h;
      h.pixelType = PixelType::Int16;
      h.size = grid;
      h.constantSpline = true;
      h.videoLayer = true;
      h.videoCodec = codec;
      h.quantizationOrigin = -1024.0;
      h.residualStep = depth == 12 ? 1.0 : 3.0;
      h.numberOfPoints = 8;
      h.residualLayer = EncodeVideoLayer(codec, samples, grid, depth, 20.0);
      const std::string path = Path("video.dcv");
      WriteFileAtomically(path, SerializeFile(h, {}));
      ExpectAgreement(path);
    }
  // A head in air on thick slices (as test/dcvVideoLayerTest.cxx): the encoder keeps the video layer.
  const GridSize     head{ 96, 96, 12 };
  std::vector<float> voxels(head.NumberOfVoxels());
  for (int32_t z = 0; z < head.z; ++z)
    for (int32_t y = 0; y < head.y; ++y)
      for (int32_t x = 0; x < head.x; ++x)
      {
        const bool inside = std::hypot(x - 48.0, y - 48.0) < 38.4;
        voxels[head.Offset(x, y, z)] = float(
          std::lround(-1000.0 + (inside ? 1040.0 + 60.0 * std::sin(0.3 * x + 0.2 * z) * std::cos(0.25 * y) : 0.0)));
      }
  EncoderInput input;
  input.voxels = voxels.data();
  input.header.pixelType = PixelType::Int16;
  input.header.size = head;
  input.header.spacing = { 0.5, 0.5, 5.0 };
  EncoderOptions options;
  options.bitsPerVoxel = 0.125;
  const EncoderResult r = Encode(input, options);
  ASSERT_TRUE(r.header.videoLayer);
  const std::string path = Path("encoded-video.dcv");
  WriteFileAtomically(path, r.bytes);
  ExpectAgreement(path);
}

// The bounded-error layer (form bit 5): the reference decoder gives the library's samples and the bound the
// layer states, lossless and near-lossless, on integers and floats, and refuses what the library refuses.
TEST_F(FormatSpecification, BoundedErrorLayer)
{
  // Volumes of 10,000 to 12,000 voxels: the reference decoder takes a fraction of a second on each.
  auto encode = [this](auto image, double bound, const std::string & name) {
    EncoderOptions options;
    options.maximumError = bound;
    const EncoderResult r = itk::DCVEncode(image.GetPointer(), options);
    EXPECT_TRUE(r.header.boundedLayer) << name;
    EXPECT_TRUE(r.header.constantSpline) << name;
    const std::string path = Path(name);
    WriteFileAtomically(path, r.bytes);
    return path;
  };
  // A phantom (uint8), lossless (h = 1: form bit 1) on an oblique grid (the one-byte direction code), then
  // within 2 (h = 5).
  const GridSize phantom{ 28, 22, 18 };
  ExpectAgreement(encode(test::PhantomImage(phantom, true), 0.0, "phantom-lossless.dcv"));
  ExpectAgreement(encode(test::PhantomImage(phantom), 2.0, "phantom-2.dcv"));

  // int16 noise over a wide range (large residuals, folded), lossless and within 3.
  using Int16Image = itk::Image<int16_t, 3>;
  auto noise = Int16Image::New();
  noise->SetRegions(Int16Image::SizeType{ { 26, 22, 18 } });
  noise->Allocate();
  std::mt19937                       random(5);
  std::uniform_int_distribution<int> wide(-30000, 32000);
  for (std::size_t i = 0; i < noise->GetPixelContainer()->Size(); ++i)
    noise->GetBufferPointer()[i] = int16_t(i % 7 == 0 ? wide(random) : wide(random) / 64);
  ExpectAgreement(encode(noise, 0.0, "int16-lossless.dcv"));
  ExpectAgreement(encode(noise, 3.0, "int16-3.dcv"));

  // float32: a smooth field with noise, within 0.5 (h just under 1, stored).
  using FloatImage = itk::Image<float, 3>;
  auto field = FloatImage::New();
  field->SetRegions(FloatImage::SizeType{ { 28, 21, 18 } });
  field->Allocate();
  std::uniform_real_distribution<double> jitter(-2.0, 2.0);
  float *                                f = field->GetBufferPointer();
  for (int32_t z = 0; z < 18; ++z)
    for (int32_t y = 0; y < 21; ++y)
      for (int32_t x = 0; x < 28; ++x)
        *f++ = float(300.0 * std::sin(0.2 * x + 0.3 * z) * std::cos(0.15 * y) - 17.25 + jitter(random));
  const std::string floats = encode(field, 0.5, "float-0.5.dcv");
  ExpectAgreement(floats);

  // Damaged: the library and the reference decoder refuse the same files, by the same rule.
  const Decoded d = DecodeWithTheLibrary(floats);
  auto expectRefused = [&](const std::vector<uint8_t> & bytes, const std::string & name, const std::string & phrase) {
    const std::string path = Path(name);
    WriteFileAtomically(path, bytes);
    EXPECT_THROW(Decode(ReadCompressedFile(path)), FormatError) << name;
    const Result r = RunReference(path);
    EXPECT_EQ(r.status, 1) << name << ": " << r.errors;
    EXPECT_NE(r.errors.find(path + ": "), std::string::npos) << r.errors;
    EXPECT_NE(r.errors.find(phrase), std::string::npos) << "expected '" << phrase << "' in: " << r.errors;
    EXPECT_TRUE(r.output.empty()) << r.output;
  };
  FileHeader h = d.header;
  h.residualLayer.push_back(0);
  expectRefused(SerializeFile(h, {}), "trailing.dcv", "1 bytes follow the bounded-error layer");
  h = d.header;
  h.residualLayer.erase(h.residualLayer.begin() + 24); // the slab's length no longer fits
  expectRefused(SerializeFile(h, {}), "cut.dcv", "the bounded-error layer ends inside slab 1 of 1");
  h = d.header;
  h.residualLayer[16] ^= 1; // S, the slices of a slab
  expectRefused(SerializeFile(h, {}), "slab.dcv", "damaged bounded-error layer (slabs of");
  h = d.header;
  const double negative = -1.0;
  std::memcpy(h.residualLayer.data(), &negative, 8); // E
  expectRefused(SerializeFile(h, {}), "bound.dcv", "its bound is not a finite non-negative number");
  // The form byte with form bit 2 (compact) too, its CRC-32 made again: a rule of the container.
  std::vector<uint8_t> bytes = d.bytes;
  const uint8_t        flags = bytes[6];
  const std::size_t    form = 62 + ((flags & 1) ? ((flags & 64) ? 1 : 72) : 0) + ((flags & 4) ? 3 : 0);
  ASSERT_EQ(bytes[form] & 32, 32);
  bytes[form] |= 4;
  const uint32_t crc = uint32_t(crc32(0L, bytes.data(), uInt(bytes.size() - 4)));
  for (int b = 0; b < 4; ++b)
    bytes[bytes.size() - 4 + b] = uint8_t(crc >> (8 * b));
  expectRefused(bytes, "compact.dcv", "bounded-error layer (form bit 5)");
}

TEST_F(FormatSpecification, DamagedFilesAreRefused)
{
  FileHeader h;
  h.quantizationStep = 4.0;
  const std::string good = WriteDcv("good.dcv", h, Phantom(GridSize{ 20, 18, 16 }, Mode::Silva, 200, 0.0, 4.0));
  const Decoded     d = DecodeWithTheLibrary(good);
  const std::string neighbours = WriteNeighbours(d.approximation.points, d.header.scale, "neighbours.txt");
  const std::vector<uint8_t> & bytes = d.bytes;
  const std::vector<uint8_t> & payload = d.payload;

  auto write = [this](const std::string & name, const std::vector<uint8_t> & content) {
    std::ofstream(Path(name), std::ios::binary)
      .write(reinterpret_cast<const char *>(content.data()), std::streamsize(content.size()));
    return Path(name);
  };
  auto expectRefused = [&](const std::string & file, const std::string & phrase, bool withNeighbours) {
    const Result r = RunReference(file, withNeighbours ? neighbours : "");
    EXPECT_EQ(r.status, 1) << file << ": " << r.errors;
    EXPECT_NE(r.errors.find(file + ": "), std::string::npos) << r.errors;
    EXPECT_NE(r.errors.find(phrase), std::string::npos) << "expected '" << phrase << "' in: " << r.errors;
    EXPECT_TRUE(r.output.empty()) << r.output;
  };

  // Truncated or altered anywhere: the CRC-32 catches it (the library refuses it too).
  const std::string truncated = write("truncated.dcv", std::vector<uint8_t>(bytes.begin(), bytes.end() - 10));
  EXPECT_THROW(DecodeWithTheLibrary(truncated), FormatError);
  expectRefused(truncated, "CRC-32 mismatch", false);
  std::vector<uint8_t> altered = bytes;
  altered[bytes.size() / 2] ^= 0x10;
  expectRefused(write("altered.dcv", altered), "CRC-32 mismatch", false);
  expectRefused(write("text.dcv", { 'D', 'C', 'V', '1', '\n' }), "not a .dcv file", false);

  // A sound container around a cut payload: the stream overruns, in the positions or in the values.
  const std::string shortPositions =
    write("short-positions.dcv", SerializeFile(d.header, std::vector<uint8_t>(payload.begin(), payload.begin() + 6)));
  EXPECT_THROW(DecodeWithTheLibrary(shortPositions), FormatError);
  expectRefused(shortPositions, "point positions", false); // a missing corner or the overrun, checked in this order
  const std::string shortValues =
    write("short-values.dcv", SerializeFile(d.header, std::vector<uint8_t>(payload.begin(), payload.end() - 1)));
  EXPECT_THROW(DecodeWithTheLibrary(shortValues), FormatError);
  expectRefused(shortValues, "ends inside the values", true);
}

} // namespace
