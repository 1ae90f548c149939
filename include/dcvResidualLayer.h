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
#include <functional>
#include <limits>
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
DelaunayCompression_EXPORT ResidualSamples
DecodeResidualLayer(const std::vector<uint8_t> & codestream, const GridSize & grid, const std::string & name,
                    int32_t levels = 0);

/** DecodeResidualLayer row by row, without a volume of the samples: each row (slice z's row y, x
 * samples, valid during the call) goes to `sink(y, z, row)`, from several threads, each row once. A
 * decoder adds them to its voxels as they come; the encoder sums a trial's error. */
DelaunayCompression_EXPORT void
DecodeResidualRows(const std::vector<uint8_t> & codestream, const GridSize & grid, const std::string & name,
                   int32_t levels, const std::function<void(int32_t y, int32_t z, const int32_t * row)> & sink);

/** Bytes of the fields a compact layer stores instead of its codestream's SOC, SIZ, COD, SOT, SOD and EOC. */
constexpr std::size_t CompactLayerFieldBytes = 4;

/** The compact form of a residual layer's codestream (docs/format.md, "Compact residual layer"): its
 * fields, its QCD marker segment and its tile's data, without the markers a decoder rebuilds from the
 * fields and the grid. False (and `stored` empty) unless ExpandLayer() gives exactly `codestream` back. */
DelaunayCompression_EXPORT bool
CompactLayer(const std::vector<uint8_t> & codestream, const GridSize & grid, std::vector<uint8_t> & stored);

/** The codestream of a compact layer; throws FormatError starting with `name` when its fields are not valid. */
DelaunayCompression_EXPORT std::vector<uint8_t>
ExpandLayer(const std::vector<uint8_t> & stored, const GridSize & grid, const std::string & name);

/** The bytes a residual layer's codestream takes in a file: compact when it can be, else whole. */
DelaunayCompression_EXPORT std::size_t
                           StoredLayerBytes(const std::vector<uint8_t> & codestream, const GridSize & grid);

/** The bytes the compact form of an arrangement's codestream saves (when OpenJPEG writes it as expected). */
DelaunayCompression_EXPORT std::size_t
                           CompactLayerSaving(const GridSize & grid, Arrangement arrangement);

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
  ResidualSamples      samples;     // as the decoder gets them
  double               squaredError{ 0.0 };
};

/** A wavelet, an arrangement and the levels of the inter-slice wavelet. */
struct ResidualCoding
{
  Wavelet     wavelet;
  Arrangement arrangement;
  int32_t     levels{ 0 };
  /** 2D wavelet levels fewer than the most the image takes (JPEG 2000 resolutions: one more than the levels
   * the image's smaller side allows, at most 6). At low rates the coarse levels of a small mosaic span the
   * borders between its slices, and fewer of them decode closer. */
  int32_t fewerResolutions{ 0 };
};

/** Codes the spline's residual against `voxels` (the original, laid out as the grid) in at most
 * `maximumBytes` bytes (the codestream as stored, StoredLayerBytes(), and, with an inter-slice wavelet, its levels),
 * one coding at a time, so that the caller chooses the next coding from the errors so far; keeps the coding that
 * decodes closest, decoded as a decoder will. The spline is rasterized once (a constant one is filled), on the
 * encoder's threads; the residual samples for each encode (no volume of them is kept between). `voxels` must outlive
 * it. */
class DelaunayCompression_EXPORT ResidualSearch
{
public:
  ResidualSearch(const float * voxels, PixelType type, const Approximation & spline, double step,
                 std::size_t maximumBytes);
  /** The squared error of the spline alone (without a layer). */
  double
  SplineError() const
  {
    return splineError;
  }
  /** Codes and decodes with `coding`: the first codestream that fits, from a target of the whole budget
   * down; the squared error of the volume it decodes to (infinity when no codestream fits). */
  double
  Try(const ResidualCoding & coding);
  /** Fills the budget with the best coding so far: OpenJPEG lands up to 0.5% under its target, so while
   * more than `slack` bytes are left, up to `attempts` more targets between the largest that fit and the
   * smallest that did not; each codestream that fits is decoded and kept if it decodes closer. Returns
   * the encodes it ran. */
  std::size_t
  Fill(std::size_t slack, int attempts = 3);
  /** The best coding so far and what the next trial starts from: Save() it before a trial whose result
   * may be refused, Restore() it to refuse the trial. */
  struct State
  {
    ResidualChoice best;
    ResidualCoding coding;
    double         target;
    std::size_t    stored;
    double         backOff;
  };
  State
  Save() const
  {
    return { best, bestCoding, bestTarget, bestStored, backOff };
  }
  void
  Restore(State && s)
  {
    best = std::move(s.best);
    bestCoding = s.coding;
    bestTarget = s.target;
    bestStored = s.stored;
    backOff = s.backOff;
  }
  /** Bytes of the budget the best codestream leaves (0 with none). */
  std::size_t
  Unused() const
  {
    return best.codestream.empty() ? 0 : Limit(bestCoding) - bestStored;
  }
  /** The squared error of the best coding so far (infinity with none). */
  double
  BestError() const
  {
    return best.codestream.empty() ? std::numeric_limits<double>::infinity() : best.squaredError;
  }
  /** The best coding tried (no codestream when none fits), its codestream decoded again for the samples. */
  ResidualChoice
  Best() &&;

private:
  /** The residual in steps, row by row (slice z's row y), computed on each call: no volume of it is kept. */
  std::function<void(int32_t y, int32_t z, int32_t * row)>
  Source() const;
  double
  Measure(std::vector<uint8_t> && codestream, const ResidualCoding & coding, double target);
  std::size_t
  Limit(const ResidualCoding & coding) const;

  const float *        voxels;
  PixelType            type;
  GridSize             grid;
  std::size_t          maximumBytes;
  std::vector<uint8_t> splineVoxels;              // the spline's voxels, of the pixel type (one when constant)
  uint64_t             voxelMask{ ~uint64_t(0) }; // voxel i of the spline is splineVoxels[i & voxelMask]
  double               splineError{ 0.0 };
  ResidualChoice       best;
  ResidualCoding       bestCoding{ Wavelet::Irreversible97, Arrangement::Mosaic, 0 };
  double               bestTarget{ 0.0 }; // OpenJPEG's target that gave the best codestream
  std::size_t          bestStored{ 0 };   // the bytes it takes in a file (StoredLayerBytes())
  double               backOff{ 0.0 };    // below the budget the last coding's target had to be, as a fraction
};

/** Codes the spline's residual against `voxels` (the original, laid out as the grid) with each of
 * `codings` in at most `maximumBytes` bytes, decodes each codestream as a decoder will, and returns
 * the one of smallest squared error (no codestream when none fits). */
DelaunayCompression_EXPORT ResidualChoice
ChooseResidualLayer(const float * voxels, PixelType type, const Approximation & spline, double step,
                    std::size_t maximumBytes, const std::vector<ResidualCoding> & codings);

} // namespace dcv

#endif
