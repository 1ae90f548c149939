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
// dcvBoundedBenchmark: the bounded-error layer alone (dcv::EncodeBoundedLayer, dcv::DecodeBoundedLayer) on a
// raw volume in memory, the input dcvCharlsPeer takes, so that scripts/lossless_speed.py times both on the same
// samples. Checks that the decoder gives the encoder's samples and that every one is within NEAR of the input.
//
// Usage: dcvBoundedBenchmark IN.raw WIDTH HEIGHT SLICES BITS NEAR [THREADS]
//
// IN.raw: unsigned samples, x fastest, then y, then z; one byte each for BITS <= 8, else two bytes little-endian.
// THREADS: 0 (default) one per core. Prints the layer's bytes and the seconds of one encode and one decode.
#include "dcvBoundedLayer.h"

#include <tbb/task_arena.h>

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
  std::fprintf(stderr, "usage: dcvBoundedBenchmark IN.raw WIDTH HEIGHT SLICES BITS NEAR [THREADS]\n");
  return 2;
}
} // namespace

int
main(int argc, char * argv[])
{
  if (argc != 7 && argc != 8)
  {
    return Usage();
  }
  try
  {
    dcv::GridSize grid;
    grid.x = std::stoi(argv[2]);
    grid.y = std::stoi(argv[3]);
    grid.z = std::stoi(argv[4]);
    const int bits = std::stoi(argv[5]);
    const int nearLossless = std::stoi(argv[6]);
    const int threads = argc == 8 ? std::stoi(argv[7]) : 0;
    if (grid.x <= 0 || grid.y <= 0 || grid.z <= 0 || bits < 1 || bits > 16 || nearLossless < 0 || threads < 0)
    {
      return Usage();
    }
    const std::size_t voxels = grid.NumberOfVoxels();
    const std::size_t bytesPerSample = bits <= 8 ? 1 : 2;

    std::ifstream              in(argv[1], std::ios::binary);
    const std::vector<uint8_t> raw{ std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>() };
    if (!in.is_open() || raw.size() != voxels * bytesPerSample)
    {
      std::fprintf(stderr,
                   "dcvBoundedBenchmark: %s: expected %zu bytes, read %zu\n",
                   argv[1],
                   voxels * bytesPerSample,
                   raw.size());
      return 1;
    }
    std::vector<int32_t> input(voxels);
    for (std::size_t i = 0; i < voxels; ++i)
    {
      input[i] = bytesPerSample == 1 ? raw[i] : int32_t(raw[2 * i] | (raw[2 * i + 1] << 8));
    }

    tbb::task_arena      arena(threads == 0 ? tbb::task_arena::automatic : threads);
    std::vector<int32_t> encoded = input; // the encoder leaves the decoded samples in place
    std::vector<uint8_t> layer;
    auto                 start = Clock::now();
    arena.execute([&] { layer = dcv::EncodeBoundedLayer(encoded.data(), grid, uint32_t(nearLossless), nearLossless); });
    const double encodeSeconds = Since(start);

    dcv::ResidualSamples decoded;
    start = Clock::now();
    arena.execute([&] { decoded = dcv::DecodeBoundedLayer(layer, grid, argv[1]); });
    const double decodeSeconds = Since(start);

    for (std::size_t i = 0; i < voxels; ++i)
    {
      if (decoded[i] != encoded[i] || std::abs(decoded[i] - input[i]) > nearLossless)
      {
        std::fprintf(stderr,
                     "dcvBoundedBenchmark: voxel %zu: input %d, encoder %d, decoder %d\n",
                     i,
                     input[i],
                     encoded[i],
                     decoded[i]);
        return 1;
      }
    }
    std::printf("bytes %zu\nencode_seconds %.6f\ndecode_seconds %.6f\nthreads %d\n",
                layer.size(),
                encodeSeconds,
                decodeSeconds,
                arena.max_concurrency());
    return 0;
  }
  catch (const std::exception & e)
  {
    std::fprintf(stderr, "dcvBoundedBenchmark: %s\n", e.what());
    return 1;
  }
}
