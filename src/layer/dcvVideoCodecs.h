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
#ifndef dcvVideoCodecs_h
#define dcvVideoCodecs_h

// The video layer's two codecs behind dcvVideoLayer.h, each in its own source with its libraries:
// HEVC (dcvVideoHEVC.cxx: x265, libde265) and AV1 (dcvVideoAV1.cxx: libaom, dav1d).
#include "dcvVideoLayer.h"

namespace dcv
{

/** The rows of slice z from a decoded picture's plane (8-bit samples, or 16-bit where `wide`) to `sink`,
 * through `row` (size x): what both decoders give. */
void
SendSliceRows(const uint8_t * plane, std::ptrdiff_t stride, bool wide, const GridSize & grid, int32_t z,
              std::vector<int32_t> & row, const std::function<void(int32_t y, int32_t z, const int32_t * row)> & sink);

/** Samples 0 to 2^depth - 1 (grid order) as an HEVC stream at x265's rate factor `quality` (0 to 51, or
 * VideoLossless); `search`: x265's faster preset, for the search of the factor by size. */
std::vector<uint8_t>
EncodeHEVC(const std::vector<uint16_t> & samples, const GridSize & grid, int32_t depth, double quality, bool search);

void
DecodeHEVCRows(const std::vector<uint8_t> & stream, const GridSize & grid, const std::string & name,
               const std::function<void(int32_t y, int32_t z, const int32_t * row)> & sink);

std::string
HEVCLibraryVersions();

/** The same as an AV1 stream at libaom's quantizer level `quality` (0 to 63, integer, or VideoLossless);
 * `search`: libaom's faster speed. */
std::vector<uint8_t>
EncodeAV1(const std::vector<uint16_t> & samples, const GridSize & grid, int32_t depth, double quality, bool search);

void
DecodeAV1Rows(const std::vector<uint8_t> & stream, const GridSize & grid, const std::string & name,
              const std::function<void(int32_t y, int32_t z, const int32_t * row)> & sink);

std::string
AV1LibraryVersions();

} // namespace dcv

#endif
