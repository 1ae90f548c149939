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
// Reads a .dcv file as an ordinary ITK image with itk::ImageFileReader, prints what its header holds,
// and writes the decoded volume in any format ITK writes (chosen by OUTPUT's extension):
//
//   ReadDCVImage INPUT.dcv OUTPUT
//
// Nothing here is specific to .dcv files: the package registers its ImageIO in every program that
// links DelaunayCompression::DelaunayCompression, so the reader recognises the file by its extension and
// magic bytes and decodes it (the points, their Delaunay tetrahedralization, the residual layer if any).
#include "itkImageFileReader.h"
#include "itkImageFileWriter.h"
#include "itkImageIOFactory.h"
#include "itkMinimumMaximumImageCalculator.h"

#include <iostream>

int
main(int argc, char * argv[])
{
  if (argc != 3)
  {
    std::cerr << "Usage: " << argv[0] << " INPUT.dcv OUTPUT" << std::endl;
    return EXIT_FAILURE;
  }
  try
  {
    // The ImageIO that will read the file, asked for the header only: size, spacing and the pixel type
    // the volume had when it was compressed.
    auto io = itk::ImageIOFactory::CreateImageIO(argv[1], itk::ImageIOFactory::FileModeEnum::ReadMode);
    if (!io)
    {
      std::cerr << argv[1] << ": not a file ITK can read" << std::endl;
      return EXIT_FAILURE;
    }
    io->SetFileName(argv[1]);
    io->ReadImageInformation();
    std::cout << "IO: " << io->GetNameOfClass()
              << "\nstored pixel type: " << itk::ImageIOBase::GetComponentTypeAsString(io->GetComponentType())
              << "\nsize:";
    for (unsigned int d = 0; d < io->GetNumberOfDimensions(); ++d)
    {
      std::cout << ' ' << io->GetDimensions(d);
    }
    std::cout << std::endl;

    // The image itself. The reader converts the decoded values to the pixel type asked for here
    // (float keeps every stored type's values); `dcv decompress` keeps the stored type instead.
    using ImageType = itk::Image<float, 3>;
    const ImageType::Pointer image = itk::ReadImage<ImageType>(argv[1]);
    auto                     range = itk::MinimumMaximumImageCalculator<ImageType>::New();
    range->SetImage(image);
    range->Compute();
    std::cout << "spacing: " << image->GetSpacing() << "\nvalues: " << range->GetMinimum() << " to "
              << range->GetMaximum() << std::endl;

    itk::WriteImage(image, argv[2], true); // true: compressed, where the format allows it
  }
  catch (const itk::ExceptionObject & e)
  {
    std::cerr << e.GetDescription() << std::endl;
    return EXIT_FAILURE;
  }
  return EXIT_SUCCESS;
}
