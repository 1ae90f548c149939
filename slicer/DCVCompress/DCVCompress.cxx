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
// DCVCompress, a 3D Slicer command-line module: a volume into a .dcv file, through the library's encoder
// (as `dcv compress`). Its parameters are those of DCVCompress.xml.
#include "DCVCompressXML.h"
#include "dcvSlicerModule.h"
#include "dcvTools.h"
#include "itkDCVEncoder.h"

int
main(int argc, char * argv[])
{
  using namespace dcv::tools;
  return dcv::slicer::RunModule(DCVCompressXML, argc, argv, [](dcv::slicer::Arguments & arguments) {
    const std::string   input = arguments.String("inputVolume");
    const std::string   output = arguments.String("outputFile");
    dcv::EncoderOptions options = dcv::slicer::EncoderOptionsFrom(arguments);
    options.maximumError = arguments.Double("maxError");
    if (options.maximumError >= 0.0) // the bound replaces the module's other targets
      options.bitsPerVoxel = options.psnr = 0.0;
    const VolumeInput volume = OpenVolume(input);
    CheckOutput(output, true, true);

    dcv::slicer::SlicerProgress progress("DCV Compress", "Compressing " + input + " into " + output);
    options.metadata = volume.metadata;
    options.progress = progress.Stage(0.05, 0.95);
    dcv::EncoderResult result;
    dcv::VisitPixelType(volume.type, [&](auto pixel) {
      const auto image = ReadVolume<decltype(pixel)>(volume);
      progress.Report(0.05);
      try
      {
        result = itk::DCVEncode(image.GetPointer(), options);
      }
      catch (const itk::ExceptionObject & e)
      {
        throw Failure("cannot compress " + Quoted(input) + ": " + e.GetDescription());
      }
      catch (const std::exception & e)
      {
        throw Failure("cannot compress " + Quoted(input) + ": " + e.what());
      }
    });
    dcv::WriteFileAtomically(output, result.bytes);
    dcv::slicer::ReturnEncoderFigures(arguments, result);
    progress.End();
  });
}
