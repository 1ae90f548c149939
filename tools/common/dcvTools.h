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
#ifndef dcvTools_h
#define dcvTools_h

// The layer every program of the project shares (dcv, the benchmarks, and the DICOM, batch and Slicer
// tools to come): user-facing errors, reading any volume ITK reads, dispatch on its pixel type,
// atomic outputs, and progress on a terminal.
#include "dcvCodec.h"
#include "dcvFileFormat.h"
#include "itkDCVImageInformation.h"
#include "itkImageFileReader.h"
#include "itkImageFileWriter.h"
#include "itkGDCMImageIO.h"
#include "itkImageIOBase.h"
#include "itkImageSeriesReader.h"

#include "dcvDicom.h"

#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>

namespace dcv::tools
{

/** A user-facing failure: the message names the file and the problem; printed as "dcv: message"
 * with exit status 1. */
struct Failure : std::runtime_error
{
  using std::runtime_error::runtime_error;
};

inline std::string
Quoted(const std::string & path)
{
  return "'" + path + "'";
}

/** Reads a volume file's header and checks that it is a 3D scalar volume of a .dcv pixel type with at
 * least 2 voxels along each axis; throws Failure otherwise. */
itk::ImageIOBase::Pointer
ReadVolumeHeader(const std::string & path);

/** The pixel type of a volume file (ReadVolumeHeader's checks included). */
PixelType
ReadVolumePixelType(const std::string & path);

/** Reads a volume as an image of pixel type T; throws Failure naming the file. */
template <typename T>
typename itk::Image<T, 3>::Pointer
ReadVolume(const std::string & path)
{
  auto reader = itk::ImageFileReader<itk::Image<T, 3>>::New();
  reader->SetFileName(path);
  try
  {
    reader->Update();
  }
  catch (const itk::ExceptionObject & e)
  {
    throw Failure("cannot read " + Quoted(path) + ": " + e.GetDescription());
  }
  return reader->GetOutput();
}

/** A volume to read: a volume file, or a DICOM series (a directory, or one of its files). */
struct VolumeInput
{
  std::string                                      path;
  PixelType                                        type{ PixelType::UInt8 };
  DicomSeries                                      dicom;        // files empty: not DICOM
  std::vector<std::pair<std::string, std::string>> metadata;     // what a derived file keeps (DICOM attributes)
  std::size_t                                      skipped{ 0 }; // files of a DICOM directory that are not DICOM
  DicomResampling                                  resampling;   // needed: a tilted or uneven series, resampled
};

/** Opens a volume: checks a volume file's header (ReadVolumeHeader), or finds and checks a DICOM series
 * (`series`: its Series Instance UID, needed when a directory holds several; `resample`: a tilted or
 * unevenly spaced series is resampled instead of refused); Failure otherwise. */
VolumeInput
OpenVolume(const std::string & path, const std::string & series = "", bool resample = false);

/** Reads an opened volume as an image of pixel type T (DICOM: rescaled, so CT is in Hounsfield units). */
template <typename T>
typename itk::Image<T, 3>::Pointer
ReadVolume(const VolumeInput & v)
{
  if (v.dicom.files.empty())
  {
    return ReadVolume<T>(v.path);
  }
  if (v.resampling.needed)
  {
    return RoundedImage<T>(ReadResampledDicomSeries(v.dicom, v.resampling).GetPointer());
  }
  auto reader = itk::ImageSeriesReader<itk::Image<T, 3>>::New();
  reader->SetImageIO(itk::GDCMImageIO::New());
  reader->SetFileNames(v.dicom.files);
  reader->MetaDataDictionaryArrayUpdateOff();
  try
  {
    reader->Update();
  }
  catch (const itk::ExceptionObject & e)
  {
    throw Failure("cannot read the DICOM series " + Quoted(v.path) + ": " + e.GetDescription());
  }
  return reader->GetOutput();
}

/** Refuses to clobber an existing file unless forced, a missing directory, and (unless `dcvFile`) a
 * name no ITK image format writes; with `dcvFile` the name must end in .dcv. */
void
CheckOutput(const std::string & output, bool force, bool dcvFile = false);

/** CheckOutput's checks of the path alone (an existing file unless forced, a directory, a missing
 * directory), for outputs whose format the caller checks (meshes). */
void
CheckOutputPath(const std::string & output, bool force);

/** Where a volume is written before it gets its name: a temporary file in the same directory for
 * formats that are one file, the name itself for those that are several (.mhd/.raw, .hdr/.img). */
std::string
TemporaryOutput(const std::string & output);

/** Moves the temporary output to its name; on failure (or `failed`) removes it. */
void
FinishOutput(const std::string & temporary, const std::string & output, bool failed);

/** Writes an image (gzip compressed where the format allows) through TemporaryOutput(), so that a
 * failure never leaves a partial or empty file under the output's name. */
template <typename TImage>
void
WriteVolume(const TImage * image, const std::string & output)
{
  const std::string temporary = TemporaryOutput(output);
  auto              writer = itk::ImageFileWriter<TImage>::New();
  writer->SetInput(image);
  writer->SetFileName(temporary);
  writer->UseCompressionOn();
  try
  {
    writer->Update();
  }
  catch (const itk::ExceptionObject & e)
  {
    FinishOutput(temporary, output, true);
    throw Failure("cannot write " + Quoted(output) + ": " + e.GetDescription());
  }
  FinishOutput(temporary, output, false);
}

/** Parses the bytes of a whole .dcv file made in memory, as ReadCompressedFile() parses a file (FormatError
 * starting with `name` otherwise). */
CompressedFile
ParseCompressedBytes(const std::vector<uint8_t> & bytes, const std::string & name);

/** Decodes a parsed .dcv file as every reader does (Decode, then Rasterize: rounded and clamped to T) into
 * an itk::Image of pixel type T with the file's geometry. */
template <typename T>
typename itk::Image<T, 3>::Pointer
DecodeImage(const CompressedFile & file, const DecodeLimits & limits = DecodeLimits())
{
  const Approximation a = Decode(file, limits); // refuses what exceeds `limits` before allocating
  auto                image = itk::Image<T, 3>::New();
  itk::CopyDCVGeometry(file.header, image.GetPointer());
  image->SetBufferedRegion(image->GetLargestPossibleRegion());
  image->Allocate();
  Rasterize(a, image->GetBufferPointer());
  return image;
}

/** Calls f(image) with the file decoded in its own pixel type (DecodeImage): what `dcv decompress`
 * writes. */
template <typename TFunction>
void
DecodeVolume(const CompressedFile & file, TFunction && f, const DecodeLimits & limits = DecodeLimits())
{
  VisitPixelType(file.header.pixelType, [&](auto pixel) { f(DecodeImage<decltype(pixel)>(file, limits)); });
}

/** A progress function that shows "label NN%" on stderr when it is a terminal (and not `quiet`);
 * an empty function otherwise. */
std::function<void(double)>
TerminalProgress(const std::string & label, bool quiet);

} // namespace dcv::tools

#endif
