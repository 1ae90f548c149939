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
#include "dcvCodec.h"
#include "dcvBoundedLayer.h"
#include "dcvResidualLayer.h"
#include "dcvVideoLayer.h"
#include "dcvArithmeticCoder.h"
#include "dcvFileFormat.h"
#include "dcvMemory.h"
#include "dcvParallel.h"
#include "dcvPositionCoder.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <unordered_map>

namespace dcv
{
namespace
{
/** The earlier neighbours of each vertex through the tetrahedra (those of smaller index: the only ones a
 * prediction reads, half the pairs), as compressed rows, each in the order of its first tetrahedron: a
 * prediction sums integers, so the order within a row does not matter. */
struct Adjacency
{
  std::vector<uint32_t> start; // size n + 1
  std::vector<uint32_t> neighbour;

  Adjacency(std::size_t n, const std::vector<Tetrahedron> & tetrahedra)
  {
    // Compressed rows by counting, then each short row deduplicated with marks (no sort: rate control
    // codes a mesh some ten times, and sorting the rows was a third of it). An eighth of the rows at
    // a time: before deduplication the pairs (6 a tetrahedron) are about five times the rows after it,
    // and rate control encodes at the encoder's peak (norm-256 at 0.25 bpv: 126 MB of pairs at once).
    // The pairs of every row are counted in one pass; as many eighths at once as there are threads
    // then fill their own rows, appended in order: the same rows whatever the threads.
    constexpr std::size_t parts = 8;
    start.assign(n + 1, 0);
    // Room for all the rows at once, which hold each edge once: a tetrahedralization of a ball has
    // n + t + h / 2 - 1 edges (Euler), h <= 2 n hull faces. Grown by doubling and shrunk by a copy,
    // the rows took up to three times their size at once.
    neighbour.reserve(std::min(2 * n + tetrahedra.size(), 6 * tetrahedra.size()));
    // pairs[r]: row r's entries before deduplication (the vertices of its tetrahedra before it),
    // summed into offsets.
    std::vector<uint32_t> pairs(n + 1, 0);
    for (const auto & t : tetrahedra)
      for (int i = 0; i < 4; ++i)
        pairs[t[i] + 1] +=
          uint32_t(t[0] < t[i]) + uint32_t(t[1] < t[i]) + uint32_t(t[2] < t[i]) + uint32_t(t[3] < t[i]);
    for (std::size_t r = 0; r < n; ++r)
      pairs[r + 1] += pairs[r];
    const std::size_t                  rowsPerPart = (n + parts - 1) / parts;
    const std::size_t                  together = std::min<std::size_t>(parts, CurrentThreads());
    std::vector<std::vector<uint32_t>> rows(together), ends(together);
    for (std::size_t batch = 0; batch < parts; batch += together)
    {
      ParallelFor(std::min(together, parts - batch), 1, [&](std::size_t k) {
        const std::size_t     lo = std::min(n, (batch + k) * rowsPerPart), hi = std::min(n, lo + rowsPerPart);
        const uint32_t        base = pairs[lo];
        std::vector<uint32_t> entries(pairs[hi] - base, 0);
        std::vector<uint32_t> fill(pairs.begin() + lo, pairs.begin() + hi);
        for (const auto & t : tetrahedra)
          for (int i = 0; i < 4; ++i)
            if (t[i] >= lo && t[i] < hi)
              for (int j = 0; j < 4; ++j)
                if (t[j] < t[i])
                  entries[fill[t[i] - lo]++ - base] = t[j];
        // mark[j] == r + 1: j is in row r already (rows of a part are distinct, so no clearing).
        std::vector<uint32_t> mark(hi, 0);
        rows[k].clear();
        ends[k].clear();
        for (std::size_t r = lo; r < hi; ++r)
        {
          for (uint32_t e = pairs[r] - base; e < pairs[r + 1] - base; ++e)
          {
            const uint32_t j = entries[e];
            if (mark[j] != uint32_t(r + 1))
            {
              mark[j] = uint32_t(r + 1);
              rows[k].push_back(j);
            }
          }
          ends[k].push_back(uint32_t(rows[k].size()));
        }
      });
      for (std::size_t k = 0; k < together && batch + k < parts; ++k)
      {
        const std::size_t lo = std::min(n, (batch + k) * rowsPerPart), offset = neighbour.size();
        neighbour.insert(neighbour.end(), rows[k].begin(), rows[k].end());
        for (std::size_t r = 0; r < ends[k].size(); ++r)
          start[lo + r + 1] = uint32_t(offset + ends[k][r]);
        std::vector<uint32_t>().swap(rows[k]);
      }
    }
  }
};

/** Value model: the residual against the mean of the neighbours decoded so far, with a context per
 * how many there are (a prediction from one neighbour is rougher than one from six). */
class ValueCoder
{
public:
  static int
  Context(int known)
  {
    return known == 0 ? 0 : known <= 2 ? 1 : known <= 5 ? 2 : 3;
  }
  /** Prediction of vertex i from the already coded vertices j < i among its neighbours. */
  static int64_t
  Predict(const Adjacency & adjacency, const std::vector<int64_t> & k, uint32_t i, int & known)
  {
    int64_t sum = 0;
    known = 0;
    for (uint32_t e = adjacency.start[i]; e < adjacency.start[i + 1]; ++e)
    {
      sum += k[adjacency.neighbour[e]]; // an earlier neighbour: already coded
      ++known;
    }
    if (known == 0)
    {
      return i > 0 ? k[i - 1] : 0;
    }
    return int64_t(std::floor(double(sum) / known + 0.5));
  }
  SIntModel residual[4];
};
} // namespace

std::vector<uint8_t>
EncodePayload(const Approximation & a, double q0, double q, bool delaunay)
{
  Approximation copy;
  copy.grid = a.grid;
  copy.scale = a.scale;
  copy.points = a.points;
  copy.values = a.values;
  if (delaunay)
    copy.tetrahedra = a.tetrahedra;
  return EncodePayload(std::move(copy), q0, q, delaunay);
}

std::vector<uint8_t>
EncodePayload(Approximation && a, double q0, double q, bool delaunay)
{
  if (!(q > 0.0))
  {
    throw std::invalid_argument("EncodePayload: the quantization step must be positive");
  }
  // Values follow the points in the coder's order: `sorted[i]` is the position there of a.points[i].
  std::unordered_map<uint64_t, uint32_t> indexAt;
  indexAt.reserve(a.points.size());
  for (std::size_t i = 0; i < a.points.size(); ++i)
  {
    indexAt[a.grid.Offset(a.points[i][0], a.points[i][1], a.points[i][2])] = uint32_t(i);
  }
  std::vector<GridPoint> points = std::move(a.points);
  SortPositions(a.grid, points);
  std::vector<uint32_t> sorted(points.size());
  std::vector<int64_t>  k(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    const uint32_t original = indexAt.at(a.grid.Offset(points[i][0], points[i][1], points[i][2]));
    sorted[original] = uint32_t(i);
    const double v = a.values[original];
    const double index = std::round((v - q0) / q);
    if (std::abs(index - (v - q0) / q) > 1e-6 || std::abs(index) >= double(MaximumQuantizationIndex))
    {
      throw std::invalid_argument("EncodePayload: value " + std::to_string(v) + " is not on the quantization lattice");
    }
    k[i] = int64_t(index);
  }
  // What the mesh's adjacency no longer needs goes before it is built (the rate control's peak).
  std::unordered_map<uint64_t, uint32_t>().swap(indexAt);
  std::vector<double>().swap(a.values);
  ReturnFreedMemory(); // the map's nodes: small blocks, whose pages the adjacency's buffers do not reuse
  std::vector<Tetrahedron> tetrahedra;
  if (delaunay)
  {
    tetrahedra = std::move(a.tetrahedra); // renumbered in place: no second copy of the mesh
    for (auto & t : tetrahedra)
      t = { sorted[t[0]], sorted[t[1]], sorted[t[2]], sorted[t[3]] };
  }
  else
  {
    tetrahedra = Tetrahedralize(points, a.scale);
  }
  std::vector<uint32_t>().swap(sorted);
  const Adjacency adjacency(points.size(), tetrahedra);
  std::vector<Tetrahedron>().swap(tetrahedra);
  std::vector<uint8_t> bytes;
  ArithmeticEncoder    encoder(bytes);
  EncodePositions(encoder, a.grid, points);
  ValueCoder values;
  for (uint32_t i = 0; i < points.size(); ++i)
  {
    int           known = 0;
    const int64_t prediction = ValueCoder::Predict(adjacency, k, i, known);
    values.residual[ValueCoder::Context(known)].Encode(encoder, int32_t(k[i] - prediction));
  }
  encoder.Finish();
  return bytes;
}

Approximation
DecodePayload(const std::vector<uint8_t> & payload, const GridSize & grid, uint32_t count, double q0, double q,
              const std::string & name, const GridScale & scale)
{
  if (uint64_t(count) > MaximumPointsPerPayloadByte * payload.size())
  {
    throw FormatError(name + ": damaged (" + std::to_string(count) + " points cannot be coded in " +
                      std::to_string(payload.size()) + " payload bytes)");
  }
  ArithmeticDecoder decoder(payload.data(), payload.size());
  Approximation     a;
  a.grid = grid;
  a.scale = scale;
  try
  {
    a.points = DecodePositions(decoder, grid, count); // stops where the stream is overrun
    if (decoder.Overrun())
    {
      throw FormatError(name + ": the payload ends inside the point positions");
    }
    CheckPoints(grid, a.points);
  }
  catch (const std::invalid_argument & e)
  {
    throw FormatError(name + ": damaged point positions (" + e.what() + ")");
  }
  a.tetrahedra = Tetrahedralize(a.points, a.scale);
  const Adjacency      adjacency(a.points.size(), a.tetrahedra);
  std::vector<int64_t> k(a.points.size());
  ValueCoder           values;
  a.values.resize(a.points.size());
  for (uint32_t i = 0; i < a.points.size(); ++i)
  {
    int           known = 0;
    const int64_t prediction = ValueCoder::Predict(adjacency, k, i, known);
    k[i] = prediction + values.residual[ValueCoder::Context(known)].Decode(decoder);
    if (decoder.Overrun())
    {
      throw FormatError(name + ": the payload ends inside the values");
    }
    if (std::abs(k[i]) >= (int64_t(1) << 31))
    {
      throw FormatError(name + ": damaged values");
    }
    a.values[i] = q0 + double(k[i]) * q;
  }
  if (decoder.Overrun())
  {
    throw FormatError(name + ": the payload ends inside the values");
  }
  if (decoder.GetPosition() != payload.size())
  {
    // A correct stream is read to its last byte (docs/format.md, "Arithmetic decoder").
    throw FormatError(name + ": " + std::to_string(payload.size() - decoder.GetPosition()) +
                      " bytes follow the coded values");
  }
  return a;
}

Approximation
ConstantSpline(const GridSize & grid, const GridScale & scale, double value)
{
  Approximation a;
  a.grid = grid;
  a.scale = scale;
  for (int32_t z : { 0, grid.z - 1 })
    for (int32_t y : { 0, grid.y - 1 })
      for (int32_t x : { 0, grid.x - 1 })
        a.points.push_back({ x, y, z });
  a.values.assign(8, value);
  a.tetrahedra = Tetrahedralize(a.points, a.scale);
  return a;
}

Approximation
DecodeMesh(const CompressedFile & file, const DecodeLimits & limits)
{
  const FileHeader & h = file.header;
  CheckDecodingMemory(h, file.name, DecodeOutput::Mesh, limits);
  if (h.constantSpline)
    return ConstantSpline(h.size, h.scale, h.quantizationOrigin); // no point is coded
  return DecodePayload(
    file.payload, h.size, h.numberOfPoints, h.quantizationOrigin, h.quantizationStep, file.name, h.scale);
}

Approximation
Decode(const CompressedFile & file, const DecodeLimits & limits)
{
  const FileHeader & h = file.header;
  CheckDecodingMemory(h, file.name, DecodeOutput::Volume, limits);
  Approximation a = DecodeMesh(file, limits);
  if (h.residualStep > 0.0)
  {
    a.residual = { h.residualStep,
                   h.boundedLayer ? DecodeBoundedLayer(h.residualLayer, h.size, file.name)
                   : h.videoLayer ? DecodeVideoLayer(h.videoCodec, h.residualLayer, h.size, file.name)
                                  : DecodeResidualLayer(h.residualLayer, h.size, file.name, h.residualLevels) };
  }
  return a;
}

} // namespace dcv
