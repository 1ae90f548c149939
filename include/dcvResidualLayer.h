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
#ifndef dcvResidualLayer_h
#define dcvResidualLayer_h

#include "DelaunayCompressionExport.h"
#include "dcvApproximation.h"
#include "dcvFileFormat.h"

#include <cstdint>
#include <string>
#include <vector>

/** \file dcvResidualLayer.h
 * The residual layer of a .dcv file (docs/format.md): what the spline leaves, in integer multiples of
 * a residual step, coded by JPEG 2000 (OpenJPEG) with the slices tiled into one 2D mosaic, as per-slice
 * transform coders code thick-slice volumes well. OpenJPEG stays inside the compiled sources.
 * \ingroup DelaunayCompression
 */
namespace dcv
{

/** The wavelet of a residual layer: JPEG 2000's irreversible 9/7 or reversible 5/3. */
enum class Wavelet
{
  Irreversible97,
  Reversible53
};

/** How the slices become a JPEG 2000 image: tiled into one mosaic (one component), or one component
 * per slice (rate allocated over all of them). Each wins somewhere (the 5 mm CT series at 0.125 bpv:
 * 44.58 dB as components, 44.51 as a mosaic; ct-avm-4mm at 0.03125: 34.62 and 36.12). */
enum class Arrangement
{
  Mosaic,
  Components
};

/** Most components a JPEG 2000 codestream holds (its Csiz). */
constexpr int32_t MaximumComponents = 16384;

/** Columns of the mosaic of `grid.z` slices: near square, fewest empty tiles. Rows: ceil(z / columns). */
DelaunayCompression_EXPORT int32_t
MosaicColumns(const GridSize & grid);

/** Codes residual samples (laid out as the grid, x fastest; |sample| < 2^15) as a JPEG 2000 codestream
 * of at most `maximumBytes` bytes, after `levels` levels of the inter-slice wavelet
 * (dcvInterSliceWavelet.h; 0: none). Returns an empty vector when no codestream that small can be made
 * (or more slices than MaximumComponents as components). */
DelaunayCompression_EXPORT std::vector<uint8_t>
EncodeResidualLayer(const std::vector<int32_t> & samples, const GridSize & grid, std::size_t maximumBytes,
                    Wavelet wavelet, Arrangement arrangement = Arrangement::Mosaic, int32_t levels = 0);

/** Decodes a residual layer's codestream to samples laid out as the grid, undoing `levels` levels of
 * the inter-slice wavelet. Throws FormatError starting with `name` when the codestream is damaged or
 * does not hold a mosaic of the grid's slices. */
DelaunayCompression_EXPORT std::vector<int32_t>
DecodeResidualLayer(const std::vector<uint8_t> & codestream, const GridSize & grid, const std::string & name,
                    int32_t levels = 0);

/** Bytes a residual layer adds to a file besides its codestream (its step and length). */
constexpr std::size_t ResidualLayerFieldBytes = 12;

/** Bytes the levels of an inter-slice wavelet add (format flag bit 5). */
constexpr std::size_t InterSliceLevelsFieldBytes = 1;

/** The residual step: 1 for integer data whose range fits 14 bits, the range over 2^14 otherwise
 * (whole for integer data), so that every sample fits 15 signed bits. */
DelaunayCompression_EXPORT double
ResidualStep(double peak, bool integer);

/** A residual layer for a spline, and the squared error of the volume it decodes to. */
struct ResidualChoice
{
  double               step{ 0.0 };
  int32_t              levels{ 0 }; // of the inter-slice wavelet
  std::vector<uint8_t> codestream;  // empty: none fits
  std::vector<int32_t> samples;     // as the decoder gets them
  double               squaredError{ 0.0 };
};

/** A wavelet, an arrangement and the levels of the inter-slice wavelet. */
struct ResidualCoding
{
  Wavelet     wavelet;
  Arrangement arrangement;
  int32_t     levels{ 0 };
};

/** Codes the spline's residual against `voxels` (the original, laid out as the grid) in at most
 * `maximumBytes` bytes (the codestream and, with an inter-slice wavelet, its levels), one coding at a time, so that the
 * caller chooses the next coding from the errors so far; keeps the coding that decodes closest, decoded as a decoder
 * will. `voxels` must outlive it. */
class DelaunayCompression_EXPORT ResidualSearch
{
public:
  ResidualSearch(const float * voxels, PixelType type, const Approximation & spline, double step,
                 std::size_t maximumBytes);
  /** Codes and decodes with `coding`; the squared error of the volume it decodes to (infinity when no
   * codestream fits). */
  double
  Try(const ResidualCoding & coding);
  /** The best coding tried (no codestream when none fits). */
  ResidualChoice
  Best() &&
  {
    return std::move(best);
  }

private:
  const float *        voxels;
  PixelType            type;
  GridSize             grid;
  std::size_t          maximumBytes;
  std::vector<uint8_t> splineVoxels; // the spline's voxels, of the pixel type
  std::vector<int32_t> samples;      // the residual in steps
  ResidualChoice       best;
};

/** Codes the spline's residual against `voxels` (the original, laid out as the grid) with each of
 * `codings` in at most `maximumBytes` bytes, decodes each codestream as a decoder will, and returns
 * the one of smallest squared error (no codestream when none fits). */
DelaunayCompression_EXPORT ResidualChoice
ChooseResidualLayer(const float * voxels, PixelType type, const Approximation & spline, double step,
                    std::size_t maximumBytes, const std::vector<ResidualCoding> & codings);

} // namespace dcv

#endif
