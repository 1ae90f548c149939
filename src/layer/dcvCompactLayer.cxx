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
// The compact residual layer (docs/format.md, "Compact residual layer"): a JPEG 2000 codestream's main
// header reduced to the fields the decoder cannot derive from the grid, and expanded back to the same bytes.
#include "dcvResidualLayer.h"
#include "dcvFileFormat.h"

#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace dcv
{
namespace
{
void
PutU16(std::vector<uint8_t> & b, uint32_t v)
{
  b.push_back(uint8_t(v >> 8));
  b.push_back(uint8_t(v));
}
void
PutU32(std::vector<uint8_t> & b, uint32_t v)
{
  PutU16(b, v >> 16);
  PutU16(b, v & 0xffff);
}
uint32_t
GetU16(const uint8_t * p)
{
  return (uint32_t(p[0]) << 8) | p[1];
}
uint32_t
GetU32(const uint8_t * p)
{
  return (GetU16(p) << 16) | GetU16(p + 2);
}

/** The fields of a compact layer (docs/format.md, "Compact residual layer"). */
struct CompactFields
{
  uint32_t columns{ 0 }; // of the mosaic; 0: one component per slice
  uint32_t precision{ 0 };
  uint32_t levels{ 0 }; // of the 2D wavelet (resolutions - 1)
  bool     reversible{ false };
};

/** The 9/7 step of each band as OpenJPEG 2.5 writes it (docs/format.md, "Compact residual layer"): for
 * OpenJPEG's level index 0 to 5 (0 the finest), {p, mantissa} of LL, of HL and LH, of HH; the band's SPqcd is
 * ((precision - p) << 11) | mantissa. Measured from its codestreams at 4 to 16 bits and 1 to 6 resolutions. */
constexpr int QcdSteps[6][3][2] = {
  { { 0, 0 }, { -2, 2003 }, { -2, 1890 } },     { { -1, 36 }, { -2, 5 }, { -2, 71 } },
  { { -3, 1874 }, { -4, 1872 }, { -4, 1896 } }, { { -4, 1848 }, { -5, 1792 }, { -5, 1760 } },
  { { -5, 1824 }, { -6, 1776 }, { -6, 1728 } }, { { -6, 1824 }, { 0, 0 }, { 0, 0 } }
};
constexpr uint32_t MaximumImplicitQcdLevels = 5;

/** The QCD marker segment OpenJPEG writes for these fields (levels at most MaximumImplicitQcdLevels). */
std::vector<uint8_t>
ImplicitQcd(const CompactFields & f)
{
  std::vector<uint8_t> q;
  const uint32_t       bands = 3 * f.levels + 1;
  PutU16(q, 0xff5c);
  PutU16(q, 3 + bands * (f.reversible ? 1 : 2));
  q.push_back(f.reversible ? 0x40 : 0x42); // 2 guard bits; no quantization or scalar expounded
  for (uint32_t b = 0; b < bands; ++b)
  {
    const uint32_t resolution = b == 0 ? 0 : (b - 1) / 3 + 1;
    const uint32_t orientation = b == 0 ? 0 : (b - 1) % 3 + 1; // LL, HL, LH, HH
    if (f.reversible)
    {
      const uint32_t gain = orientation == 0 ? 0 : orientation == 3 ? 2 : 1;
      q.push_back(uint8_t((f.precision + gain) << 3));
    }
    else
    {
      const int * step = QcdSteps[f.levels - resolution][orientation == 0 ? 0 : orientation == 3 ? 2 : 1];
      PutU16(q, (uint32_t(int(f.precision) - step[0]) << 11) | uint32_t(step[1]));
    }
  }
  return q;
}

/** SOC, SIZ and COD as a compact layer's fields give them; empty when the fields are not valid for the grid. */
std::vector<uint8_t>
MainHeader(const CompactFields & f, const GridSize & grid)
{
  if (f.precision < 1 || f.precision > 38 || f.levels > 32 || (f.columns == 0 && grid.z > MaximumComponents) ||
      f.columns > uint32_t(grid.z))
    return {};
  const uint32_t components = f.columns == 0 ? uint32_t(grid.z) : 1;
  const uint64_t width = f.columns == 0 ? uint64_t(grid.x) : uint64_t(f.columns) * uint64_t(grid.x);
  const uint64_t height =
    f.columns == 0 ? uint64_t(grid.y) : uint64_t((grid.z + f.columns - 1) / f.columns) * uint64_t(grid.y);
  if (width > 0xffffffffu || height > 0xffffffffu)
    return {};
  std::vector<uint8_t> h;
  PutU16(h, 0xff4f); // SOC
  PutU16(h, 0xff51); // SIZ
  PutU16(h, 38 + 3 * components);
  PutU16(h, 0); // Rsiz
  for (uint64_t v : { width, height, uint64_t(0), uint64_t(0), width, height, uint64_t(0), uint64_t(0) })
    PutU32(h, uint32_t(v));
  PutU16(h, components);
  for (uint32_t c = 0; c < components; ++c)
  {
    h.push_back(uint8_t(0x80 | (f.precision - 1))); // signed
    h.push_back(1);
    h.push_back(1);
  }
  PutU16(h, 0xff52); // COD
  PutU16(h, 12);
  h.push_back(0); // Scod: default precincts, no SOP, no EPH
  h.push_back(0); // LRCP
  PutU16(h, 1);   // one quality layer
  h.push_back(0); // no component transform
  h.push_back(uint8_t(f.levels));
  h.push_back(4); // 64 x 64 code-blocks
  h.push_back(4);
  h.push_back(0); // code-block style
  h.push_back(f.reversible ? 1 : 0);
  return h;
}

/** The codestream a compact layer stands for (an empty vector when its fields or its QCD are not valid). */
std::vector<uint8_t>
Expand(const uint8_t * stored, std::size_t n, const GridSize & grid)
{
  if (n < CompactLayerFieldBytes)
    return {};
  CompactFields f;
  f.columns = GetU16(stored);
  f.precision = uint32_t(stored[2] & 0x3f) + 1;
  f.reversible = (stored[2] & 0x80) != 0;
  f.levels = stored[3];
  const bool implicitQcd = (stored[2] & 0x40) != 0;
  if (implicitQcd && (f.levels > MaximumImplicitQcdLevels || f.precision > (f.reversible ? 29u : 25u)))
    return {};
  std::vector<uint8_t> c = MainHeader(f, grid);
  const uint8_t *      qcd = stored + CompactLayerFieldBytes;
  const std::size_t    rest = n - CompactLayerFieldBytes;
  if (c.empty())
    return {};
  if (implicitQcd)
  {
    const std::vector<uint8_t> q = ImplicitQcd(f);
    c.insert(c.end(), q.begin(), q.end());
  }
  else if (rest < 4 || GetU16(qcd) != 0xff5c || GetU16(qcd + 2) < 3 || 2 + std::size_t(GetU16(qcd + 2)) > rest)
    return {};
  const std::size_t qcdBytes = implicitQcd ? 0 : 2 + GetU16(qcd + 2);
  const std::size_t data = rest - qcdBytes;
  if (data + 14 > 0xffffffffu)
    return {};
  c.reserve(c.size() + rest + 16);
  c.insert(c.end(), qcd, qcd + qcdBytes); // nothing when implicit
  PutU16(c, 0xff90);                      // SOT: tile 0, its only tile-part
  PutU16(c, 10);
  PutU16(c, 0);
  PutU32(c, uint32_t(14 + data));
  c.push_back(0);
  c.push_back(1);
  PutU16(c, 0xff93); // SOD
  c.insert(c.end(), qcd + qcdBytes, qcd + rest);
  PutU16(c, 0xffd9); // EOC
  return c;
}
} // namespace

bool
CompactLayer(const std::vector<uint8_t> & codestream, const GridSize & grid, std::vector<uint8_t> & stored)
{
  const std::vector<uint8_t> & c = codestream;
  // SOC, SIZ (its fields read back), COD, QCD, SOT, SOD, ..., EOC: exactly what Expand() writes, or nothing.
  if (c.size() < 4 + 4 + 38 + 3 + 14 + 5 + 14 || GetU16(c.data()) != 0xff4f || GetU16(c.data() + 2) != 0xff51)
    return false;
  const std::size_t siz = 2 + GetU16(c.data() + 4);
  if (siz < 41 || 2 + siz + 14 > c.size())
    return false;
  CompactFields  f;
  const uint32_t components = GetU16(c.data() + 40);
  if (components < 1 || 2 + 40 + 3 * std::size_t(components) > c.size())
    return false;
  f.columns = components > 1 ? 0 : GetU32(c.data() + 8) / uint32_t(grid.x);
  f.precision = uint32_t(c[42] & 0x7f) + 1;
  const std::size_t cod = 2 + siz;
  f.levels = c[cod + 9];
  f.reversible = c[cod + 13] == 1;
  if (f.columns > 0xffff || f.precision > 64)
    return false;
  const std::vector<uint8_t> header = MainHeader(f, grid);
  if (header.empty() || header.size() > c.size() || !std::equal(header.begin(), header.end(), c.begin()))
    return false;
  std::size_t p = header.size();
  if (p + 4 > c.size() || GetU16(c.data() + p) != 0xff5c)
    return false;
  const std::size_t qcdBytes = 2 + GetU16(c.data() + p + 2);
  if (p + qcdBytes + 14 + 2 > c.size())
    return false;
  bool implicitQcd = false;
  if (f.levels <= MaximumImplicitQcdLevels && f.precision <= (f.reversible ? 29u : 25u))
  {
    const std::vector<uint8_t> q = ImplicitQcd(f);
    implicitQcd = q.size() == qcdBytes && std::equal(q.begin(), q.end(), c.begin() + std::ptrdiff_t(p));
  }
  stored.clear();
  PutU16(stored, f.columns);
  stored.push_back(uint8_t((f.precision - 1) | (implicitQcd ? 0x40 : 0) | (f.reversible ? 0x80 : 0)));
  stored.push_back(uint8_t(f.levels));
  if (!implicitQcd)
    stored.insert(stored.end(), c.begin() + std::ptrdiff_t(p), c.begin() + std::ptrdiff_t(p + qcdBytes));
  p += qcdBytes + 14; // SOT and SOD, checked by the round trip below
  stored.insert(stored.end(), c.begin() + std::ptrdiff_t(p), c.end() - 2);
  if (Expand(stored.data(), stored.size(), grid) != c)
  {
    stored.clear();
    return false;
  }
  return true;
}

std::vector<uint8_t>
ExpandLayer(const std::vector<uint8_t> & stored, const GridSize & grid, const std::string & name)
{
  std::vector<uint8_t> c = Expand(stored.data(), stored.size(), grid);
  if (c.empty())
    throw FormatError(name + ": damaged residual layer (invalid compact fields)");
  return c;
}

std::size_t
StoredLayerBytes(const std::vector<uint8_t> & codestream, const GridSize & grid)
{
  std::vector<uint8_t> stored;
  return CompactLayer(codestream, grid, stored) ? stored.size() : codestream.size();
}

std::size_t
CompactLayerSaving(const GridSize & grid, Arrangement arrangement)
{
  const std::size_t components = arrangement == Arrangement::Components ? std::size_t(grid.z) : 1;
  // SOC 2, SIZ 2 + 38 + 3 C, COD 14, SOT 12, SOD 2, EOC 2 and the 9/7 QCD of 5 levels (37), less the fields
  return 2 + 40 + 3 * components + 14 + 12 + 2 + 2 + 37 - CompactLayerFieldBytes;
}
} // namespace dcv
