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
// Decodes only some slices of a .dcv file with itk::DCVImageSource, the way a viewer or a streaming
// pipeline asks for part of a volume, and writes them:
//
//   DecodeDCVRegion INPUT.dcv OUTPUT FIRST_SLICE LAST_SLICE
//
// DCVImageSource reads the points and values once and rebuilds their tetrahedralization, then on each
// update rasterizes only the tetrahedra that meet the region requested downstream; the other voxels are
// never computed. Here the request comes from RegionOfInterestImageFilter.
#include "itkDCVImageSource.h"
#include "itkImageFileWriter.h"
#include "itkRegionOfInterestImageFilter.h"

#include <iostream>
#include <string>

int
main(int argc, char * argv[])
{
  if (argc != 5)
  {
    std::cerr << "Usage: " << argv[0] << " INPUT.dcv OUTPUT FIRST_SLICE LAST_SLICE" << std::endl;
    return EXIT_FAILURE;
  }
  // Any pixel type: values are rounded and clamped for integer types.
  using ImageType = itk::Image<float, 3>;
  try
  {
    auto source = itk::DCVImageSource<ImageType>::New();
    source->SetFileName(argv[1]);
    // The header alone: the whole volume's grid, so that the slices can be checked against it.
    source->UpdateOutputInformation();
    const ImageType::RegionType whole = source->GetOutput()->GetLargestPossibleRegion();
    const long                  first = std::stol(argv[3]);
    const long                  last = std::stol(argv[4]);
    if (first < 0 || last < first || last >= long(whole.GetSize(2)))
    {
      std::cerr << "slices " << first << " to " << last << " are not within 0 to " << whole.GetSize(2) - 1 << std::endl;
      return EXIT_FAILURE;
    }

    // The slab of slices first..last, full in x and y.
    ImageType::RegionType slab = whole;
    slab.SetIndex(2, first);
    slab.SetSize(2, itk::SizeValueType(last - first + 1));

    // The filter asks its input for the slab only and gives an image of that size, its origin moved so
    // that the voxels keep their physical positions.
    auto roi = itk::RegionOfInterestImageFilter<ImageType, ImageType>::New();
    roi->SetInput(source->GetOutput());
    roi->SetRegionOfInterest(slab);
    itk::WriteImage(roi->GetOutput(), argv[2], true);

    std::cout << "decoded " << slab.GetNumberOfPixels() << " of " << whole.GetNumberOfPixels() << " voxels ("
              << source->GetNumberOfRasterizedCells() << " tetrahedra rasterized)" << std::endl;
  }
  catch (const std::exception & e) // itk::ExceptionObject, or std::stol's errors
  {
    std::cerr << e.what() << std::endl;
    return EXIT_FAILURE;
  }
  return EXIT_SUCCESS;
}
