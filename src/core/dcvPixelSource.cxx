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
#include "dcvPixelSource.h"
#include "dcvParallel.h"

#include <algorithm>
#include <cmath>

namespace dcv
{
PixelSource::PixelSource(const float * image, uint64_t voxels)
  : m_Image(image)
{
  if (image == nullptr || voxels == 0)
    return;
  const auto   range = ParallelMinMax(image, voxels);
  const float  lowest = range.first;
  const double span = double(range.second) - double(lowest);
  // (NaN anywhere: the floats; a NaN minimum or maximum makes the span NaN.)
  if (!(span < 256.0) || !(std::abs(lowest) < 1e18f))
    return;
  // Within that range a float is an integer when its truncation gives it back; NaN is never cast.
  if (ParallelCount(image, voxels, [](float v) { return !(v == v && double(int64_t(v)) == double(v)); }) > 0)
    return;
  m_Offset = double(lowest);
  m_Bytes.resize(voxels);
  // v - lowest is exact: two integers of the same sign and scale, or both below 2^24.
  ParallelFor(voxels, std::size_t(1) << 16, [&](std::size_t i) { m_Bytes[i] = uint8_t(image[i] - lowest); });
}
} // namespace dcv
