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
#ifndef itkDCVGridPoint_h
#define itkDCVGridPoint_h

#include "dcvRasterizer.h"
#include "itkImageBase.h"

#include <cmath>

namespace itk
{

/** The grid position (relative to the region's first index) of the voxel of `image` at physical
 * point p, when p lies on a voxel of `region` (within 1e-3 voxel); false otherwise. One rule for
 * every place that turns a mesh point back into a voxel of the .dcv grid.
 * \ingroup DelaunayCompression */
template <typename TPoint>
bool
PhysicalPointToGridPoint(const ImageBase<3> * image, const ImageRegion<3> & region, const TPoint & p, dcv::GridPoint & g)
{
  typename ImageBase<3>::PointType physical;
  physical.CastFrom(p);
  const auto continuous = image->TransformPhysicalPointToContinuousIndex<double>(physical);
  for (unsigned int d = 0; d < 3; ++d)
  {
    const double c = continuous[d] - double(region.GetIndex()[d]);
    const double r = std::round(c);
    if (std::abs(c - r) > 1e-3 || r < 0 || r >= double(region.GetSize()[d]))
    {
      return false;
    }
    g[d] = int32_t(r);
  }
  return true;
}

} // namespace itk

#endif
