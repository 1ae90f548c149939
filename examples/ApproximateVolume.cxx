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
// Approximate a 3D volume by a linear spline over an adaptive Delaunay tetrahedralization, then
// rasterize the spline back onto the volume's grid:
//
//   ApproximateVolume INPUT OUTPUT [POINTS]
//
// INPUT is any 3D image ITK can read (read as 16-bit signed integers), OUTPUT the approximation on
// the same grid, POINTS the number of significant points kept (default 5000).
#include "itkDelaunayApproximationImageToMeshFilter.h"
#include "itkImage.h"
#include "itkImageFileReader.h"
#include "itkImageFileWriter.h"
#include "itkMesh.h"
#include "itkTetrahedralMeshToImageFilter.h"

#include <cstdlib>
#include <iostream>
#include <string>

int
main(int argc, char * argv[])
{
  if (argc < 3 || argc > 4)
  {
    std::cerr << "Usage: " << argv[0] << " INPUT OUTPUT [POINTS]\n"
              << "  Approximates a 3D volume with POINTS significant points (default 5000)\n"
              << "  and writes the approximation, on the input's grid, to OUTPUT." << std::endl;
    return EXIT_FAILURE;
  }
  const char *       inputFileName = argv[1];
  const char *       outputFileName = argv[2];
  itk::SizeValueType numberOfPoints = 5000;
  if (argc == 4)
  {
    // The filter clamps the count to at least 8 (the grid's corners).
    const std::string text = argv[3];
    std::size_t       parsed = 0;
    long long         value = 0;
    try
    {
      value = std::stoll(text, &parsed);
    }
    catch (const std::exception &)
    {
      parsed = 0;
    }
    if (parsed != text.size() || value <= 0)
    {
      std::cerr << "POINTS must be a positive integer, not '" << text << "'" << std::endl;
      return EXIT_FAILURE;
    }
    numberOfPoints = static_cast<itk::SizeValueType>(value);
  }

  // The filters are templated over the image type and the mesh type. The mesh carries the spline's
  // value at each point as float point data; its cells are tetrahedra.
  constexpr unsigned int Dimension = 3;
  using ImageType = itk::Image<short, Dimension>;
  using MeshType = itk::Mesh<float, Dimension>;
  using ReaderType = itk::ImageFileReader<ImageType>;
  using ApproximationFilterType = itk::DelaunayApproximationImageToMeshFilter<ImageType, MeshType>;
  using RasterizeFilterType = itk::TetrahedralMeshToImageFilter<MeshType, ImageType>;
  using WriterType = itk::ImageFileWriter<ImageType>;

  try
  {
    auto reader = ReaderType::New();
    reader->SetFileName(inputFileName);

    // Encoder: starting from the 8 corners, greedy refinement inserts the voxels the current spline
    // approximates worst, until NumberOfPoints points are in the tetrahedralization (or the
    // approximation is exact). The output mesh holds the points, in physical coordinates, with the
    // spline's values as point data, and the tetrahedra.
    auto approximate = ApproximationFilterType::New();
    approximate->SetInput(reader->GetOutput());
    approximate->SetNumberOfPoints(numberOfPoints);
    approximate->Update();

    const MeshType * mesh = approximate->GetOutput();
    std::cout << "Mesh points: " << mesh->GetNumberOfPoints() << '\n'
              << "Mesh cells (tetrahedra): " << mesh->GetNumberOfCells() << '\n'
              << "Mean squared error: " << approximate->GetMeanSquaredError() << std::endl;

    // Decoder: evaluate the spline at every voxel of the input's grid (size, origin, spacing and
    // direction all come from the reference image). Values are rounded and clamped to short.
    auto rasterize = RasterizeFilterType::New();
    rasterize->SetInput(mesh);
    rasterize->SetReferenceImage(reader->GetOutput());

    auto writer = WriterType::New();
    writer->SetInput(rasterize->GetOutput());
    writer->SetFileName(outputFileName);
    writer->UseCompressionOn();
    writer->Update();
  }
  catch (const itk::ExceptionObject & error)
  {
    std::cerr << "Error: " << error << std::endl;
    return EXIT_FAILURE;
  }
  return EXIT_SUCCESS;
}
