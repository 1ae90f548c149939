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
// dcvAblation: the paper's Table 1. Rows: volumes; columns: the modes silva, dec, dec+com and best,
// each as PSNR in dB and seconds (the whole filter, bilateral smoothing included).
//
// Usage: dcvAblation [--voxels-per-point V | --bpv R] VOLUME...
//   --voxels-per-point V: equal point counts, points = voxels / V (default V = 600: about what 0.03125
//                         bits per voxel affords); PSNR of the unrounded spline
//   --bpv R:              equal file sizes, as dcv compress --bpv R (rate control chooses the point
//                         count and the step); PSNR of the decoded image, what dcv decompress writes
#include "dcvApproximation.h"
#include "dcvTools.h"
#include "itkDelaunayApproximationImageToMeshFilter.h"

#include "itkImageFileReader.h"
#include "itkMesh.h"
#include "itkTetrahedralMeshToImageFilter.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

namespace
{
using MeshType = itk::Mesh<double, 3>;
constexpr dcv::Mode modes[] = { dcv::Mode::Silva, dcv::Mode::Dec, dcv::Mode::DecCom, dcv::Mode::Best };

template <typename TPixel>
void
Row(const std::string & path, double voxelsPerPoint, double bpv)
{
  using ImageType = itk::Image<TPixel, 3>;
  auto         image = itk::ReadImage<ImageType>(path);
  const auto   n = image->GetLargestPossibleRegion().GetNumberOfPixels();
  const auto   points = std::max<std::size_t>(8, std::size_t(double(n) / voxelsPerPoint));
  const double peak = dcv::PSNRPeak(image->GetBufferPointer(), n);
  const auto   size = image->GetLargestPossibleRegion().GetSize();
  std::printf("| %s | %lux%lux%lu |", std::filesystem::path(path).filename().c_str(), size[0], size[1], size[2]);
  if (bpv > 0.0)
    std::printf(" %.0f |", std::floor(bpv * double(n) / 8.0));
  else
    std::printf(" %zu |", points);
  std::string split;
  for (dcv::Mode mode : modes)
  {
    auto filter = itk::DelaunayApproximationImageToMeshFilter<ImageType, MeshType>::New();
    filter->SetInput(image);
    filter->SetNumberOfPoints(points);
    filter->SetMode(mode);
    if (bpv > 0.0)
    {
      filter->SetBitsPerVoxel(bpv); // and QuantizationStep 0: rate control chooses it, as dcv compress
    }
    const auto start = std::chrono::steady_clock::now();
    filter->Update();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (bpv > 0.0)
    {
      auto rasterize = itk::TetrahedralMeshToImageFilter<MeshType, ImageType>::New();
      rasterize->SetInput(filter->GetOutput());
      rasterize->SetReferenceImage(image);
      rasterize->Update();
      const double error = dcv::SquaredError(image->GetBufferPointer(), rasterize->GetOutput()->GetBufferPointer(), n);
      std::printf(" %.2f (%lu, %g, %.1f s) |",
                  dcv::PSNR(error, n, peak),
                  filter->GetOutput()->GetNumberOfPoints(),
                  filter->GetChosenQuantizationStep(),
                  seconds);
    }
    else
    {
      std::printf(" %.2f (%.1f s) |", dcv::PSNR(filter->GetSquaredError(), n, peak), seconds);
    }
    std::fflush(stdout);
    if (mode == dcv::Mode::Best)
    {
      const auto & t = filter->GetTimings();
      char         text[200];
      std::snprintf(text,
                    sizeof(text),
                    "  best: smoothing %.1f s, refinement %.1f s, decimation %.1f s, least squares %.1f s; "
                    "PSNR(I*) %.2f dB",
                    t.smoothing,
                    t.refinement,
                    t.decimation,
                    t.leastSquares,
                    filter->GetSmoothedPSNR());
      split = text;
    }
  }
  std::printf("\n");
  std::cerr << std::filesystem::path(path).filename().string() << split << std::endl;
}
} // namespace

int
main(int argc, char * argv[])
{
  std::vector<std::string> volumes;
  double                   voxelsPerPoint = 600.0;
  double                   bpv = 0.0;
  for (int i = 1; i < argc; ++i)
  {
    const std::string a = argv[i];
    if (a == "--voxels-per-point" && i + 1 < argc)
    {
      voxelsPerPoint = std::stod(argv[++i]);
    }
    else if (a == "--bpv" && i + 1 < argc)
    {
      bpv = std::stod(argv[++i]);
    }
    else
    {
      volumes.push_back(a);
    }
  }
  if (volumes.empty() || !(voxelsPerPoint >= 1.0) || !(bpv >= 0.0))
  {
    std::cerr << "usage: dcvAblation [--voxels-per-point V | --bpv R] VOLUME..." << std::endl;
    return 1;
  }
  std::printf("| volume | size | %s | silva dB (s) | dec | dec+com | best |\n|---|---|---:|---:|---:|---:|---:|\n",
              bpv > 0.0 ? "bytes" : "points");
  for (const auto & path : volumes)
  {
    try
    {
      dcv::VisitPixelType(dcv::tools::ReadVolumePixelType(path),
                          [&](auto pixel) { Row<decltype(pixel)>(path, voxelsPerPoint, bpv); });
    }
    catch (const std::exception & e)
    {
      std::cerr << "dcvAblation: " << e.what() << std::endl;
      return 1;
    }
  }
  return 0;
}
