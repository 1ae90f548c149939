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

#include "itkDCVEncoder.h"
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
  dcv::EncoderOptions options;
  options.numberOfPoints = m_NumberOfPoints;
  options.mode = m_Mode;
  options.domainSigma = m_DomainSigma;
  options.rangeSigma = m_RangeSigma;
  options.alpha = m_Alpha;
  options.quantizationStep = m_QuantizationStep;
  options.bitsPerVoxel = m_BitsPerVoxel;
  options.psnr = m_PSNR;
  options.scale = m_Scale;
  options.progress = [this](double fraction) {
    this->UpdateProgress(float(fraction));
    if (this->GetAbortGenerateData())
    {
      ProcessAborted e(__FILE__, __LINE__);
      e.SetDescription("DelaunayApproximationImageToMeshFilter: aborted");
      throw e;
    }
  };
  dcv::EncoderResult r;
  try
  {
    r = DCVApproximate(input, options);
  }
  catch (const ExceptionObject &)
  {
    throw;
  }
  catch (const std::exception & e)
  {
    itkExceptionMacro(<< e.what());
  }
  m_QuantizationOrigin = r.header.quantizationOrigin;
  m_ChosenQuantizationStep = r.quantizationStep;
  m_ChosenScale = r.header.scale;
  m_SquaredError = r.squaredError;
  m_MeanSquaredError = m_SquaredError / double(r.header.size.NumberOfVoxels());
  m_SmoothedPSNR = r.smoothedPSNR;
  m_Timings = r.timings;

  const dcv::Approximation & approximation = r.approximation;
  OutputMeshType *           mesh = this->GetOutput();
  mesh->Initialize();
  auto points = OutputMeshType::PointsContainer::New();
  points->Reserve(approximation.points.size());
  auto pointData = OutputMeshType::PointDataContainer::New();
  pointData->Reserve(approximation.points.size());
  const auto region = input->GetBufferedRegion();
  for (std::size_t i = 0; i < approximation.points.size(); ++i)
  {
    typename OutputMeshType::PointType p;
    p.CastFrom(GridPointToPhysicalPoint(input, region, approximation.points[i]));
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
  // The whole mesh is generated: mark it buffered, so that the pipeline does not run the filter again
  // for each consumer that updates after it.
  mesh->SetBufferedRegion(mesh->GetRequestedRegion());
}

template <typename TInputImage, typename TOutputMesh>
void
DelaunayApproximationImageToMeshFilter<TInputImage, TOutputMesh>::PrintSelf(std::ostream & os, Indent indent) const
{
  Superclass::PrintSelf(os, indent);
  os << indent << "NumberOfPoints: " << m_NumberOfPoints << std::endl;
  os << indent << "Mode: " << m_Mode << std::endl;
  os << indent << "DomainSigma: " << m_DomainSigma << std::endl;
  os << indent << "RangeSigma: " << m_RangeSigma << std::endl;
  os << indent << "Alpha: " << m_Alpha << std::endl;
  os << indent << "QuantizationStep: " << m_QuantizationStep << std::endl;
  os << indent << "QuantizationOrigin: " << m_QuantizationOrigin << std::endl;
  os << indent << "BitsPerVoxel: " << m_BitsPerVoxel << std::endl;
  os << indent << "PSNR: " << m_PSNR << std::endl;
  os << indent << "Scale: " << m_Scale[0] << " " << m_Scale[1] << " " << m_Scale[2] << std::endl;
  os << indent << "ChosenScale: " << m_ChosenScale[0] << " " << m_ChosenScale[1] << " " << m_ChosenScale[2]
     << std::endl;
  os << indent << "ChosenQuantizationStep: " << m_ChosenQuantizationStep << std::endl;
  os << indent << "SquaredError: " << m_SquaredError << std::endl;
  os << indent << "MeanSquaredError: " << m_MeanSquaredError << std::endl;
  os << indent << "SmoothedPSNR: " << m_SmoothedPSNR << std::endl;
}

} // namespace itk

#endif
