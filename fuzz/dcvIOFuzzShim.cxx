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
// The ITK side of the IO fuzz target (fuzz/dcvIOFuzzer.cxx): Debian's ITK 5.2 headers refuse clang, so
// this file and src/itk/itkDCV{Image,Mesh}IO.cxx are compiled by g++ (with ASan and UBSan) and linked into the
// clang-built libFuzzer driver, which holds the coverage-instrumented ITK-free core. One C function: the
// input is written to a .dcv file and read as every ITK caller reads one, through DCVImageIO (CanReadFile,
// ReadImageInformation, Read into a buffer of the size it reports) and DCVMeshIO (CanReadFile,
// ReadMeshInformation, ReadPoints, ReadCells, ReadPointData). An itk::ExceptionObject is the expected
// refusal of a damaged file; anything else escaping (another exception, a crash, a sanitizer report) is a
// finding: abort() so that libFuzzer keeps the input.
#include "itkDCVImageIO.h"
#include "itkDCVMeshIO.h"

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <string>
#include <vector>

#include <unistd.h>

namespace
{
// The decoders' own limit keeps every input within libFuzzer's memory limit (-rss_limit_mb=2048).
constexpr uint64_t MaximumMemory = uint64_t(64) << 20;

std::string directory;

void
RemoveDirectory()
{
  std::remove((directory + "/input.dcv").c_str());
  ::rmdir(directory.c_str());
}

const std::string &
InputPath()
{
  static const std::string path = [] {
    const char * tmp = std::getenv("TMPDIR");
    std::string  pattern = std::string(tmp && *tmp ? tmp : "/tmp") + "/dcv-io-fuzz-XXXXXX";
    if (!::mkdtemp(pattern.data()))
    {
      std::perror("dcvIOFuzzShim: mkdtemp");
      std::abort();
    }
    directory = pattern;
    std::atexit(RemoveDirectory);
    return directory + "/input.dcv";
  }();
  return path;
}

void
ReadImage(const char * path)
{
  auto io = itk::DCVImageIO::New();
  io->SetMaximumMemory(MaximumMemory);
  if (!io->CanReadFile(path))
    return;
  io->SetFileName(path);
  try
  {
    io->ReadImageInformation();
  }
  catch (const itk::ExceptionObject &)
  {
    return;
  }
  // ImageFileReader allocates the image from what ReadImageInformation reported, then calls Read.
  std::vector<char> buffer(io->GetImageSizeInBytes());
  try
  {
    io->Read(buffer.data());
  }
  catch (const itk::ExceptionObject &)
  {}
}

void
ReadMesh(const char * path)
{
  auto io = itk::DCVMeshIO::New();
  io->SetMaximumMemory(MaximumMemory);
  if (!io->CanReadFile(path))
    return;
  io->SetFileName(path);
  try
  {
    io->ReadMeshInformation();
  }
  catch (const itk::ExceptionObject &)
  {
    return;
  }
  // MeshFileReader's buffers, of the sizes ReadMeshInformation reported (double points and point data,
  // uint32 cells).
  std::vector<double> points(io->GetNumberOfPoints() * io->GetPointDimension());
  io->ReadPoints(points.data());
  std::vector<uint32_t> cells(io->GetCellBufferSize());
  io->ReadCells(cells.data());
  std::vector<double> values(io->GetNumberOfPointPixels() * io->GetNumberOfPointPixelComponents());
  io->ReadPointData(values.data());
}
} // namespace

extern "C" int
dcvFuzzReadWithITK(const uint8_t * data, size_t size)
{
  const std::string & path = InputPath();
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char *>(data), std::streamsize(size));
    if (!out.flush())
    {
      std::fprintf(stderr, "dcvIOFuzzShim: cannot write %s\n", path.c_str());
      std::abort();
    }
  }
  try
  {
    ReadImage(path.c_str());
    ReadMesh(path.c_str());
  }
  catch (const std::exception & e)
  {
    std::fprintf(stderr, "dcvIOFuzzShim: unexpected exception: %s\n", e.what());
    std::abort();
  }
  catch (...)
  {
    std::fprintf(stderr, "dcvIOFuzzShim: unexpected exception of unknown type\n");
    std::abort();
  }
  return 0;
}
