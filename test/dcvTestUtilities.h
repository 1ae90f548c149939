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
#ifndef dcvTestUtilities_h
#define dcvTestUtilities_h

#include "dcvApproximation.h"
#include "dcvPhantom.h"

#include "itkImageFileReader.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>
#include <string>
#include <sys/wait.h>
#include <unistd.h>

namespace dcv::test
{

/** A real volume of ../shared/data as floats, with its PSNR peak. */
struct Volume
{
  GridSize           grid;
  std::vector<float> voxels;
  double             peak{ 255.0 };
};

/** The real volumes: $DCV_DATA_DIR when set, else ../shared/data next to the source tree. */
inline std::string
DataFile(const std::string & name)
{
  const char * directory = std::getenv("DCV_DATA_DIR");
  return std::string(directory && *directory ? directory : DCV_DATA_DIR) + "/" + name;
}

inline bool
HaveData(const std::string & name)
{
  return std::filesystem::exists(DataFile(name));
}

/** Skips the calling test, with the reason, when a shared volume is not there. */
#define DCV_REQUIRE_DATA(name)                                                                                         \
  if (!dcv::test::HaveData(name))                                                                                      \
  {                                                                                                                    \
    GTEST_SKIP() << "needs " << dcv::test::DataFile(name) << " (../shared/data is absent)";                            \
  }

inline Volume
ReadVolume(const std::string & name)
{
  using ImageType = itk::Image<float, 3>;
  auto reader = itk::ImageFileReader<ImageType>::New();
  reader->SetFileName(DataFile(name));
  reader->Update();
  const auto * image = reader->GetOutput();
  const auto   size = image->GetLargestPossibleRegion().GetSize();
  Volume       v;
  v.grid = GridSize{ int32_t(size[0]), int32_t(size[1]), int32_t(size[2]) };
  v.voxels.assign(image->GetBufferPointer(), image->GetBufferPointer() + v.grid.NumberOfVoxels());
  const auto range = std::minmax_element(v.voxels.begin(), v.voxels.end());
  const bool eightBit = reader->GetImageIO()->GetComponentSize() == 1;
  v.peak = PSNRPeak(*range.first, *range.second, eightBit);
  return v;
}

/** What a run of the dcv tool gave. */
struct Result
{
  int         status;
  std::string output; // stdout and stderr
};

/** Runs a shell command and collects its standard output. */
inline Result
RunCommand(const std::string & command)
{
  FILE * pipe = ::popen(command.c_str(), "r");
  Result r{ -1, "" };
  if (!pipe)
    return r;
  char buffer[4096];
  while (std::size_t n = std::fread(buffer, 1, sizeof(buffer), pipe))
    r.output.append(buffer, n);
  const int status = ::pclose(pipe);
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

/** Runs `dcv ARGUMENTS` (the tool built with the tests), stdout and stderr together. */
inline Result
RunDcv(const std::string & arguments)
{
  return RunCommand(std::string(DCV_EXECUTABLE) + " " + arguments + " 2>&1");
}

/** A Shepp-Logan phantom image; `oblique` puts it on a rotated, anisotropic, shifted grid (spacing 0.5,
 * 1, 2.5; a quarter turn about z) whose region starts at `start`. */
inline itk::Image<uint8_t, 3>::Pointer
PhantomImage(const GridSize & grid, bool oblique = false, const itk::Index<3> & start = { { 0, 0, 0 } })
{
  using ImageType = itk::Image<uint8_t, 3>;
  auto                image = ImageType::New();
  ImageType::SizeType size{ { itk::SizeValueType(grid.x), itk::SizeValueType(grid.y), itk::SizeValueType(grid.z) } };
  image->SetRegions(ImageType::RegionType(start, size));
  image->Allocate();
  const auto voxels = SheppLoganPhantom(grid);
  std::copy(voxels.begin(), voxels.end(), image->GetBufferPointer());
  if (oblique)
  {
    ImageType::SpacingType spacing;
    spacing[0] = 0.5;
    spacing[1] = 1.0;
    spacing[2] = 2.5;
    image->SetSpacing(spacing);
    ImageType::PointType origin;
    origin[0] = 10.0;
    origin[1] = -5.0;
    origin[2] = 3.25;
    image->SetOrigin(origin);
    ImageType::DirectionType direction;
    direction.Fill(0.0);
    direction(0, 1) = 1.0;
    direction(1, 0) = -1.0;
    direction(2, 2) = 1.0;
    image->SetDirection(direction);
  }
  return image;
}

/** A fresh directory for one test, removed with the object. */
class TemporaryDirectory
{
public:
  TemporaryDirectory()
    : m_Path(std::filesystem::temp_directory_path() / ("dcv-test-" + std::to_string(::getpid()) + "-" +
                                                       ::testing::UnitTest::GetInstance()->current_test_info()->name()))
  {
    std::filesystem::remove_all(m_Path);
    std::filesystem::create_directories(m_Path);
  }
  ~TemporaryDirectory() { std::filesystem::remove_all(m_Path); }
  std::string
  operator/(const std::string & name) const
  {
    return (m_Path / name).string();
  }

private:
  std::filesystem::path m_Path;
};

/** The bytes of a file. */
inline std::string
FileBytes(const std::string & path)
{
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/** The 8 corners of a grid. */
inline std::vector<GridPoint>
Corners(const GridSize & g)
{
  std::vector<GridPoint> out;
  for (int k = 0; k < 8; ++k)
  {
    out.push_back({ (k & 1) ? g.x - 1 : 0, (k & 2) ? g.y - 1 : 0, (k & 4) ? g.z - 1 : 0 });
  }
  return out;
}

/** Every cell of a CGAL 3D triangulation whose vertices hold their ids as info, infinite cells too (the
 * infinite vertex as 0xffffffff), as its vertices' ids in the cell's own order, sorted: two triangulations
 * list the same when they have the same cells with their vertices in the same order. */
template <typename TTriangulation>
std::vector<std::array<uint32_t, 4>>
ListedCells(const TTriangulation & dt)
{
  std::vector<std::array<uint32_t, 4>> out;
  for (auto c = dt.all_cells_begin(); c != dt.all_cells_end(); ++c)
  {
    std::array<uint32_t, 4> ids;
    for (int i = 0; i < 4; ++i)
      ids[std::size_t(i)] = dt.is_infinite(c->vertex(i)) ? 0xffffffffu : uint32_t(c->vertex(i)->info());
    out.push_back(ids);
  }
  std::sort(out.begin(), out.end());
  return out;
}

/** Corners plus `n` distinct random grid points. */
inline std::vector<GridPoint>
RandomPoints(const GridSize & g, std::size_t n, unsigned seed)
{
  std::vector<GridPoint> out = Corners(g);
  std::mt19937           random(seed);
  std::vector<char>      used(g.NumberOfVoxels(), 0);
  for (const auto & p : out)
  {
    used[g.Offset(p[0], p[1], p[2])] = 1;
  }
  while (out.size() < n + 8 && out.size() < g.NumberOfVoxels())
  {
    const GridPoint p{ int32_t(random() % g.x), int32_t(random() % g.y), int32_t(random() % g.z) };
    char &          u = used[g.Offset(p[0], p[1], p[2])];
    if (!u)
    {
      u = 1;
      out.push_back(p);
    }
  }
  return out;
}

} // namespace dcv::test

#endif
