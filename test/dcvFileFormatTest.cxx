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
// The .dcv container: round trips, and a clear error for every kind of damage.
#include "dcvCodec.h"
#include "dcvFileFormat.h"
#include "dcvPhantom.h"
#include "dcvRateControl.h"
#include "dcvRefinementEngine.h"
#include "dcvTestUtilities.h"

#include <fstream>
#include <unistd.h>
#include <zlib.h>

namespace
{
using namespace dcv;

FileHeader
SampleHeader(bool withDirectionAndMetadata)
{
  FileHeader h;
  h.pixelType = PixelType::Int16;
  h.mode = 3;
  h.size = GridSize{ 64, 64, 93 };
  h.spacing = { 3.2, 3.2, 1.5 };
  h.origin = { -10.5, 20.25, 7.0 };
  h.quantizationOrigin = -1024.0;
  h.quantizationStep = 4.0;
  h.numberOfPoints = 634;
  if (withDirectionAndMetadata)
  {
    h.direction = { 0, 1, 0, -1, 0, 0, 0, 0, 1 };
    h.metadata = { { "PatientID", "anon-7" }, { "Modality", "CT" }, { "Note", "é ü 中文" } };
    h.scale = { { 2, 2, 11 } };
  }
  return h;
}

std::string
ParseError(const std::vector<uint8_t> & bytes)
{
  FileHeader           h;
  std::vector<uint8_t> payload;
  try
  {
    ParseFile(bytes, "x.dcv", h, payload);
  }
  catch (const FormatError & e)
  {
    return e.what();
  }
  return "";
}

TEST(FileFormat, RoundTrip)
{
  for (bool full : { false, true })
  {
    const FileHeader           in = SampleHeader(full);
    const std::vector<uint8_t> payload{ 1, 2, 3, 250, 0, 7 };
    const auto                 bytes = SerializeFile(in, payload);
    FileHeader                 out;
    std::vector<uint8_t>       decoded;
    ParseFile(bytes, "x.dcv", out, decoded);
    EXPECT_EQ(decoded, payload);
    EXPECT_EQ(out.pixelType, in.pixelType);
    EXPECT_EQ(out.mode, in.mode);
    EXPECT_EQ(out.size.x, 64);
    EXPECT_EQ(out.size.z, 93);
    EXPECT_EQ(out.spacing, in.spacing);
    EXPECT_EQ(out.origin, in.origin);
    EXPECT_EQ(out.direction, in.direction);
    EXPECT_EQ(out.scale, in.scale);
    EXPECT_EQ(out.quantizationOrigin, in.quantizationOrigin);
    EXPECT_EQ(out.quantizationStep, in.quantizationStep);
    EXPECT_EQ(out.numberOfPoints, in.numberOfPoints);
    EXPECT_EQ(out.metadata, in.metadata);
  }
}

TEST(FileFormat, HeaderOverheadIsUnder100Bytes)
{
  const auto bytes = SerializeFile(SampleHeader(false), {});
  EXPECT_LT(bytes.size(), 100u); // header and checksum around an empty payload
}

TEST(FileFormat, WrongMagicAndUnknownVersion)
{
  auto bytes = SerializeFile(SampleHeader(false), { 9, 9 });
  auto wrong = bytes;
  wrong[1] = 'X';
  EXPECT_NE(ParseError(wrong).find("not a .dcv file"), std::string::npos);
  auto future = bytes;
  future[4] = 2;
  EXPECT_NE(ParseError(future).find("version 2 is not supported"), std::string::npos);
  EXPECT_NE(ParseError({}).find("not a .dcv file"), std::string::npos);
}

TEST(FileFormat, TruncationAtAnyByteIsDetected)
{
  const auto bytes = SerializeFile(SampleHeader(true), std::vector<uint8_t>(50, 0x5a));
  for (std::size_t n = 0; n < bytes.size(); ++n)
  {
    const std::string error = ParseError(std::vector<uint8_t>(bytes.begin(), bytes.begin() + std::ptrdiff_t(n)));
    ASSERT_FALSE(error.empty()) << "truncated to " << n << " bytes was accepted";
    ASSERT_EQ(error.rfind("x.dcv: ", 0), 0u) << error;
  }
}

TEST(FileFormat, AFlippedBitAnywhereIsDetected)
{
  const auto bytes = SerializeFile(SampleHeader(true), std::vector<uint8_t>(40, 0x33));
  for (std::size_t i = 0; i < bytes.size(); ++i)
  {
    for (int bit = 0; bit < 8; ++bit)
    {
      auto damaged = bytes;
      damaged[i] ^= uint8_t(1u << bit);
      ASSERT_FALSE(ParseError(damaged).empty()) << "byte " << i << " bit " << bit;
    }
  }
}

/** A file with a consistent checksum but absurd numbers: what a malicious or buggy writer makes. */
std::vector<uint8_t>
Reseal(std::vector<uint8_t> bytes)
{
  bytes.resize(bytes.size() - 4);
  FileHeader           h;
  std::vector<uint8_t> unused;
  const uint32_t       crc = uint32_t(::crc32(::crc32(0L, Z_NULL, 0), bytes.data(), uInt(bytes.size())));
  for (int i = 0; i < 4; ++i)
    bytes.push_back(uint8_t(crc >> (8 * i)));
  return bytes;
}

TEST(FileFormat, AbsurdNumbersAreRefusedBeforeAllocating)
{
  const auto bytes = SerializeFile(SampleHeader(false), { 1, 2, 3 });
  auto       tooManyPoints = bytes;
  // numberOfPoints sits 8 bytes before the payload (after it: payload length).
  const std::size_t pointsAt = bytes.size() - 4 - 3 - 8;
  tooManyPoints.at(pointsAt + 3) = 0x7f;
  EXPECT_NE(ParseError(Reseal(tooManyPoints)).find("absurd point count"), std::string::npos);
  auto hugePayload = bytes;
  hugePayload.at(pointsAt + 4 + 3) = 0x7f;
  EXPECT_NE(ParseError(Reseal(hugePayload)).find("truncated (the payload is"), std::string::npos);
  auto flat = bytes;
  flat[8] = 1; // size x = 1
  flat[9] = 0;
  EXPECT_NE(ParseError(Reseal(flat)).find("absurd volume size"), std::string::npos);
  auto type = bytes;
  type[5] = 99;
  EXPECT_NE(ParseError(Reseal(type)).find("unknown pixel type"), std::string::npos);
}

TEST(FileFormat, AtomicWriteReplacesOnlyAtTheEnd)
{
  namespace fs = std::filesystem;
  const fs::path directory = fs::temp_directory_path() / ("dcv-format-" + std::to_string(::getpid()));
  fs::create_directories(directory);
  const std::string path = (directory / "a.dcv").string();
  const auto        bytes = SerializeFile(SampleHeader(false), { 4, 5 });
  WriteFileAtomically(path, bytes);
  EXPECT_EQ(ReadWholeFile(path), bytes);
  EXPECT_EQ(std::distance(fs::directory_iterator(directory), fs::directory_iterator()), 1); // no temporary left
  EXPECT_THROW(WriteFileAtomically((directory / "missing" / "b.dcv").string(), bytes), FormatError);
  EXPECT_THROW(ReadWholeFile((directory / "none.dcv").string()), FormatError);
  fs::remove_all(directory);
}

TEST(Codec, PayloadDecodesToTheEngineOutputBitForBit)
{
  const GridSize           grid{ 40, 36, 30 };
  const auto               bytes = SheppLoganPhantom(grid);
  const std::vector<float> image(bytes.begin(), bytes.end());
  RefinementParameters     p = ParametersForMode(Mode::Dec);
  p.quantizationStep = 4.0;
  p.quantizationOrigin = 0.0;
  p.valueMin = 0.0;
  p.valueMax = 255.0;
  RefinementEngine engine(image.data(), grid, p);
  engine.Approximate(700);
  const Approximation  encoded = engine.GetApproximation();
  const auto           payload = EncodePayload(encoded, 0.0, 4.0);
  const Approximation  decoded = DecodePayload(payload, grid, uint32_t(encoded.points.size()), 0.0, 4.0, "p");
  std::vector<uint8_t> a(grid.NumberOfVoxels()), b(grid.NumberOfVoxels());
  Rasterize(encoded, a.data());
  Rasterize(decoded, b.data());
  EXPECT_EQ(a, b);
  // Positions and values cost less than a raw listing (3 x 16 + 8 bits a point).
  EXPECT_LT(payload.size() * 8, encoded.points.size() * 56);
  // Every truncation is reported, never a crash.
  for (std::size_t n = 0; n < payload.size(); n += 7)
  {
    const std::vector<uint8_t> cut(payload.begin(), payload.begin() + std::ptrdiff_t(n));
    EXPECT_THROW(DecodePayload(cut, grid, uint32_t(encoded.points.size()), 0.0, 4.0, "p"), FormatError) << n;
  }
  // Bytes after a complete stream are refused too.
  std::vector<uint8_t> longer = payload;
  longer.push_back(0);
  EXPECT_THROW(DecodePayload(longer, grid, uint32_t(encoded.points.size()), 0.0, 4.0, "p"), FormatError);
  // Values off the lattice are refused by the encoder.
  Approximation off = encoded;
  off.values[3] += 1.0;
  EXPECT_THROW(EncodePayload(off, 0.0, 4.0), std::invalid_argument);
}

TEST(Codec, ScaledSpaceDecodesToTheEngineOutputBitForBit)
{
  const GridSize           grid{ 36, 32, 10 };
  const auto               bytes = SheppLoganPhantom(grid);
  const std::vector<float> image(bytes.begin(), bytes.end());
  RefinementParameters     p = ParametersForMode(Mode::Best);
  p.quantizationStep = 4.0;
  p.valueMin = 0.0;
  p.valueMax = 255.0;
  p.scale = { { 1, 1, 6 } };
  RefinementEngine engine(image.data(), grid, p);
  engine.Approximate(500);
  const Approximation encoded = engine.GetApproximation();
  EXPECT_EQ(encoded.scale, p.scale);
  FileHeader h;
  h.size = grid;
  h.scale = p.scale;
  h.quantizationStep = 4.0;
  h.numberOfPoints = uint32_t(encoded.points.size());
  CompressedFile file;
  file.name = "scaled";
  ParseFile(SerializeFile(h, EncodePayload(encoded, 0.0, 4.0)), file.name, file.header, file.payload);
  const Approximation  decoded = Decode(file);
  std::vector<uint8_t> a(grid.NumberOfVoxels()), b(grid.NumberOfVoxels());
  Rasterize(encoded, a.data());
  Rasterize(decoded, b.data());
  EXPECT_EQ(a, b);
  // Decoded in the unscaled space the neighbours differ, so the values cannot be read: the scale is part
  // of the file.
  file.header.scale = { { 1, 1, 1 } };
  EXPECT_THROW(Decode(file), FormatError);
}

/** ApproximateToBudget on a volume: the payload fits `bpv` bits per voxel (less the header),
 * fills at least 97% of it, and is the engine's final approximation, decoded bit for bit. */
void
ExpectBudgetMet(const std::vector<float> & image, const GridSize & grid, double peak, double q, double bpv,
                Mode mode = Mode::Best)
{
  RefinementParameters p = ParametersForMode(mode);
  const auto           range = std::minmax_element(image.begin(), image.end());
  p.quantizationStep = q;
  p.quantizationOrigin = *range.first;
  p.valueMin = *range.first;
  p.valueMax = *range.second;
  p.peak = peak;
  RefinementEngine   engine(image.data(), grid, p);
  const std::size_t  budget = std::size_t(bpv * double(grid.NumberOfVoxels()) / 8.0) - 90;
  const BudgetResult r = ApproximateToBudget(engine, budget, p.quantizationOrigin, { 1.0, 2.0, 4.0 });
  EXPECT_LE(r.payload.size(), budget) << bpv;
  EXPECT_GE(double(r.payload.size()), 0.97 * double(budget)) << bpv;
  EXPECT_LE(r.adjustments, 12u);
  EXPECT_TRUE(r.step == q || r.step == 2 * q || r.step == 4 * q) << r.step;
  EXPECT_EQ(engine.GetParameters().quantizationStep, r.step);
  const Approximation final = engine.GetApproximation();
  EXPECT_EQ(EncodePayload(final, p.quantizationOrigin, r.step), r.payload);
  const Approximation decoded =
    DecodePayload(r.payload, grid, uint32_t(final.points.size()), p.quantizationOrigin, r.step, "budget");
  std::vector<float> a(grid.NumberOfVoxels()), b(grid.NumberOfVoxels());
  Rasterize(final, a.data());
  Rasterize(decoded, b.data());
  EXPECT_EQ(a, b);
}

TEST(Codec, RateControlFillsTheBudgetOnThePhantom)
{
  const GridSize           grid{ 48, 44, 40 };
  const auto               bytes = SheppLoganPhantom(grid);
  const std::vector<float> image(bytes.begin(), bytes.end());
  for (double bpv : { 0.0625, 0.25 })
  {
    ExpectBudgetMet(image, grid, 255.0, 4.0, bpv);
    ExpectBudgetMet(image, grid, 255.0, 4.0, bpv, Mode::Silva); // grows by refinement only
  }
}

TEST(Codec, RateControlFillsTheBudgetOnRealData)
{
  DCV_REQUIRE_DATA("headsq-ct.nrrd");
  const test::Volume v = test::ReadVolume("headsq-ct.nrrd"); // int16
  for (double bpv : { 0.03125, 0.125 })
  {
    ExpectBudgetMet(v.voxels, v.grid, v.peak, std::round(v.peak / 64.0), bpv);
  }
}

TEST(Codec, RateControlAbandonsThePointsOnlyForABetterCompetitor)
{
  const GridSize           grid{ 48, 44, 40 };
  const auto               bytes = SheppLoganPhantom(grid);
  const std::vector<float> image(bytes.begin(), bytes.end());
  const std::size_t        budget = std::size_t(0.0625 * double(grid.NumberOfVoxels()) / 8.0) - 90;
  RefinementParameters     p = ParametersForMode(Mode::Best);
  p.quantizationStep = 4.0;
  auto run = [&](double competitorError, RefinementEngine::Timings & timings) {
    RefinementEngine   engine(image.data(), grid, p);
    const BudgetResult r =
      ApproximateToBudget(engine, budget, 0.0, { 1.0, 2.0, 4.0 }, {}, [competitorError] { return competitorError; });
    timings = engine.GetTimings();
    return std::make_pair(r, engine.GetSquaredError());
  };
  RefinementEngine::Timings timings;
  const auto [full, fullError] = run(std::numeric_limits<double>::infinity(), timings);
  ASSERT_FALSE(full.abandoned);
  ASSERT_GT(fullError, 0.0);
  // A competitor that is exact: abandoned after the first refinement, before any decimation.
  const auto [exact, exactError] = run(0.0, timings);
  EXPECT_TRUE(exact.abandoned);
  EXPECT_TRUE(exact.payload.empty());
  EXPECT_EQ(timings.decimation, 0.0);
  // A competitor the points beat (by 3 dB): they go to the end, and give the same file as without one.
  const auto [beaten, beatenError] = run(2.0 * fullError, timings);
  EXPECT_FALSE(beaten.abandoned);
  EXPECT_EQ(beaten.payload, full.payload);
}

TEST(Codec, RateControlRefusesABudgetTheCornersExceed)
{
  const GridSize           grid{ 20, 20, 20 };
  const auto               bytes = SheppLoganPhantom(grid);
  const std::vector<float> image(bytes.begin(), bytes.end());
  RefinementParameters     p;
  p.quantizationStep = 4.0;
  RefinementEngine engine(image.data(), grid, p);
  EXPECT_THROW(ApproximateToBudget(engine, 2, 0.0), std::length_error);
  RefinementEngine unquantized(image.data(), grid);
  EXPECT_THROW(ApproximateToBudget(unquantized, 1000, 0.0), std::invalid_argument);
}

} // namespace

TEST(FileFormat, MetadataIsDeflatedWhenThatIsSmaller)
{
  FileHeader h = SampleHeader(false);
  for (int i = 0; i < 20; ++i)
    h.metadata.emplace_back("DICOM SeriesInstanceUID " + std::to_string(i), "1.3.46.670589.33.1.6002432791750815306");
  const auto bytes = SerializeFile(h, { 1, 2 });
  EXPECT_EQ(bytes[6] & 16, 16) << "not deflated";
  FileHeader           back;
  std::vector<uint8_t> payload;
  ParseFile(bytes, "x", back, payload);
  EXPECT_EQ(back.metadata, h.metadata);
  std::size_t plain = 0;
  for (const auto & kv : h.metadata)
    plain += 8 + kv.first.size() + kv.second.size();
  EXPECT_LT(bytes.size(), SerializeFile(SampleHeader(false), { 1, 2 }).size() + plain / 2);
  // Tiny metadata stays as it is (deflating would not pay).
  FileHeader small = SampleHeader(false);
  small.metadata = { { "a", "b" } };
  EXPECT_EQ(SerializeFile(small, {}).at(6) & 16, 0);
  // A damaged stream is refused even with a recomputed CRC-32.
  auto damaged = bytes;
  damaged[damaged.size() - 10] ^= 0x55;
  const uint32_t crc = uint32_t(crc32(0L, damaged.data(), uInt(damaged.size() - 4)));
  for (int i = 0; i < 4; ++i)
    damaged[damaged.size() - 4 + i] = uint8_t(crc >> (8 * i));
  EXPECT_NE(ParseError(damaged).find("metadata"), std::string::npos) << ParseError(damaged);
}

TEST(FileFormat, DicomHeaderBlockRoundTripsAndADamagedOneIsRefused)
{
  DicomHeaderBlock block;
  block.mode = 1;
  block.common = std::string("\x08\x00\x60\x00"
                             "CS\x02\x00"
                             "CT",
                             10);
  block.files = { std::string("\x20\x00\x13\x00"
                              "IS\x02\x00"
                              "1 ",
                              10),
                  "" };
  FileHeader h = SampleHeader(true);
  h.metadata.emplace_back(DicomHeaderKey, JoinDicomHeader(block));
  const auto           bytes = SerializeFile(h, { 1, 2, 3 });
  FileHeader           back;
  std::vector<uint8_t> payload;
  ParseFile(bytes, "x.dcv", back, payload);
  ASSERT_EQ(back.metadata, h.metadata);
  const DicomHeaderBlock parsed = SplitDicomHeader(back.metadata.back().second, "x.dcv");
  EXPECT_EQ(parsed.mode, 1);
  EXPECT_EQ(parsed.common, block.common);
  EXPECT_EQ(parsed.files, block.files);
  // A block whose lengths do not add up, under a valid checksum, and one of an unknown version.
  std::string value = JoinDicomHeader(block);
  for (const std::string & damaged : { value.substr(0, value.size() - 1), value + "x", "\x02" + value.substr(1) })
  {
    h.metadata.back().second = damaged;
    const std::string error = ParseError(SerializeFile(h, { 1, 2, 3 }));
    EXPECT_EQ(error.rfind("x.dcv: ", 0), 0u) << error;
    EXPECT_NE(error.find("DICOM header"), std::string::npos) << error;
  }
  // Two blocks.
  h.metadata.back().second = value;
  h.metadata.emplace_back(DicomHeaderKey, value);
  EXPECT_NE(ParseError(SerializeFile(h, { 1, 2, 3 })).find("two DICOM header blocks"), std::string::npos);
}

TEST(FileFormat, AxisDirectionsTakeOneByte)
{
  // Every flip and swap of the axes (48 signed permutations, identity aside) in one byte, exactly.
  const FileHeader           plain = SampleHeader(false);
  const std::vector<uint8_t> some(64, 0); // room for the points the header claims
  const std::size_t          identityBytes = SerializeFile(plain, some).size();
  int                        permutations = 0;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b)
      for (int c = 0; c < 3; ++c)
      {
        if (a == b || b == c || a == c)
          continue;
        for (int signs = 0; signs < 8; ++signs)
        {
          FileHeader h = plain;
          h.direction = { 0, 0, 0, 0, 0, 0, 0, 0, 0 };
          h.direction[std::size_t(a)] = (signs & 1) ? -1.0 : 1.0;
          h.direction[std::size_t(3 + b)] = (signs & 2) ? -1.0 : 1.0;
          h.direction[std::size_t(6 + c)] = (signs & 4) ? -1.0 : 1.0;
          const auto bytes = SerializeFile(h, some);
          const bool identity = a == 0 && b == 1 && c == 2 && signs == 0;
          EXPECT_EQ(bytes.size(), identityBytes + (identity ? 0 : 1));
          FileHeader           back;
          std::vector<uint8_t> payload;
          ParseFile(bytes, "x.dcv", back, payload);
          EXPECT_EQ(back.direction, h.direction);
          ++permutations;
        }
      }
  EXPECT_EQ(permutations, 48);
  // An ulp off 1, as ITK's NRRD reader leaves it, is a flip too.
  {
    FileHeader h = plain;
    h.direction = { -0.9999999999999999, 0, 0, 0, -1, 0, 0, 0, 1 };
    const auto bytes = SerializeFile(h, some);
    EXPECT_EQ(bytes.size(), identityBytes + 1);
    FileHeader           back;
    std::vector<uint8_t> payload;
    ParseFile(bytes, "x.dcv", back, payload);
    EXPECT_EQ(back.direction, (std::array<double, 9>{ -1, 0, 0, 0, -1, 0, 0, 0, 1 }));
  }
  // Anything else (a rotation, a permutation off by 6e-8) keeps its 9 doubles, exactly.
  FileHeader h = plain;
  h.direction = { 0.9999999404, 0, 0, 0, 0, -1, 0, -1, 0 };
  const auto bytes = SerializeFile(h, some);
  EXPECT_EQ(bytes.size(), identityBytes + 72);
  FileHeader           back;
  std::vector<uint8_t> payload;
  ParseFile(bytes, "x.dcv", back, payload);
  EXPECT_EQ(back.direction, h.direction);
  // A code naming no permutation is refused, even with a recomputed CRC-32.
  h.direction = { -1, 0, 0, 0, 1, 0, 0, 0, 1 };
  auto           damaged = SerializeFile(h, some);
  const uint32_t at = 62; // the code follows the origin
  ASSERT_EQ(damaged[at], 8);
  damaged[at] = 7;
  const uint32_t crc = uint32_t(crc32(0L, damaged.data(), uInt(damaged.size() - 4)));
  for (int i = 0; i < 4; ++i)
    damaged[damaged.size() - 4 + i] = uint8_t(crc >> (8 * i));
  EXPECT_NE(ParseError(damaged).find("invalid direction code 7"), std::string::npos) << ParseError(damaged);
}
