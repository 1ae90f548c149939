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
#include "itkDCVGridPoint.h"
#include "itkVersion.h"

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

/** Copies n values of a buffer of the given component type into doubles. */
void
ToDouble(const void * buffer, IOComponentEnum type, std::size_t n, std::vector<double> & out)
{
  out.resize(n);
  switch (type)
  {
#define DCV_CASE(E, T)                                                                                                 \
  case IOComponentEnum::E:                                                                                             \
    for (std::size_t i = 0; i < n; ++i)                                                                                \
      out[i] = double(static_cast<const T *>(buffer)[i]);                                                              \
    return;
    DCV_CASE(UCHAR, unsigned char)
    DCV_CASE(CHAR, signed char)
    DCV_CASE(USHORT, unsigned short)
    DCV_CASE(SHORT, short)
    DCV_CASE(UINT, unsigned int)
    DCV_CASE(INT, int)
    DCV_CASE(ULONG, unsigned long)
    DCV_CASE(LONG, long)
    DCV_CASE(ULONGLONG, unsigned long long)
    DCV_CASE(LONGLONG, long long)
    DCV_CASE(FLOAT, float)
    DCV_CASE(DOUBLE, double)
#undef DCV_CASE
    default:
      itkGenericExceptionMacro("DCVMeshIO: unsupported component type " << type);
  }
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
  std::vector<uint8_t> payload;
  dcv::Approximation   a;
  try
  {
    const std::string name = "'" + m_FileName + "'";
    dcv::ParseFile(dcv::ReadWholeFile(m_FileName), name, m_Header, payload);
    a = dcv::DecodePayload(payload,
                           m_Header.size,
                           m_Header.numberOfPoints,
                           m_Header.quantizationOrigin,
                           m_Header.quantizationStep,
                           name);
  }
  catch (const dcv::FormatError & e)
  {
    itkExceptionMacro(<< e.what());
  }
  m_Points.clear();
  for (const auto & p : a.points)
  {
    for (unsigned int r = 0; r < 3; ++r)
    {
      double x = m_Header.origin[r];
      for (unsigned int c = 0; c < 3; ++c)
      {
        x += m_Header.direction[3 * r + c] * m_Header.spacing[c] * p[c];
      }
      m_Points.push_back(x);
    }
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
  ToDouble(buffer, this->GetPointComponentType(), this->GetNumberOfPoints() * 3, m_Points);
}

void
DCVMeshIO::WritePointData(void * buffer)
{
  if (this->GetNumberOfPointPixelComponents() != 1)
  {
    itkExceptionMacro("Cannot write '" << m_FileName << "': .dcv point data must be scalar values.");
  }
  ToDouble(buffer, this->GetPointPixelComponentType(), this->GetNumberOfPointPixels(), m_Values);
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
    itkExceptionMacro("Cannot write " << name << ": QuantizationStep must be positive.");
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
  h.pixelType = m_DecodedPixelType;
  h.mode = 255; // not made by the encoder
  h.size = a.grid;
  ImageBase<3>::PointType first;
  m_ReferenceImage->TransformIndexToPhysicalPoint(region.GetIndex(), first);
  for (unsigned int i = 0; i < 3; ++i)
  {
    h.spacing[i] = m_ReferenceImage->GetSpacing()[i];
    h.origin[i] = first[i];
    for (unsigned int j = 0; j < 3; ++j)
    {
      h.direction[3 * i + j] = m_ReferenceImage->GetDirection()(i, j);
    }
  }
  h.quantizationOrigin = m_QuantizationOrigin;
  h.quantizationStep = m_QuantizationStep;
  h.numberOfPoints = uint32_t(n);
  try
  {
    dcv::CheckPoints(a.grid, a.points);
    dcv::WriteFileAtomically(m_FileName, dcv::SerializeFile(h, dcv::EncodePayload(a, m_QuantizationOrigin, m_QuantizationStep)));
  }
  catch (const std::exception & e)
  {
    itkExceptionMacro("Cannot write " << name << ": " << e.what());
  }
}

void
DCVMeshIO::PrintSelf(std::ostream & os, Indent indent) const
{
  Superclass::PrintSelf(os, indent);
  os << indent << "ReferenceImage: " << m_ReferenceImage.GetPointer() << std::endl;
  os << indent << "QuantizationOrigin: " << m_QuantizationOrigin << std::endl;
  os << indent << "QuantizationStep: " << m_QuantizationStep << std::endl;
  os << indent << "DecodedPixelType: " << dcv::PixelTypeName(m_DecodedPixelType) << std::endl;
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
