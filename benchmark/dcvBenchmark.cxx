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
// dcvBenchmark: times the encoder (RefinementEngine) and the decoder (Tetrahedralize + Rasterize) on
// one volume for increasing point counts, and prints one Markdown table row per count.
//
// Usage: dcvBenchmark [--no-header] VOLUME N1 [N2 ...]
#include "dcvApproximation.h"
#include "dcvRefinementEngine.h"
#include "dcvTools.h"

#include "itkImage.h"
#include "itkImageFileReader.h"
#include "itkImageIOFactory.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <sys/resource.h>

namespace fs = std::filesystem;

namespace
{
using ImageType = itk::Image<float, 3>;
using Clock = std::chrono::steady_clock;

using dcv::tools::Failure; // printed as "dcvBenchmark: message" with exit status 1
using dcv::tools::Quoted;

struct Volume
{
  ImageType::Pointer image;
  dcv::GridSize      grid;
  bool               eightBit{ false };
};

/** Reads a scalar 3D volume as float; the header tells whether the file holds 8-bit data, which
 * fixes the PSNR peak at 255 (the project's convention). */
Volume
ReadVolume(const std::string & path)
{
  const auto io = dcv::tools::ReadVolumeHeader(path);

  Volume     volume;
  const auto component = io->GetComponentType();
  volume.eightBit = component == itk::IOComponentEnum::UCHAR || component == itk::IOComponentEnum::CHAR;

  auto reader = itk::ImageFileReader<ImageType>::New();
  reader->SetFileName(path);
  try
  {
    reader->Update();
  }
  catch (const itk::ExceptionObject & e)
  {
    throw Failure("cannot read " + Quoted(path) + ": " + e.GetDescription());
  }
  volume.image = reader->GetOutput();
  const auto size = volume.image->GetBufferedRegion().GetSize();
  for (unsigned int d = 0; d < 3; ++d)
  {
    if (size[d] < 2 || size[d] > itk::SizeValueType(dcv::MaximumGridExtent))
    {
      throw Failure(Quoted(path) + " is " + std::to_string(size[0]) + "x" + std::to_string(size[1]) + "x" +
                    std::to_string(size[2]) + " voxels; each axis needs 2 to " +
                    std::to_string(dcv::MaximumGridExtent) + " voxels");
    }
  }
  volume.grid = { int32_t(size[0]), int32_t(size[1]), int32_t(size[2]) };
  return volume;
}

/** A point count: a whole number of at least 8 (the corners of the volume). */
std::size_t
ParseCount(const std::string & text)
{
  std::size_t        used = 0;
  unsigned long long value = 0;
  try
  {
    value = std::stoull(text, &used);
  }
  catch (const std::exception &)
  {
    used = 0;
  }
  if (used == 0 || used != text.size() || text[0] == '-' || value < 8)
  {
    throw Failure("point count " + Quoted(text) + " is not a whole number of at least 8");
  }
  return std::size_t(value);
}

double
SecondsSince(Clock::time_point start)
{
  return std::chrono::duration<double>(Clock::now() - start).count();
}

/** Peak resident set size of the process so far, in bytes (ru_maxrss is in KiB on Linux). */
double
PeakResidentBytes()
{
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return double(usage.ru_maxrss) * 1024.0;
}

void
PrintHeader()
{
  std::printf("| volume | size | points | PSNR dB | engine s | decode s | decode Mvoxels/s | peak RSS MB | "
              "peak bytes/voxel |\n");
  std::printf("|---|---|---:|---:|---:|---:|---:|---:|---:|\n");
}

int
Usage()
{
  std::cerr << "usage: dcvBenchmark [--no-header] VOLUME N1 [N2 ...]\n"
               "  Encodes VOLUME with N1, N2, ... significant points, decodes each result and prints a Markdown\n"
               "  table row per count: PSNR, encoder and decoder seconds, decoder throughput and peak memory.\n";
  return 1;
}

/** Runs the encoder and the decoder for each count; returns false on a decoder mismatch. */
bool
Benchmark(const std::string & path, const Volume & volume, const std::vector<std::size_t> & counts)
{
  const dcv::GridSize & grid = volume.grid;
  const uint64_t        voxels = grid.NumberOfVoxels();
  const float *         original = volume.image->GetBufferPointer();
  const auto            range = std::minmax_element(original, original + voxels);
  const double          peak = dcv::PSNRPeak(*range.first, *range.second, volume.eightBit);
  const std::string     name = fs::path(path).filename().string();
  const std::string     size = std::to_string(grid.x) + "x" + std::to_string(grid.y) + "x" + std::to_string(grid.z);

  // Allocated once, so the peak memory reflects the engine rather than repeated buffers.
  std::vector<float> decoded(voxels);
  std::vector<float> reference(voxels);

  for (const std::size_t count : counts)
  {
    auto                  start = Clock::now();
    dcv::RefinementEngine engine(original, grid);
    engine.Refine(count);
    const double engineSeconds = SecondsSince(start);

    const dcv::Approximation encoded = engine.GetApproximation();
    dcv::Approximation       received = encoded;
    received.tetrahedra.clear(); // what a decoder gets: points and values only

    // NaN everywhere, so a voxel that no cell owns cannot pass for a decoded value.
    std::fill(decoded.begin(), decoded.end(), std::numeric_limits<float>::quiet_NaN());
    std::fill(reference.begin(), reference.end(), std::numeric_limits<float>::quiet_NaN());
    // Decoding takes a fraction of a second, so one run is at the mercy of the machine's other work:
    // report the median of three.
    std::vector<double> decodeRuns;
    for (int run = 0; run < 3; ++run)
    {
      received.tetrahedra.clear();
      start = Clock::now();
      dcv::Decode(received, decoded.data());
      decodeRuns.push_back(SecondsSince(start));
    }
    std::sort(decodeRuns.begin(), decodeRuns.end());
    const double decodeSeconds = decodeRuns[1];
    dcv::Rasterize(encoded, reference.data());

    if (std::memcmp(decoded.data(), reference.data(), voxels * sizeof(float)) != 0)
    {
      uint64_t i = 0;
      while (std::memcmp(&decoded[i], &reference[i], sizeof(float)) == 0)
      {
        ++i;
      }
      const uint64_t x = i % uint64_t(grid.x);
      const uint64_t y = (i / uint64_t(grid.x)) % uint64_t(grid.y);
      const uint64_t z = i / (uint64_t(grid.x) * uint64_t(grid.y));
      std::fflush(stdout);
      std::cerr << "MISMATCH: " << name << " with " << engine.GetNumberOfPoints() << " points: the decoder ("
                << received.tetrahedra.size() << " cells) differs from the encoder (" << encoded.tetrahedra.size()
                << " cells) at voxel (" << x << ", " << y << ", " << z << "): " << decoded[i] << " vs " << reference[i]
                << std::endl;
      return false;
    }

    const double psnr = dcv::PSNR(dcv::SquaredError(original, decoded.data(), voxels), voxels, peak);
    const double peakBytes = PeakResidentBytes();
    std::printf("| %s | %s | %zu | %.2f | %.3f | %.3f | %.2f | %.1f | %.1f |\n",
                name.c_str(),
                size.c_str(),
                engine.GetNumberOfPoints(),
                psnr,
                engineSeconds,
                decodeSeconds,
                double(voxels) / decodeSeconds / 1e6,
                peakBytes / (1024.0 * 1024.0),
                peakBytes / double(voxels));
    std::fflush(stdout); // rows appear as they are measured, also through a pipe
  }
  return true;
}
} // namespace

int
main(int argc, char * argv[])
{
  std::vector<std::string> arguments(argv + 1, argv + argc);
  bool                     header = true;
  if (!arguments.empty() && arguments.front() == "--no-header")
  {
    header = false;
    arguments.erase(arguments.begin());
  }
  if (arguments.size() < 2 || arguments.front() == "-h" || arguments.front() == "--help")
  {
    return Usage();
  }

  try
  {
    std::vector<std::size_t> counts;
    for (std::size_t i = 1; i < arguments.size(); ++i)
    {
      counts.push_back(ParseCount(arguments[i]));
    }
    std::sort(counts.begin(), counts.end());

    const std::string & path = arguments.front();
    const Volume        volume = ReadVolume(path);
    if (header)
    {
      PrintHeader();
    }
    return Benchmark(path, volume, counts) ? 0 : 2;
  }
  catch (const Failure & e)
  {
    std::cerr << "dcvBenchmark: " << e.what() << std::endl;
  }
  catch (const itk::ExceptionObject & e)
  {
    std::cerr << "dcvBenchmark: " << Quoted(arguments.front()) << ": " << e.GetDescription() << std::endl;
  }
  catch (const std::exception & e)
  {
    std::cerr << "dcvBenchmark: " << Quoted(arguments.front()) << ": " << e.what() << std::endl;
  }
  return 1;
}
