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
#include "dcvEncoder.h"
#include "dcvBoundedEncoder.h"
#include "dcvCodec.h"
#include "dcvParallel.h"
#include "dcvRateControl.h"
#include "dcvResidualLayer.h"
#include "dcvVideoLayer.h"
#include "dcvInterSliceWavelet.h"
#include "dcvMemory.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <functional>
#include <future>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <mutex>
#include <condition_variable>
#include <stdexcept>
#include <string>
#include <tuple>

namespace dcv
{
namespace
{
std::string
Number(double v)
{
  std::string s = std::to_string(v);
  s.erase(s.find_last_not_of('0') + 1);
  if (!s.empty() && s.back() == '.')
    s.pop_back();
  return s;
}

/** The range of values of a pixel type. */
std::pair<double, double>
ValueRange(PixelType type)
{
  std::pair<double, double> range;
  VisitPixelType(type, [&range](auto pixel) {
    using T = decltype(pixel);
    range = { double(std::numeric_limits<T>::lowest()), double(std::numeric_limits<T>::max()) };
  });
  return range;
}

bool
EightBit(PixelType type)
{
  return type == PixelType::UInt8 || type == PixelType::Int8;
}
} // namespace

void
CheckOptions(const EncoderOptions & o)
{
  // Each option is named as the ITK classes call it and as the dcv tool spells it.
  auto refuse = [](const std::string & what, const std::string & rule, double v) {
    char text[32]; // 1e-300 in fixed notation would read as 0
    std::snprintf(text, sizeof(text), "%g", v);
    const bool plain = v == 0.0 || (std::abs(v) >= 1e-4 && std::abs(v) < 1e15);
    throw std::invalid_argument(what + " must be " + rule + ", got " + (plain ? Number(v) : std::string(text)));
  };
  if (!(o.bitsPerVoxel >= 0.0) || !std::isfinite(o.bitsPerVoxel))
    refuse("BitsPerVoxel (--bpv)", "positive, or 0: off", o.bitsPerVoxel);
  // No budget beyond the widest voxel's own size (float64) is ever needed; the volume's own bound is
  // checked with its pixel type (CheckOptions with the input).
  if (o.bitsPerVoxel > MaximumBitsPerVoxel)
    refuse("BitsPerVoxel (--bpv)", "at most " + std::to_string(int(MaximumBitsPerVoxel)), o.bitsPerVoxel);
  if (!(o.psnr >= 0.0) || !std::isfinite(o.psnr))
    refuse("PSNR (--psnr)", "positive, or 0: off", o.psnr);
  if (o.bitsPerVoxel > 0.0 && o.psnr > 0.0)
    throw std::invalid_argument("give BitsPerVoxel (--bpv) or PSNR (--psnr), not both");
  if (std::isnan(o.maximumError) || std::isinf(o.maximumError))
    refuse("MaximumError (--max-error)", "a finite number (negative: off)", o.maximumError);
  if (o.maximumError >= 0.0 && (o.bitsPerVoxel > 0.0 || o.psnr > 0.0))
    throw std::invalid_argument(std::string("give MaximumError (--max-error) or ") +
                                (o.bitsPerVoxel > 0.0 ? "BitsPerVoxel (--bpv)" : "PSNR (--psnr)") + ", not both");
  if (o.numberOfPoints < 8)
    refuse("NumberOfPoints (--points)", "at least 8 (the corners of the volume)", double(o.numberOfPoints));
  if (!(o.quantizationStep >= 0.0) || !std::isfinite(o.quantizationStep))
    refuse("QuantizationStep (--step)", "positive, or 0: automatic", o.quantizationStep);
  if (!(o.domainSigma > 0.0) || !std::isfinite(o.domainSigma))
    refuse("DomainSigma (--domain-sigma)", "positive", o.domainSigma);
  if (!(o.rangeSigma >= 0.0) || !std::isfinite(o.rangeSigma))
    refuse("RangeSigma (--range-sigma)", "positive, or 0: automatic", o.rangeSigma);
  if (!(o.alpha > 0.0) || !std::isfinite(o.alpha))
    refuse("Alpha (--alpha)", "positive", o.alpha);
  const bool automatic = o.scale == GridScale{ { 0, 0, 0 } };
  for (int32_t s : o.scale)
  {
    if (!automatic && (s < 1 || s > MaximumGridScale))
      refuse(
        "Scale (--scale)", "1 to " + std::to_string(MaximumGridScale) + " on each axis, or 0 on all: automatic", s);
  }
}

uint64_t
EncodingMemory(const GridSize & grid, const EncoderOptions & o)
{
  const double voxels = double(grid.NumberOfVoxels());
  if (o.maximumError >= 0.0) // the voxels as doubles, the layer's samples, the coded bytes: 13 to 14 a voxel
    return uint64_t(std::min(voxels * EncodingBytesPerVoxel, 1.8e19));
  const bool   residual = o.bitsPerVoxel > 0.0 && o.residualLayer;
  const double points = o.bitsPerVoxel > 0.0 ? std::max(8.0, std::min(voxels, o.bitsPerVoxel * voxels / 8.0))
                                             : std::min(voxels, double(o.numberOfPoints));
  const double bytes = voxels * (residual ? EncodingBytesPerVoxelWithResidualLayer : EncodingBytesPerVoxel) +
                       points * EncodingBytesPerPoint;
  return bytes < 1.8e19 ? uint64_t(bytes) : std::numeric_limits<uint64_t>::max();
}

void
CheckEncodingMemory(const GridSize & grid, const EncoderOptions & o)
{
  const uint64_t needed = EncodingMemory(grid, o);
  if (o.maximumMemory > 0 && needed > o.maximumMemory)
  {
    throw std::invalid_argument(
      "encoding " + std::to_string(grid.x) + "x" + std::to_string(grid.y) + "x" + std::to_string(grid.z) +
      " voxels with these options may need " + FormatByteCount(needed) + ", more than the limit of " +
      FormatByteCount(o.maximumMemory) + " (MaximumMemory, --max-memory; fewer points or a smaller budget need less)");
  }
}

void
CheckOptions(const EncoderOptions & o, const EncoderInput & input)
{
  CheckOptions(o);
  const uint64_t voxels = input.header.size.NumberOfVoxels();
  const float *  end = input.voxels + (input.voxels != nullptr ? voxels : 0);
  // Non-finite values would make the quantization origin, the step and the PSNR NaN or infinite.
  const auto nonFinite =
    ParallelCount(input.voxels, std::size_t(end - input.voxels), [](float v) { return !std::isfinite(v); });
  if (nonFinite > 0)
  {
    throw std::invalid_argument("the volume holds " + std::to_string(nonFinite) +
                                " non-finite voxels (NaN or infinite); dcv codes finite values only");
  }
  int bits = 0;
  VisitPixelType(input.header.pixelType, [&bits](auto pixel) { bits = int(8 * sizeof(pixel)); });
  if (o.bitsPerVoxel > double(bits))
  {
    throw std::invalid_argument("BitsPerVoxel (--bpv) must be at most " + std::to_string(bits) + " for " +
                                PixelTypeName(input.header.pixelType) +
                                " voxels (the size of the volume itself), got " + Number(o.bitsPerVoxel));
  }
  const double budget = std::floor(o.bitsPerVoxel * double(voxels) / 8.0);
  if (budget > double(MaximumPayloadBytes))
  {
    throw std::invalid_argument("BitsPerVoxel (--bpv) " + Number(o.bitsPerVoxel) + " allows " + Number(budget) +
                                " bytes for " + std::to_string(voxels) + " voxels; a .dcv payload holds at most " +
                                std::to_string(MaximumPayloadBytes) + " (a uint32 length)");
  }
  if (o.bitsPerVoxel == 0.0 && o.psnr == 0.0 && o.maximumError < 0.0 && o.numberOfPoints > voxels)
  {
    throw std::invalid_argument("NumberOfPoints (--points) must be at most the number of voxels, " +
                                std::to_string(voxels) + ", got " + std::to_string(o.numberOfPoints));
  }
  CheckEncodingMemory(input.header.size, o); // after the targets' own bounds: their messages say more
  if (input.voxels != nullptr && o.quantizationStep > 0.0)
  {
    // The value coder takes lattice indices k = (v - q0) / q below 2^30 (EncodePayload), q0 the minimum;
    // half of that leaves room for least-squares values beyond the range of the voxels.
    const auto   range = ParallelMinMax(input.voxels, voxels);
    const double span = double(range.second) - double(range.first);
    const double smallest = span / double(MaximumQuantizationIndex / 2);
    if (o.quantizationStep < smallest)
    {
      char text[96];
      std::snprintf(text,
                    sizeof(text),
                    "at least %g for values from %g to %g (2^29 steps)",
                    smallest,
                    double(range.first),
                    double(range.second));
      char given[32];
      std::snprintf(given, sizeof(given), "%g", o.quantizationStep);
      throw std::invalid_argument(std::string("QuantizationStep (--step) must be ") + text + ", got " + given);
    }
  }
}

void
CheckGrid(const GridSize & grid)
{
  for (int32_t n : { grid.x, grid.y, grid.z })
  {
    if (n < 2 || n > MaximumGridExtent)
    {
      throw std::invalid_argument("the volume is " + std::to_string(grid.x) + "x" + std::to_string(grid.y) + "x" +
                                  std::to_string(grid.z) + " voxels; each axis needs 2 to " +
                                  std::to_string(MaximumGridExtent) + " voxels");
    }
  }
}

GridScale
AutomaticScale(const std::array<double, 3> & spacing)
{
  // The smallest common multiplier m whose rounded m x ratios are within 5% of the ratios (ct-avm,
  // 0.72 x 0.72 x 1 mm: 3, 3, 4, +0.29 dB at 0.03125 bpv over 1, 1, 1; ct-avm-4mm, 4 mm slices: 2, 2, 11,
  // +2.5 dB), else the closest with the largest factor at most MaximumGridScale.
  const double finest = *std::min_element(spacing.begin(), spacing.end());
  const double coarsest = *std::max_element(spacing.begin(), spacing.end());
  GridScale    best{ { 1, 1, 1 } };
  double       bestError = std::numeric_limits<double>::infinity();
  for (int m = 1; m <= MaximumGridScale && m * coarsest / finest < MaximumGridScale + 0.5; ++m)
  {
    GridScale scale;
    double    error = 0.0;
    for (int d = 0; d < 3; ++d)
    {
      const double ideal = m * spacing[d] / finest;
      scale[d] = int32_t(std::clamp(std::round(ideal), 1.0, double(MaximumGridScale)));
      error = std::max(error, std::abs(scale[d] - ideal) / ideal);
    }
    if (error < bestError - 1e-12)
    {
      best = scale;
      bestError = error;
    }
    if (error <= 0.05)
    {
      break;
    }
  }
  if (!(coarsest / finest < MaximumGridScale + 0.5))
  {
    for (int d = 0; d < 3; ++d) // thicker than 16 pixels: as thick as allowed
      best[d] = int32_t(std::clamp(std::round(spacing[d] / finest), 1.0, double(MaximumGridScale)));
  }
  return best;
}

double
PSNRPeak(const EncoderInput & input)
{
  const auto range = ParallelMinMax(input.voxels, input.header.size.NumberOfVoxels());
  return PSNRPeak(range.first, range.second, EightBit(input.header.pixelType));
}

double
DecodedSquaredError(const Approximation & a, PixelType type, const float * voxels)
{
  double error = 0.0;
  VisitPixelType(type, [&](auto pixel) {
    std::vector<decltype(pixel)> decoded(a.grid.NumberOfVoxels());
    Rasterize(a, decoded.data(), CurrentThreads());
    error = SquaredError(voxels, decoded.data(), decoded.size());
  });
  return error;
}

namespace
{
/** The 8 corners of the grid, all at `value`: the spline under a residual layer that takes all of the
 * budget. */
Approximation
Corners(const GridSize & grid, const GridScale & scale, double value)
{
  return ConstantSpline(grid, scale, value);
}

/** Slices this many times as thick as their pixels are wide or more: the corners' layer tries one
 * JPEG 2000 component per slice as well as the mosaic. */
constexpr double ThickSlices = 1.5;

/** At most this many bits a voxel, the corners' layer's descent tries more levels of the inter-slice
 * wavelet before fewer (docs/rd/levels.md: the best level count falls as the rate rises). */
constexpr double UpFirstBitsPerVoxel = 0.125;

/** Below this many bytes a codestream is mostly its own headers. */
constexpr std::size_t MinimumCodestream = 256;

/** The bytes a layer's codestream (as stored) and levels may take in a file of `fileBytes` with header
 * h and a payload. */
std::size_t
LayerRoom(const FileHeader & h, double step, std::size_t fileBytes, std::size_t payloadBytes)
{
  FileHeader withLayer = h;
  withLayer.residualStep = step;
  withLayer.residualLevels = 0;
  withLayer.residualLayer = { 0 };
  // The payload follows its fixed-size length as it is: measured without it, then added.
  const std::size_t used = SerializeFile(withLayer, {}).size() - 1 + payloadBytes;
  return fileBytes > used ? fileBytes - used : 0;
}

/** The other way to spend a budget: the 8 corners, one constant, under a residual layer that takes all
 * of it. */
struct CornersCandidate
{
  FileHeader                      header; // a constant spline (form bit 0): no points, no payload
  Approximation                   spline;
  double                          step{ 0.0 };
  std::unique_ptr<ResidualSearch> search;      // none: no room for a codestream, or a constant volume
  FileHeader                      videoHeader; // the corners under a video layer (form bits 0 and 3)
  VideoChoice                     video;       // no stream: none fits

  double
  Error() const
  {
    const double layer = search ? search->BestError() : std::numeric_limits<double>::infinity();
    return video.stream.empty() ? layer : std::min(layer, video.squaredError);
  }
};

/** Opens once, for good: the points' thread is done with the cores (or waits for the corners' layer), so a
 * second video search may take one. */
class CoreFree
{
public:
  void
  Open()
  {
    {
      const std::lock_guard<std::mutex> lock(m_Mutex);
      m_Open = true;
    }
    m_Changed.notify_all();
  }
  void
  Wait()
  {
    std::unique_lock<std::mutex> lock(m_Mutex);
    m_Changed.wait(lock, [this] { return m_Open; });
  }

private:
  std::mutex              m_Mutex;
  std::condition_variable m_Changed;
  bool                    m_Open{ false };
};

/** Codes the video layer over the constant spline at the input's minimum (video samples are unsigned), in
 * the bytes a file of `fileBytes` leaves it: each codec, the one that decodes closest kept. */
void
TryVideo(const EncoderInput & input, CornersCandidate & candidate, std::size_t fileBytes, double minimum,
         double maximum, const std::vector<VideoCodec> & codecs, const std::function<void(double)> & tried,
         CoreFree * coreFree)
{
  const PixelType type = input.header.pixelType;
  const double    step = VideoStep(double(maximum) - double(minimum), IsInteger(type));
  FileHeader &    h = candidate.videoHeader;
  h = candidate.header;
  h.videoLayer = true;
  h.quantizationOrigin = minimum;
  const std::size_t room = LayerRoom(h, step, fileBytes, 0);
  if (room < MinimumCodestream)
    return;
  // The codecs' searches side by side once a core is free: a search is mostly one encode after another on
  // one core (norm-256 at 0.03125 bpv: 47 CPU s in 35.5 s of wall time, the points abandoned after 9 s),
  // and the searches do not depend on each other. The second starts when the points' thread is done or
  // the first search is (with the points still running it took their core: norm-256 at 0.25 bpv 94 s
  // instead of 83). The bound reported is the best error of either so far; the choice, in the codecs'
  // order, is the same whichever ends first.
  std::vector<VideoChoice> choices(codecs.size());
  std::mutex               reporting;
  double                   best = std::numeric_limits<double>::infinity();
  auto                     report = [&](double error) {
    const std::lock_guard<std::mutex> lock(reporting);
    best = std::min(best, error);
    if (tried)
      tried(best);
  };
  auto search = [&](std::size_t i) {
    // Slices a codec cannot code (larger than its pictures may be) leave the other candidates, as a budget
    // too small for a stream does.
    try
    {
      choices[i] = ChooseVideoLayer(codecs[i], input.voxels, type, input.header.size, minimum, step, room, report);
    }
    catch (const std::runtime_error &)
    {
      choices[i] = VideoChoice();
    }
  };
  std::vector<std::future<void>> others;
  for (std::size_t i = 1; i < codecs.size(); ++i)
    others.push_back(std::async(std::launch::async, [&, i, threads = CurrentThreads()] {
      if (coreFree)
        coreFree->Wait();
      WithThreads(threads, [&] { search(i); });
    }));
  if (!codecs.empty())
  {
    struct FreeAtEnd // also when the search throws: the others wait for it
    {
      CoreFree * free;
      ~FreeAtEnd()
      {
        if (free)
          free->Open();
      }
    } freeAtEnd{ coreFree };
    search(0);
  }
  for (auto & other : others)
    other.get();
  for (VideoChoice & choice : choices)
  {
    if (!choice.stream.empty() &&
        (candidate.video.stream.empty() || choice.squaredError < candidate.video.squaredError))
      candidate.video = std::move(choice);
  }
  if (candidate.video.stream.empty())
    return;
  h.videoCodec = candidate.video.codec;
  // Kept when it decodes closer than every other candidate (ChooseLayers); the error the caller reports
  // is the best of both layers.
  if (tried)
    tried(candidate.Error());
}

/** Codes the residual layer over the corners. Done before the points, whose rate control stops as soon
 * as they cannot reach its error. `tried`, where given, is called after each trial with the best error
 * so far (the most the candidate's error will be). */
CornersCandidate
TryCorners(const EncoderInput & input, const FileHeader & header, std::size_t fileBytes, double minimum, double maximum,
           double peak, const std::vector<VideoCodec> & video, const std::function<void(double)> & tried = {},
           CoreFree * coreFree = nullptr)
{
  const PixelType  type = input.header.pixelType;
  const double     step = ResidualStep(peak, IsInteger(type));
  CornersCandidate candidate;
  if (!(step > 0.0) || !(maximum > minimum))
    return candidate; // a constant volume: the points are exact
  // Splits between the two layers measured worse than either alone (ct-avm-4mm at 0.0625 bpv: 39.44 dB
  // with all to the points, 38.83 and 38.34 with a half and a quarter), so the other candidate is all
  // to the residual, where per-slice transform coding wins (thick slices, higher rates).
  // The corners' value puts the input's minimum on the lowest sample JPEG 2000 holds at the precision
  // the range needs, so that its decoder clips the ringing below the background (air in a CT) away:
  // measured +0.38 dB on the 5 mm CT series at 0.03125 bpv over a value in the middle of the range.
  // The corners' step is that offset, so the value is on their lattice q0 + k q (q0 = the minimum).
  double offset = step;
  while (minimum + 2.0 * offset - step < maximum) // 2 offset - step: the range p bits hold
    offset *= 2.0;
  candidate.step = offset;
  candidate.header = header;
  candidate.header.constantSpline = true;
  candidate.header.scale = { { 1, 1, 1 } };
  candidate.header.quantizationOrigin = header.quantizationOrigin + candidate.step;
  candidate.spline = Corners(input.header.size, candidate.header.scale, candidate.header.quantizationOrigin);
  const std::size_t room = LayerRoom(candidate.header, step, fileBytes, 0);
  if (room < MinimumCodestream)
    return candidate;
  // The levels of the inter-slice wavelet by descent on the mosaic from 2 levels (one level more or
  // fewer at a time, as long as it decodes closer), then one component per slice at those levels.
  // Over the 40 dev runs (docs/rd/levels.md) every level count between 0 and 5 was the best somewhere
  // (norm-256 at 0.25 bpv: 57.35 dB with 1 level, 56.90 with 2; avg152t1 at 0.03125: 27.03 with 5, 26.72
  // with 4), each arrangement's error against the levels had one minimum, and components won on the 5 mm
  // CT series alone (slices 11 times as thick as wide), at the mosaic's best levels (53.49 dB against
  // 53.28 at 0.25 bpv), and lost on every near-isotropic volume (norm-256 at 0.25 bpv: 57.18). 9/7 beat
  // 5/3 on every run tried.
  candidate.search = std::make_unique<ResidualSearch>(input.voxels, type, candidate.spline, step, room);
  ResidualSearch & search = *candidate.search;
  const int32_t    most = InterSliceLevels(input.header.size.z);
  auto             trial = [&](const ResidualCoding & coding) {
    const double e = search.Try(coding);
    if (tried)
      tried(search.BestError());
    return e;
  };
  auto    mosaic = [&](int32_t levels) { return trial({ Wavelet::Irreversible97, Arrangement::Mosaic, levels }); };
  int32_t levels = std::min(2, most);
  double  error = mosaic(levels);
  // More levels first at low rates, where they won more often: a wrong first step costs a trial.
  const int32_t first =
    double(fileBytes) * 8.0 <= UpFirstBitsPerVoxel * double(input.header.size.NumberOfVoxels()) ? +1 : -1;
  for (const int32_t direction : { first, -first })
  {
    bool moved = false;
    for (int32_t next = levels + direction; next >= 0 && next <= most; next += direction)
    {
      const double e = mosaic(next);
      if (!(e < error))
        break;
      levels = next;
      error = e;
      moved = true;
    }
    if (moved)
      break; // the other side was worse than where the descent started
  }
  // Then fewer 2D wavelet levels, one at a time, as long as the layer decodes closer: the coarsest levels
  // of a mosaic mix its slices across their borders, and at low rates they cost more than they give.
  // A coarser coding that decodes closer but leaves the file short of the budget's promise (at least
  // MinimumFileBytes) where the finer one kept it is undone: its codestream grows in steps that no target
  // lands between (a 40^3 phantom at 500 bytes: 481 bytes and 17.68 dB against 492 and 17.54).
  const std::size_t spare = fileBytes - MinimumFileBytes(fileBytes);
  for (int32_t fewer = 1;; ++fewer)
  {
    ResidualSearch::State before = search.Save();
    const bool            kept = search.Unused() <= spare;
    const double          e = search.Try({ Wavelet::Irreversible97, Arrangement::Mosaic, levels, fewer });
    if (!(e < error))
      break;
    if (kept && search.Unused() > spare)
    {
      search.Restore(std::move(before));
      break;
    }
    error = e;
    if (tried)
      tried(search.BestError());
  }
  // Thick slices only: slices that differ much gain nothing from lying side by side in the mosaic, whose
  // 2D wavelet then codes the borders between them (a trial costs about a second at 256^3).
  const auto & spacing = input.header.spacing;
  if (input.header.size.z > 1 && spacing[2] >= ThickSlices * std::max(spacing[0], spacing[1]))
    trial({ Wavelet::Irreversible97, Arrangement::Components, levels });
  if (!video.empty())
  {
    const double layer = search.BestError();
    TryVideo(
      input,
      candidate,
      fileBytes,
      minimum,
      maximum,
      video,
      [&](double error) {
        if (tried)
          tried(std::min(layer, error));
      },
      coreFree);
  }
  return candidate;
}

/** Tries the residual layer in the bytes the spline's payload leaves (unless the points were abandoned),
 * fills the budget with the best candidate, and keeps in r and payload whichever of the points, the
 * points with a layer and the corners' layer decodes closest to the input. */
void
ChooseLayers(const EncoderInput & input, std::size_t fileBytes, bool pointsAbandoned, CornersCandidate && corners,
             EncoderResult & r, std::vector<uint8_t> & payload)
{
  const PixelType type = input.header.pixelType;
  const double    step = ResidualStep(r.peak, IsInteger(type));
  const double    q = r.quantizationStep;
  if (!(step > 0.0))
    return;
  // The points' spline, rasterized once: its error, and the spline under a layer in the bytes it leaves.
  std::unique_ptr<ResidualSearch> points;
  double                          bestError = std::numeric_limits<double>::infinity();
  if (!pointsAbandoned)
  {
    const std::size_t pointsRoom = LayerRoom(r.header, step, fileBytes, payload.size());
    points = std::make_unique<ResidualSearch>(input.voxels, type, r.approximation, step, pointsRoom);
    bestError = points->SplineError();
    // Nothing decodes closer than exactly (a constant volume, whose step and peak are 0 as well).
    if (!(bestError > 0.0))
      return;
    // Measured on the 5 mm CT series at 0.125 bpv, a residual in the 2% the points leave: +0.35 dB.
    if (pointsRoom >= MinimumCodestream)
      points->Try({ Wavelet::Irreversible97, Arrangement::Mosaic });
  }
  // OpenJPEG's codestream follows its target within a few bytes, in steps (the passes of its
  // code-blocks). The first that fits is kept; where it leaves more than 0.3% of the file, the best
  // candidate tries to fill it (2 more encodes and decodes at most).
  const std::size_t slack = std::max<std::size_t>(8, 3 * fileBytes / 1000);
  // Only the winner's layer is decoded again (Best()).
  auto keep = [&](ResidualSearch &        search,
                  Approximation &&        spline,
                  std::vector<uint8_t> && splinePayload,
                  double                  step,
                  const FileHeader &      h) {
    ResidualChoice c = std::move(search).Best();
    r.header.constantSpline = h.constantSpline;
    r.header.scale = h.scale;
    r.header.quantizationOrigin = h.quantizationOrigin;
    r.quantizationStep = step;
    r.squaredError = c.squaredError;
    r.header.residualStep = c.step;
    r.header.residualLevels = c.levels;
    r.header.residualLayer = std::move(c.codestream);
    r.approximation = std::move(spline);
    r.approximation.residual = { c.step, std::move(c.samples) };
    payload = std::move(splinePayload);
  };
  ResidualSearch * leader = corners.search && (!points || corners.search->BestError() < points->BestError())
                              ? corners.search.get()
                              : points.get();
  if (leader && leader->BestError() < bestError && leader->Unused() > slack)
    leader->Fill(slack, 2);
  // The points alone, the points with their layer, the corners' layer or the video layer: the first of the
  // closest.
  const double withLayer = points ? points->BestError() : std::numeric_limits<double>::infinity();
  const double cornersError = corners.search ? corners.search->BestError() : std::numeric_limits<double>::infinity();
  const double videoError =
    corners.video.stream.empty() ? std::numeric_limits<double>::infinity() : corners.video.squaredError;
  if (videoError < std::min({ bestError, withLayer, cornersError }))
  {
    VideoChoice & v = corners.video;
    r.header.constantSpline = true;
    r.header.videoLayer = true;
    r.header.videoCodec = v.codec;
    r.header.scale = { { 1, 1, 1 } };
    r.header.quantizationOrigin = corners.videoHeader.quantizationOrigin;
    r.header.residualStep = v.step;
    r.header.residualLevels = 0;
    r.quantizationStep = 1.0;
    r.squaredError = v.squaredError;
    r.approximation = Corners(input.header.size, r.header.scale, r.header.quantizationOrigin);
    r.approximation.residual = { v.step, DecodeVideoLayer(v.codec, v.stream, input.header.size, "video layer") };
    r.header.residualLayer = std::move(v.stream);
    payload.clear();
  }
  else if (cornersError < std::min(bestError, withLayer))
  {
    keep(*corners.search, std::move(corners.spline), {}, corners.step, corners.header);
  }
  else if (withLayer < bestError)
  {
    Approximation        spline = r.approximation;
    std::vector<uint8_t> splinePayload = payload;
    const FileHeader     h = r.header;
    keep(*points, std::move(spline), std::move(splinePayload), q, h);
  }
}

/** Approximate() and, with `coded`, the payload as rate control measured it (or coded once here). */
EncoderResult
Run(const EncoderInput & input, const EncoderOptions & o, bool coded, std::vector<uint8_t> & payload)
{
  const auto start = std::chrono::steady_clock::now();
  CheckOptions(o);
  const GridSize & grid = input.header.size;
  CheckGrid(grid);
  if (input.voxels == nullptr || (UsesSmoothedImage(o.mode) && input.smoothed == nullptr))
  {
    throw std::invalid_argument("the encoder needs the voxels, and I* in modes that use it");
  }
  // Everything that depends on the volume (the point count, the memory, finite voxels, ...), for callers of
  // dcv::Encode without itk::DCVEncode's earlier check: a pass or two over the voxels, against the seconds
  // of the encoding.
  CheckOptions(o, input);
  const uint64_t voxels = grid.NumberOfVoxels();
  const auto     range = ParallelMinMax(input.voxels, voxels);
  const bool     integer = IsInteger(input.header.pixelType);

  RefinementParameters parameters = ParametersForMode(o.mode);
  parameters.alpha = o.alpha;
  std::tie(parameters.valueMin, parameters.valueMax) = ValueRange(input.header.pixelType);
  parameters.peak = PSNRPeak(range.first, range.second, EightBit(input.header.pixelType));
  parameters.smoothed = UsesSmoothedImage(o.mode) ? input.smoothed : nullptr;
  parameters.quantizationOrigin = double(range.first);
  parameters.scale = o.scale == GridScale{ { 0, 0, 0 } } ? AutomaticScale(input.header.spacing) : o.scale;
  const double targetError =
    o.psnr > 0.0 ? double(voxels) * parameters.peak * parameters.peak / std::pow(10.0, o.psnr / 10.0) : 0.0;
  // The step: given; chosen by rate control (bit budget); bounded by the target (quality); or the
  // default step when the file is coded at a point count.
  const bool automaticStep = o.bitsPerVoxel > 0.0 && o.quantizationStep == 0.0;
  if (o.quantizationStep > 0.0)
    parameters.quantizationStep = o.quantizationStep;
  else if (o.psnr > 0.0)
    parameters.quantizationStep = QualityQuantizationStep(parameters.peak, integer, targetError, double(voxels));
  else if (o.bitsPerVoxel > 0.0 || coded)
    parameters.quantizationStep = DefaultQuantizationStep(parameters.peak, integer);

  EncoderResult r;
  r.header = input.header;
  r.header.mode = uint8_t(o.mode);
  r.header.metadata = o.metadata;
  r.header.quantizationOrigin = parameters.quantizationOrigin;
  r.header.scale = parameters.scale;
  r.quantizationStep = parameters.quantizationStep;
  MapLargeAllocations();
  // Owned here so that its state (the mesh, the heaps: about 1.5 KiB a point) is freed before the residual
  // layers, which need volume-sized buffers of their own.
  auto               owned = std::make_unique<RefinementEngine>(input.voxels, grid, parameters);
  RefinementEngine & engine = *owned;
  // The file is the payload plus a header that depends on the geometry and the metadata only.
  const double     fileBytes = std::floor(o.bitsPerVoxel * double(voxels) / 8.0);
  const double     headerBytes = double(SerializeFile(r.header, {}).size());
  const bool       layers = coded && o.bitsPerVoxel > 0.0 && o.residualLayer;
  CornersCandidate corners;
  bool             pointsAbandoned = false;
  // The corners' layer is coded on a thread of its own while the points' first refinement and schedule
  // run (mostly on one thread); rate control asks for it once it is done. Neither depends on the other,
  // so the file is the same as if they ran one after the other. Its thread keeps the process's priority:
  // at nice 19, giving way to the points' parallel parts (norm-256 at 0.03125 bpv 8% faster on an idle
  // machine), it starved beside other busy processes of the same login, and rate control waited for it:
  // the 5 mm CT series at 0.125 bpv 203 s instead of 8 s beside two busy loops (docs/profile.md).
  // The corners' best error so far, for rate control's check before the layer is done (declared before
  // the future, whose destructor waits for the thread that writes it).
  std::atomic<double>           cornersBound{ std::numeric_limits<double>::infinity() };
  CoreFree                      pointsDone; // opened when the points' thread stops or waits for the layer
  std::future<CornersCandidate> cornersLater;
  struct OpenAtEnd // before the future waits for the layer's thread, whatever ends this function
  {
    CoreFree & free;
    ~OpenAtEnd() { free.Open(); }
  } openAtEnd{ pointsDone };
  if (layers)
  {
    cornersLater = std::async(std::launch::async, [&, header = r.header, threads = CurrentThreads()] {
      return WithThreads(threads, [&] {
        const auto       start = std::chrono::steady_clock::now();
        CornersCandidate c = TryCorners(
          input,
          header,
          std::size_t(fileBytes),
          range.first,
          range.second,
          parameters.peak,
          o.videoLayer ? o.videoCodecs : std::vector<VideoCodec>(),
          [&](double error) { cornersBound.store(error); },
          &pointsDone);
        r.timings.residualLayer += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        return c;
      });
    });
  }
  auto cornersDone = [&]() -> const CornersCandidate & {
    if (cornersLater.valid())
    {
      const auto waitFrom = std::chrono::steady_clock::now();
      pointsDone.Open();
      corners = cornersLater.get();
      r.timings.residualLayerOnPath +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - waitFrom).count();
    }
    return corners;
  };
  if (o.bitsPerVoxel > 0.0)
  {
    try
    {
      BudgetResult b = ApproximateToBudget(
        engine,
        std::size_t(std::max(0.0, fileBytes - headerBytes)),
        parameters.quantizationOrigin,
        automaticStep ? RateControl::StepMultiples() : std::vector<double>{ 1.0 },
        o.progress,
        layers ? std::function<double()>([&] { return cornersDone().Error(); }) : std::function<double()>(),
        [&] {
          return !cornersLater.valid() || cornersLater.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
        },
        layers ? std::function<double()>([&] { return cornersBound.load(); }) : std::function<double()>());
      r.quantizationStep = b.step;
      r.adjustments = b.adjustments;
      payload = std::move(b.payload);
      pointsAbandoned = b.abandoned;
    }
    catch (const std::length_error & e)
    {
      throw std::length_error(Number(o.bitsPerVoxel) + " bits per voxel allow a .dcv file of " + Number(fileBytes) +
                              " bytes, " + Number(headerBytes) + " of them header: too few (" + e.what() + ")");
    }
  }
  else if (o.psnr > 0.0)
  {
    try
    {
      BudgetResult b = ApproximateToQuality(
        engine,
        targetError,
        parameters.quantizationOrigin,
        [&](const RefinementEngine & e) {
          return DecodedSquaredError(e.GetApproximation(), input.header.pixelType, input.voxels);
        },
        o.progress);
      r.adjustments = b.adjustments;
      payload = std::move(b.payload);
    }
    catch (const std::range_error & e)
    {
      throw std::range_error("a PSNR of " + Number(o.psnr) + " dB cannot be reached: " + e.what());
    }
  }
  else
  {
    engine.Approximate(o.numberOfPoints, o.progress);
  }
  // Abandoned points give way to the corners' layer: no copy of their mesh.
  if (!pointsAbandoned)
    r.approximation = engine.GetApproximation();
  if (coded && payload.empty() && !pointsAbandoned)
  {
    payload = EncodePayload(r.approximation, parameters.quantizationOrigin, r.quantizationStep, true);
  }
  r.squaredError = engine.GetSquaredError();
  r.smoothedPSNR = engine.GetSmoothedPSNR();
  r.peak = parameters.peak;
  r.timings.refinement = engine.GetTimings().refinement;
  r.timings.decimation = engine.GetTimings().decimation;
  r.timings.leastSquares = engine.GetTimings().leastSquares;
  owned.reset();
  if (input.releaseSmoothed && input.smoothed != input.voxels)
    input.releaseSmoothed();
  ReturnFreedMemory(); // the engine's cells and heaps, for the residual layers' buffers
  if (layers)
  {
    cornersDone();
    const auto start = std::chrono::steady_clock::now();
    ChooseLayers(input, std::size_t(fileBytes), pointsAbandoned, std::move(corners), r, payload);
    const double choosing = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    r.timings.residualLayer += choosing;
    r.timings.residualLayerOnPath += choosing;
  }
  r.header.quantizationStep = r.quantizationStep > 0.0 ? r.quantizationStep : 1.0;
  r.header.numberOfPoints = uint32_t(r.approximation.points.size());
  r.timings.total = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}
} // namespace

namespace
{
EncoderResult
EncodeFile(const EncoderInput & input, const EncoderOptions & options)
{
  const auto           start = std::chrono::steady_clock::now();
  std::vector<uint8_t> payload;
  EncoderResult        r = Run(input, options, true, payload);
  r.bytes = SerializeFile(r.header, payload);
  const uint64_t voxels = r.header.size.NumberOfVoxels();
  if (options.bitsPerVoxel > 0.0 && double(r.bytes.size()) > std::floor(options.bitsPerVoxel * double(voxels) / 8.0))
  {
    throw std::logic_error("internal error: " + std::to_string(r.bytes.size()) + " bytes exceed the bit budget");
  }
  r.psnr = PSNR(DecodedSquaredError(r.approximation, r.header.pixelType, input.voxels), voxels, r.peak);
  r.timings.total = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}
} // namespace

EncoderResult
Approximate(const EncoderInput & input, const EncoderOptions & options)
{
  if (options.maximumError >= 0.0)
    throw std::invalid_argument("MaximumError (--max-error) makes a file without points: encode it, there is "
                                "nothing to approximate");
  return WithThreads(options.threads, [&] {
    std::vector<uint8_t> payload;
    return Run(input, options, false, payload);
  });
}

EncoderResult
Encode(const EncoderInput & input, const EncoderOptions & options)
{
  if (options.maximumError >= 0.0)
    return WithThreads(options.threads, [&] { return EncodeBounded(input, options); });
  return WithThreads(options.threads, [&] { return EncodeFile(input, options); });
}

} // namespace dcv
