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
#ifndef itkTetrahedralMeshToImageFilter_hxx
#define itkTetrahedralMeshToImageFilter_hxx

#include "itkTetrahedralMeshToImageFilter.h"

#include "itkDCVImageInformation.h"

#include "dcvRasterizer.h"
#include "itkCellInterface.h"

#include <cmath>

namespace itk
{

template <typename TInputMesh, typename TOutputImage>
TetrahedralMeshToImageFilter<TInputMesh, TOutputImage>::TetrahedralMeshToImageFilter()
{
  this->SetNumberOfRequiredInputs(1);
}

template <typename TInputMesh, typename TOutputImage>
void
TetrahedralMeshToImageFilter<TInputMesh, TOutputImage>::SetInput(const InputMeshType * mesh)
{
  this->ProcessObject::SetNthInput(0, const_cast<InputMeshType *>(mesh));
}

template <typename TInputMesh, typename TOutputImage>
auto
TetrahedralMeshToImageFilter<TInputMesh, TOutputImage>::GetInput() const -> const InputMeshType *
{
  return static_cast<const InputMeshType *>(this->ProcessObject::GetInput(0));
}

template <typename TInputMesh, typename TOutputImage>
void
TetrahedralMeshToImageFilter<TInputMesh, TOutputImage>::GenerateOutputInformation()
{
  OutputImageType * output = this->GetOutput();
  if (m_ReferenceImage)
  {
    output->SetLargestPossibleRegion(m_ReferenceImage->GetLargestPossibleRegion());
    output->SetSpacing(m_ReferenceImage->GetSpacing());
    output->SetOrigin(m_ReferenceImage->GetOrigin());
    output->SetDirection(m_ReferenceImage->GetDirection());
  }
  else
  {
    output->SetLargestPossibleRegion(typename OutputImageType::RegionType(m_Index, m_Size));
    output->SetSpacing(m_Spacing);
    output->SetOrigin(m_Origin);
    output->SetDirection(m_Direction);
  }
}

template <typename TInputMesh, typename TOutputImage>
void
TetrahedralMeshToImageFilter<TInputMesh, TOutputImage>::EnlargeOutputRequestedRegion(DataObject * output)
{
  Superclass::EnlargeOutputRequestedRegion(output);
  output->SetRequestedRegionToLargestPossibleRegion();
}

template <typename TInputMesh, typename TOutputImage>
void
TetrahedralMeshToImageFilter<TInputMesh, TOutputImage>::GenerateData()
{
  const InputMeshType * mesh = this->GetInput();
  if (mesh == nullptr)
  {
    itkExceptionMacro("No input mesh.");
  }
  OutputImageType * output = this->GetOutput();
  const auto        region = output->GetLargestPossibleRegion();
  const auto        size = region.GetSize();
  for (unsigned int d = 0; d < 3; ++d)
  {
    if (size[d] < 1 || size[d] > SizeValueType(dcv::MaximumGridExtent))
    {
      itkExceptionMacro("The output grid is " << size << " voxels; each axis needs 1 to " << dcv::MaximumGridExtent
                                              << " voxels.");
    }
  }
  output->SetBufferedRegion(region);
  output->Allocate();
  output->FillBuffer(m_BackgroundValue);
  const dcv::GridSize grid{ int32_t(size[0]), int32_t(size[1]), int32_t(size[2]) };

  // Points to grid positions, values from the point data.
  const SizeValueType numberOfPoints = mesh->GetNumberOfPoints();
  const auto *        pointData = mesh->GetPointData();
  if (numberOfPoints > 0 && (pointData == nullptr || pointData->Size() < numberOfPoints))
  {
    itkExceptionMacro("The mesh has " << numberOfPoints << " points but " << (pointData ? pointData->Size() : 0)
                                      << " point data values; every point needs its value.");
  }
  std::vector<dcv::GridPoint> points(numberOfPoints);
  std::vector<double>         values(numberOfPoints);
  SizeValueType               i = 0;
  for (auto it = mesh->GetPoints()->Begin(); it != mesh->GetPoints()->End(); ++it, ++i)
  {
    const auto id = it->Index();
    if (id >= numberOfPoints)
    {
      itkExceptionMacro("Mesh point identifier " << id << " is not below the number of points " << numberOfPoints
                                                 << "; identifiers must be 0 to n-1.");
    }
    if (!PhysicalPointToGridPoint(output, region, it->Value(), points[id]))
    {
      itkExceptionMacro("Mesh point " << id << " at " << it->Value() << " is not on a voxel of the output grid.");
    }
    values[id] = double(pointData->ElementAt(id));
  }

  const SizeValueType numberOfCells = mesh->GetNumberOfCells();
  SizeValueType       done = 0;
  const SizeValueType every = std::max<SizeValueType>(1, numberOfCells / 100);
  OutputPixelType *   buffer = output->GetBufferPointer();
  for (auto it = mesh->GetCells()->Begin(); it != mesh->GetCells()->End(); ++it, ++done)
  {
    const auto * cell = it->Value();
    if (cell->GetType() != CellGeometryEnum::TETRAHEDRON_CELL || cell->GetNumberOfPoints() != 4)
    {
      itkExceptionMacro("Cell " << it->Index() << " is not a tetrahedron; only tetrahedral meshes can be rasterized.");
    }
    std::array<dcv::GridPoint, 4> p;
    std::array<double, 4>         v;
    auto                          ids = cell->PointIdsBegin();
    for (unsigned int k = 0; k < 4; ++k, ++ids)
    {
      if (*ids >= numberOfPoints)
      {
        itkExceptionMacro("Cell " << it->Index() << " refers to point " << *ids << ", which the mesh does not have.");
      }
      p[k] = points[*ids];
      v[k] = values[*ids];
    }
    dcv::RasterizeTetrahedron(grid, p, v, buffer);
    if (done % every == 0)
    {
      this->UpdateProgress(float(done) / float(numberOfCells));
      if (this->GetAbortGenerateData())
      {
        ProcessAborted e(__FILE__, __LINE__);
        e.SetDescription("TetrahedralMeshToImageFilter: aborted");
        throw e;
      }
    }
  }
  this->UpdateProgress(1.0f);
}

template <typename TInputMesh, typename TOutputImage>
void
TetrahedralMeshToImageFilter<TInputMesh, TOutputImage>::PrintSelf(std::ostream & os, Indent indent) const
{
  Superclass::PrintSelf(os, indent);
  os << indent << "Size: " << m_Size << std::endl;
  os << indent << "Index: " << m_Index << std::endl;
  os << indent << "Spacing: " << m_Spacing << std::endl;
  os << indent << "Origin: " << m_Origin << std::endl;
  os << indent << "Direction: " << m_Direction << std::endl;
  os << indent << "ReferenceImage: " << m_ReferenceImage.GetPointer() << std::endl;
  os << indent
     << "BackgroundValue: " << static_cast<typename NumericTraits<OutputPixelType>::PrintType>(m_BackgroundValue)
     << std::endl;
}

} // namespace itk

#endif
