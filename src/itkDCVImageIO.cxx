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
#include "itkDCVImageIO.h"
#include "itkDCVImageIOFactory.h"

#include "dcvCodec.h"
#include "dcvFileFormat.h"
#include "itkVersion.h"

#include <algorithm>
#include <fstream>
#include <mutex>

namespace itk
{

DCVImageIO::DCVImageIO()
{
  this->SetNumberOfDimensions(3);
  this->SetNumberOfComponents(1);
  this->SetPixelType(IOPixelEnum::SCALAR);
  this->AddSupportedReadExtension(".dcv");
}

bool
DCVImageIO::CanReadFile(const char * fileName)
{
  const std::string name(fileName ? fileName : "");
  if (!this->HasSupportedReadExtension(fileName))
  {
    return false;
  }
  std::ifstream in(name, std::ios::binary);
  uint8_t       magic[4] = { 0, 0, 0, 0 };
  in.read(reinterpret_cast<char *>(magic), 4);
  return in.gcount() == 4 && dcv::HasMagic(magic, 4);
}

namespace
{
void
ReadHeader(const std::string & fileName, dcv::FileHeader & header, std::vector<uint8_t> & payload)
{
  try
  {
    dcv::ParseFile(dcv::ReadWholeFile(fileName), "'" + fileName + "'", header, payload);
  }
  catch (const dcv::FormatError & e)
  {
    itkGenericExceptionMacro(<< e.what());
  }
}
} // namespace

void
DCVImageIO::ReadImageInformation()
{
  dcv::FileHeader      h;
  std::vector<uint8_t> payload;
  ReadHeader(m_FileName, h, payload);
  const int32_t size[3] = { h.size.x, h.size.y, h.size.z };
  for (unsigned int i = 0; i < 3; ++i)
  {
    this->SetDimensions(i, SizeValueType(size[i]));
    this->SetSpacing(i, h.spacing[i]);
    this->SetOrigin(i, h.origin[i]);
    // ITK's IO keeps directions by column: axis i's direction vector.
    std::vector<double> axis(3);
    for (unsigned int r = 0; r < 3; ++r)
    {
      axis[r] = h.direction[3 * r + i];
    }
    this->SetDirection(i, axis);
  }
  dcv::VisitPixelType(h.pixelType, [this](auto pixel) {
    this->SetComponentType(MapPixelType<decltype(pixel)>::CType);
  });
}

void
DCVImageIO::Read(void * buffer)
{
  dcv::FileHeader      h;
  std::vector<uint8_t> payload;
  ReadHeader(m_FileName, h, payload);
  dcv::Approximation a;
  try
  {
    a = dcv::DecodePayload(payload, h.size, h.numberOfPoints, h.quantizationOrigin, h.quantizationStep, "'" + m_FileName + "'");
  }
  catch (const dcv::FormatError & e)
  {
    itkExceptionMacro(<< e.what());
  }
  dcv::VisitPixelType(h.pixelType, [&](auto pixel) { dcv::Rasterize(a, static_cast<decltype(pixel) *>(buffer)); });
}

void
DCVImageIO::Write(const void *)
{
  itkExceptionMacro("DCVImageIO does not write: .dcv files are made by the encoder (dcv compress).");
}

void
DCVImageIO::PrintSelf(std::ostream & os, Indent indent) const
{
  Superclass::PrintSelf(os, indent);
}

DCVImageIOFactory::DCVImageIOFactory()
{
  this->RegisterOverride(
    "itkImageIOBase", "itkDCVImageIO", "DCV Image IO", true, CreateObjectFunction<DCVImageIO>::New());
}

const char *
DCVImageIOFactory::GetITKSourceVersion() const
{
  return ITK_SOURCE_VERSION;
}

const char *
DCVImageIOFactory::GetDescription() const
{
  return "DCV ImageIO Factory, reads .dcv files (DelaunayCompression)";
}

void
DCVImageIOFactory::RegisterOneFactory()
{
  // ITK 5.2 has no RegisterInternalFactoryOnce: guard as its own mesh IO factories do.
  static std::once_flag once;
  std::call_once(once, [] { ObjectFactoryBase::RegisterFactoryInternal(DCVImageIOFactory::New()); });
}

// Entry point of ITK's factory registration (FACTORY_NAMES ImageIO::DCV in a build inside ITK).
void DelaunayCompression_EXPORT
     DCVImageIOFactoryRegister__Private()
{
  DCVImageIOFactory::RegisterOneFactory();
}

} // namespace itk
