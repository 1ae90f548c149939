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
// atomic outputs (the progress of a job: dcvProgress.h).
#include "dcvCodec.h"
#include "dcvFileFormat.h"
#include "itkDCVImageInformation.h"
#include "itkImageFileReader.h"
#include "itkImageFileWriter.h"
#include "itkImageIOBase.h"
#include "itkImageSeriesReader.h"

#include "dcvDicom.h"
#include "dcvDicomHeader.h"
#include "dcvGDCM.h"

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace dcv::tools
{

/** A user-facing failure: the message names the file and the problem; printed as "dcv: message"
 * with exit status 1. */
struct Failure : std::runtime_error
{
  using std::runtime_error::runtime_error;
};

/** A failure of the command line itself (an option out of range, an output name no format has, the
 * output given as the input): what can be told without reading any input. Exit status 2. */
struct UsageError : Failure
{
  using Failure::Failure;
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
  DicomResampling                                  resampling; // the grid; needed: a tilted or uneven series, resampled
};

/** Opens a volume: checks a volume file's header (ReadVolumeHeader), or finds and checks a DICOM series
 * (`series`: its Series Instance UID, needed when a directory holds several; `resample`: a tilted or
 * unevenly spaced series is resampled instead of refused; every file's pixel data whole); Failure
 * otherwise. A series on its own grid keeps every file's header (`header`: all of it, or the essential
 * attributes) in its metadata, as the "DICOM Header" pair (ReadDicomHeaders). */
VolumeInput
OpenVolume(const std::string & path, const std::string & series = "", bool resample = false,
           DicomHeaderMode header = DicomHeaderMode::Full);

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
  reader->SetImageIO(GDCM().newImageIO());
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
  // The grid the checks found in the slices' headers (CheckDicomSlices), as for a resampled series: the
  // series reader's own comes from GDCM, which reads no image plane in Secondary Capture images.
  typename itk::Image<T, 3>::Pointer image = reader->GetOutput();
  PlaceOnGrid(*image, v.resampling);
  return image;
}

/** Refuses to clobber an existing file unless forced, a missing directory, and (unless `dcvFile`) a
 * name no ITK image format writes (UsageError); with `dcvFile` the name must end in .dcv. */
void
CheckOutput(const std::string & output, bool force, bool dcvFile = false);

/** CheckOutput's checks of the path alone (an existing file unless forced, a directory, a missing
 * directory), for outputs whose format the caller checks (meshes). */
void
CheckOutputPath(const std::string & output, bool force);

/** Refuses (UsageError) an output that is one of the inputs, compared by file-system identity (device
 * and inode), so that no spelling of the same path (links, ./, ..) overwrites what is being read. */
void
CheckOutputIsNotInput(const std::vector<std::string> & inputs, const std::string & output);

/** While it lives, a temporary file (or a directory of files, one level) that SIGINT, SIGTERM and SIGHUP
 * remove before the process dies of them (async-signal-safe: a fixed table, unlink, rmdir). The
 * handlers are installed by the first registration, for the signals nobody else handles or ignores.
 * SIGKILL cannot be caught: its leftovers are named `.dcv-PID-*` (README, "Outputs"). */
class RemovedOnSignal
{
public:
  RemovedOnSignal(const std::string & path, bool directory);
  ~RemovedOnSignal();
  RemovedOnSignal(const RemovedOnSignal &) = delete;
  RemovedOnSignal &
  operator=(const RemovedOnSignal &) = delete;

private:
  int m_Slot{ -1 };
};

/** An output on its way to its name. It is written under a temporary name in the target's directory
 * (`.dcv-PID-NAME`, keeping NAME's extension so that ITK picks the same format; `.dcv-PID-NAME.tmp` for
 * bytes; for the formats of several files, .mhd/.raw, .hdr/.img, .nhdr, a directory `.dcv-PID-NAME.tmp`
 * holding them), registered so that SIGINT, SIGTERM and SIGHUP remove it, and removed on destruction
 * unless Commit() gave it its name. */
class PendingOutput
{
public:
  /** `itkFormat`: ITK picks the writer from Path()'s extension (else the bytes are written by hand);
   * `force`: Commit() may replace an existing file. Nothing is flushed to the disk here: a volume or a
   * mesh decoded or converted from an input that stays is not, as cp, gzip or ITK's writers do not
   * (norm-256 at 0.03125 bpv: the flush was 12% of `dcv decompress`); WriteOutputBytes flushes a .dcv
   * file, which may be the only copy once the original is deleted. */
  PendingOutput(const std::string & output, bool force, bool itkFormat);
  ~PendingOutput();
  PendingOutput(const PendingOutput &) = delete;
  PendingOutput &
  operator=(const PendingOutput &) = delete;

  /** Where to write. */
  const std::string &
  Path() const
  {
    return m_Path;
  }
  /** Moves what was written to the output's name: without `force` only if no file of that name appeared
   * meanwhile (renameat2 RENAME_NOREPLACE, else link and
   * unlink, both atomic); Failure naming the output otherwise, and the temporary is removed. */
  void
  Commit();

  /** After a failed write, the cause when the disk or a limit tells it ("the disk is full ...", a
   * `ulimit -f` size reached), else empty. */
  std::string
  LimitReached() const;

private:
  std::string                      m_Output;
  std::string                      m_Path;      // the temporary file
  std::string                      m_Directory; // the temporary directory of a format of several files, else empty
  bool                             m_Force;
  bool                             m_Committed{ false };
  std::unique_ptr<RemovedOnSignal> m_Registration;

  /** The files written, the header last. */
  std::vector<std::filesystem::path>
  Files() const;
};

/** Writes bytes (a .dcv file) to `output` through a PendingOutput, flushed to the disk before the rename
 * (a crash after it never leaves an empty file under the name): a failure (a full disk, a missing
 * permission) never leaves a partial or empty file, and is a Failure naming the file and the cause. */
void
WriteOutputBytes(const std::string & output, const std::vector<uint8_t> & bytes, bool force);

/** Whether the file `path` ends with the `n` bytes at `bytes` (read a block at a time). */
bool
FileEndsWith(const std::string & path, const void * bytes, std::size_t n);

/** Writes an image (gzip compressed where the format allows, unless `compression` is false) through a
 * PendingOutput, so that a failure never leaves a partial or empty file under the output's name; `force`:
 * an existing file may be replaced. Every image written is made from an input that stays (decoded,
 * converted, generated): not flushed to the disk (PendingOutput). */
template <typename TImage>
void
WriteVolume(const TImage * image, const std::string & output, bool force, bool compression = true)
{
  PendingOutput pending(output, force, true);
  auto          writer = itk::ImageFileWriter<TImage>::New();
  writer->SetInput(image);
  writer->SetFileName(pending.Path());
  writer->SetUseCompression(compression);
  try
  {
    writer->Update();
  }
  catch (const itk::ExceptionObject & e)
  {
    const std::string limit = pending.LimitReached();
    throw Failure("cannot write " + Quoted(output) + ": " + (limit.empty() ? e.GetDescription() : limit));
  }
  // ITK's MetaImage, NIfTI and Analyze writers report a failed write (a full disk) on stderr only, and
  // their readers take the short file without an error: what was written is read back and compared.
  // Uncompressed, a file of one piece ends with the voxels as they are in memory (NRRD, MetaImage): then
  // comparing its end is enough, without a reader and a second volume; otherwise ITK reads it back.
  const auto n = image->GetBufferedRegion().GetNumberOfPixels();
  bool       same =
    !compression && FileEndsWith(pending.Path(), image->GetBufferPointer(), n * sizeof(typename TImage::PixelType));
  try
  {
    if (!same)
    {
      auto reader = itk::ImageFileReader<TImage>::New();
      reader->SetFileName(pending.Path());
      reader->Update();
      const TImage * back = reader->GetOutput();
      same =
        back->GetBufferedRegion().GetSize() == image->GetBufferedRegion().GetSize() &&
        std::memcmp(back->GetBufferPointer(), image->GetBufferPointer(), n * sizeof(typename TImage::PixelType)) == 0;
    }
  }
  catch (const itk::ExceptionObject &)
  {}
  if (!same)
  {
    const std::string limit = pending.LimitReached();
    throw Failure(
      "cannot write " + Quoted(output) + ": " +
      (limit.empty() ? "the file written reads back short or different (a write failed: the disk full?)" : limit));
  }
  pending.Commit();
}

/** Parses the bytes of a whole .dcv file made in memory, as ReadCompressedFile() parses a file (FormatError
 * starting with `name` otherwise). */
CompressedFile
ParseCompressedBytes(const std::vector<uint8_t> & bytes, const std::string & name);

/** Decodes a parsed .dcv file as every reader does (DecodeVolume: rounded and clamped to T) into
 * an itk::Image of pixel type T with the file's geometry. */
template <typename T>
typename itk::Image<T, 3>::Pointer
DecodeImage(const CompressedFile & file, const DecodeLimits & limits = DecodeLimits())
{
  CheckDecodingMemory(file.header, file.name, DecodeOutput::Volume, limits); // before the image is allocated
  auto image = itk::Image<T, 3>::New();
  itk::CopyDCVGeometry(file.header, image.GetPointer());
  image->SetBufferedRegion(image->GetLargestPossibleRegion());
  image->Allocate();
  DecodeVolume(file, image->GetBufferPointer(), limits);
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

/** ReadVolume, WriteVolume and DecodeImage for an image of pixel type T: the explicit instantiation
 * declarations (EXTERN: extern) or definitions (EXTERN empty). */
#define DCV_TOOLS_INSTANTIATION(EXTERN, T)                                                                             \
  EXTERN template itk::Image<T, 3>::Pointer ReadVolume<T>(const std::string &);                                        \
  EXTERN template itk::Image<T, 3>::Pointer ReadVolume<T>(const VolumeInput &);                                        \
  EXTERN template void                      WriteVolume(const itk::Image<T, 3> *, const std::string &, bool, bool);    \
  EXTERN template itk::Image<T, 3>::Pointer DecodeImage<T>(const CompressedFile &, const DecodeLimits &)

// ITK's readers (a file, a DICOM series) and writers for the .dcv pixel types are compiled once, in
// dcvToolsInstantiations*.cxx, instead of again in every program that reads, writes or decodes a volume.
DCV_TOOLS_INSTANTIATION(extern, uint8_t);
DCV_TOOLS_INSTANTIATION(extern, int8_t);
DCV_TOOLS_INSTANTIATION(extern, uint16_t);
DCV_TOOLS_INSTANTIATION(extern, int16_t);
DCV_TOOLS_INSTANTIATION(extern, uint32_t);
DCV_TOOLS_INSTANTIATION(extern, int32_t);
DCV_TOOLS_INSTANTIATION(extern, float);
DCV_TOOLS_INSTANTIATION(extern, double);

} // namespace dcv::tools

#endif
