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
#ifndef itkDCVImageSource_h
#define itkDCVImageSource_h

#include "dcvApproximation.h"
#include "dcvCodec.h"
#include "dcvFileFormat.h"
#include "itkDCVImageInformation.h"
#include "itkImageSource.h"

namespace itk
{

/** \class DCVImageSource
 * \brief Decodes a .dcv file straight to an image; a requested sub-region rasterizes only the cells
 * that cross it.
 *
 * The output has the file's size, spacing, origin and direction; its pixel type is the template
 * argument (values are rounded and clamped for integer types). The points and values are decoded, and
 * their tetrahedralization rebuilt, once per file; each update then rasterizes only the cells whose
 * bounding box meets the requested region, so streaming a volume slab by slab costs about one full
 * decode.
 *
 * Parameters: FileName (no default); MaximumMemory (bytes that decoding may need, default
 * dcv::DefaultMaximumMemory(), half of the physical memory; 0: no limit), checked against what the
 * header implies before the output is allocated (as DCVImageIO).
 * \sa DCVImageIO
 * \ingroup DelaunayCompression
 */
template <typename TOutputImage>
class ITK_TEMPLATE_EXPORT DCVImageSource : public ImageSource<TOutputImage>
{
public:
  ITK_DISALLOW_COPY_AND_MOVE(DCVImageSource);

  using Self = DCVImageSource;
  using Superclass = ImageSource<TOutputImage>;
  using Pointer = SmartPointer<Self>;
  using ConstPointer = SmartPointer<const Self>;

  itkNewMacro(Self);
  itkTypeMacro(DCVImageSource, ImageSource);

  using OutputImageType = TOutputImage;
  static_assert(OutputImageType::ImageDimension == 3, "DCVImageSource makes 3D images");

  itkSetStringMacro(FileName);
  itkGetStringMacro(FileName);

  itkSetMacro(MaximumMemory, uint64_t);
  itkGetConstMacro(MaximumMemory, uint64_t);

  /** Number of cells rasterized by the last update (for tests and diagnostics). */
  itkGetConstMacro(NumberOfRasterizedCells, SizeValueType);

protected:
  DCVImageSource() = default;
  ~DCVImageSource() override = default;

  void
  PrintSelf(std::ostream & os, Indent indent) const override
  {
    Superclass::PrintSelf(os, indent);
    os << indent << "FileName: " << m_FileName << std::endl;
    os << indent << "NumberOfRasterizedCells: " << m_NumberOfRasterizedCells << std::endl;
    os << indent << "MaximumMemory: " << m_MaximumMemory << std::endl;
  }

  void
  GenerateOutputInformation() override
  {
    dcv::CompressedFile file;
    try
    {
      file = dcv::ReadCompressedFile(m_FileName);
      dcv::CheckDecodingMemory(file.header, file.name, dcv::DecodeOutput::Volume, { m_MaximumMemory });
    }
    catch (const dcv::FormatError & e)
    {
      itkExceptionMacro(<< e.what());
    }
    if (file.payload != m_File.payload || file.header.numberOfPoints != m_File.header.numberOfPoints)
    {
      m_File = std::move(file);
      m_Decoded = false;
    }
    CopyDCVGeometry(m_File.header, this->GetOutput());
  }

  void
  GenerateData() override
  {
    OutputImageType * output = this->GetOutput();
    const auto        region = output->GetRequestedRegion();
    output->SetBufferedRegion(region);
    output->Allocate();
    if (!m_Decoded)
    {
      try
      {
        m_Approximation = dcv::Decode(m_File, { m_MaximumMemory });
      }
      catch (const dcv::FormatError & e)
      {
        itkExceptionMacro(<< e.what());
      }
      m_Decoded = true;
    }
    dcv::GridPoint first, last;
    for (unsigned int d = 0; d < 3; ++d)
    {
      first[d] = int32_t(region.GetIndex()[d]);
      last[d] = int32_t(region.GetIndex()[d] + IndexValueType(region.GetSize()[d]) - 1);
    }
    m_NumberOfRasterizedCells = dcv::RasterizeBox(m_Approximation, first, last, output->GetBufferPointer());
  }

private:
  std::string         m_FileName;
  dcv::CompressedFile m_File;
  dcv::Approximation  m_Approximation;
  bool                m_Decoded{ false };
  SizeValueType       m_NumberOfRasterizedCells{ 0 };
  uint64_t            m_MaximumMemory{ dcv::DefaultMaximumMemory() };
};

} // namespace itk

#endif
