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
// The encoder's resource limit and its memory model: what a job may need is
// estimated from the grid and the options, and a job above MaximumMemory (--max-memory) is refused before
// the volume is copied, naming what it would need and the limit.
#include "dcvEncoder.h"
#include "dcvTestUtilities.h"
#include "itkDCVEncoder.h"

#include <filesystem>

namespace
{
using dcv::test::RunDcv;
namespace fs = std::filesystem;
} // namespace

TEST(EncoderLimits, TheModelCountsVoxelsAndThePointsTheTargetAllows)
{
  const dcv::GridSize grid{ 100, 100, 100 };
  dcv::EncoderOptions o;
  o.numberOfPoints = 5000;
  EXPECT_EQ(dcv::EncodingMemory(grid, o),
            uint64_t(1e6 * dcv::EncodingBytesPerVoxel + 5000 * dcv::EncodingBytesPerPoint));
  // A budget of 0.125 bits a voxel holds at most 15625 points of 8 bits; the residual layer's buffers
  // count per voxel.
  o.bitsPerVoxel = 0.125;
  EXPECT_EQ(dcv::EncodingMemory(grid, o),
            uint64_t(1e6 * dcv::EncodingBytesPerVoxelWithResidualLayer + 15625 * dcv::EncodingBytesPerPoint));
  o.residualLayer = false;
  EXPECT_EQ(dcv::EncodingMemory(grid, o),
            uint64_t(1e6 * dcv::EncodingBytesPerVoxel + 15625 * dcv::EncodingBytesPerPoint));
  // The largest grid at the largest budget does not overflow.
  o.bitsPerVoxel = dcv::MaximumBitsPerVoxel;
  EXPECT_GT(dcv::EncodingMemory({ 65535, 65535, 65535 }, o),
            uint64_t(65535.0 * 65535.0 * 65535.0 * dcv::EncodingBytesPerVoxelWithResidualLayer));
}

TEST(EncoderLimits, AJobAboveTheLimitIsRefusedBeforeAnyWork)
{
  const auto          image = dcv::test::PhantomImage({ 40, 40, 40 });
  dcv::EncoderOptions o;
  o.numberOfPoints = 500;
  o.maximumMemory = 1 << 20;
  try
  {
    itk::DCVEncode(image.GetPointer(), o);
    FAIL() << "a job of about 2.0 MiB ran under a limit of 1 MiB";
  }
  catch (const std::invalid_argument & e)
  {
    EXPECT_NE(
      std::string(e.what()).find("40x40x40 voxels with these options may need 2.0 MiB, more than the limit of 1.0 MiB"),
      std::string::npos)
      << e.what();
  }
  o.maximumMemory = 0; // no limit
  EXPECT_EQ(itk::DCVEncode(image.GetPointer(), o).header.numberOfPoints, 500u);
  o.maximumMemory = dcv::EncodingMemory({ 40, 40, 40 }, o); // exactly what it needs
  EXPECT_EQ(itk::DCVEncode(image.GetPointer(), o).header.numberOfPoints, 500u);
}

TEST(EncoderLimits, TheToolRefusesWithTheFileAndWritesNothing)
{
  const dcv::test::TemporaryDirectory d;
  ASSERT_EQ(RunDcv("phantom " + d / "p.nrrd" + " --size 40").status, 0);
  const auto r = RunDcv("compress " + d / "p.nrrd" + " " + d / "p.dcv" + " --bpv 0.5 --max-memory 2M");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("p.nrrd"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("more than the limit of 2.0 MiB"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(d / "p.dcv"));
  const auto bad = RunDcv("compress " + d / "p.nrrd" + " " + d / "p.dcv" + " --max-memory lots");
  EXPECT_EQ(bad.status, 2) << bad.output;
  const auto fine = RunDcv("compress " + d / "p.nrrd" + " " + d / "p.dcv" + " --bpv 0.5 --max-memory 1G -q");
  EXPECT_EQ(fine.status, 0) << fine.output;
  EXPECT_TRUE(fs::exists(d / "p.dcv"));
}
