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
// The fuzz targets' CRC-32 fix: the last 4 bytes of an input rewritten as the CRC-32 (little endian, as
// in a .dcv file) of the others, so that mutations behind the header reach the field checks and the
// payload decoder instead of stopping at the checksum.
#ifndef dcvFuzzCrc_h
#define dcvFuzzCrc_h

#include <zlib.h>

#include <cstdint>
#include <vector>

inline void
FixCrc32(std::vector<uint8_t> & bytes)
{
  if (bytes.size() < 8)
    return;
  const std::size_t body = bytes.size() - 4;
  const uint32_t    crc = uint32_t(::crc32(::crc32(0L, Z_NULL, 0), bytes.data(), uInt(body)));
  for (int i = 0; i < 4; ++i)
    bytes[body + i] = uint8_t(crc >> (8 * i));
}

#endif
