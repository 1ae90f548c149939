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
// Resource limits of the decoder: what a header implies is checked before anything is
// allocated from it, and a payload that runs out stops the decoding at once. The reproducers of the issue
// are forged here with the project's own writer (SerializeFile computes the CRC-32).
#include "dcvArithmeticCoder.h"
#include "dcvCodec.h"
#include "dcvFileFormat.h"
#include "dcvPositionCoder.h"
#include "dcvTestUtilities.h"
#include "itkDCVImageIO.h"
#include "itkDCVMeshIO.h"

#include <filesystem>
#include <fstream>
#include <random>
#include <unistd.h>

namespace
{
using namespace dcv;
namespace fs = std::filesystem;

/** A header as a forger writes it: any grid, any point count, for `length` bytes of random payload. */
std::vector<uint8_t>
ForgedFile(const GridSize & grid, uint32_t points, std::size_t length, PixelType type = PixelType::UInt8)
{
  FileHeader h;
  h.pixelType = type;
  h.size = grid;
  h.numberOfPoints = points;
  std::vector<uint8_t> payload(length);
  std::mt19937         random(7);
  for (auto & b : payload)
    b = uint8_t(random());
  return SerializeFile(h, payload);
}

std::string
ParseError(const std::vector<uint8_t> & bytes, const std::string & name = "'forged.dcv'")
{
  CompressedFile file;
  try
  {
    ParseFile(bytes, name, file.header, file.payload);
  }
  catch (const FormatError & e)
  {
    return e.what();
  }
  return "";
}

CompressedFile
Parsed(const std::vector<uint8_t> & bytes, const std::string & name = "'forged.dcv'")
{
  CompressedFile file;
  file.name = name;
  file.size = bytes.size();
  ParseFile(bytes, name, file.header, file.payload);
  return file;
}

std::string
DecodeError(const CompressedFile & file, const DecodeLimits & limits, DecodeOutput output = DecodeOutput::Volume)
{
  try
  {
    if (output == DecodeOutput::Volume)
      Decode(file, limits);
    else
      DecodeMesh(file, limits);
  }
  catch (const FormatError & e)
  {
    return e.what();
  }
  return "";
}

/** A small real file: corners and random points of a 16^3 grid, values on the lattice 10 + 2 k. */
std::vector<uint8_t>
SmallRealFile()
{
  const GridSize grid{ 16, 16, 16 };
  Approximation  a;
  a.grid = grid;
  a.points = test::RandomPoints(grid, 60, 3);
  for (std::size_t i = 0; i < a.points.size(); ++i)
    a.values.push_back(10.0 + 2.0 * double(i % 7));
  FileHeader h;
  h.size = grid;
  h.quantizationOrigin = 10.0;
  h.quantizationStep = 2.0;
  h.numberOfPoints = uint32_t(a.points.size());
  return SerializeFile(h, EncodePayload(a, 10.0, 2.0));
}

class ResourceLimits : public ::testing::Test
{
protected:
  std::string
  Write(const std::vector<uint8_t> & bytes, const std::string & name) const
  {
    const std::string path = m_Directory / name;
    std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char *>(bytes.data()), std::streamsize(bytes.size()));
    return path;
  }
  test::TemporaryDirectory m_Directory;
};

// The 94-byte reproducer: a 65535^3 grid and 2^32 - 1 points in 4 payload bytes (it grew to std::bad_alloc).
TEST_F(ResourceLimits, TheMostPointsOfTheLargestGridInFourBytesAreRefusedByTheParser)
{
  const auto bytes = ForgedFile({ 65535, 65535, 65535 }, 0xFFFFFFFFu, 4);
  EXPECT_EQ(bytes.size(), 94u);
  const std::string error = ParseError(bytes);
  EXPECT_EQ(error.rfind("'forged.dcv': damaged (4294967295 points cannot be coded in 4 payload bytes", 0), 0u) << error;
}

// n = 10^8 (106 s and 1.6 GB before the refusal): with too short a payload refused by the parser, and with
// a payload long enough to hold them refused by the memory limit before a point is decoded.
TEST_F(ResourceLimits, AHundredMillionPointsAreRefusedBeforeDecoding)
{
  const GridSize grid{ 65535, 65535, 65535 };
  EXPECT_NE(ParseError(ForgedFile(grid, 100000000u, 100)).find("points cannot be coded in 100 payload bytes"),
            std::string::npos);
  const std::size_t    length = 100000000u / MaximumPointsPerPayloadByte + 1;
  const CompressedFile file = Parsed(ForgedFile(grid, 100000000u, length));
  const std::string    error = DecodeError(file, DecodeLimits{ uint64_t(1) << 30 }, DecodeOutput::Mesh);
  EXPECT_EQ(error.rfind("'forged.dcv': decoding would need about 95.4 GiB (100000000 points), more than the "
                        "memory limit of 1.0 GiB",
                        0),
            0u)
    << error;
  // The volume (2^48 voxels) is counted too.
  EXPECT_NE(DecodeError(file, DecodeLimits{ uint64_t(1) << 30 }).find("65535x65535x65535 voxels of uint8"),
            std::string::npos);
  // The default limit is the machine's: half of its memory, under the 95 GiB unless it has 190 GiB.
  EXPECT_GT(DefaultMaximumMemory(), uint64_t(256) << 20);
}

// A 100^3 grid with 10^6 points (35 s and 944 MB): its few payload bytes cannot hold the values.
TEST_F(ResourceLimits, AMillionPointsInAFewBytesAreRefusedByTheParser)
{
  const std::string error = ParseError(ForgedFile({ 100, 100, 100 }, 1000000u, 20));
  EXPECT_EQ(error, "'forged.dcv': damaged (1000000 points cannot be coded in 20 payload bytes, at most 234560)");
}

// The bound of the parser is safe: the cheapest value stream there is (every value equal to its
// prediction, as for a full grid of one value, whose positions cost nothing) stays within it.
TEST_F(ResourceLimits, TheCheapestValueStreamFitsTheBoundOfThePointCount)
{
  for (const uint32_t n : { 8u, 1000u, 100000u, 4000000u })
  {
    std::vector<uint8_t> bytes;
    ArithmeticEncoder    encoder(bytes);
    SIntModel            residual[4];
    for (uint32_t i = 0; i < n; ++i)
      residual[i % 4 == 0 ? 0 : 3].Encode(encoder, 0);
    encoder.Finish();
    EXPECT_LE(n, MaximumPointsPerPayloadByte * bytes.size()) << n << " values in " << bytes.size() << " bytes";
    if (n == 4000000u)
    {
      // ... and it is nearly tight (within 5%).
      EXPECT_GT(1.05 * double(n), double(MaximumPointsPerPayloadByte * bytes.size())) << bytes.size();
    }
  }
  // A real full grid of one value round-trips (13824 points in a few bytes).
  const GridSize grid{ 24, 24, 24 };
  Approximation  a;
  a.grid = grid;
  for (int32_t z = 0; z < grid.z; ++z)
    for (int32_t y = 0; y < grid.y; ++y)
      for (int32_t x = 0; x < grid.x; ++x)
        a.points.push_back({ x, y, z });
  a.values.assign(a.points.size(), 5.0);
  FileHeader h;
  h.size = grid;
  h.numberOfPoints = uint32_t(a.points.size());
  const auto file = Parsed(SerializeFile(h, EncodePayload(a, 0.0, 1.0)));
  EXPECT_LT(file.payload.size(), 16u);
  EXPECT_EQ(Decode(file).values, a.values);
}

// Positions stop as soon as the stream is overrun, not after decoding all the points from zeros.
TEST_F(ResourceLimits, PositionsStopWhereThePayloadEnds)
{
  const GridSize             grid{ 64, 64, 64 };
  const std::vector<uint8_t> two{ 0x12, 0x34 };
  ArithmeticDecoder          decoder(two.data(), two.size());
  const auto                 points = DecodePositions(decoder, grid, 20000);
  EXPECT_TRUE(decoder.Overrun());
  EXPECT_TRUE(points.empty()) << points.size();
  const std::string error = DecodeError(Parsed(ForgedFile(grid, 20000, 2)), DecodeLimits{});
  EXPECT_EQ(error, "'forged.dcv': the payload ends inside the point positions");
  // A stream cut inside the values stops there too (the real file, its payload shortened).
  CompressedFile file = Parsed(SmallRealFile());
  file.payload.resize(file.payload.size() - 3);
  const std::string cut = DecodeError(file, DecodeLimits{});
  EXPECT_NE(cut.find("the payload ends inside the"), std::string::npos) << cut;
}

// A tiny limit refuses a real file before decoding, in the library, the IOs and the command line.
TEST_F(ResourceLimits, ATinyLimitRefusesARealFileEverywhere)
{
  const std::vector<uint8_t> bytes = SmallRealFile();
  const CompressedFile       file = Parsed(bytes, "'small.dcv'");
  EXPECT_EQ(DecodingMemory(file.header, DecodeOutput::Mesh), 68u * 1024u);
  EXPECT_EQ(DecodingMemory(file.header, DecodeOutput::Volume), 68u * 1024u + 4096u);
  EXPECT_EQ(DecodeError(file, DecodeLimits{ 1000 }),
            "'small.dcv': decoding would need about 72.0 KiB (68 points, 16x16x16 voxels of uint8), more than "
            "the memory limit of 1000 bytes (--max-memory, MaximumMemory)");
  EXPECT_EQ(DecodeError(file, DecodeLimits{ 68u * 1024u }, DecodeOutput::Mesh), "");
  EXPECT_NE(DecodeError(file, DecodeLimits{ 68u * 1024u }), "");
  EXPECT_EQ(DecodeError(file, DecodeLimits{ 0 }), ""); // 0: no limit
  EXPECT_EQ(DecodeError(file, DecodeLimits{}), "");

  const std::string path = Write(bytes, "small.dcv");
  auto              imageIO = itk::DCVImageIO::New();
  EXPECT_EQ(imageIO->GetMaximumMemory(), DefaultMaximumMemory());
  imageIO->SetMaximumMemory(1000);
  imageIO->SetFileName(path);
  try
  {
    imageIO->ReadImageInformation();
    ADD_FAILURE() << "DCVImageIO read past its limit";
  }
  catch (const itk::ExceptionObject & e)
  {
    EXPECT_NE(std::string(e.GetDescription()).find("'" + path + "': decoding would need about 72.0 KiB"),
              std::string::npos)
      << e.GetDescription();
  }
  std::ostringstream printed;
  imageIO->Print(printed);
  EXPECT_NE(printed.str().find("MaximumMemory: 1000"), std::string::npos);

  auto meshIO = itk::DCVMeshIO::New();
  meshIO->SetMaximumMemory(1000);
  meshIO->SetFileName(path.c_str());
  try
  {
    meshIO->ReadMeshInformation();
    ADD_FAILURE() << "DCVMeshIO read past its limit";
  }
  catch (const itk::ExceptionObject & e)
  {
    EXPECT_NE(std::string(e.GetDescription()).find("'" + path + "': decoding would need about 68.0 KiB (68 points)"),
              std::string::npos)
      << e.GetDescription();
  }

  const std::string output = m_Directory / "out.nrrd";
  test::Result      r = test::RunDcv("decompress " + path + " " + output + " --max-memory 1K");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("'" + path + "': decoding would need about 72.0 KiB"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("memory limit of 1.0 KiB"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(output));
  r = test::RunDcv("mesh " + path + " " + m_Directory / "out.vtu" + " --max-memory 0.0005M");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("memory limit of 524 bytes"), std::string::npos) << r.output;
  r = test::RunDcv("decompress " + path + " " + output + " --max-memory lots");
  EXPECT_EQ(r.status, 2); // a usage error
  EXPECT_NE(r.output.find("--max-memory"), std::string::npos) << r.output;
  r = test::RunDcv("decompress " + path + " " + output + " --max-memory 1G --quiet");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(fs::exists(output));
  r = test::RunDcv("info " + path);
  EXPECT_NE(r.output.find("memory to decode: 72.0 KiB (mesh alone 68.0 KiB)"), std::string::npos) << r.output;
}

// The fuzzers' seeds (fuzz/corpus, scripts/fuzz.sh) are real files: each decodes, and each is refused under a
// limit below what it needs. Inputs the fuzzers find that crash, hang or exhaust memory join this corpus
// and this test (none so far: 515,985 runs in 100 minutes over the decode and io targets, README "Fuzzing
// the decoder").
TEST(FuzzCorpus, EverySeedDecodesWithinItsLimitAndIsRefusedBelowIt)
{
  std::size_t seeds = 0;
  for (const auto & entry : fs::directory_iterator(DCV_FUZZ_CORPUS))
  {
    const CompressedFile file = ReadCompressedFile(entry.path().string());
    const uint64_t       needed = DecodingMemory(file.header, DecodeOutput::Volume);
    const Approximation  a = Decode(file, DecodeLimits{ needed });
    std::vector<float>   volume(a.grid.NumberOfVoxels());
    Rasterize(a, volume.data(), 1);
    EXPECT_NE(DecodeError(file, DecodeLimits{ needed - 1 }).find(file.name + ": decoding would need"),
              std::string::npos);
    ++seeds;
  }
  EXPECT_GE(seeds, 5u);
}

} // namespace
