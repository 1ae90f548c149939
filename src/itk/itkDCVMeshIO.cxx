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
#include "itkDCVMeshIO.h"
#include "itkDCVMeshIOFactory.h"

#include "dcvApproximation.h"
#include "dcvCodec.h"
#include "dcvEncoder.h"
#include "itkDCVImageInformation.h"
#include "itkImage.h"
#include "itkVersion.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <mutex>

namespace itk
{
namespace
{
bool
HasDcvExtension(const char * fileName)
{
  const std::string name(fileName ? fileName : "");
  return name.size() > 4 && name.compare(name.size() - 4, 4, ".dcv") == 0;
}

/** Copies n values of a buffer of one of the .dcv pixel types into doubles. */
void
ToDouble(const void * buffer, IOComponentEnum type, std::size_t n, std::vector<double> & out, const std::string & name)
{
  out.resize(n);
  dcv::VisitPixelType(DCVPixelType(type, name), [&](auto pixel) {
    const auto * values = static_cast<const decltype(pixel) *>(buffer);
    std::copy(values, values + n, out.begin());
  });
}
} // namespace

DCVMeshIO::DCVMeshIO()
{
  this->AddSupportedReadExtension(".dcv");
  this->AddSupportedWriteExtension(".dcv");
  this->SetFileType(IOFileEnum::BINARY);
}

bool
DCVMeshIO::CanReadFile(const char * fileName)
{
  if (!HasDcvExtension(fileName))
  {
    return false;
  }
  std::ifstream in(fileName, std::ios::binary);
  uint8_t       magic[4] = { 0, 0, 0, 0 };
  in.read(reinterpret_cast<char *>(magic), 4);
  return in.gcount() == 4 && dcv::HasMagic(magic, 4);
}

bool
DCVMeshIO::CanWriteFile(const char * fileName)
{
  return HasDcvExtension(fileName);
}

void
DCVMeshIO::Decode()
{
  dcv::Approximation a;
  try
  {
    const dcv::CompressedFile file = dcv::ReadCompressedFile(m_FileName);
    m_Header = file.header;
    a = dcv::DecodeMesh(file, { m_MaximumMemory }); // the spline: a residual layer is voxels, not part of a mesh
  }
  catch (const dcv::FormatError & e)
  {
    itkExceptionMacro(<< e.what());
  }
  auto grid = ImageBase<3>::New();
  CopyDCVGeometry(m_Header, grid.GetPointer());
  m_Points.clear();
  m_Points.reserve(3 * a.points.size());
  for (const auto & g : a.points)
  {
    const auto p = GridPointToPhysicalPoint(grid.GetPointer(), grid->GetLargestPossibleRegion(), g);
    m_Points.insert(m_Points.end(), p.Begin(), p.End());
  }
  m_Values = a.values;
  m_Cells.clear();
  for (const auto & t : a.tetrahedra)
  {
    m_Cells.push_back(uint32_t(CellGeometryEnum::TETRAHEDRON_CELL));
    m_Cells.push_back(4);
    m_Cells.insert(m_Cells.end(), t.begin(), t.end());
  }
}

void
DCVMeshIO::ReadMeshInformation()
{
  this->Decode();
  this->SetPointDimension(3);
  this->SetNumberOfPoints(m_Values.size());
  this->SetPointComponentType(IOComponentEnum::DOUBLE);
  this->SetNumberOfCells(m_Cells.size() / 6);
  this->SetCellComponentType(IOComponentEnum::UINT);
  this->SetCellBufferSize(m_Cells.size());
  this->SetNumberOfPointPixels(m_Values.size());
  this->SetPointPixelType(IOPixelEnum::SCALAR);
  this->SetPointPixelComponentType(IOComponentEnum::DOUBLE);
  this->SetNumberOfPointPixelComponents(1);
  this->SetNumberOfCellPixels(0);
  this->SetUpdatePoints(true);
  this->SetUpdateCells(true);
  this->SetUpdatePointData(true);
  this->SetUpdateCellData(false);
}

void
DCVMeshIO::ReadPoints(void * buffer)
{
  std::memcpy(buffer, m_Points.data(), m_Points.size() * sizeof(double));
}

void
DCVMeshIO::ReadCells(void * buffer)
{
  std::memcpy(buffer, m_Cells.data(), m_Cells.size() * sizeof(uint32_t));
}

void
DCVMeshIO::ReadPointData(void * buffer)
{
  std::memcpy(buffer, m_Values.data(), m_Values.size() * sizeof(double));
}

void
DCVMeshIO::WritePoints(void * buffer)
{
  ToDouble(buffer, this->GetPointComponentType(), this->GetNumberOfPoints() * 3, m_Points, "'" + m_FileName + "'");
}

void
DCVMeshIO::WritePointData(void * buffer)
{
  if (this->GetNumberOfPointPixelComponents() != 1)
  {
    itkExceptionMacro("Cannot write '" << m_FileName << "': .dcv point data must be scalar values.");
  }
  ToDouble(
    buffer, this->GetPointPixelComponentType(), this->GetNumberOfPointPixels(), m_Values, "'" + m_FileName + "'");
}

void
DCVMeshIO::Write()
{
  const std::string name = "'" + m_FileName + "'";
  if (!m_ReferenceImage)
  {
    itkExceptionMacro("Cannot write " << name << ": DCVMeshIO needs the voxel grid (SetReferenceImage).");
  }
  const std::size_t n = m_Points.size() / 3;
  if (n == 0 || m_Values.size() != n)
  {
    itkExceptionMacro("Cannot write " << name << ": the mesh has " << n << " points and " << m_Values.size()
                                      << " point data values; each point needs its value.");
  }
  if (!(m_QuantizationStep > 0.0))
  {
    itkExceptionMacro("Cannot write " << name
                                      << ": set the QuantizationStep (and QuantizationOrigin) of the values, as the "
                                         "approximation filter reports them (GetChosenQuantizationStep).");
  }
  const auto         region = m_ReferenceImage->GetLargestPossibleRegion();
  dcv::Approximation a;
  a.grid = dcv::GridSize{ int32_t(region.GetSize()[0]), int32_t(region.GetSize()[1]), int32_t(region.GetSize()[2]) };
  for (std::size_t i = 0; i < n; ++i)
  {
    ImageBase<3>::PointType p;
    for (unsigned int d = 0; d < 3; ++d)
    {
      p[d] = m_Points[3 * i + d];
    }
    dcv::GridPoint g;
    if (!PhysicalPointToGridPoint(m_ReferenceImage.GetPointer(), region, p, g))
    {
      itkExceptionMacro("Cannot write " << name << ": mesh point " << i << " at " << p
                                        << " is not on a voxel of the reference grid.");
    }
    a.points.push_back(g);
    const double k = std::round((m_Values[i] - m_QuantizationOrigin) / m_QuantizationStep);
    a.values.push_back(m_QuantizationOrigin + k * m_QuantizationStep);
  }
  dcv::FileHeader h;
  CopyDCVGeometry(m_ReferenceImage, region, h);
  h.pixelType = this->GetDecodedPixelType();
  h.mode = dcv::FileHeader::UnknownMode;
  h.scale = m_Scale == dcv::GridScale{ { 0, 0, 0 } } ? dcv::AutomaticScale(h.spacing) : m_Scale;
  a.scale = h.scale; // the value prediction follows the neighbours of the scaled Delaunay space
  h.quantizationOrigin = m_QuantizationOrigin;
  h.quantizationStep = m_QuantizationStep;
  h.numberOfPoints = uint32_t(n);
  try
  {
    dcv::CheckPoints(a.grid, a.points);
    dcv::WriteFileAtomically(m_FileName,
                             dcv::SerializeFile(h, dcv::EncodePayload(a, m_QuantizationOrigin, m_QuantizationStep)));
  }
  catch (const std::exception & e)
  {
    itkExceptionMacro("Cannot write " << name << ": " << e.what());
  }
}

dcv::PixelType
DCVMeshIO::GetDecodedPixelType() const
{
  if (m_DecodedPixelTypeSet || !m_ReferenceImage)
  {
    return m_DecodedPixelType;
  }
  dcv::PixelType type = m_DecodedPixelType;
  for (auto candidate : { dcv::PixelType::UInt8,
                          dcv::PixelType::Int8,
                          dcv::PixelType::UInt16,
                          dcv::PixelType::Int16,
                          dcv::PixelType::UInt32,
                          dcv::PixelType::Int32,
                          dcv::PixelType::Float32,
                          dcv::PixelType::Float64 })
  {
    dcv::VisitPixelType(candidate, [&](auto pixel) {
      if (dynamic_cast<const Image<decltype(pixel), 3> *>(m_ReferenceImage.GetPointer()))
      {
        type = candidate;
      }
    });
  }
  return type;
}

void
DCVMeshIO::PrintSelf(std::ostream & os, Indent indent) const
{
  Superclass::PrintSelf(os, indent);
  os << indent << "ReferenceImage: " << m_ReferenceImage.GetPointer() << std::endl;
  os << indent << "QuantizationOrigin: " << m_QuantizationOrigin << std::endl;
  os << indent << "QuantizationStep: " << m_QuantizationStep << std::endl;
  os << indent << "MaximumMemory: " << m_MaximumMemory << std::endl;
  os << indent << "Scale: " << m_Scale[0] << " " << m_Scale[1] << " " << m_Scale[2] << std::endl;
  os << indent << "DecodedPixelType: " << dcv::PixelTypeName(this->GetDecodedPixelType()) << std::endl;
}

DCVMeshIOFactory::DCVMeshIOFactory()
{
  this->RegisterOverride("itkMeshIOBase", "itkDCVMeshIO", "DCV Mesh IO", true, CreateObjectFunction<DCVMeshIO>::New());
}

const char *
DCVMeshIOFactory::GetITKSourceVersion() const
{
  return ITK_SOURCE_VERSION;
}

const char *
DCVMeshIOFactory::GetDescription() const
{
  return "DCV MeshIO Factory, reads and writes .dcv files (DelaunayCompression)";
}

void
DCVMeshIOFactory::RegisterOneFactory()
{
  static std::once_flag once;
  std::call_once(once, [] { ObjectFactoryBase::RegisterFactoryInternal(DCVMeshIOFactory::New()); });
}

void DelaunayCompression_EXPORT
DCVMeshIOFactoryRegister__Private()
{
  DCVMeshIOFactory::RegisterOneFactory();
}

} // namespace itk
