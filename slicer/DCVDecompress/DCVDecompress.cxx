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
// DCVDecompress, a 3D Slicer command-line module: a .dcv file into a volume, decoded as `dcv decompress`
// decodes it. Its parameters are those of DCVDecompress.xml.
#include "DCVDecompressXML.h"
#include "dcvSlicerModule.h"
#include "dcvTools.h"

int
main(int argc, char * argv[])
{
  using namespace dcv::tools;
  return dcv::slicer::RunModule(DCVDecompressXML, argc, argv, [](dcv::slicer::Arguments & arguments) {
    const std::string         input = arguments.String("inputFile");
    const std::string         output = arguments.String("outputVolume");
    const dcv::CompressedFile file = dcv::ReadCompressedFile(input);
    CheckOutput(output, true);

    dcv::slicer::SlicerProgress progress("DCV Decompress", "Decoding " + input + " into " + output);
    progress.Report(0.1);
    DecodeVolume(file, [&](auto image) {
      progress.Report(0.7);
      WriteVolume(image.GetPointer(), output, true); // Slicer chooses the names it reads back
    });
    arguments.Return("outputPoints", int64_t(file.header.numberOfPoints));
    arguments.Return("outputBitsPerVoxel", double(file.size) * 8.0 / double(file.header.size.NumberOfVoxels()));
    progress.End();
  });
}
