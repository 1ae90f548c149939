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
#include "dcvTools.h"

#include "itkImageIOFactory.h"

#include <cstdio>
#include <memory>
#include <unistd.h>

namespace fs = std::filesystem;

namespace dcv::tools
{

itk::ImageIOBase::Pointer
ReadVolumeHeader(const std::string & path)
{
  if (!fs::exists(path))
  {
    throw Failure("cannot read " + Quoted(path) + ": no such file");
  }
  if (fs::is_directory(path))
  {
    throw Failure("cannot read " + Quoted(path) + ": it is a directory, not a volume file");
  }
  auto io = itk::ImageIOFactory::CreateImageIO(path.c_str(), itk::IOFileModeEnum::ReadMode);
  if (!io)
  {
    throw Failure("cannot read " + Quoted(path) + ": not an image format ITK knows (NRRD, NIfTI, MetaImage, ...)");
  }
  io->SetFileName(path);
  try
  {
    io->ReadImageInformation();
  }
  catch (const itk::ExceptionObject & e)
  {
    throw Failure("cannot read " + Quoted(path) + ": " + e.GetDescription());
  }
  const unsigned int dimensions = io->GetNumberOfDimensions();
  if (dimensions != 3)
  {
    throw Failure(Quoted(path) + " is a " + std::to_string(dimensions) + "D image; a 3D volume is needed");
  }
  if (io->GetNumberOfComponents() != 1)
  {
    throw Failure(Quoted(path) + " has " + std::to_string(io->GetNumberOfComponents()) + " components per voxel (" +
                  itk::ImageIOBase::GetPixelTypeAsString(io->GetPixelType()) + " pixels); a scalar volume is needed");
  }
  for (unsigned int d = 0; d < 3; ++d)
  {
    if (io->GetDimensions(d) < 2)
    {
      throw Failure(Quoted(path) + " is " + std::to_string(io->GetDimensions(0)) + "x" +
                    std::to_string(io->GetDimensions(1)) + "x" + std::to_string(io->GetDimensions(2)) +
                    " voxels; at least 2 voxels along each axis are needed");
    }
  }
  return io;
}

PixelType
ReadVolumePixelType(const std::string & path)
{
  const auto io = ReadVolumeHeader(path);
  try
  {
    return itk::DCVPixelType(io->GetComponentType(), Quoted(path));
  }
  catch (const itk::ExceptionObject & e)
  {
    throw Failure(e.GetDescription());
  }
}

VolumeInput
OpenVolume(const std::string & path, const std::string & series, bool resample)
{
  VolumeInput v;
  v.path = path;
  if (!fs::exists(path))
  {
    throw Failure("cannot read " + Quoted(path) + ": no such file");
  }
  if (!IsDicomInput(path))
  {
    if (!series.empty())
    {
      throw Failure("--series chooses a DICOM series; " + Quoted(path) + " is not DICOM");
    }
    v.type = ReadVolumePixelType(path);
    return v;
  }
  v.dicom = FindDicomSeries(path, series, v.skipped);
  v.resampling = CheckDicomSlices("the DICOM series " + Quoted(path), ReadDicomSlices(v.dicom), resample);
  v.type = DicomPixelType(v.dicom);
  v.metadata = DicomMetadata(v.dicom);
  if (v.resampling.needed)
  {
    v.metadata.emplace_back("Resampled", v.resampling.description); // the DICOM writer's derivation says so
  }
  return v;
}

void
CheckOutput(const std::string & output, bool force, bool dcvFile)
{
  CheckOutputPath(output, force);
  if (dcvFile)
  {
    if (fs::path(output).extension() != ".dcv")
    {
      throw Failure("cannot write " + Quoted(output) + ": a compressed volume's file name ends in .dcv");
    }
  }
  else if (!itk::ImageIOFactory::CreateImageIO(output.c_str(), itk::IOFileModeEnum::WriteMode))
  {
    throw Failure("cannot write " + Quoted(output) +
                  ": no image format is known for that file name "
                  "(use .nrrd, .nii.gz, .mha, ...)");
  }
}

void
CheckOutputPath(const std::string & output, bool force)
{
  if (fs::exists(output) && !force)
  {
    throw Failure(Quoted(output) + " already exists; use --force to overwrite it");
  }
  if (fs::is_directory(output))
  {
    throw Failure(Quoted(output) + " is a directory");
  }
  const fs::path parent = fs::absolute(output).parent_path();
  if (!fs::is_directory(parent))
  {
    throw Failure("cannot write " + Quoted(output) + ": directory " + Quoted(parent.string()) + " does not exist");
  }
}

namespace
{
/** Formats whose header names its data file: renaming the header would break it. */
bool
IsSeveralFiles(const fs::path & target)
{
  std::string extension = target.extension().string();
  if (extension == ".gz")
  {
    extension = target.stem().extension().string() + extension;
  }
  for (const char * e : { ".mhd", ".hdr", ".img", ".img.gz", ".hdr.gz", ".nhdr" })
  {
    if (extension == e)
      return true;
  }
  return false;
}
} // namespace

std::string
TemporaryOutput(const std::string & output)
{
  const fs::path target(output);
  if (IsSeveralFiles(target))
  {
    return output;
  }
  // The same name after a prefix, so that ITK picks the format from the same extension.
  return (target.parent_path() / (".dcv-" + std::to_string(::getpid()) + "-" + target.filename().string())).string();
}

void
FinishOutput(const std::string & temporary, const std::string & output, bool failed)
{
  std::error_code error;
  if (failed)
  {
    fs::remove(temporary, error);
    return;
  }
  if (temporary != output)
  {
    fs::rename(temporary, output, error);
    if (error)
    {
      fs::remove(temporary, error);
      throw Failure("cannot write " + Quoted(output) + ": rename failed");
    }
  }
}

CompressedFile
ParseCompressedBytes(const std::vector<uint8_t> & bytes, const std::string & name)
{
  CompressedFile file;
  file.name = name;
  file.size = bytes.size();
  ParseFile(bytes, file.name, file.header, file.payload);
  return file;
}

std::function<void(double)>
TerminalProgress(const std::string & label, bool quiet)
{
  if (quiet || !::isatty(2))
  {
    return {};
  }
  auto last = std::make_shared<int>(-1);
  return [label, last](double fraction) {
    const int percent = int(fraction * 100.0);
    if (percent != *last)
    {
      *last = percent;
      std::fprintf(stderr, "\r%s %3d%%", label.c_str(), percent);
      if (percent >= 100)
      {
        std::fprintf(stderr, "\r%*s\r", int(label.size()) + 6, "");
      }
      std::fflush(stderr);
    }
  };
}

} // namespace dcv::tools
