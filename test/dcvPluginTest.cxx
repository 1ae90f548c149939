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
// A program that does not link DelaunayCompression: with the plugin's directory in ITK_AUTOLOAD_PATH,
// ImageFileReader and ImageFileWriter still handle .dcv files.
//
//   dcvPluginTest INPUT.dcv OUTPUT.dcv   exits 0 when the file was read by DCVImageIO and written again
#include "itkImageFileReader.h"
#include "itkImageFileWriter.h"

#include <iostream>

int
main(int argc, char * argv[])
{
  if (argc != 3)
  {
    std::cerr << "Usage: " << argv[0] << " INPUT.dcv OUTPUT.dcv" << std::endl;
    return 2;
  }
  using ImageType = itk::Image<float, 3>;
  try
  {
    auto reader = itk::ImageFileReader<ImageType>::New();
    reader->SetFileName(argv[1]);
    reader->Update();
    const std::string io = reader->GetImageIO()->GetNameOfClass();
    if (io != "DCVImageIO")
    {
      std::cerr << argv[1] << " was read by " << io << std::endl;
      return 1;
    }
    itk::WriteImage(reader->GetOutput(), argv[2]);
  }
  catch (const itk::ExceptionObject & e)
  {
    std::cerr << e.GetDescription() << std::endl;
    return 1;
  }
  std::cout << "read " << argv[1] << " and wrote " << argv[2] << " through the plugin" << std::endl;
  return 0;
}
