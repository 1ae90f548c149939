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
// The encoder's bounded-error mode (EncoderOptions::maximumError): the voxels quantized to a lattice of
// step h (2E + 1 on integers, just under 2E on floats) around a constant spline, the lattice indices coded
// without loss by the bounded-error layer. Every voxel is checked against the bound with the decoder's
// own arithmetic before the file is made.
#include "dcvBoundedEncoder.h"
#include "dcvBoundedLayer.h"
#include "dcvCodec.h"
#include "dcvParallel.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace dcv
{
namespace
{
std::string
Text(double v)
{
  char text[32];
  std::snprintf(text, sizeof(text), "%.9g", v);
  return text;
}

/** How a bound is kept: samples x' = q0 + h r with r integers, the layer's own bound `near` in steps of h. */
struct Lattice
{
  double   origin{ 0.0 }; // q0: the constant spline, a value of the pixel type
  double   step{ 1.0 };   // h
  double   bound{ 0.0 };  // what the file states: the bound it keeps
  uint32_t near{ 0 };
  bool     integer{ true };
};

template <typename T>
double
Spacing(double v)
{
  // The distance to the next representable value of T above |v|: what rounding into T may add.
  const T a = T(std::abs(v));
  return double(std::nextafter(a, std::numeric_limits<T>::infinity())) - double(a);
}

/** The spacing of the pixel type's values near the largest magnitude of the range: what rounding into the
 * type may add, twice over. */
double
SpacingNear(PixelType type, double minimum, double maximum)
{
  const double largest = std::max(std::abs(minimum), std::abs(maximum));
  return type == PixelType::Float32 ? Spacing<float>(largest) : Spacing<double>(largest);
}
} // namespace

double
SmallestMaximumError(PixelType type, double minimum, double maximum)
{
  if (IsInteger(type))
    return 0.0;
  // The lattice step (2E - spacing) / 9 must be positive and (max - min) / step fit the 32-bit indices.
  return std::max(
    { SpacingNear(type, minimum, maximum), 9.0 * (maximum - minimum) / 4.0e9, std::numeric_limits<double>::min() });
}

EncoderResult
EncodeBounded(const EncoderInput & input, const EncoderOptions & options)
{
  const auto     start = std::chrono::steady_clock::now();
  const GridSize grid = input.header.size;
  const uint64_t voxels = grid.NumberOfVoxels();
  const double * x = input.exact;
  if (x == nullptr)
    throw std::invalid_argument("MaximumError (--max-error) needs the voxels at full precision (EncoderInput::exact)");
  auto progress = [&](double f) {
    if (options.progress)
      options.progress(f);
  };
  progress(0.0);
  const std::size_t nonFinite = ParallelCount(x, voxels, [](double v) { return !std::isfinite(v); });
  if (nonFinite > 0)
    throw std::invalid_argument("the volume holds " + std::to_string(nonFinite) +
                                " non-finite voxels (NaN or infinite); dcv codes finite values only");
  const auto      range = ParallelMinMax(x, voxels);
  const double    minimum = range.first, maximum = range.second;
  const PixelType type = input.header.pixelType;

  Lattice lattice;
  lattice.integer = IsInteger(type);
  const double requested = options.maximumError;
  if (lattice.integer)
  {
    // |x - x'| is a whole number: a bound of 2.5 keeps 2. The samples are the voxels themselves (step 1),
    // the layer quantizes each prediction's residual to steps of 2E + 1.
    lattice.bound = std::floor(std::min(requested, 1.0e9));
    lattice.near = uint32_t(lattice.bound);
    lattice.step = 1.0;
    // The samples fit int32: uint32 voxels beyond it are taken from the middle of their range.
    lattice.origin = maximum > double(std::numeric_limits<int32_t>::max()) ? minimum + 2147483648.0 : 0.0;
  }
  else
  {
    const double smallest = SmallestMaximumError(type, minimum, maximum);
    if (requested < smallest)
      throw std::invalid_argument("MaximumError (--max-error) must be at least " + Text(smallest) + " for " +
                                  PixelTypeName(type) + " values from " + Text(minimum) + " to " + Text(maximum) +
                                  " (the precision of the pixel type and 2^32 steps), got " + Text(requested));
    lattice.bound = requested;
    // A lattice of 9 steps to 2E, 4 of them the layer's own bound: 4.5 steps within E, and a flat region
    // off by at most half a step (a lattice of 2E alone shifted such regions by up to E). Rounding each
    // decoded value into the pixel type may add half its spacing near the largest value.
    lattice.near = 4;
    lattice.step = (2.0 * requested - SpacingNear(type, minimum, maximum)) / 9.0;
    const double top = std::floor((maximum - minimum) / lattice.step + 0.5);
    // The indices fit int32: moved down when their count needs it (the largest then 2^31 - 1).
    const double offset = std::max(0.0, top - double(std::numeric_limits<int32_t>::max()));
    // A value of the pixel type, as the decoder's constant spline is.
    lattice.origin =
      type == PixelType::Float32 ? double(float(minimum + offset * lattice.step)) : minimum + offset * lattice.step;
  }

  ResidualSamples samples(voxels);
  for (uint64_t i = 0; i < voxels; ++i) // the lattice indices (integers: the voxels)
  {
    const double k = lattice.integer ? x[i] - lattice.origin : std::floor((x[i] - lattice.origin) / lattice.step + 0.5);
    samples[i] = int32_t(std::clamp(k, -2147483648.0, 2147483647.0));
  }
  progress(0.1);
  std::vector<uint8_t> layer =
    EncodeBoundedLayer(samples.data(), grid, lattice.near, lattice.bound, [&](double f) { progress(0.1 + 0.8 * f); });

  // Every voxel as the decoder gives it (the layer left the decoded samples), checked against the bound.
  double squaredError = 0.0;
  double worst = 0.0;
  VisitPixelType(type, [&](auto pixel) {
    using T = decltype(pixel);
    const T             spline = ConvertValue<T>(lattice.origin); // the constant spline as the decoder has it
    const std::size_t   blocks = PassBlocks(voxels);
    std::vector<double> blockError(blocks, 0.0), blockWorst(blocks, 0.0);
    ParallelFor(blocks, 1, [&](std::size_t b) {
      const std::size_t lo = b * PassBlock, hi = std::min<std::size_t>(voxels, lo + PassBlock);
      double            error = 0.0, w = 0.0;
      for (std::size_t i = lo; i < hi; ++i)
      {
        const double d = double(AddResidual<T>(spline, lattice.step, samples[i])) - x[i];
        error += d * d;
        w = std::max(w, std::abs(d));
      }
      blockError[b] = error;
      blockWorst[b] = w;
    });
    for (std::size_t b = 0; b < blocks; ++b)
    {
      squaredError += blockError[b];
      worst = std::max(worst, blockWorst[b]);
    }
  });
  if (!(worst <= lattice.bound))
    throw std::logic_error("internal error: a voxel would decode " + Text(worst) +
                           " from the input, beyond the bound " + Text(lattice.bound));

  EncoderResult r;
  r.header = input.header;
  r.header.mode = FileHeader::BoundedMode;
  r.header.scale = { { 1, 1, 1 } };
  r.header.constantSpline = true;
  r.header.numberOfPoints = 8; // the corners, as a reader gets them
  r.header.boundedLayer = true;
  r.header.quantizationOrigin = lattice.origin;
  r.header.residualStep = lattice.step;
  r.header.metadata = options.metadata;
  r.header.residualLayer = std::move(layer);
  r.bytes = SerializeFile(r.header, {});
  r.approximation = ConstantSpline(grid, r.header.scale, lattice.origin);
  r.approximation.residual = { lattice.step, std::move(samples) };
  r.quantizationStep = 1.0;
  r.squaredError = squaredError;
  r.peak = PSNRPeak(minimum, maximum, type == PixelType::UInt8 || type == PixelType::Int8);
  r.psnr = PSNR(squaredError, voxels, r.peak);
  r.maximumError = lattice.bound;
  r.timings.residualLayer = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.timings.residualLayerOnPath = r.timings.residualLayer;
  r.timings.total = r.timings.residualLayer;
  progress(1.0);
  return r;
}

} // namespace dcv
