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
#ifndef dcvVolumeHeader_h
#define dcvVolumeHeader_h

// The checks every program of the project makes on a volume file before reading it (dcv and
// dcvBenchmark), so that a bad input gets one clear message naming the file.
#include "itkImageIOBase.h"
#include "itkImageIOFactory.h"

#include <filesystem>
#include <stdexcept>
#include <string>

namespace dcv
{

/** A user-facing failure: the message names the file and the problem. */
struct Failure : std::runtime_error
{
  using std::runtime_error::runtime_error;
};

inline std::string
Quoted(const std::string & path)
{
  return "'" + path + "'";
}

/** Reads a volume file's header and checks that it is a 3D scalar volume with at least 2 voxels
 * along each axis; throws Failure otherwise. */
inline itk::ImageIOBase::Pointer
ReadVolumeHeader(const std::string & path)
{
  namespace fs = std::filesystem;
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

} // namespace dcv

#endif
