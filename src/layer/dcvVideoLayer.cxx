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
#include "dcvVideoLayer.h"
#include "dcvVideoCodecs.h"

#include "../core/dcvParallel.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace dcv
{

namespace
{
/** The quality (x265's rate factor, libaom's level) for a stream of `target` bytes, from the sizes of the
 * streams tried so far: the secant of log size against the quality through the last two (the first step at
 * `slope`), within the bracket of the smallest quality whose stream fitted and the largest whose did not,
 * on the codec's lattice (`per` qualities a unit: 100 for x265's factor, 1 for libaom's levels). */
class RateFactorSearch
{
public:
  RateFactorSearch(double target, double coarsest, double per, double slope)
    : logTarget(std::log2(target))
    , coarsest(coarsest)
    , per(per)
    , fitCrf(coarsest + 1.0)
    , slope(slope)
  {}
  double
  Slope() const
  {
    return slope;
  }
  /** Records a trial; returns the next factor, or a negative number when the bracket is closed. */
  double
  Next(double crf, std::size_t bytes, bool fits)
  {
    const double bits = std::log2(double(std::max<std::size_t>(bytes, 1)));
    if (fits)
      fitCrf = std::min(fitCrf, crf);
    else
      overCrf = std::max(overCrf, crf);
    // Within half a step the size moves by noise as much as by the factor (ct-avm-4mm: 18,446 bytes at
    // 26.08, 18,344 at 26.28, 18,787 at 25.87): the slope is kept from farther trials.
    if (tried && std::abs(crf - lastCrf) >= 0.5 && lastBits != bits)
      slope = std::clamp((lastBits - bits) / (crf - lastCrf), 1.0 / 30.0, 1.0);
    tried = true;
    lastCrf = crf;
    lastBits = bits;
    const double lo = overCrf >= 0.0 ? overCrf : 0.0, hi = fitCrf <= coarsest ? fitCrf : coarsest;
    if (hi - lo < 2.0 / per - 1e-9)
      return -1.0;
    const double margin = overCrf >= 0.0 && fitCrf <= coarsest ? 0.1 * (hi - lo) : 0.0;
    double       next = std::round(std::clamp(crf + (bits - logTarget) / slope, lo + margin, hi - margin) * per) / per;
    // On a coarse lattice the rounding may land on a bound, already tried.
    if (overCrf >= 0.0)
      next = std::max(next, overCrf + 1.0 / per);
    if (fitCrf <= coarsest)
      next = std::min(next, fitCrf - 1.0 / per);
    return next;
  }

private:
  double logTarget;
  double coarsest, per;
  double fitCrf;          // the smallest factor whose stream fits
  double overCrf{ -1.0 }; // the largest whose stream does not
  double lastCrf{ 0.0 }, lastBits{ 0.0 };
  double slope; // of log2 size per step of the factor
  bool   tried{ false };
};

/** What the search needs of a codec: its lattice of qualities, where to start, and how fast the size falls. */
struct Lattice
{
  double coarsest, per, start, slope;
};
Lattice
LatticeOf(VideoCodec codec)
{
  // x265: 6 rate factor steps a halving of the size on the dev volumes; libaom: 6 to 11 levels a halving
  // (norm-256: 486 KB at level 3, 252 KB at 9, 123 KB at 20, 64 KB at 31).
  return codec == VideoCodec::AV1 ? Lattice{ 63.0, 1.0, 32.0, 1.0 / 9.0 } : Lattice{ 51.0, 100.0, 30.0, 1.0 / 6.0 };
}
} // namespace

const char *
VideoCodecName(VideoCodec codec)
{
  return codec == VideoCodec::AV1 ? "AV1" : "HEVC";
}

std::vector<VideoCodec>
ParseVideoCodecs(const std::string & name)
{
  if (name == "both")
    return { VideoCodec::HEVC, VideoCodec::AV1 };
  if (name == "hevc")
    return { VideoCodec::HEVC };
  if (name == "av1")
    return { VideoCodec::AV1 };
  throw std::invalid_argument("unknown video codec '" + name + "' (both, hevc or av1)");
}

double
VideoCoarsest(VideoCodec codec)
{
  return LatticeOf(codec).coarsest;
}

int32_t
VideoDepth(double largest)
{
  for (int32_t depth : { 8, 10, 12 })
    if (largest <= double((1 << depth) - 1))
      return depth;
  return 0;
}

double
VideoStep(double range, bool integer)
{
  const double most = double((1 << VideoMaximumDepth) - 1);
  if (!integer) // the 12 bits over the range, whatever it is
    return range > 0.0 ? range / most : 1.0;
  return range > most ? std::ceil(range / most) : 1.0;
}

namespace
{
std::vector<uint8_t>
Encode(VideoCodec codec, const std::vector<uint16_t> & samples, const GridSize & grid, int32_t depth, double quality,
       bool search)
{
  if (depth != 8 && depth != 10 && depth != 12)
    throw std::invalid_argument("EncodeVideoLayer: the depth must be 8, 10 or 12");
  if (samples.size() != grid.NumberOfVoxels())
    throw std::invalid_argument("EncodeVideoLayer: one sample a voxel");
  return codec == VideoCodec::AV1 ? EncodeAV1(samples, grid, depth, quality, search)
                                  : EncodeHEVC(samples, grid, depth, quality, search);
}
} // namespace

std::vector<uint8_t>
EncodeVideoLayer(VideoCodec codec, const std::vector<uint16_t> & samples, const GridSize & grid, int32_t depth,
                 double quality)
{
  return Encode(codec, samples, grid, depth, quality, false);
}

void
SendSliceRows(const uint8_t * plane, std::ptrdiff_t stride, bool wide, const GridSize & grid, int32_t z,
              std::vector<int32_t> & row, const std::function<void(int32_t y, int32_t z, const int32_t * row)> & sink)
{
  row.resize(std::size_t(grid.x));
  for (int32_t y = 0; y < grid.y; ++y)
  {
    const uint8_t * in = plane + std::ptrdiff_t(y) * stride;
    if (wide)
      for (int32_t x = 0; x < grid.x; ++x)
        row[std::size_t(x)] = reinterpret_cast<const uint16_t *>(in)[x];
    else
      for (int32_t x = 0; x < grid.x; ++x)
        row[std::size_t(x)] = in[x];
    sink(y, z, row.data());
  }
}

ResidualSamples
DecodeVideoLayer(VideoCodec codec, const std::vector<uint8_t> & stream, const GridSize & grid, const std::string & name)
{
  ResidualSamples samples(grid.NumberOfVoxels());
  DecodeVideoRows(codec, stream, grid, name, [&](int32_t y, int32_t z, const int32_t * row) {
    std::copy_n(row, grid.x, samples.data() + grid.Offset(0, y, z));
  });
  return samples;
}

void
DecodeVideoRows(VideoCodec codec, const std::vector<uint8_t> & stream, const GridSize & grid, const std::string & name,
                const std::function<void(int32_t y, int32_t z, const int32_t * row)> & sink)
{
  if (codec == VideoCodec::AV1)
    DecodeAV1Rows(stream, grid, name, sink);
  else
    DecodeHEVCRows(stream, grid, name, sink);
}

VideoChoice
ChooseVideoLayer(VideoCodec codec, const float * voxels, PixelType type, const GridSize & grid, double origin,
                 double step, std::size_t maximumBytes, const std::function<void(double)> & tried)
{
  VideoChoice best;
  best.codec = codec;
  best.step = step;
  best.squaredError = std::numeric_limits<double>::infinity();
  if (!(step > 0.0))
    return best;
  const uint64_t        n = grid.NumberOfVoxels();
  std::vector<uint16_t> samples(n);
  double                largest = 0.0;
  for (uint64_t i = 0; i < n; ++i)
  {
    const double s = std::max(0.0, std::round((double(voxels[i]) - origin) / step));
    largest = std::max(largest, s);
  }
  const int32_t depth = VideoDepth(largest);
  if (depth == 0)
    return best;
  const double top = double((1 << depth) - 1);
  ParallelFor(std::size_t(grid.z), 1, [&](std::size_t z) {
    const uint64_t plane = uint64_t(grid.x) * uint64_t(grid.y);
    for (uint64_t i = z * plane, end = i + plane; i < end; ++i)
      samples[i] = uint16_t(std::clamp(std::round((double(voxels[i]) - origin) / step), 0.0, top));
  });
  // The squared error of the volume a stream decodes to, slice by slice in slice order (the same sum
  // whatever the threads).
  auto measure = [&](const std::vector<uint8_t> & stream) {
    const ResidualSamples decoded = DecodeVideoLayer(codec, stream, grid, "video layer");
    std::vector<double>   partial(std::size_t(grid.z), 0.0);
    VisitPixelType(type, [&](auto pixel) {
      using T = decltype(pixel);
      const T        base = ConvertValue<T>(origin);
      const uint64_t plane = uint64_t(grid.x) * uint64_t(grid.y);
      ParallelFor(std::size_t(grid.z), 1, [&](std::size_t z) {
        double s = 0.0;
        for (uint64_t i = z * plane, end = i + plane; i < end; ++i)
        {
          const double e = double(voxels[i]) - double(AddResidual(base, step, decoded[i]));
          s += e * e;
        }
        partial[z] = s;
      });
    });
    double sum = 0.0;
    for (double s : partial)
      sum += s;
    return sum;
  };
  // First the factor that fills the budget at the search preset, from sizes alone (no stream decoded);
  // then the kept preset from there (its stream is 5% smaller or 15% larger at the same factor), each
  // fitting stream decoded, until one fills 97% of the budget (the promise of dcv::MinimumFileBytes).
  const double     target = double(maximumBytes) * 0.985;
  const Lattice    lattice = LatticeOf(codec);
  RateFactorSearch search(target, lattice.coarsest, lattice.per, lattice.slope);
  double           crf = lattice.start;
  bool             lossless = false;
  for (int encode = 0; encode < 5; ++encode)
  {
    const std::size_t bytes = Encode(codec, samples, grid, depth, crf, true).size();
    ++best.encodes;
    const bool fits = bytes <= maximumBytes;
    if ((fits && double(bytes) >= 0.95 * target) || (!fits && crf >= lattice.coarsest))
      break;
    if (fits && crf <= 0.0)
    {
      lossless = true; // the finest factor leaves room: the stream that decodes exactly, if it fits
      break;
    }
    const double next = search.Next(crf, bytes, fits);
    if (next < 0.0)
      break;
    crf = next;
  }
  RateFactorSearch kept(target, lattice.coarsest, lattice.per, search.Slope());
  for (int encode = 0; encode < 5; ++encode)
  {
    std::vector<uint8_t> stream = EncodeVideoLayer(codec, samples, grid, depth, lossless ? VideoLossless : crf);
    ++best.encodes;
    const std::size_t bytes = stream.size();
    const bool        fits = bytes <= maximumBytes;
    if (fits)
    {
      const double error = measure(stream);
      if (error < best.squaredError)
      {
        best.squaredError = error;
        best.stream = std::move(stream);
        best.quality = lossless ? VideoLossless : crf;
      }
      if (tried)
        tried(best.squaredError);
    }
    if (lossless)
    {
      if (fits)
        break;
      lossless = false; // crf stays 0
      continue;
    }
    if ((fits && double(bytes) >= 0.97 * double(maximumBytes)) || (!fits && crf >= lattice.coarsest))
      break;
    const double next = kept.Next(crf, bytes, fits);
    if (next < 0.0)
      break;
    crf = next;
  }
  return best;
}

std::string
VideoLibraryVersions()
{
  return HEVCLibraryVersions() + ", " + AV1LibraryVersions();
}

} // namespace dcv
