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
#ifndef itkDelaunayApproximationImageToMeshFilter_hxx
#define itkDelaunayApproximationImageToMeshFilter_hxx

#include "itkDelaunayApproximationImageToMeshFilter.h"

#include "dcvRefinementEngine.h"
#include "itkImageRegionConstIterator.h"
#include "itkProcessObject.h"

#include <stdexcept>

namespace itk
{

template <typename TInputImage, typename TOutputMesh>
DelaunayApproximationImageToMeshFilter<TInputImage, TOutputMesh>::DelaunayApproximationImageToMeshFilter()
{
  this->SetNumberOfRequiredInputs(1);
}

template <typename TInputImage, typename TOutputMesh>
void
DelaunayApproximationImageToMeshFilter<TInputImage, TOutputMesh>::GenerateInputRequestedRegion()
{
  Superclass::GenerateInputRequestedRegion();
  // The refinement looks at the whole image.
  auto * input = const_cast<InputImageType *>(this->GetInput());
  if (input)
  {
    input->SetRequestedRegionToLargestPossibleRegion();
  }
}

template <typename TInputImage, typename TOutputMesh>
void
DelaunayApproximationImageToMeshFilter<TInputImage, TOutputMesh>::GenerateData()
{
  const InputImageType * input = this->GetInput();
  if (input == nullptr)
  {
    itkExceptionMacro("No input image.");
  }
  const auto             region = input->GetBufferedRegion();
  const auto             size = region.GetSize();
  const dcv::GridSize    grid{ int32_t(size[0]), int32_t(size[1]), int32_t(size[2]) };
  for (unsigned int i = 0; i < 3; ++i)
  {
    if (size[i] < 2 || size[i] > SizeValueType(dcv::MaximumGridExtent))
    {
      itkExceptionMacro("The input image is " << size << " voxels; each axis needs 2 to " << dcv::MaximumGridExtent
                                               << " voxels.");
    }
  }

  // The engine works on float values laid out as the grid (x fastest, as ITK's buffer).
  std::vector<float> values;
  values.reserve(grid.NumberOfVoxels());
  for (ImageRegionConstIterator<InputImageType> it(input, region); !it.IsAtEnd(); ++it)
  {
    values.push_back(static_cast<float>(it.Get()));
  }

  dcv::Approximation approximation;
  try
  {
    dcv::RefinementEngine engine(values.data(), grid);
    engine.Refine(m_NumberOfPoints, [this](double fraction) {
      this->UpdateProgress(float(fraction));
      if (this->GetAbortGenerateData())
      {
        ProcessAborted e(__FILE__, __LINE__);
        e.SetDescription("DelaunayApproximationImageToMeshFilter: aborted");
        throw e;
      }
    });
    m_SquaredError = engine.GetSquaredError();
    m_MeanSquaredError = m_SquaredError / double(grid.NumberOfVoxels());
    approximation = engine.GetApproximation();
  }
  catch (const std::exception & e)
  {
    if (dynamic_cast<const ExceptionObject *>(&e))
    {
      throw;
    }
    itkExceptionMacro("Approximation failed: " << e.what());
  }

  OutputMeshType * mesh = this->GetOutput();
  mesh->Initialize();
  auto points = OutputMeshType::PointsContainer::New();
  points->Reserve(approximation.points.size());
  auto pointData = OutputMeshType::PointDataContainer::New();
  pointData->Reserve(approximation.points.size());
  const auto start = region.GetIndex();
  for (std::size_t i = 0; i < approximation.points.size(); ++i)
  {
    typename InputImageType::IndexType index;
    for (unsigned int d = 0; d < 3; ++d)
    {
      index[d] = start[d] + approximation.points[i][d];
    }
    typename InputImageType::PointType physical;
    input->TransformIndexToPhysicalPoint(index, physical);
    typename OutputMeshType::PointType p;
    p.CastFrom(physical);
    points->SetElement(i, p);
    pointData->SetElement(i, static_cast<OutputPixelType>(approximation.values[i]));
  }
  mesh->SetPoints(points);
  mesh->SetPointData(pointData);
  mesh->SetCells(OutputMeshType::CellsContainer::New());
  mesh->GetCells()->Reserve(approximation.tetrahedra.size());
  for (std::size_t c = 0; c < approximation.tetrahedra.size(); ++c)
  {
    typename CellType::CellAutoPointer cell;
    cell.TakeOwnership(new TetrahedronCellType);
    for (unsigned int k = 0; k < 4; ++k)
    {
      cell->SetPointId(k, approximation.tetrahedra[c][k]);
    }
    mesh->SetCell(c, cell);
  }
}

template <typename TInputImage, typename TOutputMesh>
void
DelaunayApproximationImageToMeshFilter<TInputImage, TOutputMesh>::PrintSelf(std::ostream & os, Indent indent) const
{
  Superclass::PrintSelf(os, indent);
  os << indent << "NumberOfPoints: " << m_NumberOfPoints << std::endl;
  os << indent << "SquaredError: " << m_SquaredError << std::endl;
  os << indent << "MeanSquaredError: " << m_MeanSquaredError << std::endl;
}

} // namespace itk

#endif
