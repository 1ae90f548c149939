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
#ifndef itkDCVImageIO_h
#define itkDCVImageIO_h

#include "DelaunayCompressionExport.h"
#include "itkImageIOBase.h"

namespace itk
{

/** \class DCVImageIO
 * \brief Reads .dcv files (docs/format.md) as images, so that ImageFileReader opens them.
 *
 * The header gives the size, spacing, origin, direction and pixel type; reading decodes the points
 * and values, rebuilds their Delaunay tetrahedralization and rasterizes it, exactly as `dcv
 * decompress` does. A file is recognised by its extension (.dcv) and its magic bytes. Writing is done
 * by the encoder (`dcv compress`), not by this IO: CanWriteFile() is false.
 * \ingroup DelaunayCompression
 */
class DelaunayCompression_EXPORT DCVImageIO : public ImageIOBase
{
public:
  ITK_DISALLOW_COPY_AND_MOVE(DCVImageIO);

  using Self = DCVImageIO;
  using Superclass = ImageIOBase;
  using Pointer = SmartPointer<Self>;
  using ConstPointer = SmartPointer<const Self>;

  itkNewMacro(Self);
  itkTypeMacro(DCVImageIO, ImageIOBase);

  bool
  CanReadFile(const char * fileName) override;
  void
  ReadImageInformation() override;
  void
  Read(void * buffer) override;

  bool
  CanWriteFile(const char *) override
  {
    return false;
  }
  void
  WriteImageInformation() override
  {}
  void
  Write(const void *) override;

protected:
  DCVImageIO();
  ~DCVImageIO() override = default;
  void
  PrintSelf(std::ostream & os, Indent indent) const override;
};

} // namespace itk

#endif
