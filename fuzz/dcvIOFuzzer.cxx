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
// libFuzzer target of the ITK entry points: DCVImageIO and DCVMeshIO CanReadFile / ReadImageInformation
// (ReadMeshInformation) / Read (ReadPoints, ReadCells, ReadPointData) on each input written to a .dcv file.
// This driver and the ITK-free core are built by clang (coverage, ASan, UBSan); the ITK side is
// fuzz/dcvIOFuzzShim.cxx with src/itk/itkDCV*IO.cxx, built by g++ (Debian's ITK 5.2 headers refuse clang).
// scripts/fuzz.sh builds it twice: as is (target io) and with DCV_FUZZ_FIX_CRC (io-crc), which rewrites
// the CRC-32 so that the payload decoder is reached.
#include "dcvFuzzCrc.h"

#include <cstddef>
#include <cstdint>
#include <vector>

extern "C" int
dcvFuzzReadWithITK(const uint8_t * data, size_t size);

extern "C" int
LLVMFuzzerTestOneInput(const uint8_t * data, size_t size)
{
#ifdef DCV_FUZZ_FIX_CRC
  std::vector<uint8_t> bytes(data, data + size);
  FixCrc32(bytes);
  return dcvFuzzReadWithITK(bytes.data(), bytes.size());
#else
  return dcvFuzzReadWithITK(data, size);
#endif
}
