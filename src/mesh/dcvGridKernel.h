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
#ifndef dcvGridKernel_h
#define dcvGridKernel_h

// Internal to the compiled sources: CGAL's Epick kernel with the two predicates a Delaunay
// triangulation of grid points asks most, computed in integers. On a grid four points are coplanar and
// five cospherical all the time: there Epick's floating-point filters cannot decide, and each such test
// is computed again in exact arithmetic. The points are integers (grid coordinates times integer scales,
// 65535 x 16 at most), so the determinants are exact in 64 and 128 bits at once. The signs are those of
// the same determinants, so the triangulation is the same cell for cell (CGAL's symbolic perturbation of
// cospherical points orders them by their coordinates and asks the same orientations).
#include "dcvRasterizer.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <cstdint>
#include <stdexcept>
#include <string>

namespace dcv
{
struct GridKernel : public CGAL::Epick
{
  using Point_3 = CGAL::Epick::Point_3;

  /** Every coordinate of a point the predicates see is an integer in [0, CoordinateLimit) (the caller
   * checks): differences are then below 2^20, an orientation's 3 x 3 determinant below 6 x 2^60
   * (int64) and an in-sphere's 4 x 4 below 2^107 (int128). */
  static constexpr int64_t CoordinateLimit = int64_t(1) << 20;

  static int64_t
  Difference(double a, double b)
  {
    return int64_t(a) - int64_t(b); // integers: the conversions are exact
  }

  template <typename T>
  static CGAL::Sign
  SignOf(T v)
  {
    return v > 0 ? CGAL::POSITIVE : v < 0 ? CGAL::NEGATIVE : CGAL::ZERO;
  }

  /** The 3 x 3 determinant of the rows a, b, c. */
  static int64_t
  Det3(const int64_t a[3], const int64_t b[3], const int64_t c[3])
  {
    return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
  }

  /** orientation(p, q, r, s): the sign of det(q - p, r - p, s - p), as CGAL's orientationC3. */
  class Orientation_3 : public CGAL::Epick::Orientation_3
  {
  public:
    using CGAL::Epick::Orientation_3::operator();
    CGAL::Orientation
    operator()(const GridKernel::Point_3 & p, const GridKernel::Point_3 & q, const GridKernel::Point_3 & r,
               const GridKernel::Point_3 & s) const
    {
      int64_t u[3], v[3], w[3];
      for (int i = 0; i < 3; ++i)
      {
        u[i] = Difference(q[i], p[i]);
        v[i] = Difference(r[i], p[i]);
        w[i] = Difference(s[i], p[i]);
      }
      return SignOf(Det3(u, v, w));
    }
  };

  /** side_of_oriented_sphere(p, q, r, s, t): the sign of CGAL's side_of_oriented_sphereC3, the
   * determinant of the rows p - t, r - t, q - t, s - t, each lifted by its squared length. */
  class Side_of_oriented_sphere_3 : public CGAL::Epick::Side_of_oriented_sphere_3
  {
  public:
    using CGAL::Epick::Side_of_oriented_sphere_3::operator();
    CGAL::Oriented_side
    operator()(const GridKernel::Point_3 & p, const GridKernel::Point_3 & q, const GridKernel::Point_3 & r,
               const GridKernel::Point_3 & s, const GridKernel::Point_3 & t) const
    {
      const GridKernel::Point_3 * rows[4] = { &p, &r, &q, &s };
      int64_t                     d[4][3];
      int64_t                     lifted[4];
      for (int k = 0; k < 4; ++k)
      {
        for (int i = 0; i < 3; ++i)
          d[k][i] = Difference((*rows[k])[i], t[i]);
        lifted[k] = d[k][0] * d[k][0] + d[k][1] * d[k][1] + d[k][2] * d[k][2];
      }
      // Along the lifted column: the sum over k of (-1)^(k + 3) lifted[k] times the 3 x 3 determinant
      // of the other three rows.
      const __int128 det = -__int128(lifted[0]) * Det3(d[1], d[2], d[3]) +
                           __int128(lifted[1]) * Det3(d[0], d[2], d[3]) - __int128(lifted[2]) * Det3(d[0], d[1], d[3]) +
                           __int128(lifted[3]) * Det3(d[0], d[1], d[2]);
      return SignOf(det);
    }
  };

  Orientation_3
  orientation_3_object() const
  {
    return Orientation_3();
  }
  Side_of_oriented_sphere_3
  side_of_oriented_sphere_3_object() const
  {
    return Side_of_oriented_sphere_3();
  }
};
static_assert(int64_t(MaximumGridExtent - 1) * MaximumGridScale < GridKernel::CoordinateLimit,
              "the integer predicates hold every grid");

/** Throws std::invalid_argument unless each axis scale is 1 to MaximumGridScale. */
inline void
CheckGridScale(const GridScale & scale)
{
  for (int32_t s : scale)
  {
    if (s < 1 || s > MaximumGridScale)
    {
      throw std::invalid_argument("Tetrahedralization: each axis scale must be 1 to " +
                                  std::to_string(MaximumGridScale) + ", got " + std::to_string(s));
    }
  }
}

/** The point in the space scaled by `s`, where the kernel's integer predicates need coordinates in
 * [0, GridKernel::CoordinateLimit): every grid of the format (MaximumGridExtent x MaximumGridScale).
 * Throws std::invalid_argument for a point outside that range. */
inline GridKernel::Point_3
ToGridKernel(const GridPoint & p, const GridScale & s)
{
  for (int i = 0; i < 3; ++i)
  {
    if (p[i] < 0 || int64_t(p[i]) * s[i] >= GridKernel::CoordinateLimit)
    {
      throw std::invalid_argument("Tetrahedralization: point (" + std::to_string(p[0]) + ", " + std::to_string(p[1]) +
                                  ", " + std::to_string(p[2]) + ") lies outside the grids it can hold");
    }
  }
  return GridKernel::Point_3(double(p[0]) * s[0], double(p[1]) * s[1], double(p[2]) * s[2]);
}

} // namespace dcv

#endif
