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
// dcvDecodeBenchmark: times the one decode path of every reader on .dcv files, stage by stage (parse and
// CRC, points and tetrahedra, rasterization, residual layer added), in memory: no output file, so that the
// figures are the decoder's own. Prints one Markdown table row per file (medians of RUNS runs).
//
// Usage: dcvDecodeBenchmark [--runs N] [--threads N] FILE.dcv...
#include "dcvApproximation.h"
#include "dcvCodec.h"
#include "dcvFileFormat.h"
#include "dcvResidualLayer.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <vector>

#include <sys/resource.h>

namespace
{
using Clock = std::chrono::steady_clock;

double
Since(Clock::time_point start)
{
  return std::chrono::duration<double>(Clock::now() - start).count();
}

double
Median(std::vector<double> v)
{
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double
PeakResidentMiB()
{
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return double(usage.ru_maxrss) / 1024.0; // KiB on Linux
}

struct Stages
{
  std::vector<double> parse, mesh, residual, rasterize, total;
};

/** One decode of the file's bytes into a buffer of its pixel type, as dcv::DecodeVolume does it, with
 * each stage timed: the mesh, its rasterization, then the residual layer decoded and added row by row. */
void
DecodeOnce(const std::string & path, const std::vector<uint8_t> & bytes, unsigned int threads, Stages & s)
{
  const auto          start = Clock::now();
  dcv::CompressedFile file;
  file.name = path;
  file.size = bytes.size();
  dcv::ParseFile(bytes, path, file.header, file.payload);
  s.parse.push_back(Since(start));

  auto                     t = Clock::now();
  const dcv::Approximation a = dcv::DecodeMesh(file);
  s.mesh.push_back(Since(t));

  const dcv::FileHeader & h = file.header;
  dcv::VisitPixelType(h.pixelType, [&](auto pixel) {
    using T = decltype(pixel);
    t = Clock::now();
    std::vector<T> out(a.grid.NumberOfVoxels());
    dcv::Rasterize(a, out.data(), threads);
    s.rasterize.push_back(Since(t));
    t = Clock::now();
    if (h.residualStep > 0.0)
    {
      dcv::DecodeResidualRows(
        h.residualLayer, h.size, path, h.residualLevels, [&](int32_t y, int32_t z, const int32_t * row) {
          dcv::detail::AddResidualToRow(h.residualStep, row, out.data() + h.size.Offset(0, y, z), uint64_t(h.size.x));
        });
    }
    s.residual.push_back(Since(t));
  });
  s.total.push_back(Since(start));
}
} // namespace

int
main(int argc, char * argv[])
{
  int                      runs = 5;
  int                      threads = 0; // 0: one per core
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i)
  {
    const std::string arg = argv[i];
    if ((arg == "--runs" || arg == "--threads") && i + 1 < argc)
      (arg == "--runs" ? runs : threads) = std::atoi(argv[++i]);
    else if (!arg.empty() && arg[0] == '-')
    {
      std::fprintf(stderr, "usage: dcvDecodeBenchmark [--runs N] [--threads N] FILE.dcv...\n");
      return 2;
    }
    else
      files.push_back(arg);
  }
  if (files.empty() || runs < 1 || threads < 0)
  {
    std::fprintf(stderr, "usage: dcvDecodeBenchmark [--runs N] [--threads N] FILE.dcv...\n");
    return 2;
  }
  std::printf("| file | size | points | bytes | parse s | points and cells s | residual layer s | rasterize s | "
              "decode s | Mvoxels/s | peak RSS MiB |\n");
  std::printf("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  try
  {
    for (const std::string & path : files)
    {
      const std::vector<uint8_t> bytes = dcv::ReadWholeFile(path);
      Stages                     s;
      for (int r = 0; r < runs; ++r)
        DecodeOnce(path, bytes, unsigned(threads), s);
      dcv::FileHeader      h;
      std::vector<uint8_t> payload;
      dcv::ParseFile(bytes, path, h, payload);
      const double voxels = double(h.size.NumberOfVoxels());
      std::printf("| %s | %dx%dx%d | %u | %zu | %.3f | %.3f | %.3f | %.3f | %.3f | %.1f | %.0f |\n",
                  path.substr(path.find_last_of('/') + 1).c_str(),
                  h.size.x,
                  h.size.y,
                  h.size.z,
                  h.numberOfPoints,
                  bytes.size(),
                  Median(s.parse),
                  Median(s.mesh),
                  Median(s.residual),
                  Median(s.rasterize),
                  Median(s.total),
                  voxels / Median(s.total) / 1e6,
                  PeakResidentMiB());
      std::fflush(stdout);
    }
  }
  catch (const std::exception & e)
  {
    std::fprintf(stderr, "dcvDecodeBenchmark: %s\n", e.what());
    return 1;
  }
  return 0;
}
