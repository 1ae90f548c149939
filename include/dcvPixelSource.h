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
#ifndef dcvPixelSource_h
#define dcvPixelSource_h

#include "DelaunayCompressionExport.h"

#include <cmath>
#include <cstdint>
#include <vector>

namespace dcv
{
/** The image as the refinement engine's scans read it. Where every voxel is an integer within 256 of the
 * smallest (8-bit volumes), a copy in one byte a voxel of the voxels less that smallest value; else the
 * floats themselves. Either way a voxel reads as the very double of its float, so the engine's sums, and
 * the files, do not depend on which is read. The scans' loads of the image miss the caches: the copy
 * gives them a quarter of the memory to wait on, and a 256^3 volume (16.7 MB) fits a 32 MB L3 cache where
 * its floats do not (norm-256 at 0.03125 bpv: 5% less time). A copy in two bytes for 16-bit volumes was
 * measured 7% slower on the 5 mm CT series (19 MiB more, no scan faster): none is made.
 * \ingroup DelaunayCompression */
class DelaunayCompression_EXPORT PixelSource
{
public:
  /** `image` (`voxels` floats) must outlive the source. */
  PixelSource(const float * image, uint64_t voxels);

  /** f(pixels) with the copy (const uint8_t *) or the floats (const float *). */
  template <typename F>
  decltype(auto)
  Visit(F && f) const
  {
    if (!m_Bytes.empty())
      return f(m_Bytes.data());
    return f(m_Image);
  }

  /** Voxel x of a row that Visit() handed out, as the double of its float. */
  double
  operator()(const float * row, int64_t x) const
  {
    return double(row[x]);
  }
  double
  operator()(const uint8_t * row, int64_t x) const
  {
    return double(row[x]) + m_Offset; // both integers, their sum exact
  }

  /** The sums over voxels x0 to x1 of a row that Visit() handed out, of I and of (x - x0) I: the very
   * doubles of adding each voxel's double in order. On the copy, with a smallest value below 2^20 in
   * magnitude, every partial sum is an integer below 2^53 (exact either way), so they are summed as
   * integers, which the compiler vectorizes; else voxel by voxel. */
  void
  RowSums(const float * row, int32_t x0, int32_t x1, double & sumI, double & sumUI) const
  {
    VoxelByVoxelSums(row, x0, x1, sumI, sumUI);
  }
  void
  RowSums(const uint8_t * row, int32_t x0, int32_t x1, double & sumI, double & sumUI) const
  {
    if (!(std::abs(m_Offset) < double(1 << 20)))
    {
      VoxelByVoxelSums(row, x0, x1, sumI, sumUI);
      return;
    }
    int64_t bytes = 0, weighted = 0;
    for (int32_t x = x0; x <= x1; ++x)
    {
      bytes += row[x];
      weighted += int64_t(x - x0) * row[x];
    }
    const int64_t n = int64_t(x1) - x0 + 1, offset = int64_t(m_Offset);
    sumI = double(bytes + n * offset);
    sumUI = double(weighted + n * (n - 1) / 2 * offset);
  }

  /** Bytes a voxel of the copy: 1, or 0 (the floats are read). */
  unsigned
  BytesPerVoxel() const
  {
    return m_Bytes.empty() ? 0u : 1u;
  }

private:
  template <typename T>
  void
  VoxelByVoxelSums(const T * row, int32_t x0, int32_t x1, double & sumI, double & sumUI) const
  {
    sumI = 0.0;
    sumUI = 0.0;
    for (int32_t x = x0; x <= x1; ++x)
    {
      const double value = (*this)(row, x);
      sumI += value;
      sumUI += double(x - x0) * value;
    }
  }

  const float *        m_Image;
  double               m_Offset{ 0.0 };
  std::vector<uint8_t> m_Bytes;
};
} // namespace dcv

#endif
