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
#include "dcvPhantom.h"

#include <algorithm>
#include <cmath>

namespace dcv
{
namespace
{
struct Ellipsoid
{
  double x, y, z;    // centre
  double a, b, c;    // half axes
  double phiDegrees; // rotation about z
  double intensity;  // added inside
};

// Kak & Slaney's 3D head, intensities of the modified (higher contrast) phantom.
constexpr Ellipsoid ellipsoids[] = {
  { 0.0, 0.0, 0.0, 0.69, 0.92, 0.90, 0.0, 1.0 },         // skull
  { 0.0, -0.0184, 0.0, 0.6624, 0.874, 0.88, 0.0, -0.8 }, // brain
  { -0.22, 0.0, -0.25, 0.41, 0.16, 0.21, 108.0, -0.2 },  // right ventricle
  { 0.22, 0.0, -0.25, 0.31, 0.11, 0.22, 72.0, -0.2 },    // left ventricle
  { 0.0, 0.35, -0.25, 0.21, 0.25, 0.50, 0.0, 0.1 },      { 0.0, 0.1, -0.25, 0.046, 0.046, 0.046, 0.0, 0.1 },
  { -0.08, -0.65, -0.25, 0.046, 0.023, 0.02, 0.0, 0.1 }, { 0.06, -0.65, -0.25, 0.046, 0.023, 0.02, 90.0, 0.1 },
  { 0.06, -0.105, 0.625, 0.056, 0.04, 0.10, 90.0, 0.1 }, { 0.0, 0.1, 0.625, 0.056, 0.056, 0.10, 0.0, 0.1 },
};
} // namespace

std::vector<uint8_t>
SheppLoganPhantom(const GridSize & grid)
{
  std::vector<uint8_t> out(grid.NumberOfVoxels());
  const double         pi = std::acos(-1.0);
  auto                 coordinate = [](int32_t i, int32_t n) { return n > 1 ? -1.0 + 2.0 * i / (n - 1) : 0.0; };
  std::size_t          k = 0;
  for (int32_t iz = 0; iz < grid.z; ++iz)
  {
    const double z = coordinate(iz, grid.z);
    for (int32_t iy = 0; iy < grid.y; ++iy)
    {
      // Image rows go down: the phantom's +y is the top of the head.
      const double y = -coordinate(iy, grid.y);
      for (int32_t ix = 0; ix < grid.x; ++ix, ++k)
      {
        const double x = coordinate(ix, grid.x);
        double       value = 0.0;
        for (const Ellipsoid & e : ellipsoids)
        {
          const double phi = e.phiDegrees * pi / 180.0;
          const double dx = x - e.x, dy = y - e.y, dz = z - e.z;
          const double u = (dx * std::cos(phi) + dy * std::sin(phi)) / e.a;
          const double v = (-dx * std::sin(phi) + dy * std::cos(phi)) / e.b;
          const double w = dz / e.c;
          if (u * u + v * v + w * w <= 1.0)
          {
            value += e.intensity;
          }
        }
        out[k] = uint8_t(std::clamp(std::lround(value * 255.0), 0L, 255L));
      }
    }
  }
  return out;
}

} // namespace dcv
