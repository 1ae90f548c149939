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
// Writes a volume as a .dcv file at a chosen bits per voxel with plain itk::ImageFileWriter, and reads it
// back with itk::ImageFileReader, which finds the .dcv IO by itself:
//
//   WriteReadDCV INPUT OUTPUT.dcv BITS_PER_VOXEL
#include "itkDCVImageIO.h"
#include "itkImageFileReader.h"
#include "itkImageFileWriter.h"

#include <iostream>

int
main(int argc, char * argv[])
{
  if (argc != 4)
  {
    std::cerr << "Usage: " << argv[0] << " INPUT OUTPUT.dcv BITS_PER_VOXEL" << std::endl;
    return EXIT_FAILURE;
  }
  using ImageType = itk::Image<short, 3>;
  auto io = itk::DCVImageIO::New();
  io->SetBitsPerVoxel(std::stod(argv[3])); // or SetPSNR(dB), SetNumberOfPoints(n)
  auto writer = itk::ImageFileWriter<ImageType>::New();
  writer->SetInput(itk::ReadImage<ImageType>(argv[1]));
  writer->SetImageIO(io);
  writer->SetFileName(argv[2]);
  try
  {
    writer->Update();
    const auto decoded = itk::ReadImage<ImageType>(argv[2]);
    std::cout << "PSNR " << io->GetLastEncoderResult().psnr << " dB, " << decoded->GetBufferedRegion().GetSize()
              << " voxels read back" << std::endl;
  }
  catch (const itk::ExceptionObject & e)
  {
    std::cerr << e.GetDescription() << std::endl;
    return EXIT_FAILURE;
  }
  return EXIT_SUCCESS;
}
