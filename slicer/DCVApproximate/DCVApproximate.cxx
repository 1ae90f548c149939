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
// DCVApproximate, a 3D Slicer command-line module: what DCVCompress would give, seen before a rate is
// chosen. The volume is encoded with the same options (no file is written) and the bytes decoded as
// DCVDecompress decodes them; the outputs are that volume and |input - approximation|. Its parameters
// are those of DCVApproximate.xml.
#include "DCVApproximateXML.h"
#include "dcvSlicerModule.h"
#include "dcvTools.h"
#include "itkDCVEncoder.h"

#include <cmath>
#include <filesystem>
#include <type_traits>

namespace
{
/** The error's pixel type: float, or double where float cannot hold every difference exactly. */
template <typename T>
using ErrorPixel =
  std::conditional_t<std::is_same_v<T, double> || (std::is_integral_v<T> && sizeof(T) >= 4), double, float>;
} // namespace

int
main(int argc, char * argv[])
{
  using namespace dcv::tools;
  return dcv::slicer::RunModule(DCVApproximateXML, argc, argv, [](dcv::slicer::Arguments & arguments) {
    const std::string   input = arguments.String("inputVolume");
    const std::string   output = arguments.String("outputVolume");
    const std::string   errorOutput = arguments.String("errorVolume");
    dcv::EncoderOptions options = dcv::slicer::EncoderOptionsFrom(arguments);
    const VolumeInput   volume = OpenVolume(input);
    CheckOutput(output, true);
    CheckOutput(errorOutput, true);
    if (std::filesystem::absolute(output) == std::filesystem::absolute(errorOutput))
    {
      throw Failure("the approximation and the error are both " + Quoted(output) + "; give two files");
    }

    dcv::slicer::SlicerProgress progress("DCV Approximate", "Approximating " + input);
    options.metadata = volume.metadata;
    options.progress = progress.Stage(0.05, 0.9);
    dcv::VisitPixelType(volume.type, [&](auto pixel) {
      using T = decltype(pixel);
      using E = ErrorPixel<T>;
      const auto         image = ReadVolume<T>(volume);
      dcv::EncoderResult result;
      progress.Report(0.05);
      try
      {
        result = itk::DCVEncode(image.GetPointer(), options);
      }
      catch (const itk::ExceptionObject & e)
      {
        throw Failure("cannot approximate " + Quoted(input) + ": " + e.GetDescription());
      }
      catch (const std::exception & e)
      {
        throw Failure("cannot approximate " + Quoted(input) + ": " + e.what());
      }
      const auto approximation = DecodeImage<T>(ParseCompressedBytes(result.bytes, "the encoded volume"));
      progress.Report(0.93);

      auto error = itk::Image<E, 3>::New();
      error->CopyInformation(image);
      error->SetRegions(image->GetLargestPossibleRegion());
      error->Allocate();
      const std::size_t n = image->GetLargestPossibleRegion().GetNumberOfPixels();
      const T *         original = image->GetBufferPointer();
      const T *         decoded = approximation->GetBufferPointer();
      E *               difference = error->GetBufferPointer();
      for (std::size_t i = 0; i < n; ++i)
      {
        difference[i] = E(std::abs(double(original[i]) - double(decoded[i])));
      }

      WriteVolume(approximation.GetPointer(), output, true); // Slicer chooses the names
      try
      {
        WriteVolume(error.GetPointer(), errorOutput, true);
      }
      catch (...)
      {
        std::error_code ignored;
        std::filesystem::remove(output, ignored); // both outputs or neither
        throw;
      }
      dcv::slicer::ReturnEncoderFigures(arguments, result);
    });
    progress.End();
  });
}
