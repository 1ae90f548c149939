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
#include "dcvApproximation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace dcv
{

void
CheckPoints(const GridSize & grid, const std::vector<GridPoint> & points)
{
  int corners = 0;
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    const GridPoint & p = points[i];
    if (p[0] < 0 || p[1] < 0 || p[2] < 0 || p[0] >= grid.x || p[1] >= grid.y || p[2] >= grid.z)
    {
      throw std::invalid_argument("point " + std::to_string(i) + " (" + std::to_string(p[0]) + ", " +
                                  std::to_string(p[1]) + ", " + std::to_string(p[2]) + ") lies outside the " +
                                  std::to_string(grid.x) + "x" + std::to_string(grid.y) + "x" + std::to_string(grid.z) +
                                  " grid");
    }
    const bool cx = p[0] == 0 || p[0] == grid.x - 1;
    const bool cy = p[1] == 0 || p[1] == grid.y - 1;
    const bool cz = p[2] == 0 || p[2] == grid.z - 1;
    corners += (cx && cy && cz) ? 1 : 0;
  }
  if (corners < 8)
  {
    throw std::invalid_argument("the points do not include the 8 corners of the grid, so they cannot cover it");
  }
}

double
PSNR(double squaredError, uint64_t voxels, double peak)
{
  if (squaredError <= 0.0 || voxels == 0)
  {
    return std::numeric_limits<double>::infinity();
  }
  const double mse = squaredError / double(voxels);
  return 10.0 * std::log10(peak * peak / mse);
}

} // namespace dcv
