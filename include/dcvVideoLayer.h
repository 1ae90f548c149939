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
#ifndef dcvVideoLayer_h
#define dcvVideoLayer_h

#include "DelaunayCompressionExport.h"
#include "dcvApproximation.h"
#include "dcvFileFormat.h"

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

/** \file dcvVideoLayer.h
 * The video layer of a .dcv file (docs/format.md, "Video layer"): the volume's slices as the frames of a
 * monochrome video stream, HEVC (ITU-T H.265: libx265 codes, libde265 decodes) or AV1 (AOMedia: libaom
 * codes, dav1d decodes), whose decoded samples each standard fixes to the bit. Inter prediction between
 * slices is what a per-slice transform lacks on thick-slice CT. The libraries stay inside the compiled
 * sources.
 * \ingroup DelaunayCompression
 */
namespace dcv
{

/** "HEVC" or "AV1". */
DelaunayCompression_EXPORT const char *
VideoCodecName(VideoCodec codec);

/** The codecs a video layer's name asks the encoder to try: "both" (HEVC and AV1), "hevc" or "av1" (as
 * `dcv compress --video-codec` and the Slicer modules take them). Throws std::invalid_argument otherwise. */
DelaunayCompression_EXPORT std::vector<VideoCodec>
                           ParseVideoCodecs(const std::string & name);

/** The most bits a video layer's samples take (both codecs code 8, 10 or 12). */
constexpr int32_t VideoMaximumDepth = 12;

/** The bit depth (8, 10 or 12) that holds samples 0 to `largest`; 0 when none does. */
DelaunayCompression_EXPORT int32_t
VideoDepth(double largest);

/** The step of a video layer's samples: for integer data 1 where the range fits 12 bits, else the range over
 * 2^12 - 1 rounded up; for real data the range over 2^12 - 1. Every sample fits 12 bits. */
DelaunayCompression_EXPORT double
VideoStep(double range, bool integer);

/** The least share of a budget an AV1 video layer's file fills: libaom's quality has 64 levels, one level
 * moving the size by 6% to 12% on the dev volumes, so the finest level that fits takes at least about 88%
 * of what the coarser one left over (ct-avm-4mm at 0.03125 bpv: 8,495 bytes of 9,196, the next level 39
 * bytes too many). The file keeps it where it decodes closer than every stream that fills more. */
constexpr double AV1MinimumFill = 0.88;

/** The quality of a lossless video layer (HEVC's transquant bypass, AV1's lossless mode: the samples
 * decode exactly). */
constexpr double VideoLossless = -1.0;

/** The coarsest quality a codec takes: x265's rate factor 0 to 51 (any real), libaom's quantizer level 0 to
 * 63 (integers). */
DelaunayCompression_EXPORT double
VideoCoarsest(VideoCodec codec);

/** Codes samples (laid out as the grid, x fastest; 0 to 2^depth - 1) as a stream of `codec`: one frame a
 * slice, at `quality` (0 to VideoCoarsest: larger, smaller; VideoLossless: exact). Deterministic: the same
 * stream whatever the number of threads. Throws std::runtime_error when the codec cannot code it. */
DelaunayCompression_EXPORT std::vector<uint8_t>
EncodeVideoLayer(VideoCodec codec, const std::vector<uint16_t> & samples, const GridSize & grid, int32_t depth,
                 double quality);

/** Decodes a video layer to samples laid out as the grid. Throws FormatError starting with `name` when the
 * stream is damaged or does not hold the grid's slices. */
DelaunayCompression_EXPORT ResidualSamples
DecodeVideoLayer(VideoCodec codec, const std::vector<uint8_t> & stream, const GridSize & grid,
                 const std::string & name);

/** DecodeVideoLayer slice by slice, without a volume of the samples: each row (slice z's row y, x samples,
 * valid during the call) goes to `sink(y, z, row)`, in the grid's order. Rows of a stream that turns out
 * damaged later may have been given before the FormatError. */
DelaunayCompression_EXPORT void
DecodeVideoRows(VideoCodec codec, const std::vector<uint8_t> & stream, const GridSize & grid, const std::string & name,
                const std::function<void(int32_t y, int32_t z, const int32_t * row)> & sink);

/** A video layer over the constant spline `origin`, and the squared error of the volume it decodes to. */
struct VideoChoice
{
  VideoCodec           codec{ VideoCodec::HEVC };
  double               step{ 0.0 };
  double               quality{ 0.0 };
  std::vector<uint8_t> stream; // empty: none fits
  double               squaredError{ 0.0 };
  int32_t              encodes{ 0 };
};

/** Codes `voxels` (the original, laid out as the grid) minus `origin`, in multiples of `step`, as a video
 * layer of `codec` of at most `maximumBytes` bytes: the quality searched for the largest stream that fits
 * (a few encodes; where the finest leaves room, the lossless stream if it fits), each fitting stream decoded
 * as a decoder will; keeps the one that decodes closest. `tried`, where given, gets the best error after
 * each encode. */
DelaunayCompression_EXPORT VideoChoice
ChooseVideoLayer(VideoCodec codec, const float * voxels, PixelType type, const GridSize & grid, double origin,
                 double step, std::size_t maximumBytes, const std::function<void(double)> & tried = {});

/** The libraries' versions, for `dcv --version`: "x265 3.5, libde265 1.0.11, libaom 3.6.0, dav1d 1.0.0". */
DelaunayCompression_EXPORT std::string
                           VideoLibraryVersions();

} // namespace dcv

#endif
