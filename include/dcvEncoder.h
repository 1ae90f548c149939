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
#ifndef dcvEncoder_h
#define dcvEncoder_h

#include "DelaunayCompressionExport.h"
#include "dcvApproximation.h"
#include "dcvFileFormat.h"
#include "dcvRefinementEngine.h"

#include <functional>
#include <string>
#include <utility>
#include <vector>

/** \file dcvEncoder.h
 * The encoder every caller uses (the dcv tool, DCVImageIO under itk::ImageFileWriter, the
 * approximation filter): a volume and options in; the approximation, the .dcv bytes and the figures
 * out. itkDCVEncoder.h gives it any itk::Image.
 * \ingroup DelaunayCompression
 */
namespace dcv
{

/** What to encode and how. One target: BitsPerVoxel, PSNR or MaximumError, else NumberOfPoints. */
struct EncoderOptions
{
  /** Size of the whole .dcv file in bits per voxel (0: off). The point count, and the quantization step
   * when QuantizationStep is 0, are chosen so that the file fills 97% to 100% of it (dcv::MinimumFileBytes);
   * a video layer's stream grows in steps: an HEVC stream on small volumes may fill a little less, an AV1
   * stream at least dcv::AV1MinimumFill of it, and where the finest quality already fits (its lossless
   * stream not), the file is that stream, however short. */
  double bitsPerVoxel{ 0.0 };
  /** Quality target in dB (0: off): the smallest file whose decoded PSNR reaches it. */
  double psnr{ 0.0 };
  /** A bound on every voxel's error, in the input's units (negative: off; 0: lossless, bit for bit): the
   * smallest file the encoder makes with every decoded voxel within it of the input (a bounded-error layer
   * over a constant spline, dcvBoundedLayer.h). Integers keep its whole part (|x - x'| is a whole number);
   * floats need at least SmallestMaximumError(). Not with BitsPerVoxel or PSNR. */
  double maximumError{ -1.0 };
  /** Number of significant points when no other target is set (at least 8: the corners). */
  std::size_t numberOfPoints{ 10000 };
  /** Step of the vertex values (0: automatic: with BitsPerVoxel the best of 1, 2 and 4 times 1/64 of
   * the peak, with PSNR 1/64 of the peak or less when the target needs it, else 1/64 of the peak). */
  double quantizationStep{ 0.0 };
  /** The method (default best) and its parameters, as itk::DelaunayApproximationImageToMeshFilter. */
  Mode   mode{ Mode::Best };
  double domainSigma{ 1.0 }; // bilateral filter of I*: spatial sigma, voxels
  double rangeSigma{ 0.0 };  // bilateral filter of I*: intensity sigma (0: 8% of the peak)
  double alpha{ 0.9 };       // positions on I* until PSNR(L) >= alpha PSNR(I*)
  /** Per-axis scale of the Delaunay space (GridScale); 0 on every axis: from the voxel spacing
   * (AutomaticScale). */
  GridScale scale{ { 0, 0, 0 } };
  /** With BitsPerVoxel, also try the residual layer (JPEG 2000 of what the spline leaves,
   * dcvResidualLayer.h): in the bytes the points leave, and with all of the budget over the 8 corners;
   * the file keeps whichever of the three decodes closest to the input. Off: points only. */
  bool residualLayer{ true };
  /** With ResidualLayer, also try the video layer (the volume's slices as the frames of an HEVC or AV1 stream
   * over a constant spline, dcvVideoLayer.h), kept where it decodes closest. Off: JPEG 2000 layers only. */
  bool videoLayer{ true };
  /** The video layer's codecs, each tried, the stream that decodes closest kept: both by default (AV1 won
   * on most dev volumes, HEVC on the 5 mm CT series above 0.03125 bpv); one alone codes the video layer in
   * about half the time. */
  std::vector<VideoCodec> videoCodecs{ VideoCodec::HEVC, VideoCodec::AV1 };
  /** Key/value pairs stored in the file's metadata block (they count against the bit budget). */
  std::vector<std::pair<std::string, std::string>> metadata;
  /** Threads the encoder may use (0: one per core). The file is the same whatever their number. */
  unsigned int threads{ 0 };
  /** Called with the fraction done, in [0, 1]; it may throw to abort. */
  std::function<void(double)> progress;
  /** The most memory encoding may need (bytes, EncodingMemory(); 0: no limit): a larger job is refused
   * before the volume is copied. Default: half of the physical memory (DefaultMaximumMemory()). */
  uint64_t maximumMemory{ DefaultMaximumMemory() };
};

/** Checks the options; throws std::invalid_argument naming the first one out of range. */
DelaunayCompression_EXPORT void
CheckOptions(const EncoderOptions & options);

/** BitsPerVoxel above this is refused whatever the volume: the size of a float64 voxel. */
constexpr double MaximumBitsPerVoxel = 64.0;

struct EncoderInput;

/** CheckOptions(options), then what depends on the volume (its voxels only when input.voxels is set):
 * finite voxels, BitsPerVoxel at most the
 * pixel type's bits and within MaximumPayloadBytes, NumberOfPoints at most the voxels (when it is the
 * target), the memory the job needs within MaximumMemory (CheckEncodingMemory), and a QuantizationStep
 * whose lattice spans the values within MaximumQuantizationIndex / 2 steps (MaximumPayloadBytes,
 * MaximumQuantizationIndex: dcvFileFormat.h, dcvCodec.h). Throws std::invalid_argument. */
DelaunayCompression_EXPORT void
CheckOptions(const EncoderOptions & options, const EncoderInput & input);

/** The encoder's memory model, from above: per voxel the input as floats, I* (mode dec+com), the engine's
 * per-voxel state and, with a bit budget and the residual layer, the layer's trial buffers; per point the
 * tetrahedralization, the least squares and the heaps. The peaks of the 40 dev runs, of float32, float64
 * and int16 copies of norm-256 and of `--points` runs were 0.38 to 0.82 of it from 2 million voxels on
 * (below, the libraries' 20 MiB dominate; docs/profile.md), where the model
 * before (24 and 48 bytes a voxel, 4 KiB a point) was 2.3 to 5.2 times the peak and refused jobs that fit. */
constexpr double EncodingBytesPerVoxel = 16.0;
constexpr double EncodingBytesPerVoxelWithResidualLayer = 24.0;
constexpr double EncodingBytesPerPoint = 2048.0;

/** What encoding a grid with these options may need at most (the memory model above). The points: the
 * target NumberOfPoints, or with BitsPerVoxel as many as the budget holds at 8 bits a point; a PSNR
 * target's count is not known beforehand, NumberOfPoints stands for it. */
DelaunayCompression_EXPORT uint64_t
EncodingMemory(const GridSize & grid, const EncoderOptions & options);

/** Throws std::invalid_argument (what the job would need, and the limit) when EncodingMemory() exceeds
 * options.maximumMemory. */
DelaunayCompression_EXPORT void
CheckEncodingMemory(const GridSize & grid, const EncoderOptions & options);

/** Checks that each axis has 2 to MaximumGridExtent voxels; throws std::invalid_argument. */
DelaunayCompression_EXPORT void
CheckGrid(const GridSize & grid);

/** A volume as the encoder reads it: voxels as floats (x fastest), their pixel type and geometry in
 * `header`, and I* (same layout) when the mode uses it. */
struct EncoderInput
{
  const float * voxels{ nullptr };
  const float * smoothed{ nullptr };
  /** The voxels at full precision (same layout), for MaximumError; `voxels` and `smoothed` are then not read. */
  const double * exact{ nullptr };
  FileHeader     header; // pixelType, size, spacing, origin, direction
  /** When set, called once the encoder no longer reads I* (the points are done, the residual layers
   * follow), so that its owner can free it for them; `smoothed` is not read after the call. */
  std::function<void()> releaseSmoothed;
};

/** The scale that makes the Delaunay space follow the physical spacing: integers 1 to MaximumGridScale
 * in the ratios of the spacings, within 5% where they allow. */
DelaunayCompression_EXPORT GridScale
AutomaticScale(const std::array<double, 3> & spacing);

/** The smallest MaximumError a volume of this pixel type and range can keep: 0 for integers; for floats the
 * spacing of the pixel type's values near the largest magnitude, or 9 (max - min) / 4e9 (the lattice's 32-bit
 * indices), whichever is larger. */
DelaunayCompression_EXPORT double
SmallestMaximumError(PixelType type, double minimum, double maximum);

/** The PSNR peak of an encoder input (255 for 8-bit data, else max - min). */
DelaunayCompression_EXPORT double
PSNRPeak(const EncoderInput & input);

/** The intensity sigma of I* for the options and a peak. */
inline double
RangeSigma(const EncoderOptions & options, double peak)
{
  // Automatic: 8% of the peak (20.4 for 8-bit data). Measured on headsq-ct (int16, range 3926) at 634
  // points in mode dec+com: 24.19 dB with sigma 20, 25.02 dB with 300 (dec alone: 24.41 dB).
  return options.rangeSigma > 0.0 ? options.rangeSigma : 0.08 * peak;
}

/** What the encoder made. */
struct EncoderResult
{
  /** The whole .dcv file (Encode only). */
  std::vector<uint8_t> bytes;
  /** The file's header (quantization and point count included). */
  FileHeader header;
  /** Grid points, values (quantizationOrigin + k step when quantized) and their tetrahedra. */
  Approximation approximation;
  /** Quantization step of the values (0: not quantized; Approximate without a step or target). */
  double quantizationStep{ 0.0 };
  /** Sum over voxels of (I - L)^2 for the unrounded spline L; with a residual layer, of the decoded
   * volume. */
  double squaredError{ 0.0 };
  /** PSNR of the image a decoder gives (rounded and clamped to the pixel type), Encode only. */
  double psnr{ 0.0 };
  /** PSNR(I*) against I (0 when the mode does not smooth). */
  double smoothedPSNR{ 0.0 };
  /** The PSNR peak (255 for 8-bit data, else max - min of the input). */
  double peak{ 0.0 };
  /** The bound every decoded voxel keeps (MaximumError as the file states it; negative: none). */
  double maximumError{ -1.0 };
  /** Point-count steps of rate control after the first run of the method. */
  unsigned adjustments{ 0 };
  /** Seconds of each stage, and of the whole call. The stages of the points and the waiting for the residual
   * layer follow one another on the calling thread (the critical path); the layer's own work runs beside
   * them on a thread of its own, so `residualLayer` may overlap the points' stages. */
  struct Timings
  {
    double smoothing{ 0.0 };
    double refinement{ 0.0 };
    double decimation{ 0.0 };
    double leastSquares{ 0.0 };
    /** The residual layer's work, on its thread and on the calling thread. */
    double residualLayer{ 0.0 };
    /** The calling thread's part of it: waiting for the layer's thread, then choosing the file. */
    double residualLayerOnPath{ 0.0 };
    double total{ 0.0 };
  } timings;
};

/** Runs the method on the input as the options say, and stops there: no file is made. Values are
 * quantized when a step or a target is given. */
DelaunayCompression_EXPORT EncoderResult
Approximate(const EncoderInput & input, const EncoderOptions & options);

/** Approximate() with quantized values (the default step when none is given), then the .dcv file:
 * the payload measured once, the header with the options' metadata, and the PSNR of what a decoder
 * will give. Throws std::length_error when the bit budget cannot hold even the 8 corners. */
DelaunayCompression_EXPORT EncoderResult
Encode(const EncoderInput & input, const EncoderOptions & options);

/** Squared error between the input voxels and the approximation as a decoder gives it: rasterized
 * into the pixel type (rounded and clamped for integers). */
DelaunayCompression_EXPORT double
DecodedSquaredError(const Approximation & approximation, PixelType type, const float * voxels);

} // namespace dcv

#endif
