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
// dcv approximate: the approximation itself, written with the input's geometry and pixel type.
#include "dcvCommand.h"
#include "itkDCVEncoder.h"

#include <iostream>

namespace dcv::tools
{
namespace
{
struct ApproximateOptions
{
  std::string   input;
  std::string   output;
  MethodOptions method;
  CLI::Option * points{ nullptr };
};

void
Approximate(const ApproximateOptions & a)
{
  EncoderOptions options = a.method.Checked("approximating");
  WithVolume(a.input, a.method.series, a.output, a.method, false, [&](auto image, const VolumeInput &) {
    using T = typename decltype(image)::ObjectType::PixelType;
    CheckFiniteVoxels(image.GetPointer(), a.input);
    DefaultPointsForVolume(options, a.points, image->GetBufferedRegion().GetNumberOfPixels());
    const auto    start = std::chrono::steady_clock::now();
    EncoderResult r;
    try
    {
      r = itk::DCVApproximate(image.GetPointer(), options);
    }
    catch (const std::exception & e)
    {
      throw Failure("cannot approximate " + Quoted(a.input) + ": " + e.what());
    }
    auto result = itk::Image<T, 3>::New();
    result->CopyInformation(image);
    result->SetRegions(image->GetLargestPossibleRegion());
    result->Allocate();
    Rasterize(r.approximation, result->GetBufferPointer());
    const double seconds = SecondsSince(start);
    const auto   n = image->GetBufferedRegion().GetNumberOfPixels();
    const double psnr = PSNR(SquaredError(image->GetBufferPointer(), result->GetBufferPointer(), n),
                             n,
                             PSNRPeak(image->GetBufferPointer(), n));
    WriteVolume(result.GetPointer(), a.output, a.method.force);
    if (!a.method.quiet)
    {
      std::cout << "mode: " << ModeName(options.mode) << "\n"
                << "points: " << r.approximation.points.size() << "\n"
                << "PSNR: " << FormatPSNR(psnr) << "\n"
                << "seconds: " << seconds << "\n";
    }
  });
}

const RegisterCommand approximate{
  { "approximate",
    "Approximate a volume by a linear spline over an adaptive Delaunay "
    "tetrahedralization and write the approximation with the input's geometry and "
    "pixel type; prints points, PSNR and seconds",
    [](CLI::App & command) -> std::function<void()> {
      auto a = std::make_shared<ApproximateOptions>();
      AddMethodOptions(command, a->input, a->method);
      command.add_option("OUTPUT", a->output, "Output volume (format from its extension)")->required();
      a->points =
        command
          .add_option("--points,-n", a->method.encoder.numberOfPoints, "Number of significant points (at least 8)")
          ->check(CLI::NonNegativeNumber)
          ->capture_default_str();
      return [a] { Approximate(*a); };
    } }
};
} // namespace
} // namespace dcv::tools
