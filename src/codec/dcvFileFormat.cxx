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
#include "dcvFileFormat.h"
#include "dcvInterSliceWavelet.h"
#include "dcvResidualLayer.h"

#include <zlib.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <unistd.h>

namespace dcv
{
namespace
{
// 0x89 first, as PNG does: a file that went through a text conversion is caught by the magic.
constexpr uint8_t Magic[4] = { 0x89, 'D', 'C', 'V' };
constexpr uint8_t FlagDirection = 1;      // a non-identity direction matrix follows the origin
constexpr uint8_t FlagMetadata = 2;       // a metadata block follows the payload
constexpr uint8_t FlagScale = 4;          // three per-axis scales of the Delaunay space follow the direction
constexpr uint8_t FlagResidual = 8;       // a residual layer follows the payload
constexpr uint8_t FlagDeflated = 16;      // the metadata pairs are deflated (zlib)
constexpr uint8_t FlagInterSlice = 32;    // the residual layer has an inter-slice wavelet (with FlagResidual)
constexpr uint8_t FlagAxisDirection = 64; // the direction is one byte: a signed axis permutation (with FlagDirection)
constexpr uint8_t FlagForm = 128;         // a form byte follows the scale (with FlagResidual)
constexpr uint8_t FormConstant = 1;       // no points: the spline is the constant q0; no q, n, L, payload
constexpr uint8_t FormUnitStep = 2;       // the residual step is 1 and is not stored
constexpr uint8_t FormCompact = 4;        // the residual layer is stored compact (dcvResidualLayer.h, CompactLayer)
constexpr uint8_t FormVideo = 8;          // the residual layer is a video stream, HEVC (dcvVideoLayer.h)
constexpr uint8_t FormAV1 = 16;           // ... AV1 (with FormVideo)
constexpr uint8_t FormBounded = 32;       // the residual layer is a bounded-error layer (dcvBoundedLayer.h)

/** The permutations of the axes a direction code names: row r of the matrix is +-1 at column
 * Permutations[code & 7][r]. */
constexpr int Permutations[6][3] = { { 0, 1, 2 }, { 0, 2, 1 }, { 1, 0, 2 }, { 1, 2, 0 }, { 2, 0, 1 }, { 2, 1, 0 } };

/** The one-byte code of a direction that is a signed permutation of the axes (flips and swaps, as most
 * volumes have: 71 bytes fewer), or -1. Bits 0-2: the permutation; bit 3 + r: row r is negative. A
 * reader that normalizes a spacing vector may leave an ulp off 1 (ct-avm-4mm: -0.9999999999999999):
 * within 1e-12 counts as 1. */
int
AxisDirectionCode(const std::array<double, 9> & d)
{
  for (int code = 0; code < 6; ++code)
  {
    int  signs = 0;
    bool match = true;
    for (int r = 0; r < 3 && match; ++r)
    {
      for (int c = 0; c < 3 && match; ++c)
      {
        const double v = d[std::size_t(3 * r + c)];
        if (c == Permutations[code][r])
        {
          match = std::abs(std::abs(v) - 1.0) <= 1e-12;
          signs |= v < 0.0 ? (8 << r) : 0;
        }
        else
        {
          match = v == 0.0;
        }
      }
    }
    if (match)
      return code | signs;
  }
  return -1;
}
/** Largest inflated metadata block a reader accepts: no zip bomb grows past it. */
constexpr uint32_t MaximumInflatedMetadata = 16u << 20;

class Writer
{
public:
  std::vector<uint8_t> bytes;
  void
  U8(uint8_t v)
  {
    bytes.push_back(v);
  }
  void
  U16(uint16_t v)
  {
    U8(uint8_t(v));
    U8(uint8_t(v >> 8));
  }
  void
  U32(uint32_t v)
  {
    for (int i = 0; i < 4; ++i)
      U8(uint8_t(v >> (8 * i)));
  }
  void
  F64(double v)
  {
    uint64_t u;
    std::memcpy(&u, &v, 8);
    for (int i = 0; i < 8; ++i)
      U8(uint8_t(u >> (8 * i)));
  }
  void
  Bytes(const uint8_t * p, std::size_t n)
  {
    bytes.insert(bytes.end(), p, p + n);
  }
};

class Reader
{
public:
  Reader(const std::vector<uint8_t> & b, std::size_t end, const std::string & name)
    : m_Bytes(b)
    , m_End(end)
    , m_Name(name)
  {}
  void
  Need(std::size_t n, const char * what)
  {
    if (m_End - m_Position < n)
    {
      throw FormatError(m_Name + ": truncated (the file ends inside the " + what + ")");
    }
  }
  uint8_t
  U8(const char * what)
  {
    Need(1, what);
    return m_Bytes[m_Position++];
  }
  uint16_t
  U16(const char * what)
  {
    Need(2, what);
    const uint16_t v = uint16_t(m_Bytes[m_Position] | (m_Bytes[m_Position + 1] << 8));
    m_Position += 2;
    return v;
  }
  uint32_t
  U32(const char * what)
  {
    Need(4, what);
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i)
      v |= uint32_t(m_Bytes[m_Position + i]) << (8 * i);
    m_Position += 4;
    return v;
  }
  double
  F64(const char * what)
  {
    Need(8, what);
    uint64_t u = 0;
    for (int i = 0; i < 8; ++i)
      u |= uint64_t(m_Bytes[m_Position + i]) << (8 * i);
    m_Position += 8;
    double v;
    std::memcpy(&v, &u, 8);
    return v;
  }
  std::size_t
  Position() const
  {
    return m_Position;
  }
  std::size_t
  Left() const
  {
    return m_End - m_Position;
  }
  void
  Skip(std::size_t n)
  {
    m_Position += n;
  }

private:
  const std::vector<uint8_t> & m_Bytes;
  std::size_t                  m_End;
  std::size_t                  m_Position{ 0 };
  const std::string &          m_Name;
};

bool
IsIdentity(const std::array<double, 9> & d)
{
  for (int i = 0; i < 9; ++i)
  {
    if (d[i] != ((i % 4 == 0) ? 1.0 : 0.0))
      return false;
  }
  return true;
}

uint32_t
Crc32(const uint8_t * p, std::size_t n)
{
  return uint32_t(crc32(crc32(0L, Z_NULL, 0), p, uInt(n)));
}
} // namespace

const char *
PixelTypeName(PixelType type)
{
  switch (type)
  {
    case PixelType::UInt8:
      return "uint8";
    case PixelType::Int8:
      return "int8";
    case PixelType::UInt16:
      return "uint16";
    case PixelType::Int16:
      return "int16";
    case PixelType::UInt32:
      return "uint32";
    case PixelType::Int32:
      return "int32";
    case PixelType::Float32:
      return "float32";
    case PixelType::Float64:
      return "float64";
  }
  return "unknown";
}

bool
HasMagic(const uint8_t * bytes, std::size_t size)
{
  return size >= 4 && std::memcmp(bytes, Magic, 4) == 0;
}

std::vector<uint8_t>
SerializeFile(const FileHeader & h, const std::vector<uint8_t> & payload)
{
  for (int32_t n : { h.size.x, h.size.y, h.size.z })
  {
    if (n < 2 || n > MaximumGridExtent)
    {
      throw std::invalid_argument("a .dcv volume needs 2 to 65535 voxels along each axis");
    }
  }
  if (payload.size() > 0xffffffffu)
  {
    throw std::invalid_argument("the coded payload exceeds 4 GiB");
  }
  Writer     w;
  const bool direction = !IsIdentity(h.direction);
  const bool metadata = !h.metadata.empty();
  const bool scaled = h.scale != GridScale{ { 1, 1, 1 } };
  const bool residual = h.residualStep != 0.0;
  if (residual && (!(h.residualStep > 0.0) || !std::isfinite(h.residualStep) || h.residualLayer.empty() ||
                   h.residualLayer.size() > 0xffffffffu))
  {
    throw std::invalid_argument("a .dcv residual layer needs a positive step and a codestream below 4 GiB");
  }
  if (h.residualLevels < 0 || h.residualLevels > InterSliceLevels(h.size.z) || (h.residualLevels > 0 && !residual))
  {
    throw std::invalid_argument("a .dcv inter-slice wavelet needs a residual layer and at most " +
                                std::to_string(InterSliceLevels(h.size.z)) + " levels for " + std::to_string(h.size.z) +
                                " slices");
  }
  for (int32_t s : h.scale)
  {
    if (s < 1 || s > MaximumGridScale)
    {
      throw std::invalid_argument("a .dcv scale must be 1 to " + std::to_string(MaximumGridScale));
    }
  }
  if (h.constantSpline && (!residual || !payload.empty()))
  {
    throw std::invalid_argument("a .dcv constant spline needs a residual layer and no payload");
  }
  if (h.videoLayer && (!residual || !h.constantSpline || h.residualLevels > 0))
  {
    throw std::invalid_argument("a .dcv video layer needs a constant spline and no inter-slice wavelet");
  }
  if (h.boundedLayer && (!residual || !h.constantSpline || h.residualLevels > 0 || h.videoLayer))
  {
    throw std::invalid_argument("a .dcv bounded-error layer needs a constant spline, no inter-slice wavelet and no "
                                "video layer");
  }
  // Every residual layer comes with a form byte: the layer's fields as short as they can be.
  std::vector<uint8_t> compact;
  const bool compacted = residual && !h.videoLayer && !h.boundedLayer && CompactLayer(h.residualLayer, h.size, compact);
  const uint8_t form =
    uint8_t((h.constantSpline ? FormConstant : 0) | (h.residualStep == 1.0 ? FormUnitStep : 0) |
            (compacted ? FormCompact : 0) | (h.videoLayer ? FormVideo : 0) |
            (h.videoLayer && h.videoCodec == VideoCodec::AV1 ? FormAV1 : 0) | (h.boundedLayer ? FormBounded : 0));
  const std::vector<uint8_t> & layer = compacted ? compact : h.residualLayer;
  w.Bytes(Magic, 4);
  w.U8(FileHeader::Version);
  w.U8(uint8_t(h.pixelType));
  // The metadata pairs, deflated when that is smaller (DICOM attributes: 1150 bytes to about 500).
  Writer pairs;
  for (const auto & kv : h.metadata)
  {
    pairs.U32(uint32_t(kv.first.size()));
    pairs.Bytes(reinterpret_cast<const uint8_t *>(kv.first.data()), kv.first.size());
    pairs.U32(uint32_t(kv.second.size()));
    pairs.Bytes(reinterpret_cast<const uint8_t *>(kv.second.data()), kv.second.size());
  }
  std::vector<uint8_t> deflated;
  if (metadata && pairs.bytes.size() <= MaximumInflatedMetadata)
  {
    uLongf size = compressBound(uLong(pairs.bytes.size()));
    deflated.resize(size);
    if (compress2(deflated.data(), &size, pairs.bytes.data(), uLong(pairs.bytes.size()), 9) == Z_OK &&
        size + 4 < pairs.bytes.size())
      deflated.resize(size);
    else
      deflated.clear();
  }
  const int axisDirection = direction ? AxisDirectionCode(h.direction) : -1;
  w.U8(uint8_t((direction ? FlagDirection : 0) | (axisDirection >= 0 ? FlagAxisDirection : 0) |
               (metadata ? FlagMetadata : 0) | (scaled ? FlagScale : 0) | (residual ? FlagResidual : 0) |
               (deflated.empty() ? 0 : FlagDeflated) | (h.residualLevels > 0 ? FlagInterSlice : 0) |
               (residual ? FlagForm : 0)));
  w.U8(h.mode);
  w.U16(uint16_t(h.size.x));
  w.U16(uint16_t(h.size.y));
  w.U16(uint16_t(h.size.z));
  for (double v : h.spacing)
    w.F64(v);
  for (double v : h.origin)
    w.F64(v);
  if (axisDirection >= 0)
  {
    w.U8(uint8_t(axisDirection));
  }
  else if (direction)
  {
    for (double v : h.direction)
      w.F64(v);
  }
  if (scaled)
  {
    for (int32_t s : h.scale)
      w.U8(uint8_t(s));
  }
  if (residual)
    w.U8(form);
  w.F64(h.quantizationOrigin);
  if (!h.constantSpline)
  {
    w.F64(h.quantizationStep);
    w.U32(h.numberOfPoints);
    w.U32(uint32_t(payload.size()));
    w.Bytes(payload.data(), payload.size());
  }
  if (residual)
  {
    if (!(form & FormUnitStep))
      w.F64(h.residualStep);
    if (h.residualLevels > 0)
      w.U8(uint8_t(h.residualLevels));
    w.U32(uint32_t(layer.size()));
    w.Bytes(layer.data(), layer.size());
  }
  if (metadata)
  {
    w.U32(uint32_t(h.metadata.size()));
    if (deflated.empty())
    {
      w.U32(uint32_t(pairs.bytes.size()));
      w.Bytes(pairs.bytes.data(), pairs.bytes.size());
    }
    else
    {
      w.U32(uint32_t(4 + deflated.size()));
      w.U32(uint32_t(pairs.bytes.size()));
      w.Bytes(deflated.data(), deflated.size());
    }
  }
  w.U32(Crc32(w.bytes.data(), w.bytes.size()));
  return w.bytes;
}

void
ParseFile(const std::vector<uint8_t> & bytes, const std::string & name, FileHeader & h, std::vector<uint8_t> & payload)
{
  if (bytes.size() < 4 || !HasMagic(bytes.data(), bytes.size()))
  {
    throw FormatError(name + ": not a .dcv file (wrong magic bytes)");
  }
  if (bytes.size() < 5)
  {
    throw FormatError(name + ": truncated (the file ends inside the header)");
  }
  if (bytes[4] != FileHeader::Version)
  {
    throw FormatError(name + ": .dcv version " + std::to_string(bytes[4]) + " is not supported (this reader knows " +
                      std::to_string(FileHeader::Version) + ")");
  }
  if (bytes.size() < 9)
  {
    throw FormatError(name + ": truncated (the file ends inside the header)");
  }
  // The checksum covers everything before it: check it first, so that a damaged number is never used.
  const std::size_t body = bytes.size() - 4;
  uint32_t          stored = 0;
  for (int i = 0; i < 4; ++i)
    stored |= uint32_t(bytes[body + i]) << (8 * i);
  if (Crc32(bytes.data(), body) != stored)
  {
    throw FormatError(name + ": damaged or truncated (CRC-32 mismatch)");
  }
  Reader r(bytes, body, name);
  r.Skip(5);
  const uint8_t type = r.U8("header");
  if (type < 1 || type > 8)
  {
    throw FormatError(name + ": unknown pixel type code " + std::to_string(type));
  }
  h.pixelType = PixelType(type);
  const uint8_t flags = r.U8("header");
  if (((flags & FlagDeflated) && !(flags & FlagMetadata)) || ((flags & FlagInterSlice) && !(flags & FlagResidual)) ||
      ((flags & FlagAxisDirection) && !(flags & FlagDirection)) || ((flags & FlagForm) && !(flags & FlagResidual)))
  {
    throw FormatError(name + ": unknown header flags " + std::to_string(flags));
  }
  h.mode = r.U8("header");
  h.size.x = r.U16("header");
  h.size.y = r.U16("header");
  h.size.z = r.U16("header");
  if (h.size.x < 2 || h.size.y < 2 || h.size.z < 2)
  {
    throw FormatError(name + ": absurd volume size " + std::to_string(h.size.x) + "x" + std::to_string(h.size.y) + "x" +
                      std::to_string(h.size.z) + " (each axis needs at least 2 voxels)");
  }
  for (double & v : h.spacing)
    v = r.F64("header");
  for (double & v : h.origin)
    v = r.F64("header");
  h.direction = { 1, 0, 0, 0, 1, 0, 0, 0, 1 };
  if (flags & FlagAxisDirection)
  {
    const uint8_t code = r.U8("header");
    if ((code & 7) > 5 || code > 63)
      throw FormatError(name + ": invalid direction code " + std::to_string(code));
    h.direction = { 0, 0, 0, 0, 0, 0, 0, 0, 0 };
    for (int row = 0; row < 3; ++row)
      h.direction[std::size_t(3 * row + Permutations[code & 7][row])] = (code & (8 << row)) ? -1.0 : 1.0;
  }
  else if (flags & FlagDirection)
  {
    for (double & v : h.direction)
      v = r.F64("header");
  }
  h.scale = { { 1, 1, 1 } };
  if (flags & FlagScale)
  {
    for (int32_t & s : h.scale)
    {
      s = r.U8("header");
      if (s < 1 || s > MaximumGridScale)
        throw FormatError(name + ": invalid Delaunay scale " + std::to_string(s));
    }
  }
  for (double v : h.spacing)
  {
    if (!(v > 0.0) || !std::isfinite(v))
      throw FormatError(name + ": invalid voxel spacing");
  }
  const uint8_t form = (flags & FlagForm) ? r.U8("header") : 0;
  if (form & ~(FormConstant | FormUnitStep | FormCompact | FormVideo | FormAV1 | FormBounded))
  {
    throw FormatError(name + ": unknown form bits " + std::to_string(form));
  }
  if ((form & FormVideo) && (!(form & FormConstant) || (form & FormCompact) || (flags & FlagInterSlice)))
  {
    throw FormatError(name + ": a video layer (form bit 3) needs a constant spline (form bit 0), no compact form "
                             "and no inter-slice wavelet");
  }
  h.constantSpline = (form & FormConstant) != 0;
  if ((form & FormAV1) && !(form & FormVideo))
  {
    throw FormatError(name + ": form bit 4 (AV1) without a video layer (form bit 3)");
  }
  h.videoLayer = (form & FormVideo) != 0;
  if ((form & FormBounded) &&
      (!(form & FormConstant) || (form & (FormCompact | FormVideo)) || (flags & FlagInterSlice)))
  {
    throw FormatError(name + ": a bounded-error layer (form bit 5) needs a constant spline (form bit 0), no compact "
                             "form, no video layer and no inter-slice wavelet");
  }
  h.boundedLayer = (form & FormBounded) != 0;
  h.videoCodec = (form & FormAV1) ? VideoCodec::AV1 : VideoCodec::HEVC;
  h.quantizationOrigin = r.F64("header");
  if (h.constantSpline)
  {
    if (!std::isfinite(h.quantizationOrigin))
      throw FormatError(name + ": invalid value quantization");
    h.quantizationStep = 1.0;
    h.numberOfPoints = 8;
    payload.clear();
  }
  else
  {
    h.quantizationStep = r.F64("header");
    if (!std::isfinite(h.quantizationOrigin) || !(h.quantizationStep > 0.0) || !std::isfinite(h.quantizationStep))
    {
      throw FormatError(name + ": invalid value quantization");
    }
    h.numberOfPoints = r.U32("header");
    if (h.numberOfPoints < 8 || uint64_t(h.numberOfPoints) > h.size.NumberOfVoxels())
    {
      throw FormatError(name + ": absurd point count " + std::to_string(h.numberOfPoints) + " for " +
                        std::to_string(h.size.NumberOfVoxels()) + " voxels");
    }
    const uint32_t length = r.U32("header");
    if (length > r.Left())
    {
      throw FormatError(name + ": truncated (the payload is " + std::to_string(length) + " bytes, " +
                        std::to_string(r.Left()) + " remain)");
    }
    if (uint64_t(h.numberOfPoints) > MaximumPointsPerPayloadByte * length)
    {
      throw FormatError(name + ": damaged (" + std::to_string(h.numberOfPoints) + " points cannot be coded in " +
                        std::to_string(length) + " payload bytes, at most " +
                        std::to_string(MaximumPointsPerPayloadByte * length) + ")");
    }
    payload.assign(bytes.begin() + std::ptrdiff_t(r.Position()), bytes.begin() + std::ptrdiff_t(r.Position() + length));
    r.Skip(length);
  }
  h.residualStep = 0.0;
  h.residualLevels = 0;
  h.residualLayer.clear();
  if (flags & FlagResidual)
  {
    h.residualStep = (form & FormUnitStep) ? 1.0 : r.F64("residual layer");
    if (!(h.residualStep > 0.0) || !std::isfinite(h.residualStep))
    {
      throw FormatError(name + ": invalid residual step");
    }
    if (flags & FlagInterSlice)
    {
      h.residualLevels = r.U8("residual layer");
      if (h.residualLevels < 1 || h.residualLevels > InterSliceLevels(h.size.z))
      {
        throw FormatError(name + ": invalid inter-slice wavelet (" + std::to_string(h.residualLevels) + " levels; " +
                          std::to_string(h.size.z) + " slices take 1 to " + std::to_string(InterSliceLevels(h.size.z)) +
                          ")");
      }
    }
    const uint32_t size = r.U32("residual layer");
    if (size == 0 || size > r.Left())
    {
      throw FormatError(name + ": truncated (the residual layer is " + std::to_string(size) + " bytes, " +
                        std::to_string(r.Left()) + " remain)");
    }
    h.residualLayer.assign(bytes.begin() + std::ptrdiff_t(r.Position()),
                           bytes.begin() + std::ptrdiff_t(r.Position() + size));
    r.Skip(size);
    if (form & FormCompact)
      h.residualLayer = ExpandLayer(h.residualLayer, h.size, name);
  }
  h.metadata.clear();
  if (flags & FlagMetadata)
  {
    const uint32_t count = r.U32("metadata");
    const uint32_t size = r.U32("metadata");
    if (size != r.Left())
    {
      throw FormatError(name + ": inconsistent metadata block");
    }
    std::vector<uint8_t> inflated;
    if (flags & FlagDeflated)
    {
      const uint32_t expected = r.U32("metadata");
      if (expected > MaximumInflatedMetadata)
      {
        throw FormatError(name + ": absurd metadata size " + std::to_string(expected));
      }
      inflated.resize(expected);
      uLongf produced = expected;
      if (uncompress(inflated.data(), &produced, bytes.data() + r.Position(), uLong(r.Left())) != Z_OK ||
          produced != expected)
      {
        throw FormatError(name + ": damaged metadata block");
      }
      r.Skip(r.Left());
    }
    else
    {
      inflated.assign(bytes.begin() + std::ptrdiff_t(r.Position()),
                      bytes.begin() + std::ptrdiff_t(r.Position() + size));
      r.Skip(size);
    }
    Reader m(inflated, inflated.size(), name);
    if (count > inflated.size() / 8)
    {
      throw FormatError(name + ": inconsistent metadata block");
    }
    for (uint32_t i = 0; i < count; ++i)
    {
      std::string kv[2];
      for (auto & t : kv)
      {
        const uint32_t n = m.U32("metadata");
        m.Need(n, "metadata");
        t.assign(reinterpret_cast<const char *>(inflated.data() + m.Position()), n);
        m.Skip(n);
      }
      h.metadata.emplace_back(kv[0], kv[1]);
    }
    if (m.Left() != 0)
    {
      throw FormatError(name + ": inconsistent metadata block");
    }
    // The DICOM header block's own structure, so that a reader of its elements gets whole parts.
    bool dicomHeader = false;
    for (const auto & kv : h.metadata)
    {
      if (kv.first == DicomHeaderKey)
      {
        if (dicomHeader)
          throw FormatError(name + ": two DICOM header blocks");
        dicomHeader = true;
        SplitDicomHeader(kv.second, name);
      }
    }
  }
  if (r.Left() != 0)
  {
    throw FormatError(name + ": " + std::to_string(r.Left()) + " unexpected bytes before the checksum");
  }
}

std::string
JoinDicomHeader(const DicomHeaderBlock & block)
{
  if (block.files.empty() || block.files.size() > 65535 || block.mode > 1)
  {
    throw std::invalid_argument("a DICOM header block holds 1 to 65535 files, mode 0 or 1");
  }
  Writer w;
  w.U8(DicomHeaderBlock::Version);
  w.U8(block.mode);
  w.U32(uint32_t(block.files.size()));
  const auto part = [&w](const std::string & p) {
    if (p.size() > 0xffffffffu)
      throw std::invalid_argument("a DICOM header part exceeds 4 GiB");
    w.U32(uint32_t(p.size()));
    w.Bytes(reinterpret_cast<const uint8_t *>(p.data()), p.size());
  };
  part(block.common);
  for (const auto & f : block.files)
    part(f);
  return std::string(w.bytes.begin(), w.bytes.end());
}

DicomHeaderBlock
SplitDicomHeader(const std::string & value, const std::string & name)
{
  const std::vector<uint8_t> bytes(value.begin(), value.end());
  Reader                     r(bytes, bytes.size(), name);
  DicomHeaderBlock           block;
  const uint8_t              version = r.U8("DICOM header");
  if (version != DicomHeaderBlock::Version)
  {
    throw FormatError(name + ": DICOM header block of unknown version " + std::to_string(version));
  }
  block.mode = r.U8("DICOM header");
  const uint32_t files = r.U32("DICOM header");
  if (block.mode > 1 || files < 1 || files > 65535 || files > r.Left() / 4)
  {
    throw FormatError(name + ": inconsistent DICOM header block");
  }
  const auto part = [&]() {
    const uint32_t n = r.U32("DICOM header");
    r.Need(n, "DICOM header");
    std::string p(value.data() + r.Position(), n);
    r.Skip(n);
    return p;
  };
  block.common = part();
  for (uint32_t i = 0; i < files; ++i)
    block.files.push_back(part());
  if (r.Left() != 0)
  {
    throw FormatError(name + ": inconsistent DICOM header block");
  }
  return block;
}

std::vector<uint8_t>
ReadWholeFile(const std::string & path)
{
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error))
  {
    throw FormatError("'" + path + "': no such file");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in)
  {
    throw FormatError("'" + path + "': cannot be opened");
  }
  return std::vector<uint8_t>((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

uint64_t
DefaultMaximumMemory()
{
  const long pages = ::sysconf(_SC_PHYS_PAGES), pageSize = ::sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || pageSize <= 0)
  {
    return uint64_t(4) << 30;
  }
  return uint64_t(pages) * uint64_t(pageSize) / 2;
}

uint64_t
DecodingMemory(const FileHeader & h, DecodeOutput output)
{
  // Measured peaks (RSS, dcv mesh / decompress): 0.9 KiB per point at 10^6 points (docs/format.md).
  constexpr uint64_t BytesPerPoint = 1024;
  constexpr uint64_t ResidualBytesPerVoxel = 16;
  uint64_t           bytes = uint64_t(h.numberOfPoints) * BytesPerPoint;
  if (output == DecodeOutput::Volume)
  {
    uint64_t perVoxel = 0;
    VisitPixelType(h.pixelType, [&perVoxel](auto pixel) { perVoxel = sizeof(pixel); });
    if (h.residualStep > 0.0)
    {
      perVoxel += ResidualBytesPerVoxel;
    }
    bytes += h.size.NumberOfVoxels() * perVoxel; // below 2^48 x 24: no overflow
  }
  return bytes;
}

std::string
FormatByteCount(uint64_t bytes)
{
  static const char * const units[] = { "bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB" };
  double                    v = double(bytes);
  int                       u = 0;
  while (v >= 1024.0 && u < 6)
  {
    v /= 1024.0;
    ++u;
  }
  if (u == 0)
  {
    return std::to_string(bytes) + " bytes";
  }
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f %s", v, units[u]);
  return text;
}

void
CheckDecodingMemory(const FileHeader & h, const std::string & name, DecodeOutput output, const DecodeLimits & limits)
{
  const uint64_t needed = DecodingMemory(h, output);
  if (limits.maximumMemory != 0 && needed > limits.maximumMemory)
  {
    std::string what = std::to_string(h.numberOfPoints) + " points";
    if (output == DecodeOutput::Volume)
    {
      what += ", " + std::to_string(h.size.x) + "x" + std::to_string(h.size.y) + "x" + std::to_string(h.size.z) +
              " voxels of " + PixelTypeName(h.pixelType);
    }
    throw FormatError(name + ": decoding would need about " + FormatByteCount(needed) + " (" + what +
                      "), more than the memory limit of " + FormatByteCount(limits.maximumMemory) +
                      " (--max-memory, MaximumMemory)");
  }
}

CompressedFile
ReadCompressedFile(const std::string & path)
{
  CompressedFile file;
  file.name = "'" + path + "'";
  const std::vector<uint8_t> bytes = ReadWholeFile(path);
  file.size = bytes.size();
  ParseFile(bytes, file.name, file.header, file.payload);
  return file;
}

void
WriteFileAtomically(const std::string & path, const std::vector<uint8_t> & bytes)
{
  namespace fs = std::filesystem;
  const fs::path target(path);
  const fs::path temporary =
    target.parent_path() / (".dcv-" + std::to_string(::getpid()) + "-" + target.filename().string() + ".tmp");
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char *>(bytes.data()), std::streamsize(bytes.size()));
    out.close();
    if (!out)
    {
      std::error_code ignored;
      fs::remove(temporary, ignored);
      throw FormatError("'" + path + "': cannot be written");
    }
  }
  std::error_code error;
  fs::rename(temporary, target, error);
  if (error)
  {
    fs::remove(temporary, error);
    throw FormatError("'" + path + "': cannot be written (rename failed)");
  }
}

} // namespace dcv
