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
#ifndef dcvFileFormat_h
#define dcvFileFormat_h

#include "DelaunayCompressionExport.h"
#include "dcvRasterizer.h"

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

/** \file dcvFileFormat.h
 * The container of a .dcv file (docs/format.md): header, coded payload, optional residual layer and
 * metadata, CRC-32.
 * One reader and one writer; the coding of the payload lives elsewhere.
 * \ingroup DelaunayCompression
 */
namespace dcv
{

/** A .dcv file that cannot be read; the message names the file and the problem. */
struct FormatError : std::runtime_error
{
  using std::runtime_error::runtime_error;
};

/** Pixel type of the volume a .dcv file decodes to (codes as stored in the file). */
enum class PixelType : uint8_t
{
  UInt8 = 1,
  Int8 = 2,
  UInt16 = 3,
  Int16 = 4,
  UInt32 = 5,
  Int32 = 6,
  Float32 = 7,
  Float64 = 8
};

DelaunayCompression_EXPORT const char *
PixelTypeName(PixelType type);

/** Calls f(T()) with the C++ type T of a pixel type: one switch for every decoder. */
template <typename TFunction>
void
VisitPixelType(PixelType type, TFunction && f)
{
  switch (type)
  {
    case PixelType::UInt8:
      return f(uint8_t());
    case PixelType::Int8:
      return f(int8_t());
    case PixelType::UInt16:
      return f(uint16_t());
    case PixelType::Int16:
      return f(int16_t());
    case PixelType::UInt32:
      return f(uint32_t());
    case PixelType::Int32:
      return f(int32_t());
    case PixelType::Float32:
      return f(float());
    case PixelType::Float64:
      return f(double());
  }
}

/** The pixel type of C++ type T (any 8, 16 or 32-bit integer, float, double). */
template <typename T>
constexpr PixelType
PixelTypeOf()
{
  static_assert(std::is_arithmetic<T>::value && !std::is_same<T, bool>::value && sizeof(T) <= 8,
                ".dcv volumes hold 8, 16 or 32-bit integers, float or double");
  if constexpr (std::is_floating_point<T>::value)
  {
    static_assert(sizeof(T) == 4 || sizeof(T) == 8, "float or double");
    return sizeof(T) == 4 ? PixelType::Float32 : PixelType::Float64;
  }
  else
  {
    static_assert(sizeof(T) <= 4, ".dcv volumes hold integers of at most 32 bits");
    constexpr bool s = std::is_signed<T>::value;
    return sizeof(T) == 1   ? (s ? PixelType::Int8 : PixelType::UInt8)
           : sizeof(T) == 2 ? (s ? PixelType::Int16 : PixelType::UInt16)
                            : (s ? PixelType::Int32 : PixelType::UInt32);
  }
}

/** Whether a pixel type holds integers. */
inline bool
IsInteger(PixelType type)
{
  return type != PixelType::Float32 && type != PixelType::Float64;
}

/** The codec of a video layer (dcvVideoLayer.h): HEVC, or AV1 (form bit 4). */
enum class VideoCodec : uint8_t
{
  HEVC,
  AV1
};

/** Everything of a .dcv file but its coded payload. */
struct FileHeader
{
  static constexpr uint8_t Version = 1;
  /** The mode of a file whose points were not chosen by the encoder (written as a mesh). */
  static constexpr uint8_t UnknownMode = 255;
  /** The mode of a file with a bounded-error layer and no points (EncoderOptions::maximumError). */
  static constexpr uint8_t BoundedMode = 4;

  PixelType             pixelType{ PixelType::UInt8 };
  uint8_t               mode{ 0 }; // informative: the dcv::Mode that encoded it, or UnknownMode
  GridSize              size;
  std::array<double, 3> spacing{ 1.0, 1.0, 1.0 };
  std::array<double, 3> origin{ 0.0, 0.0, 0.0 };
  std::array<double, 9> direction{ 1, 0, 0, 0, 1, 0, 0, 0, 1 }; // row major
  GridScale             scale{ { 1, 1, 1 } };                   // of the Delaunay space (FlagScale)
  double                quantizationOrigin{ 0.0 };
  double                quantizationStep{ 1.0 };
  uint32_t              numberOfPoints{ 0 };
  std::vector<std::pair<std::string, std::string>> metadata; // UTF-8 key/value pairs
  /** The residual layer (FlagResidual, dcvResidualLayer.h): its step (0: the file has none) and its
   * JPEG 2000 codestream. */
  double               residualStep{ 0.0 };
  int32_t              residualLevels{ 0 }; // of its inter-slice wavelet (dcvInterSliceWavelet.h), 0: none
  std::vector<uint8_t> residualLayer;       // the whole codestream (a file may store it compact)
  /** The spline is the constant quantizationOrigin (the 8 corners, all at that value) under a residual
   * layer: no point is coded (form bit 0); the payload is empty, numberOfPoints 8. */
  bool constantSpline{ false };
  /** The residual layer is a video stream (form bit 3, dcvVideoLayer.h), not JPEG 2000: only over a constant
   * spline, without the inter-slice wavelet; HEVC, or with form bit 4 AV1. */
  bool       videoLayer{ false };
  VideoCodec videoCodec{ VideoCodec::HEVC };
  /** The residual layer is a bounded-error layer (form bit 5, dcvBoundedLayer.h): only over a constant spline,
   * without the inter-slice wavelet; every decoded voxel is within the bound it states of the input. */
  bool boundedLayer{ false };
};

/** The metadata key whose value holds the headers of the DICOM files a volume came from (docs/format.md,
 * "DICOM header"): bytes, not text. */
constexpr const char * DicomHeaderKey = "DICOM Header";

/** The value of the "DICOM Header" pair: the data elements (DICOM explicit VR little endian) equal in
 * every file once, then each file's others, in slice order. */
struct DicomHeaderBlock
{
  static constexpr uint8_t Version = 1;
  uint8_t                  mode{ 0 }; // 0: every attribute; 1: the essential ones
  std::string              common;
  std::vector<std::string> files;
};

/** The value of a "DICOM Header" pair. */
DelaunayCompression_EXPORT std::string
                           JoinDicomHeader(const DicomHeaderBlock & block);

/** Parses the value of a "DICOM Header" pair (its version, mode, counts and lengths; the elements are
 * the DICOM reader's to parse); throws FormatError starting with `name`. ParseFile() checks it so. */
DelaunayCompression_EXPORT DicomHeaderBlock
SplitDicomHeader(const std::string & value, const std::string & name);

/** The bytes of a whole file. */
DelaunayCompression_EXPORT std::vector<uint8_t>
                           SerializeFile(const FileHeader & header, const std::vector<uint8_t> & payload);

/** Parses and checks a whole file (magic, version, sizes, lengths, CRC-32) before anything is
 * allocated from its numbers; throws FormatError starting with `name`. */
DelaunayCompression_EXPORT void
ParseFile(const std::vector<uint8_t> & bytes, const std::string & name, FileHeader & header,
          std::vector<uint8_t> & payload);

/** A parsed .dcv file: its header and coded payload, and the name errors give it (the path, quoted). */
struct CompressedFile
{
  std::string          name;
  FileHeader           header;
  std::vector<uint8_t> payload;
  std::size_t          size{ 0 }; // bytes of the whole file
};

/** The largest payload a .dcv file holds: its length is a uint32. */
constexpr uint64_t MaximumPayloadBytes = 0xFFFFFFFFu;

/** A payload of L bytes codes at most MaximumPointsPerPayloadByte x L points, so that ParseFile() refuses
 * a larger point count before anything is decoded. Why: every point's value starts with one adaptive
 * decision (the zero flag of its residual model, maximum shift 5), whose probability stays within
 * [31, 65505] / 2^16 whatever the stream; each decision therefore divides the decoder's range by at least
 * 65536 / 65505, i.e. costs at least 6.825e-4 bits, and a stream that is not overrun reads at most L bytes:
 * n <= 8 L / 6.825e-4 < 11722 L. 11728 L leaves a margin (docs/format.md, "Resource limits"). */
constexpr uint64_t MaximumPointsPerPayloadByte = 11728;

/** What decoding may use by default: half of the machine's physical memory (4 GiB where it is unknown). */
DelaunayCompression_EXPORT uint64_t
DefaultMaximumMemory();

/** Limits on what a file may make the decoder allocate, checked against what its header implies before
 * anything is allocated from it (CheckDecodingMemory()). */
struct DecodeLimits
{
  /** Bytes that decoding a file may need (DecodingMemory()); 0: no limit. */
  uint64_t maximumMemory{ DefaultMaximumMemory() };
};

/** What a decoder builds from a file: the mesh alone (points, values, tetrahedra) or the volume too. */
enum class DecodeOutput
{
  Mesh,
  Volume
};

/** An estimate (from above) of the peak memory that decoding a file with this header needs: about 1 KiB per
 * point (the points, CGAL's triangulation, the tetrahedra, the neighbour table) and, for a volume, the
 * voxels of its pixel type plus 16 bytes per voxel with a residual layer (its samples and OpenJPEG's). */
DelaunayCompression_EXPORT uint64_t
DecodingMemory(const FileHeader & header, DecodeOutput output);

/** Throws FormatError starting with `name` (what it would need, and the limit) when DecodingMemory()
 * exceeds limits.maximumMemory. */
DelaunayCompression_EXPORT void
CheckDecodingMemory(const FileHeader & header, const std::string & name, DecodeOutput output,
                    const DecodeLimits & limits);

/** "1.5 GiB": a byte count for messages. */
DelaunayCompression_EXPORT std::string
                           FormatByteCount(uint64_t bytes);

/** Reads and parses a whole file, once (FormatError naming it when it cannot be read or parsed). */
DelaunayCompression_EXPORT CompressedFile
ReadCompressedFile(const std::string & path);

/** Reads a whole file (FormatError naming it when it cannot be read). */
DelaunayCompression_EXPORT std::vector<uint8_t>
                           ReadWholeFile(const std::string & path);

/** Writes a temporary file next to `path` and renames it over `path` at the end, so that a failure
 * never leaves a partial file (FormatError naming it on failure). */
DelaunayCompression_EXPORT void
WriteFileAtomically(const std::string & path, const std::vector<uint8_t> & bytes);

/** Whether the bytes start with the .dcv magic. */
DelaunayCompression_EXPORT bool
HasMagic(const uint8_t * bytes, std::size_t size);

} // namespace dcv

#endif
