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
#ifndef dcvCodec_h
#define dcvCodec_h

#include "DelaunayCompressionExport.h"
#include "dcvApproximation.h"
#include "dcvBoundedLayer.h"
#include "dcvFileFormat.h"
#include "dcvResidualLayer.h"
#include "dcvVideoLayer.h"

#include <cstdint>
#include <string>
#include <vector>

/** \file dcvCodec.h
 * The payload of a .dcv file (docs/format.md): the positions (dcvPositionCoder.h), then the
 * quantized values, each predicted from the mean of its Delaunay neighbours decoded before it and
 * coded as an adaptive signed residual, all in one arithmetic-coded stream. The decoder rebuilds the
 * tetrahedralization from the positions before it reads the values, and hands it on for rasterizing.
 * \ingroup DelaunayCompression
 */
namespace dcv
{

/** The value coder's lattice indices k stay below this in magnitude when coding (the decoder allows 2^31,
 * so that every residual between two of them fits an int32). */
constexpr int64_t MaximumQuantizationIndex = int64_t(1) << 30;

/** Codes the points and values of `a` (values must be q0 + k q with integer k, |k| < 2^30). The value
 * prediction needs the Delaunay tetrahedralization of the points, as the decoder rebuilds it: it is
 * computed here, unless `delaunay` says that a.tetrahedra already is it (the engine's mesh: unique
 * for the points and a.scale), which spares the encoder a tetrahedralization per rate-control step. */
DelaunayCompression_EXPORT std::vector<uint8_t>
                           EncodePayload(const Approximation & a, double q0, double q, bool delaunay = false);
/** The same, taking `a`'s points and tetrahedra (renumbered in place: a copy of the mesh less). */
DelaunayCompression_EXPORT std::vector<uint8_t>
                           EncodePayload(Approximation && a, double q0, double q, bool delaunay = false);

/** Decodes `count` points and their values, with the tetrahedra over them, ready for Rasterize().
 * Throws FormatError starting with `name` when the payload is truncated or damaged: at once when `count`
 * exceeds what the payload can hold (MaximumPointsPerPayloadByte), and as soon as the stream runs past
 * its end (a correct stream never does), not after decoding all `count` points. */
DelaunayCompression_EXPORT Approximation
DecodePayload(const std::vector<uint8_t> & payload, const GridSize & grid, uint32_t count, double q0, double q,
              const std::string & name, const GridScale & scale = { { 1, 1, 1 } });

/** The constant spline (form bit 0): the 8 corners of the grid, all at `value`, and their tetrahedra. */
DelaunayCompression_EXPORT Approximation
ConstantSpline(const GridSize & grid, const GridScale & scale, double value);

/** The spline of a parsed file alone: its points, values (dequantized) and tetrahedra, without the
 * residual layer (voxels, not part of the mesh; `residual` is left empty). What a mesh export needs:
 * nothing is rasterized. Throws FormatError naming the file when its payload is damaged, or, before
 * anything is allocated, when the mesh would need more memory than `limits` allow (CheckDecodingMemory). */
DelaunayCompression_EXPORT Approximation
DecodeMesh(const CompressedFile & file, const DecodeLimits & limits = DecodeLimits());

/** The one "decode this file" function of every reader (ImageIO, MeshIO, ImageSource, the tools):
 * the points, values and tetrahedra of a parsed file (DecodeMesh) and its residual layer, ready for
 * Rasterize(). Throws FormatError naming the file when its payload is damaged, or, before anything is
 * allocated, when the mesh and the volume would need more memory than `limits` allow. */
DelaunayCompression_EXPORT Approximation
Decode(const CompressedFile & file, const DecodeLimits & limits = DecodeLimits());

/** Decodes a parsed file into `out` (laid out as the grid, of the file's pixel type T): the voxels of
 * Rasterize(Decode(file)), with the residual layer added to them row by row as JPEG 2000 decodes it,
 * not kept as a volume of int32 first (norm-256 at 0.03125 bpv: 17,000 page faults of 45,000 less).
 * What `dcv decompress` and the ImageIO do; Decode() is for callers that rasterize parts (RasterizeBox). */
template <typename T>
void
DecodeVolume(const CompressedFile & file, T * out, const DecodeLimits & limits = DecodeLimits(),
             unsigned int threads = 0)
{
  const FileHeader & h = file.header;
  CheckDecodingMemory(h, file.name, DecodeOutput::Volume, limits);
  const Approximation a = DecodeMesh(file, limits);
  double              one = 0.0;
  // A constant spline under the layer (the corners' layer) is written with it, row by row: one pass
  // over the voxels instead of two, the same values as Rasterize() gives.
  const bool constant = h.residualStep > 0.0 && detail::IsConstantSpline<T>(a, one);
  if (!constant)
    Rasterize(a, out, threads);
  if (h.residualStep > 0.0)
  {
    const T value = ConvertValue<T>(one);
    auto    add = [&](int32_t y, int32_t z, const int32_t * row) {
      T * voxels = out + h.size.Offset(0, y, z);
      if (constant)
        std::fill_n(voxels, h.size.x, value);
      detail::AddResidualToRow(h.residualStep, row, voxels, uint64_t(h.size.x));
    };
    if (h.boundedLayer)
    {
      const ResidualSamples samples = DecodeBoundedLayer(h.residualLayer, h.size, file.name);
      for (int32_t z = 0; z < h.size.z; ++z)
        for (int32_t y = 0; y < h.size.y; ++y)
          add(y, z, samples.data() + h.size.Offset(0, y, z));
    }
    else if (h.videoLayer)
      DecodeVideoRows(h.videoCodec, h.residualLayer, h.size, file.name, add);
    else
      DecodeResidualRows(h.residualLayer, h.size, file.name, h.residualLevels, add);
  }
}

} // namespace dcv

#endif
