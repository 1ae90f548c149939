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
#include "itkDCVEncoder.h"
#include "itkDCVImageInformation.h"
#include "itkVersion.h"

#include <fstream>
#include <mutex>

namespace itk
{
namespace
{
/** The writing targets a setter turns off before it sets its own (the number of points stays: it counts only
 * where none of them is set). */
void
ClearTargets(dcv::EncoderOptions & options)
{
  options.bitsPerVoxel = 0.0;
  options.psnr = 0.0;
  options.maximumError = -1.0;
}
} // namespace

DCVImageIO::DCVImageIO()
{
  this->SetNumberOfDimensions(3);
  this->SetNumberOfComponents(1);
  this->SetPixelType(IOPixelEnum::SCALAR);
  this->AddSupportedReadExtension(".dcv");
  this->AddSupportedWriteExtension(".dcv");
  m_Options.bitsPerVoxel = 0.125;
}

void
DCVImageIO::SetBitsPerVoxel(double bitsPerVoxel)
{
  ClearTargets(m_Options);
  m_Options.bitsPerVoxel = bitsPerVoxel;
  this->Modified();
}

void
DCVImageIO::SetPSNR(double psnr)
{
  ClearTargets(m_Options);
  m_Options.psnr = psnr;
  this->Modified();
}

void
DCVImageIO::SetMaximumError(double maximumError)
{
  ClearTargets(m_Options);
  m_Options.maximumError = maximumError;
  this->Modified();
}

void
DCVImageIO::SetNumberOfPoints(SizeValueType numberOfPoints)
{
  ClearTargets(m_Options);
  m_Options.numberOfPoints = numberOfPoints;
  this->Modified();
}

void
DCVImageIO::SetMode(dcv::Mode mode)
{
  m_Options.mode = mode;
  this->Modified();
}

void
DCVImageIO::SetQuantizationStep(double step)
{
  m_Options.quantizationStep = step;
  this->Modified();
}

void
DCVImageIO::SetEncoderOptions(const dcv::EncoderOptions & options)
{
  m_Options = options;
  this->Modified();
}

bool
DCVImageIO::CanReadFile(const char * fileName)
{
  if (!this->HasSupportedReadExtension(fileName))
  {
    return false;
  }
  std::ifstream in(fileName, std::ios::binary);
  uint8_t       magic[4] = { 0, 0, 0, 0 };
  in.read(reinterpret_cast<char *>(magic), 4);
  return in.gcount() == 4 && dcv::HasMagic(magic, 4);
}

bool
DCVImageIO::CanWriteFile(const char * fileName)
{
  return this->HasSupportedWriteExtension(fileName);
}

void
DCVImageIO::ReadImageInformation()
{
  try
  {
    m_File = dcv::ReadCompressedFile(m_FileName);
    // Before ImageFileReader allocates the image from these numbers.
    dcv::CheckDecodingMemory(m_File.header, m_File.name, dcv::DecodeOutput::Volume, { m_MaximumMemory });
  }
  catch (const dcv::FormatError & e)
  {
    itkExceptionMacro(<< e.what());
  }
  CopyDCVGeometry(m_File.header, this);
  this->SetNumberOfComponents(1);
  this->SetPixelType(IOPixelEnum::SCALAR);
  this->SetComponentType(DCVComponentType(m_File.header.pixelType));
}

void
DCVImageIO::Read(void * buffer)
{
  if (m_File.name != "'" + m_FileName + "'")
  {
    this->ReadImageInformation();
  }
  try
  {
    dcv::VisitPixelType(m_File.header.pixelType, [&](auto pixel) {
      dcv::DecodeVolume(m_File, static_cast<decltype(pixel) *>(buffer), { m_MaximumMemory });
    });
  }
  catch (const dcv::FormatError & e)
  {
    itkExceptionMacro(<< e.what());
  }
}

void
DCVImageIO::Write(const void * buffer)
{
  const std::string name = "'" + m_FileName + "'";
  if (this->GetNumberOfDimensions() != 3 || this->GetNumberOfComponents() != 1)
  {
    itkExceptionMacro("Cannot write " << name << ": .dcv holds scalar 3D volumes, not " << this->GetNumberOfDimensions()
                                      << "D images of " << this->GetNumberOfComponents() << " components.");
  }
  dcv::FileHeader geometry;
  CopyDCVGeometry(this, geometry);
  const dcv::PixelType type = DCVPixelType(this->GetComponentType(), name);
  try
  {
    dcv::VisitPixelType(type, [&](auto pixel) {
      // The buffer as an image of its own type, without a copy, for the encoder.
      using ImageType = Image<decltype(pixel), 3>;
      auto image = ImageType::New();
      CopyDCVGeometry(geometry, image.GetPointer());
      image->SetBufferedRegion(image->GetLargestPossibleRegion());
      image->GetPixelContainer()->SetImportPointer(static_cast<decltype(pixel) *>(const_cast<void *>(buffer)),
                                                   image->GetLargestPossibleRegion().GetNumberOfPixels(),
                                                   false);
      m_LastResult = DCVEncode(image.GetPointer(), m_Options);
    });
    dcv::WriteFileAtomically(m_FileName, m_LastResult.bytes);
  }
  catch (const ExceptionObject &)
  {
    throw;
  }
  catch (const std::exception & e)
  {
    itkExceptionMacro("Cannot write " << name << ": " << e.what());
  }
  m_LastResult.bytes.clear();
  m_LastResult.approximation = dcv::Approximation();
}

void
DCVImageIO::PrintSelf(std::ostream & os, Indent indent) const
{
  Superclass::PrintSelf(os, indent);
  os << indent << "BitsPerVoxel: " << m_Options.bitsPerVoxel << std::endl;
  os << indent << "PSNR: " << m_Options.psnr << std::endl;
  os << indent << "MaximumError: " << m_Options.maximumError << std::endl;
  os << indent << "NumberOfPoints: " << m_Options.numberOfPoints << std::endl;
  os << indent << "Mode: " << m_Options.mode << std::endl;
  os << indent << "QuantizationStep: " << m_Options.quantizationStep << std::endl;
  os << indent << "MaximumMemory: " << m_MaximumMemory << std::endl;
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
  return "DCV ImageIO Factory, reads and writes .dcv files (DelaunayCompression)";
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
