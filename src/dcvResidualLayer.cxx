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
#include "dcvResidualLayer.h"
#include "dcvFileFormat.h"
#include "dcvInterSliceWavelet.h"
#include "dcvParallel.h"

// The path names the system OpenJPEG 2.5: ITK ships an older, mangled openjpeg.h on its include path.
#include <openjpeg-2.5/openjpeg.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>
#include <thread>

namespace dcv
{
namespace
{
/** A codestream in memory, read or written by OpenJPEG through its stream callbacks. */
struct Buffer
{
  std::vector<uint8_t> bytes;
  std::size_t          position{ 0 };
};

OPJ_SIZE_T
Read(void * out, OPJ_SIZE_T n, void * user)
{
  auto &            b = *static_cast<Buffer *>(user);
  const std::size_t count = std::min<std::size_t>(n, b.bytes.size() - b.position);
  if (count == 0)
    return OPJ_SIZE_T(-1); // end of stream, as OpenJPEG's file stream says it
  std::memcpy(out, b.bytes.data() + b.position, count);
  b.position += count;
  return count;
}

OPJ_SIZE_T
Write(void * in, OPJ_SIZE_T n, void * user)
{
  auto & b = *static_cast<Buffer *>(user);
  if (b.position + n > b.bytes.size())
    b.bytes.resize(b.position + n);
  std::memcpy(b.bytes.data() + b.position, in, n);
  b.position += n;
  return n;
}

OPJ_OFF_T
Skip(OPJ_OFF_T n, void * user)
{
  auto &        b = *static_cast<Buffer *>(user);
  const int64_t target = std::clamp<int64_t>(int64_t(b.position) + n, 0, int64_t(b.bytes.size()));
  const int64_t moved = target - int64_t(b.position);
  b.position = std::size_t(target);
  return moved;
}

OPJ_BOOL
Seek(OPJ_OFF_T n, void * user)
{
  auto & b = *static_cast<Buffer *>(user);
  if (n < 0 || uint64_t(n) > b.bytes.size())
    return OPJ_FALSE;
  b.position = std::size_t(n);
  return OPJ_TRUE;
}

struct StreamDeleter
{
  void
  operator()(opj_stream_t * s) const
  {
    opj_stream_destroy(s);
  }
};
struct CodecDeleter
{
  void
  operator()(opj_codec_t * c) const
  {
    opj_destroy_codec(c);
  }
};
struct ImageDeleter
{
  void
  operator()(opj_image_t * i) const
  {
    opj_image_destroy(i);
  }
};
using Stream = std::unique_ptr<opj_stream_t, StreamDeleter>;
using Codec = std::unique_ptr<opj_codec_t, CodecDeleter>;
using Image = std::unique_ptr<opj_image_t, ImageDeleter>;

Stream
MakeStream(Buffer & buffer, bool input)
{
  Stream s(opj_stream_create(OPJ_J2K_STREAM_CHUNK_SIZE, input ? OPJ_TRUE : OPJ_FALSE));
  if (!s)
    throw std::bad_alloc();
  opj_stream_set_user_data(s.get(), &buffer, nullptr);
  if (input)
  {
    opj_stream_set_user_data_length(s.get(), buffer.bytes.size());
    opj_stream_set_read_function(s.get(), Read);
  }
  else
  {
    opj_stream_set_write_function(s.get(), Write);
  }
  opj_stream_set_skip_function(s.get(), Skip);
  opj_stream_set_seek_function(s.get(), Seek);
  return s;
}

/** OpenJPEG's messages: errors are kept for the exception, the rest is dropped. */
void
KeepError(const char * message, void * user)
{
  auto & s = *static_cast<std::string *>(user);
  if (s.empty())
  {
    s = message;
    while (!s.empty() && (s.back() == '\n' || s.back() == ' '))
      s.pop_back();
  }
}
void
Drop(const char *, void *)
{}

void
Quiet(opj_codec_t * codec, std::string & error)
{
  opj_set_error_handler(codec, KeepError, &error);
  opj_set_warning_handler(codec, Drop, nullptr);
  opj_set_info_handler(codec, Drop, nullptr);
}

int
Threads()
{
  return int(CurrentThreads()); // the encoder's --threads; the codestream does not depend on it
}

/** Removes the comment (COM) segments of a codestream's main header: bytes for nothing in a budget. */
void
StripComments(std::vector<uint8_t> & codestream)
{
  std::size_t p = 2;                                                                       // after SOC
  while (p + 4 <= codestream.size() && codestream[p] == 0xff && codestream[p + 1] != 0x90) // up to the first SOT
  {
    const std::size_t length = (std::size_t(codestream[p + 2]) << 8) | codestream[p + 3];
    if (length < 2 || p + 2 + length > codestream.size())
      return;
    if (codestream[p + 1] == 0x64)
      codestream.erase(codestream.begin() + std::ptrdiff_t(p), codestream.begin() + std::ptrdiff_t(p + 2 + length));
    else
      p += 2 + length;
  }
}

/** One encode at a target size of `components` planes of width x height samples, one after the other in
 * `planes`; the codestream (empty when OpenJPEG fails). A fresh image each time: OpenJPEG's encoder may
 * take over the image's sample buffers. */
std::vector<uint8_t>
EncodeOnce(const std::vector<int32_t> & planes, int components, int64_t width, int64_t height, int precision,
           int resolutions, double ratio, Wavelet wavelet)
{
  opj_image_cmptparm_t component{};
  component.dx = component.dy = 1;
  component.w = OPJ_UINT32(width);
  component.h = OPJ_UINT32(height);
  component.prec = OPJ_UINT32(precision);
  component.sgnd = 1;
  std::vector<opj_image_cmptparm_t> parameters(std::size_t(components), component);
  Image image(opj_image_create(OPJ_UINT32(components), parameters.data(), OPJ_CLRSPC_UNKNOWN));
  if (!image)
    throw std::bad_alloc();
  image->x0 = image->y0 = 0;
  image->x1 = OPJ_UINT32(width);
  image->y1 = OPJ_UINT32(height);
  const std::size_t plane = std::size_t(width * height);
  for (int c = 0; c < components; ++c)
    std::copy_n(planes.data() + std::size_t(c) * plane, plane, image->comps[c].data);

  opj_cparameters_t p;
  opj_set_default_encoder_parameters(&p);
  p.tcp_numlayers = 1;
  p.tcp_rates[0] = float(ratio);
  p.cp_disto_alloc = 1;
  p.irreversible = wavelet == Wavelet::Irreversible97 ? 1 : 0;
  p.numresolution = resolutions;
  p.tcp_mct = 0; // slices are not colour channels
  // OpenJPEG writes "Created by OpenJPEG version ..." (39 bytes) without a comment of its own; an empty
  // one is 6 bytes, and StripComments removes those.
  char noComment[] = "";
  p.cp_comment = noComment;
  Codec       codec(opj_create_compress(OPJ_CODEC_J2K));
  std::string error;
  Quiet(codec.get(), error);
  Buffer buffer;
  Stream stream = MakeStream(buffer, false);
  // Code-blocks are coded independently and the rate allocation follows, so the codestream does not
  // depend on the number of threads.
  if (!opj_setup_encoder(codec.get(), &p, image.get()) || !opj_codec_set_threads(codec.get(), Threads()) ||
      !opj_start_compress(codec.get(), image.get(), stream.get()) || !opj_encode(codec.get(), stream.get()) ||
      !opj_end_compress(codec.get(), stream.get()))
  {
    return {};
  }
  StripComments(buffer.bytes);
  return std::move(buffer.bytes);
}
} // namespace

int32_t
MosaicColumns(const GridSize & grid)
{
  int32_t best = 1;
  double  bestShape = 0.0;
  int64_t bestEmpty = 0;
  for (int32_t cols = 1; cols <= grid.z; ++cols)
  {
    const int64_t rows = (grid.z + cols - 1) / cols;
    const double  w = double(cols) * grid.x, h = double(rows) * grid.y;
    const double  shape = std::max(w, h) / std::min(w, h);
    const int64_t empty = rows * cols - grid.z;
    if (cols == 1 || shape < bestShape || (shape == bestShape && empty < bestEmpty))
    {
      best = cols;
      bestShape = shape;
      bestEmpty = empty;
    }
  }
  return best;
}

std::vector<uint8_t>
EncodeResidualLayer(const std::vector<int32_t> & input, const GridSize & grid, std::size_t maximumBytes,
                    Wavelet wavelet, Arrangement arrangement, int32_t levels)
{
  if (input.size() != grid.NumberOfVoxels())
    throw std::invalid_argument("EncodeResidualLayer: one sample per voxel");
  for (int32_t s : input)
  {
    if (s <= -32768 || s >= 32768)
      throw std::invalid_argument("EncodeResidualLayer: samples must be within +-32767");
  }
  std::vector<int32_t> transformed;
  if (levels > 0)
  {
    transformed = input;
    ForwardInterSlice(transformed, grid, levels);
  }
  const std::vector<int32_t> & samples = levels > 0 ? transformed : input;
  int32_t                      lowest = 0, highest = 0;
  for (int32_t s : samples)
  {
    lowest = std::min(lowest, s);
    highest = std::max(highest, s);
  }
  // The fewest bits that hold the samples (two's complement): more bit planes measured worse at the
  // same size.
  int precision = 2;
  while (lowest < -(1 << (precision - 1)) || highest > (1 << (precision - 1)) - 1)
    ++precision;

  int                  components = 1;
  int64_t              width = grid.x, height = grid.y;
  std::vector<int32_t> mosaic;
  if (arrangement == Arrangement::Components)
  {
    if (grid.z > MaximumComponents)
      return {};
    components = grid.z; // the grid's layout is already one plane per slice
  }
  else
  {
    const int32_t cols = MosaicColumns(grid);
    const int32_t rows = (grid.z + cols - 1) / cols;
    width = int64_t(cols) * grid.x;
    height = int64_t(rows) * grid.y;
    if (width > 0x7fffffff || height > 0x7fffffff)
      return {};
    // Empty tiles of the last row hold the most frequent sample (air in a CT): no edge against the
    // background of the slices beside them (measured: +0.15 dB on ct-avm-4mm over a fill with 0).
    std::vector<uint32_t> histogram(std::size_t(highest - lowest) + 1, 0);
    for (int32_t s : samples)
      ++histogram[std::size_t(s - lowest)];
    const int32_t fill = int32_t(std::max_element(histogram.begin(), histogram.end()) - histogram.begin()) + lowest;
    mosaic.assign(std::size_t(width * height), fill);
    for (int32_t z = 0; z < grid.z; ++z)
    {
      const int64_t x0 = int64_t(z % cols) * grid.x, y0 = int64_t(z / cols) * grid.y;
      for (int32_t y = 0; y < grid.y; ++y)
      {
        std::copy_n(samples.data() + grid.Offset(0, y, z), grid.x, mosaic.data() + (y0 + y) * width + x0);
      }
    }
  }
  const std::vector<int32_t> & planes = arrangement == Arrangement::Components ? samples : mosaic;
  // Every resolution level needs a sample, as OpenJPEG asks; six levels otherwise.
  const int resolutions =
    std::max(1, std::min(6, int(std::floor(std::log2(double(std::max<int64_t>(1, std::min(width, height)))))) + 1));
  const double raw = double(width) * double(height) * components * precision / 8.0;
  // OpenJPEG's rate allocation lands within a fraction of a percent under its target; the rare
  // overshoot is taken back in proportion.
  double target = double(maximumBytes);
  for (int attempt = 0; attempt < 4 && target >= 16.0; ++attempt)
  {
    std::vector<uint8_t> codestream =
      EncodeOnce(planes, components, width, height, precision, resolutions, target < raw ? raw / target : 0.0, wavelet);
    if (codestream.empty())
      return {};
    if (codestream.size() <= maximumBytes)
      return codestream;
    target *= 0.995 * double(maximumBytes) / double(codestream.size());
  }
  return {};
}

std::vector<int32_t>
DecodeResidualLayer(const std::vector<uint8_t> & codestream, const GridSize & grid, const std::string & name,
                    int32_t levels)
{
  if (levels < 0 || levels > InterSliceLevels(grid.z))
    throw FormatError(name + ": invalid inter-slice wavelet levels " + std::to_string(levels));
  Buffer      buffer{ codestream, 0 };
  Stream      stream = MakeStream(buffer, true);
  Codec       codec(opj_create_decompress(OPJ_CODEC_J2K));
  std::string error;
  Quiet(codec.get(), error);
  opj_dparameters_t p;
  opj_set_default_decoder_parameters(&p);
  auto fail = [&](const std::string & what) {
    return FormatError(name + ": damaged residual layer (" + what + (error.empty() ? "" : ": " + error) + ")");
  };
  opj_image_t * header = nullptr;
  if (!opj_setup_decoder(codec.get(), &p) || !opj_codec_set_threads(codec.get(), Threads()) ||
      !opj_read_header(stream.get(), codec.get(), &header))
  {
    opj_image_destroy(header);
    throw fail("unreadable JPEG 2000 header");
  }
  Image image(header);
  // A mosaic of the grid's slices, or one component per slice: checked before anything is decoded.
  const int64_t width = int64_t(image->x1) - image->x0, height = int64_t(image->y1) - image->y0;
  const bool    planes = image->numcomps > 1;
  const int64_t cols = planes ? 1 : width / grid.x, rows = planes ? 1 : height / grid.y;
  bool          fits = image->x0 == 0 && image->y0 == 0 && width % grid.x == 0 && height % grid.y == 0 && cols >= 1;
  if (planes)
    fits = fits && image->numcomps == OPJ_UINT32(grid.z) && width == grid.x && height == grid.y;
  else
    fits = fits && rows == (grid.z + cols - 1) / cols;
  for (OPJ_UINT32 c = 0; fits && c < image->numcomps; ++c)
    fits = image->comps[c].dx == 1 && image->comps[c].dy == 1 && image->comps[c].prec <= 24;
  if (!fits)
  {
    throw fail("neither a mosaic of " + std::to_string(grid.z) + " slices of " + std::to_string(grid.x) + "x" +
               std::to_string(grid.y) + " samples nor one component per slice");
  }
  if (!opj_decode(codec.get(), stream.get(), image.get()) || !opj_end_decompress(codec.get(), stream.get()))
  {
    throw fail("JPEG 2000 decoding failed");
  }
  for (OPJ_UINT32 c = 0; c < image->numcomps; ++c)
  {
    const opj_image_comp_t & p = image->comps[c];
    if (p.data == nullptr || int64_t(p.w) != width || int64_t(p.h) != height)
      throw fail("JPEG 2000 decoding gave no samples");
  }
  std::vector<int32_t> samples(grid.NumberOfVoxels());
  for (int32_t z = 0; z < grid.z; ++z)
  {
    const OPJ_INT32 * data = image->comps[planes ? z : 0].data;
    const int64_t     x0 = planes ? 0 : int64_t(z % cols) * grid.x, y0 = planes ? 0 : int64_t(z / cols) * grid.y;
    for (int32_t y = 0; y < grid.y; ++y)
    {
      std::copy_n(data + (y0 + y) * width + x0, grid.x, samples.data() + grid.Offset(0, y, z));
    }
  }
  InverseInterSlice(samples, grid, levels);
  return samples;
}

double
ResidualStep(double peak, bool integer)
{
  const double step = peak / 16384.0;
  return integer ? std::max(1.0, std::ceil(step)) : step;
}

ResidualSearch::ResidualSearch(const float * voxels, PixelType type, const Approximation & spline, double step,
                               std::size_t maximumBytes)
  : voxels(voxels)
  , type(type)
  , grid(spline.grid)
  , maximumBytes(maximumBytes)
{
  best.step = step;
  VisitPixelType(type, [&](auto pixel) {
    using T = decltype(pixel);
    const uint64_t n = grid.NumberOfVoxels();
    splineVoxels.resize(n * sizeof(T));
    T *           decoded = reinterpret_cast<T *>(splineVoxels.data());
    Approximation bare = spline;
    bare.residual = {};
    Rasterize(bare, decoded);
    samples.resize(n);
    for (uint64_t i = 0; i < n; ++i)
    {
      const double r = std::round((double(voxels[i]) - double(decoded[i])) / step);
      samples[i] = int32_t(std::clamp(r, -32767.0, 32767.0));
    }
  });
}

double
ResidualSearch::Try(const ResidualCoding & coding)
{
  if (maximumBytes <= InterSliceLevelsFieldBytes)
    return std::numeric_limits<double>::infinity();
  // The levels byte comes out of the same budget.
  const std::size_t    limit = maximumBytes - (coding.levels > 0 ? InterSliceLevelsFieldBytes : 0);
  std::vector<uint8_t> codestream =
    EncodeResidualLayer(samples, grid, limit, coding.wavelet, coding.arrangement, coding.levels);
  if (codestream.empty())
    return std::numeric_limits<double>::infinity();
  Residual residual{ best.step, DecodeResidualLayer(codestream, grid, "residual layer", coding.levels) };
  double   error = 0.0;
  VisitPixelType(type, [&](auto pixel) {
    using T = decltype(pixel);
    const T * decoded = reinterpret_cast<const T *>(splineVoxels.data());
    for (uint64_t i = 0, n = grid.NumberOfVoxels(); i < n; ++i)
    {
      const double e = double(voxels[i]) - double(AddResidual(decoded[i], residual, i));
      error += e * e;
    }
  });
  if (best.codestream.empty() || error < best.squaredError)
  {
    best.codestream = std::move(codestream);
    best.levels = coding.levels;
    best.samples = std::move(residual.samples);
    best.squaredError = error;
  }
  return error;
}

ResidualChoice
ChooseResidualLayer(const float * voxels, PixelType type, const Approximation & spline, double step,
                    std::size_t maximumBytes, const std::vector<ResidualCoding> & codings)
{
  ResidualSearch search(voxels, type, spline, step, maximumBytes);
  for (const ResidualCoding & coding : codings)
    search.Try(coding);
  return std::move(search).Best();
}

} // namespace dcv
