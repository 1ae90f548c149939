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
#include "dcvEncoder.h"
#include "dcvFileFormat.h"
#include "itkImageIOBase.h"

namespace itk
{

/** \class DCVImageIO
 * \brief Reads and writes .dcv files (docs/format.md) as images, so that ImageFileReader and
 * ImageFileWriter handle them like any other format.
 *
 * Reading: the header gives the size, spacing, origin, direction and pixel type; Read() decodes the
 * points and values, rebuilds their Delaunay tetrahedralization and rasterizes it, exactly as `dcv
 * decompress` does. The file is read and checked once (ReadImageInformation keeps it for Read).
 *
 * Writing: the encoder (dcv::Encode, as `dcv compress`) with these settings; the file is byte for byte
 * what `dcv compress` writes with the same options. The target is the last one set:
 * - BitsPerVoxel (default 0.125): the whole file in bits per voxel, as `dcv compress --bpv`;
 * - PSNR (dB; 0 until set): the smallest file whose decoded PSNR reaches it, as `--psnr`;
 * - NumberOfPoints (10000 until set): a point count, as `--points`;
 * - MaximumError (negative until set): every voxel within it of the input, 0 lossless, as `--max-error`.
 * Also Mode (default dcv::Mode::Best) and QuantizationStep (default 0: automatic, as `--step`).
 * UseCompression and CompressionLevel have no effect: a .dcv file is always compressed.
 * 8, 16 and 32-bit integer, float and double scalar 3D images are written; others are refused.
 *
 * MaximumMemory (bytes; default dcv::DefaultMaximumMemory(), half of the physical memory; 0: no limit):
 * ReadImageInformation() refuses a file whose decoding would need more (dcv::DecodingMemory(): the
 * voxels, the points and their tetrahedra), before the image or anything else is allocated, as `dcv
 * decompress --max-memory`.
 *
 * A file is recognised by its extension (.dcv) and its magic bytes.
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

  /** Writing targets: setting one turns the others off. */
  void
  SetBitsPerVoxel(double bitsPerVoxel);
  double
  GetBitsPerVoxel() const
  {
    return m_Options.bitsPerVoxel;
  }
  void
  SetPSNR(double psnr);
  double
  GetPSNR() const
  {
    return m_Options.psnr;
  }
  void
  SetMaximumError(double maximumError);
  double
  GetMaximumError() const
  {
    return m_Options.maximumError;
  }
  void
  SetNumberOfPoints(SizeValueType numberOfPoints);
  SizeValueType
  GetNumberOfPoints() const
  {
    return m_Options.numberOfPoints;
  }
  void
  SetMode(dcv::Mode mode);
  dcv::Mode
  GetMode() const
  {
    return m_Options.mode;
  }
  void
  SetQuantizationStep(double step);
  double
  GetQuantizationStep() const
  {
    return m_Options.quantizationStep;
  }
  /** Reading: the most memory (bytes) that decoding a file may need; 0: no limit. */
  itkSetMacro(MaximumMemory, uint64_t);
  itkGetConstMacro(MaximumMemory, uint64_t);

  /** All the encoder's options at once (metadata and method parameters included). */
  void
  SetEncoderOptions(const dcv::EncoderOptions & options);
  const dcv::EncoderOptions &
  GetEncoderOptions() const
  {
    return m_Options;
  }
  /** What the last Write() made: header, points, step, PSNR of the decoded image, seconds (its bytes
   * and approximation are not kept). */
  const dcv::EncoderResult &
  GetLastEncoderResult() const
  {
    return m_LastResult;
  }

  bool
  CanReadFile(const char * fileName) override;
  void
  ReadImageInformation() override;
  void
  Read(void * buffer) override;

  bool
  CanWriteFile(const char * fileName) override;
  void
  WriteImageInformation() override
  {}
  void
  Write(const void * buffer) override;

protected:
  DCVImageIO();
  ~DCVImageIO() override = default;
  void
  PrintSelf(std::ostream & os, Indent indent) const override;

private:
  dcv::EncoderOptions m_Options;
  dcv::EncoderResult  m_LastResult;
  dcv::CompressedFile m_File; // as ReadImageInformation() read it, for Read()
  uint64_t            m_MaximumMemory{ dcv::DefaultMaximumMemory() };
};

} // namespace itk

#endif
