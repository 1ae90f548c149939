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
// Reads a .dcv file as a tetrahedral mesh with itk::MeshFileReader, without decoding a voxel:
//
//   ReadDCVMesh INPUT.dcv
//
// The mesh is the spline itself: the significant points in physical coordinates, their values as point
// data, and the Delaunay tetrahedra as cells. (A file's residual layer holds voxels, not a mesh; it is
// read with the image, see ReadDCVImage.) The package registers its MeshIO in every program that links
// it, so the reader finds it by itself. (ITK 5.2's VTK mesh writer has no tetrahedra: for ParaView,
// `dcv mesh INPUT.dcv OUTPUT.vtu` writes the same mesh.)
#include "itkMesh.h"
#include "itkMeshFileReader.h"

#include <algorithm>
#include <iostream>
#include <limits>

int
main(int argc, char * argv[])
{
  if (argc != 2)
  {
    std::cerr << "Usage: " << argv[0] << " INPUT.dcv" << std::endl;
    return EXIT_FAILURE;
  }
  // float point data with 3D points: the mesh type DelaunayApproximationImageToMeshFilter makes.
  using MeshType = itk::Mesh<float, 3>;
  try
  {
    auto reader = itk::MeshFileReader<MeshType>::New();
    reader->SetFileName(argv[1]);
    reader->Update();
    const MeshType * mesh = reader->GetOutput();

    // The values at the points, in the volume's own units.
    float low = std::numeric_limits<float>::max();
    float high = std::numeric_limits<float>::lowest();
    for (auto it = mesh->GetPointData()->Begin(); it != mesh->GetPointData()->End(); ++it)
    {
      low = std::min(low, it.Value());
      high = std::max(high, it.Value());
    }
    std::cout << "points: " << mesh->GetNumberOfPoints() << "\ntetrahedra: " << mesh->GetNumberOfCells()
              << "\nvalues: " << low << " to " << high << "\nbounds:";
    const auto & bounds = mesh->GetBoundingBox()->GetBounds(); // xmin, xmax, ymin, ymax, zmin, zmax
    for (const auto b : bounds)
    {
      std::cout << ' ' << b;
    }
    std::cout << std::endl;
  }
  catch (const itk::ExceptionObject & e)
  {
    std::cerr << e.GetDescription() << std::endl;
    return EXIT_FAILURE;
  }
  return EXIT_SUCCESS;
}
