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

/** The lattice of a bound: origin q0 (the constant spline, exact in the pixel type), step h, and the index
 * offset that keeps the indices within 32 bits. */
struct Lattice
{
  double  origin{ 0.0 };
  double  step{ 1.0 };
  double  bound{ 0.0 }; // what the file states: the bound the lattice keeps
  int64_t offset{ 0 };  // index of voxel v: floor((v - minimum) / h + rounding) - offset
  bool    integer{ true };
};

template <typename T>
double
Spacing(double v)
{
  // The distance to the next representable value of T above |v|: what rounding into T may add.
  const T a = T(std::abs(v));
  return double(std::nextafter(a, std::numeric_limits<T>::infinity())) - double(a);
}
} // namespace

double
SmallestMaximumError(PixelType type, double minimum, double maximum)
{
  if (IsInteger(type))
    return 0.0;
  const double largest = std::max(std::abs(minimum), std::abs(maximum));
  double       spacing = 0.0;
  if (type == PixelType::Float32)
    spacing = Spacing<float>(largest);
  else
    spacing = Spacing<double>(largest);
  // h = 2E - spacing must be positive, and (max - min) / h must fit the 32-bit indices.
  return std::max({ spacing, (maximum - minimum) / 4.0e9, std::numeric_limits<double>::min() });
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
    // |x - x'| is a whole number: a bound of 2.5 keeps 2. Indices of step 2E + 1, each voxel decoded to
    // the middle of its step's interval.
    const double e = std::floor(std::min(requested, 4.0e9));
    lattice.bound = e;
    lattice.step = 2.0 * e + 1.0;
    lattice.origin = minimum + e;
  }
  else
  {
    const double smallest = SmallestMaximumError(type, minimum, maximum);
    if (requested < smallest)
      throw std::invalid_argument("MaximumError (--max-error) must be at least " + Text(smallest) + " for " +
                                  PixelTypeName(type) + " values from " + Text(minimum) + " to " + Text(maximum) +
                                  " (the precision of the pixel type and 2^32 steps), got " + Text(requested));
    lattice.bound = requested;
    // Rounding each decoded value into the pixel type may add half its spacing near the largest value.
    lattice.step = 2.0 * requested - SmallestMaximumError(type, minimum, maximum);
  }
  const double  steps = std::floor((maximum - minimum) / lattice.step + (lattice.integer ? 0.0 : 0.5));
  const int64_t top = int64_t(steps);
  // The indices fit int32: moved down when their count needs it (the largest then 2^31 - 1).
  lattice.offset = std::max<int64_t>(0, top - std::numeric_limits<int32_t>::max());
  if (lattice.integer)
    lattice.origin = minimum + lattice.bound + double(lattice.offset) * lattice.step; // a whole number
  else // a value of the pixel type, as the decoder's constant spline is
    lattice.origin = type == PixelType::Float32 ? double(float(minimum + double(lattice.offset) * lattice.step))
                                                : minimum + double(lattice.offset) * lattice.step;

  ResidualSamples samples(voxels);
  double          squaredError = 0.0;
  double          worst = 0.0;
  VisitPixelType(type, [&](auto pixel) {
    using T = decltype(pixel);
    const T spline = ConvertValue<T>(lattice.origin); // the constant spline as the decoder rasterizes it
    // Per block: indices, then each voxel decoded as the decoder will (AddResidual) and checked.
    const std::size_t   blocks = PassBlocks(voxels);
    std::vector<double> blockError(blocks, 0.0), blockWorst(blocks, 0.0);
    ParallelFor(blocks, 1, [&](std::size_t b) {
      const std::size_t lo = b * PassBlock, hi = std::min<std::size_t>(voxels, lo + PassBlock);
      double            error = 0.0, w = 0.0;
      for (std::size_t i = lo; i < hi; ++i)
      {
        const double k = lattice.integer ? std::floor((x[i] - minimum) / lattice.step) - double(lattice.offset)
                                         : std::floor((x[i] - lattice.origin) / lattice.step + 0.5);
        samples[i] = int32_t(std::clamp(k, -2147483648.0, 2147483647.0));
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
  progress(0.2);

  EncoderResult r;
  r.header = input.header;
  r.header.mode = FileHeader::BoundedMode;
  r.header.scale = { { 1, 1, 1 } };
  r.header.constantSpline = true;
  r.header.boundedLayer = true;
  r.header.quantizationOrigin = lattice.origin;
  r.header.residualStep = lattice.step;
  r.header.metadata = options.metadata;
  r.header.residualLayer = EncodeBoundedLayer(samples.data(), grid, lattice.bound);
  progress(0.95);
  r.bytes = SerializeFile(r.header, {});
  r.approximation = ConstantSpline(grid, r.header.scale, lattice.origin);
  r.approximation.residual = { lattice.step, std::move(samples) };
  r.quantizationStep = 1.0;
  r.squaredError = squaredError;
  r.peak = PSNRPeak(minimum, maximum, type == PixelType::UInt8 || type == PixelType::Int8);
  r.psnr = PSNR(squaredError, voxels, r.peak);
  r.maximumError = lattice.bound;
  r.timings.residualLayer = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.timings.total = r.timings.residualLayer;
  progress(1.0);
  return r;
}

} // namespace dcv
