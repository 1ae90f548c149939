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
// libFuzzer target of the one decode path every reader takes: ParseFile -> DecodeVolume, on the
// ITK-free core (Debian's ITK 5.2 headers refuse clang). Built by scripts/fuzz.sh twice: as is (the CRC-32
// guards everything behind the header), and with DCV_FUZZ_FIX_CRC, which rewrites the last 4 bytes of each
// input as the CRC-32 of the others, so that mutations reach the field checks and the payload decoder.
// Anything but a FormatError (a crash, a sanitizer report, another exception, a hang, an oom) is a finding.
#include "dcvCodec.h"
#include "dcvFileFormat.h"
#include "dcvFuzzCrc.h"

#include <cstdint>
#include <cstdlib>
#include <vector>

extern "C" int
LLVMFuzzerTestOneInput(const uint8_t * data, size_t size)
{
  std::vector<uint8_t> bytes(data, data + size);
#ifdef DCV_FUZZ_FIX_CRC
  FixCrc32(bytes);
#endif
  // The decoder's own limit keeps every input within libFuzzer's memory and time limits: a file that
  // needs more is refused before anything is allocated, which is what this target checks.
  const dcv::DecodeLimits limits{ uint64_t(64) << 20 };
  try
  {
    dcv::CompressedFile file;
    file.name = "'fuzz.dcv'";
    file.size = bytes.size();
    dcv::ParseFile(bytes, file.name, file.header, file.payload);
    dcv::CheckDecodingMemory(file.header, file.name, dcv::DecodeOutput::Volume, limits); // before the volume
    dcv::VisitPixelType(file.header.pixelType, [&](auto pixel) {
      std::vector<decltype(pixel)> volume(file.header.size.NumberOfVoxels());
      dcv::DecodeVolume(file, volume.data(), limits, 1);
    });
  }
  catch (const dcv::FormatError &)
  {
    // A refusal with a message: the expected outcome for damaged input.
  }
  return 0;
}
