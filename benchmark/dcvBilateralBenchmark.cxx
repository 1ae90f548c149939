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
// dcvBilateralBenchmark: I* as the encoder makes it (domain sigma 1 voxel, kernel 1.5 sigma, range sigma
// 8% of the volume's range), by ITK's BilateralImageFilter and by DCVBilateralImageFilter in turn, on
// the volume's own pixel type. Prints one Markdown table row per volume: the seconds of each (the
// better of RUNS runs) and whether every voxel has the same bits.
//
// Usage: dcvBilateralBenchmark [--runs N] [--threads N] VOLUME...   (a file ITK reads, or a DICOM
// series' directory is not taken: convert it first with `dcv convert`)
#include "itkDCVBilateralImageFilter.h"
#include "itkImageFileReader.h"
#include "itkMinimumMaximumImageCalculator.h"
#include "itkMultiThreaderBase.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>

namespace
{
using OutputImage = itk::Image<float, 3>;

template <typename TPixel>
void
Measure(const std::string & file, int runs, unsigned threads)
{
  using InputImage = itk::Image<TPixel, 3>;
  const auto image = itk::ReadImage<InputImage>(file);
  auto       range = itk::MinimumMaximumImageCalculator<InputImage>::New();
  range->SetImage(image);
  range->Compute();
  const double rangeSigma = 0.08 * (double(range->GetMaximum()) - double(range->GetMinimum()));
  typename itk::BilateralImageFilter<InputImage, OutputImage>::ArrayType sigmas;
  for (unsigned d = 0; d < 3; ++d)
    sigmas[d] = image->GetSpacing()[d];
  double               seconds[2] = { 1e300, 1e300 };
  OutputImage::Pointer outputs[2];
  for (int run = 0; run < runs; ++run)
  {
    for (int k = 0; k < 2; ++k)
    {
      typename itk::BilateralImageFilter<InputImage, OutputImage>::Pointer filter;
      if (k == 0)
        filter = itk::BilateralImageFilter<InputImage, OutputImage>::New();
      else
        filter = itk::DCVBilateralImageFilter<InputImage, OutputImage>::New();
      filter->SetInput(image);
      filter->SetDomainSigma(sigmas);
      filter->SetDomainMu(1.5); // the encoder's kernel (itkDCVEncoder.h)
      filter->SetRangeSigma(rangeSigma > 0.0 ? rangeSigma : 1.0);
      filter->SetNumberOfWorkUnits(threads);
      const auto start = std::chrono::steady_clock::now();
      filter->Update();
      seconds[k] =
        std::min(seconds[k], std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
      outputs[k] = filter->GetOutput();
      outputs[k]->DisconnectPipeline();
    }
  }
  const auto voxels = image->GetBufferedRegion().GetNumberOfPixels();
  const bool same =
    std::memcmp(outputs[0]->GetBufferPointer(), outputs[1]->GetBufferPointer(), voxels * sizeof(float)) == 0;
  const auto slash = file.find_last_of('/');
  std::printf("| %s | %zu | %u | %.3f | %.3f | %.2f | %s |\n",
              file.substr(slash == std::string::npos ? 0 : slash + 1).c_str(),
              std::size_t(voxels),
              threads,
              seconds[0],
              seconds[1],
              seconds[0] / seconds[1],
              same ? "yes" : "NO");
  if (!same)
    throw std::runtime_error(file + ": DCVBilateralImageFilter differs from BilateralImageFilter");
}
} // namespace

int
main(int argc, char * argv[])
{
  int      runs = 1;
  unsigned threads = itk::MultiThreaderBase::GetGlobalDefaultNumberOfThreads();
  int      i = 1;
  for (; i + 1 < argc && std::strncmp(argv[i], "--", 2) == 0; i += 2)
  {
    if (std::strcmp(argv[i], "--runs") == 0)
      runs = std::max(1, std::atoi(argv[i + 1]));
    else if (std::strcmp(argv[i], "--threads") == 0)
      threads = unsigned(std::max(1, std::atoi(argv[i + 1])));
    else
      break;
  }
  if (i >= argc)
  {
    std::fprintf(stderr, "usage: dcvBilateralBenchmark [--runs N] [--threads N] VOLUME...\n");
    return 2;
  }
  itk::MultiThreaderBase::SetGlobalDefaultNumberOfThreads(threads);
  std::printf(
    "| volume | voxels | threads | ITK BilateralImageFilter s | DCVBilateralImageFilter s | ratio | same bits |\n");
  std::printf("|---|---:|---:|---:|---:|---:|---|\n");
  try
  {
    for (; i < argc; ++i)
    {
      const std::string file = argv[i];
      auto              io = itk::ImageIOFactory::CreateImageIO(file.c_str(), itk::CommonEnums::IOFileMode::ReadMode);
      if (!io)
        throw std::runtime_error(file + ": not an image ITK reads");
      io->SetFileName(file);
      io->ReadImageInformation();
      switch (io->GetComponentType())
      {
        case itk::IOComponentEnum::UCHAR:
          Measure<uint8_t>(file, runs, threads);
          break;
        case itk::IOComponentEnum::SHORT:
          Measure<int16_t>(file, runs, threads);
          break;
        case itk::IOComponentEnum::USHORT:
          Measure<uint16_t>(file, runs, threads);
          break;
        default:
          Measure<float>(file, runs, threads);
          break;
      }
    }
  }
  catch (const std::exception & e)
  {
    std::fprintf(stderr, "dcvBilateralBenchmark: %s\n", e.what());
    return 1;
  }
  return 0;
}
