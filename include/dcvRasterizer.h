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
#ifndef dcvRasterizer_h
#define dcvRasterizer_h

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>

/** \file dcvRasterizer.h
 * Exact scan conversion of a tetrahedron whose vertices lie on the voxel grid, and the linear
 * (barycentric) interpolation of its vertex values. Header-only and free of ITK and CGAL, so the
 * encoder, the decoder and the ITK filters share the very same arithmetic.
 *
 * Ownership rule: a voxel belongs to a cell when it lies strictly inside it. A voxel on a face, an
 * edge or a vertex is decided as if it were moved by (sx e, sy e^2, sz e^3) for an infinitesimal e,
 * with each sign pointing into the box (+ in the lower half of an axis, - in the upper half). The
 * moved point lies on no plane, so for any tetrahedralization of the box every voxel has exactly
 * one owner. All predicates are evaluated in 64-bit integers (coordinates < 2^16), hence exactly.
 * \ingroup DelaunayCompression
 */
namespace dcv
{

/** Voxel grid extent: number of voxels along x, y, z (x varies fastest in memory). */
struct GridSize
{
  int32_t x{ 0 };
  int32_t y{ 0 };
  int32_t z{ 0 };

  uint64_t
  NumberOfVoxels() const
  {
    return uint64_t(x) * uint64_t(y) * uint64_t(z);
  }
  uint64_t
  Offset(int32_t i, int32_t j, int32_t k) const
  {
    return uint64_t(i) + uint64_t(x) * (uint64_t(j) + uint64_t(y) * uint64_t(k));
  }
};

/** Largest grid extent along one axis: keeps every orientation determinant inside int64. */
constexpr int32_t MaximumGridExtent = 65535;

/** Integer grid coordinates of a point. */
using GridPoint = std::array<int32_t, 3>;

/** Integer factors per axis of the space in which the Delaunay tetrahedralization is built: points at
 * (sx x, sy y, sz z). With thick slices (sz > 1) cells across slices become thin, as the physical
 * spacing asks. The cells are still tetrahedra of grid points, so rasterization is unchanged; and
 * coordinates stay exact in doubles (65535 x 16 < 2^20). */
using GridScale = std::array<int32_t, 3>;
constexpr int32_t MaximumGridScale = 16;

namespace detail
{
/** floor(a / b) for b > 0 and |a| < 2^53, exact: a double product with 1/b (a 64-bit integer division
 * would dominate the rasterizer), corrected with integer products. */
inline int64_t
FloorDiv(int64_t a, int64_t b, double inverseOfB)
{
  int64_t q = int64_t(double(a) * inverseOfB); // within 2 of the truth
  while (q * b > a)
  {
    --q;
  }
  while ((q + 1) * b <= a)
  {
    ++q;
  }
  return q;
}

/** ceil and floor of a finite v with |v| < 2^31, as integers: std::ceil and std::floor are library calls
 * on the x86-64 baseline (no SSE 4.1), twice per slice of every cell rasterized. */
inline int32_t
CeilToInt(double v)
{
  const int32_t t = int32_t(v);
  return t + int32_t(double(t) < v);
}
inline int32_t
FloorToInt(double v)
{
  const int32_t t = int32_t(v);
  return t - int32_t(double(t) > v);
}

/** Sorts four elements by a network of 5 compare-exchanges: exchange(i, j) puts the pair at i < j in
 * order (std::sort's loops were 1% of the encoder's time where cells are sorted by the million). */
template <typename TExchange>
inline void
SortFour(TExchange && exchange)
{
  exchange(0, 1);
  exchange(2, 3);
  exchange(0, 2);
  exchange(1, 3);
  exchange(1, 2);
}

/** Sign of the perturbation along one axis for a voxel at coordinate c of an axis with n voxels. */
inline int
InwardSign(int64_t c, int64_t n)
{
  return 2 * c <= n - 1 ? 1 : -1;
}
} // namespace detail

/** The four vertices of a tetrahedron sorted into a canonical order (by z, then y, then x), so
 * that every computation on a cell is independent of the order its vertices were given in. */
struct CanonicalTetrahedron
{
  std::array<GridPoint, 4> p;
  std::array<double, 4>    v;

  CanonicalTetrahedron(const std::array<GridPoint, 4> & points, const std::array<double, 4> & values)
  {
    // A sorting network (every scan, solve and rasterization starts here). Distinct points have one
    // order; a cell with two equal points is flat and owns no voxel.
    auto before = [&points](int a, int b) {
      const GridPoint & A = points[a];
      const GridPoint & B = points[b];
      return A[2] != B[2] ? A[2] < B[2] : A[1] != B[1] ? A[1] < B[1] : A[0] < B[0];
    };
    std::array<int, 4> order{ 0, 1, 2, 3 };
    detail::SortFour([&](int i, int j) {
      if (before(order[j], order[i]))
        std::swap(order[i], order[j]);
    });
    for (int i = 0; i < 4; ++i)
    {
      p[i] = points[order[i]];
      v[i] = values[order[i]];
    }
  }
};

/** Six times the signed volume of the tetrahedron (exact). */
inline int64_t
SignedVolume6(const std::array<GridPoint, 4> & p)
{
  const int64_t ax = p[1][0] - p[0][0], ay = p[1][1] - p[0][1], az = p[1][2] - p[0][2];
  const int64_t bx = p[2][0] - p[0][0], by = p[2][1] - p[0][1], bz = p[2][2] - p[0][2];
  const int64_t cx = p[3][0] - p[0][0], cy = p[3][1] - p[0][1], cz = p[3][2] - p[0][2];
  return ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx);
}

/** Linear function over a tetrahedron: value(p) = v0 + g . (p - p0), with p0 the first canonical
 * vertex. Built from the canonical order so encoder and decoder get identical doubles. */
struct LinearFunction
{
  GridPoint origin{ 0, 0, 0 };
  double    value0{ 0 };
  double    gx{ 0 }, gy{ 0 }, gz{ 0 };

  LinearFunction() = default;
  explicit LinearFunction(const CanonicalTetrahedron & t)
  {
    origin = t.p[0];
    value0 = t.v[0];
    // Rows of M are the edge vectors from p0; g solves M g = dv, via the adjugate (exact integers).
    int64_t m[3][3];
    double  dv[3];
    for (int r = 0; r < 3; ++r)
    {
      for (int c = 0; c < 3; ++c)
      {
        m[r][c] = int64_t(t.p[r + 1][c]) - t.p[0][c];
      }
      dv[r] = t.v[r + 1] - t.v[0];
    }
    int64_t adj[3][3]; // adjugate: inverse(M) = adj / det
    adj[0][0] = m[1][1] * m[2][2] - m[1][2] * m[2][1];
    adj[0][1] = m[0][2] * m[2][1] - m[0][1] * m[2][2];
    adj[0][2] = m[0][1] * m[1][2] - m[0][2] * m[1][1];
    adj[1][0] = m[1][2] * m[2][0] - m[1][0] * m[2][2];
    adj[1][1] = m[0][0] * m[2][2] - m[0][2] * m[2][0];
    adj[1][2] = m[0][2] * m[1][0] - m[0][0] * m[1][2];
    adj[2][0] = m[1][0] * m[2][1] - m[1][1] * m[2][0];
    adj[2][1] = m[0][1] * m[2][0] - m[0][0] * m[2][1];
    adj[2][2] = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    const int64_t det = m[0][0] * adj[0][0] + m[0][1] * adj[1][0] + m[0][2] * adj[2][0];
    if (det == 0)
    {
      return; // flat cell: owns no voxel, constant value
    }
    const double inv = 1.0 / double(det);
    gx = (double(adj[0][0]) * dv[0] + double(adj[0][1]) * dv[1] + double(adj[0][2]) * dv[2]) * inv;
    gy = (double(adj[1][0]) * dv[0] + double(adj[1][1]) * dv[1] + double(adj[1][2]) * dv[2]) * inv;
    gz = (double(adj[2][0]) * dv[0] + double(adj[2][1]) * dv[1] + double(adj[2][2]) * dv[2]) * inv;
  }

  /** Value on row (y, z) is RowBase(y, z) + gx * (x - origin[0]). */
  double
  RowBase(int32_t y, int32_t z) const
  {
    return value0 + gy * double(y - origin[1]) + gz * double(z - origin[2]);
  }
  double
  operator()(int32_t x, int32_t y, int32_t z) const
  {
    return RowBase(y, z) + gx * double(x - origin[0]);
  }
};

namespace detail
{
/** A face of a tetrahedron as ForEachSpan steps it along a slice's rows: its inward plane n.X + d (n
 * without nx) and, where nx != 0, m = |nx| and the row step of floor(num / m), dq and dr. */
struct SpanFace
{
  int64_t ny, nz, d, m, dq, dr;
  double  inverse; // 1 / m
};

/** An edge between the slices z0 < z1 (or a flat one, z0 == z1): y = y0 + slope (z - z0). */
struct SpanEdge
{
  int32_t z0, z1;
  double  y0, slope;
};

/** ForEachSpan's slices and rows, for a cell with NL faces bounding x0 (nx > 0), then NU bounding x1
 * (nx < 0), then 4 - NL - NU parallel to x, in `faces`: compiled for each kind of cell, a row computes only
 * what its faces need (norm-256's mesh: a cell's rows 18% faster than with every face's bounds computed
 * and selected by kind). */
template <int NL, int NU, typename TFunction>
inline void
SpanSlices(const GridSize & grid, const std::array<GridPoint, 4> & p, const SpanFace * faces, const int32_t * lo,
           const int32_t * hi, TFunction && f)
{
  constexpr int N = NL + NU;
  constexpr int NP = 4 - N;
  // The edges' slopes once per cell (a product per slice instead of a division).
  SpanEdge edges[6];
  for (int i = 0, e = 0; i < 4; ++i)
  {
    for (int j = i + 1; j < 4; ++j, ++e)
    {
      const GridPoint & a = p[i][2] <= p[j][2] ? p[i] : p[j];
      const GridPoint & b = p[i][2] <= p[j][2] ? p[j] : p[i];
      edges[e] = { a[2], b[2], double(a[1]), a[2] < b[2] ? double(b[1] - a[1]) / double(b[2] - a[2]) : 0.0 };
    }
  }
  const int64_t lastX = int64_t(grid.x) - 1;
  for (int32_t z = lo[2]; z <= hi[2]; ++z)
  {
    // Rows that can meet the cross-section at this z: the y extent of the vertices on it and of the
    // edges crossing it (a superset of the owned rows; the exact face tests below decide).
    double ymin = std::numeric_limits<double>::infinity();
    double ymax = -ymin;
    for (int i = 0; i < 4; ++i)
    {
      const bool on = p[i][2] == z;
      ymin = std::min(ymin, on ? double(p[i][1]) : ymin);
      ymax = std::max(ymax, on ? double(p[i][1]) : ymax);
    }
    for (const SpanEdge & e : edges)
    {
      const bool   crosses = e.z0 < z && z < e.z1;
      const double y = e.y0 + e.slope * double(z - e.z0);
      ymin = std::min(ymin, crosses ? y : ymin);
      ymax = std::max(ymax, crosses ? y : ymax);
    }
    if (!(ymin <= ymax))
    {
      continue;
    }
    // The rows inside [ymin, ymax]; the margin covers rounding (coordinates < 2^16: an end that is not
    // an integer is at least 1/65535 from one, and the computed ends are within 1e-10 of the true ones).
    const int32_t y0 = std::max(lo[1], CeilToInt(ymin - 1e-6));
    const int32_t y1 = std::min(hi[1], FloorToInt(ymax + 1e-6));
    const int     sz = InwardSign(z, grid.z);
    // Per bounding face, along y, the inside test of a row is "x > num / m" (a lower face, num = -C) or
    // "x < num / m" (an upper one, num = C), C = n.X + d at x = 0 affine in y. Keep t = floor(num / m)
    // and r = num - t m exactly, stepping them by whole rows: one division per face and slice, none per row.
    int64_t t[N], r[N], C[NP > 0 ? NP : 1], zSign[NP > 0 ? NP : 1];
    for (int i = 0; i < N; ++i)
    {
      const int64_t c = faces[i].ny * y0 + faces[i].nz * z + faces[i].d;
      const int64_t num = i < NL ? -c : c;
      t[i] = FloorDiv(num, faces[i].m, faces[i].inverse);
      r[i] = num - t[i] * faces[i].m;
    }
    for (int k = 0; k < NP; ++k)
    {
      const SpanFace & q = faces[N + k];
      C[k] = q.ny * y0 + q.nz * z + q.d;
      zSign[k] = sz * q.nz;
    }
    for (int32_t y = y0; y <= y1; ++y)
    {
      int64_t x0 = lo[0];
      int64_t x1 = hi[0];
#pragma GCC unroll 4
      for (int i = 0; i < N; ++i)
      {
        // On the plane (r == 0) the perturbation decides: x0 = t where sx > 0, else t + 1 (x > t + r/m,
        // the sign that of sx); x1 = t - 1 where sx > 0, else t (x < t + r/m, the sign of -sx).
        const int64_t onPlaneInward = int64_t(r[i] == 0) & int64_t(2 * t[i] <= lastX);
        if (i < NL)
          x0 = std::max(x0, t[i] + 1 - onPlaneInward);
        else
          x1 = std::min(x1, t[i] - onPlaneInward);
        t[i] += faces[i].dq;
        r[i] += faces[i].dr;
        const bool carry = r[i] >= faces[i].m;
        r[i] -= carry ? faces[i].m : 0;
        t[i] += int64_t(carry);
      }
      bool outside = false;
      if constexpr (NP > 0)
      {
        // A face parallel to x: the row is outside, or lies in the face plane with the perturbation
        // pointing out (the first non-zero of sy ny, sz nz decides).
        const int64_t sy = InwardSign(y, grid.y);
        for (int k = 0; k < NP; ++k)
        {
          const int64_t ny = faces[N + k].ny;
          const int64_t sign = ny != 0 ? sy * ny : zSign[k];
          outside |= (C[k] < 0) | ((C[k] == 0) & (sign < 0));
          C[k] += ny;
        }
      }
      if (!outside && x0 <= x1)
      {
        f(y, z, int32_t(x0), int32_t(x1));
      }
    }
  }
}
} // namespace detail

/** Calls f(y, z, x0, x1) for every row of voxels [x0, x1] (inclusive) owned by the tetrahedron, in the
 * slices [zFirst, zLast] only (each slice's rows are found on their own, so a slab gets exactly the rows
 * the whole tetrahedron has there). Rows come in increasing z, then y. Flat tetrahedra own nothing. */
template <typename TFunction>
void
ForEachSpan(const GridSize & grid, const std::array<GridPoint, 4> & p, TFunction && f, int32_t zFirst = 0,
            int32_t zLast = std::numeric_limits<int32_t>::max())
{
  if (SignedVolume6(p) == 0)
  {
    return;
  }
  // Face i is opposite vertex i; its plane function n.X + d is positive inside the cell. The faces are
  // listed by kind: those bounding x0 (nx > 0), those bounding x1 (nx < 0), those parallel to x.
  static constexpr int vertexOf[4][3] = { { 1, 2, 3 }, { 0, 2, 3 }, { 0, 1, 3 }, { 0, 1, 2 } };
  detail::SpanFace     byKind[3][4];
  int                  count[3] = { 0, 0, 0 };
  for (int i = 0; i < 4; ++i)
  {
    const GridPoint & a = p[vertexOf[i][0]];
    const GridPoint & b = p[vertexOf[i][1]];
    const GridPoint & c = p[vertexOf[i][2]];
    const int64_t     ux = b[0] - a[0], uy = b[1] - a[1], uz = b[2] - a[2];
    const int64_t     wx = c[0] - a[0], wy = c[1] - a[1], wz = c[2] - a[2];
    int64_t           nx = uy * wz - uz * wy, ny = uz * wx - ux * wz, nz = ux * wy - uy * wx;
    const GridPoint & s = p[i];
    if (nx * (s[0] - a[0]) + ny * (s[1] - a[1]) + nz * (s[2] - a[2]) < 0)
    {
      nx = -nx;
      ny = -ny;
      nz = -nz;
    }
    detail::SpanFace face{ ny, nz, -(nx * a[0] + ny * a[1] + nz * a[2]), nx > 0 ? nx : -nx, 0, 0, 0.0 };
    if (nx != 0)
    {
      // num changes by -+ny per row.
      const int64_t dnum = nx > 0 ? -ny : ny;
      face.inverse = 1.0 / double(face.m);
      face.dq = detail::FloorDiv(dnum, face.m, face.inverse);
      face.dr = dnum - face.dq * face.m;
    }
    const int kind = nx > 0 ? 0 : nx < 0 ? 1 : 2;
    byKind[kind][count[kind]++] = face;
  }
  detail::SpanFace faces[4];
  for (int kind = 0, k = 0; kind < 3; ++kind)
  {
    for (int i = 0; i < count[kind]; ++i)
    {
      faces[k++] = byKind[kind][i];
    }
  }
  int32_t lo[3], hi[3];
  for (int c = 0; c < 3; ++c)
  {
    lo[c] = std::max(std::min(std::min(p[0][c], p[1][c]), std::min(p[2][c], p[3][c])), 0);
    hi[c] = std::min(std::max(std::max(p[0][c], p[1][c]), std::max(p[2][c], p[3][c])), (&grid.x)[c] - 1);
  }
  lo[2] = std::max(lo[2], zFirst);
  hi[2] = std::min(hi[2], zLast);
  // A cell of non-zero volume is bounded along x: at least one face of each of the first two kinds.
  switch (count[0] * 4 + count[1])
  {
    case 1 * 4 + 1:
      detail::SpanSlices<1, 1>(grid, p, faces, lo, hi, f);
      break;
    case 1 * 4 + 2:
      detail::SpanSlices<1, 2>(grid, p, faces, lo, hi, f);
      break;
    case 2 * 4 + 1:
      detail::SpanSlices<2, 1>(grid, p, faces, lo, hi, f);
      break;
    case 1 * 4 + 3:
      detail::SpanSlices<1, 3>(grid, p, faces, lo, hi, f);
      break;
    case 2 * 4 + 2:
      detail::SpanSlices<2, 2>(grid, p, faces, lo, hi, f);
      break;
    case 3 * 4 + 1:
      detail::SpanSlices<3, 1>(grid, p, faces, lo, hi, f);
      break;
    default:
      break;
  }
}

/** Conversion of an interpolated value to a pixel type: round half up and clamp for integers. */
template <typename T>
inline T
ConvertValue(double v)
{
  if constexpr (std::is_integral<T>::value && sizeof(T) <= 4)
  {
    // The limits are integers, so comparing v + 0.5 with them equals comparing its floor; NaN goes low.
    // Between them the floor is taken by truncation and a correction: std::floor is a library call
    // per voxel without SSE 4.1, and this runs once per voxel decoded.
    const double s = v + 0.5;
    if (!(s >= double(std::numeric_limits<T>::lowest())))
    {
      return std::numeric_limits<T>::lowest();
    }
    if (s >= double(std::numeric_limits<T>::max()))
    {
      return std::numeric_limits<T>::max();
    }
    const int64_t t = int64_t(s);
    return static_cast<T>(t - int64_t(double(t) > s));
  }
  else if constexpr (std::is_integral<T>::value)
  {
    const double r = std::floor(v + 0.5);
    if (!(r >= double(std::numeric_limits<T>::lowest())))
    {
      return std::numeric_limits<T>::lowest();
    }
    if (r >= double(std::numeric_limits<T>::max()))
    {
      return std::numeric_limits<T>::max();
    }
    return static_cast<T>(r);
  }
  else
  {
    return static_cast<T>(v);
  }
}

/** Writes the linear interpolation of one tetrahedron into a buffer laid out as the grid (in the slices
 * [zFirst, zLast] only). */
template <typename T>
void
RasterizeTetrahedron(const GridSize & grid, const std::array<GridPoint, 4> & points,
                     const std::array<double, 4> & values, T * out, int32_t zFirst = 0,
                     int32_t zLast = std::numeric_limits<int32_t>::max())
{
  const CanonicalTetrahedron t(points, values);
  const LinearFunction       L(t);
  ForEachSpan(
    grid,
    t.p,
    [&](int32_t y, int32_t z, int32_t x0, int32_t x1) {
      const double base = L.RowBase(y, z);
      T *          row = out + grid.Offset(0, y, z);
      for (int32_t x = x0; x <= x1; ++x)
      {
        row[x] = ConvertValue<T>(base + L.gx * double(x - L.origin[0]));
      }
    },
    zFirst,
    zLast);
}

} // namespace dcv

#endif
