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
// dcvCharlsPeer: the JPEG-LS peer of scripts/lossless_benchmark.py. Codes every z slice of a raw volume as its
// own JPEG-LS image with CharLS at a given NEAR (0: lossless), as a DICOM toolkit stores a JPEG-LS series (one
// frame per slice), decodes every slice back and writes the decoded volume, so that the script checks the
// error bound on every voxel itself. Debian ships CharLS as a library only (libcharls-dev), no command-line tool.
//
// Usage: dcvCharlsPeer --version
//        dcvCharlsPeer IN.raw WIDTH HEIGHT SLICES BITS NEAR OUT.raw
//
// IN.raw and OUT.raw: unsigned samples, x fastest, then y, then z; one byte each for BITS <= 8, else two bytes
// little-endian (the host order CharLS reads: x86 and ARM). Prints the sum of the slices' JPEG-LS stream bytes
// (what the .jls files would hold) and the seconds spent in CharLS's encoder and decoder.
#include <charls/charls.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace
{
using Clock = std::chrono::steady_clock;

double
Since(Clock::time_point start)
{
  return std::chrono::duration<double>(Clock::now() - start).count();
}

int
Usage()
{
  std::fprintf(stderr,
               "usage: dcvCharlsPeer --version\n"
               "       dcvCharlsPeer IN.raw WIDTH HEIGHT SLICES BITS NEAR OUT.raw\n");
  return 2;
}
} // namespace

int
main(int argc, char * argv[])
{
  if (argc == 2 && std::string(argv[1]) == "--version")
  {
    std::printf("CharLS %s\n", charls_get_version_string());
    return 0;
  }
  if (argc != 8)
  {
    return Usage();
  }
  try
  {
    const auto width = static_cast<uint32_t>(std::stoul(argv[2]));
    const auto height = static_cast<uint32_t>(std::stoul(argv[3]));
    const auto slices = static_cast<size_t>(std::stoul(argv[4]));
    const auto bits = static_cast<int32_t>(std::stoi(argv[5]));
    const auto nearLossless = static_cast<int32_t>(std::stoi(argv[6]));
    if (width == 0 || height == 0 || bits < 2 || bits > 16 || nearLossless < 0)
    {
      return Usage();
    }
    const size_t sliceBytes = size_t{ width } * height * (bits <= 8 ? 1 : 2);

    std::ifstream              in(argv[1], std::ios::binary);
    const std::vector<uint8_t> volume{ std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>() };
    if (!in.is_open() || volume.size() != sliceBytes * slices)
    {
      std::fprintf(
        stderr, "dcvCharlsPeer: %s: expected %zu bytes, read %zu\n", argv[1], sliceBytes * slices, volume.size());
      return 1;
    }

    std::vector<uint8_t> decoded(volume.size());
    std::vector<uint8_t> stream;
    size_t               total = 0;
    double               encodeSeconds = 0;
    double               decodeSeconds = 0;
    for (size_t k = 0; k < slices; ++k)
    {
      const uint8_t *        slice = volume.data() + k * sliceBytes;
      auto                   start = Clock::now();
      charls::jpegls_encoder encoder;
      encoder.frame_info({ width, height, bits, 1 }).near_lossless(nearLossless);
      stream.resize(encoder.estimated_destination_size());
      encoder.destination(stream);
      const size_t bytes = encoder.encode(slice, sliceBytes);
      encodeSeconds += Since(start);
      total += bytes;

      start = Clock::now();
      const charls::jpegls_decoder decoder(stream.data(), bytes, true);
      decoder.decode(decoded.data() + k * sliceBytes, sliceBytes);
      decodeSeconds += Since(start);
    }

    std::ofstream out(argv[7], std::ios::binary);
    out.write(reinterpret_cast<const char *>(decoded.data()), static_cast<std::streamsize>(decoded.size()));
    if (!out.flush())
    {
      std::fprintf(stderr, "dcvCharlsPeer: cannot write %s\n", argv[7]);
      return 1;
    }
    std::printf("bytes %zu\nencode_seconds %.6f\ndecode_seconds %.6f\n", total, encodeSeconds, decodeSeconds);
    return 0;
  }
  catch (const std::exception & e)
  {
    std::fprintf(stderr, "dcvCharlsPeer: %s\n", e.what());
    return 1;
  }
}
