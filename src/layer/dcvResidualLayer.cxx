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
#include "dcvMemory.h"
#include "dcvParallel.h"

// The path names the system OpenJPEG 2.5: ITK ships an older, mangled openjpeg.h on its include path.
#include <openjpeg-2.5/openjpeg.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <thread>
#include <utility>

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

/** Slice z's row y of a layer's samples (x of them), written to `row`. */
using RowSource = std::function<void(int32_t y, int32_t z, int32_t * row)>;

/** The sample planes of an OpenJPEG image, from OpenJPEG's allocator: an image takes them, and its
 * encoder frees them (it takes a one-tile image's samples and transforms them in place). */
struct Planes
{
  std::vector<int32_t *> data;

  Planes() = default;
  Planes(std::size_t count, std::size_t samples)
  {
    data.reserve(count);
    for (std::size_t c = 0; c < count; ++c)
    {
      // Not zeroed: every sample is written before the encode.
      data.push_back(static_cast<int32_t *>(opj_image_data_alloc(samples * sizeof(int32_t))));
      if (data.back() == nullptr)
        throw std::bad_alloc();
    }
  }
  Planes(Planes && o) noexcept
    : data(std::exchange(o.data, {}))
  {}
  Planes &
  operator=(Planes && o) noexcept
  {
    std::swap(data, o.data);
    return *this;
  }
  ~Planes()
  {
    for (int32_t * p : data)
      opj_image_data_free(p);
  }
};

/** One encode at a target size of the planes (`components` of width x height samples); the codestream
 * (empty when OpenJPEG fails). The planes go to OpenJPEG, which transforms them in place and frees them. */
std::vector<uint8_t>
EncodeOnce(Planes && planes, int components, int64_t width, int64_t height, int precision, int resolutions,
           double ratio, Wavelet wavelet)
{
  opj_image_cmptparm_t component{};
  component.dx = component.dy = 1;
  component.w = OPJ_UINT32(width);
  component.h = OPJ_UINT32(height);
  component.prec = OPJ_UINT32(precision);
  component.sgnd = 1;
  std::vector<opj_image_cmptparm_t> parameters(std::size_t(components), component);
  Image image(opj_image_tile_create(OPJ_UINT32(components), parameters.data(), OPJ_CLRSPC_UNKNOWN));
  if (!image || planes.data.size() != std::size_t(components))
    throw std::bad_alloc();
  image->x0 = image->y0 = 0;
  image->x1 = OPJ_UINT32(width);
  image->y1 = OPJ_UINT32(height);
  for (int c = 0; c < components; ++c)
    image->comps[c].data = std::exchange(planes.data[std::size_t(c)], nullptr); // the image's now

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
  std::vector<uint8_t> codestream = std::move(buffer.bytes);
  codec.reset();
  image.reset();
  ReturnFreedMemory(); // OpenJPEG's code-blocks, freed on its threads
  return codestream;
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

namespace
{
/** A coding's JPEG 2000 image: its shape, prepared once, then encoded at as many targets as asked. Its
 * samples are computed again for each encode after the first, straight into the planes OpenJPEG takes,
 * never kept as a volume laid out as the grid (page faults of a fresh volume cost more than computing
 * the samples again). */
struct LayerImage
{
  RowSource   source; // the samples
  GridSize    grid;
  Arrangement arrangement{ Arrangement::Mosaic };
  int32_t     levels{ 0 };
  int32_t     columns{ 1 }; // of the mosaic
  int32_t     fill{ 0 };    // the mosaic's empty tiles
  Planes      pending;      // the first encode's planes, written by PrepareImage
  int         components{ 1 };
  int64_t     width{ 0 }, height{ 0 };
  int         precision{ 2 };
  int         resolutions{ 1 };
  double      raw{ 0.0 }; // bytes of the samples at that precision: what OpenJPEG's ratio refers to

  /** Where slice (or mosaic tile) z's row y is in the planes. */
  int32_t *
  Row(Planes & planes, int32_t y, int32_t z) const
  {
    if (arrangement == Arrangement::Components)
      return planes.data[std::size_t(z)] + int64_t(y) * grid.x;
    const int64_t x0 = int64_t(z % columns) * grid.x, y0 = int64_t(z / columns) * grid.y;
    return planes.data[0] + (y0 + y) * width + x0;
  }

  /** New planes holding the transformed samples (the mosaic's empty tiles not written). */
  Planes
  Transformed() const
  {
    Planes planes(std::size_t(components), std::size_t(width * height));
    ForwardInterSlice(
      source,
      [&](int32_t y, int32_t z, const int32_t * row) { std::copy_n(row, grid.x, Row(planes, y, z)); },
      grid,
      levels);
    return planes;
  }

  void
  FillEmptyTiles(Planes & planes) const
  {
    if (arrangement == Arrangement::Components)
      return;
    const int32_t tiles = columns * int32_t(height / grid.y);
    for (int32_t z = grid.z; z < tiles; ++z)
      for (int32_t y = 0; y < grid.y; ++y)
        std::fill_n(Row(planes, y, z), grid.x, fill);
  }

  /** The planes of the next encode. */
  Planes
  Take()
  {
    if (!pending.data.empty())
      return std::move(pending);
    Planes planes = Transformed();
    FillEmptyTiles(planes);
    return planes;
  }
};

/** Prepares the samples `source` gives as a JPEG 2000 image; false when they cannot be one (more slices
 * than MaximumComponents as components, a mosaic too wide). */
bool
PrepareImage(RowSource source, const GridSize & grid, Arrangement arrangement, int32_t levels, LayerImage & image)
{
  image.source = std::move(source);
  image.grid = grid;
  image.arrangement = arrangement;
  image.levels = levels;
  image.components = 1;
  image.width = grid.x;
  image.height = grid.y;
  if (arrangement == Arrangement::Components)
  {
    if (grid.z > MaximumComponents)
      return false;
    image.components = grid.z;
  }
  else
  {
    image.columns = MosaicColumns(grid);
    const int32_t rows = (grid.z + image.columns - 1) / image.columns;
    image.width = int64_t(image.columns) * grid.x;
    image.height = int64_t(rows) * grid.y;
    if (image.width > 0x7fffffff || image.height > 0x7fffffff)
      return false;
  }
  Planes  planes = image.Transformed();
  int32_t lowest = 0, highest = 0;
  for (int32_t z = 0; z < grid.z; ++z)
    for (int32_t y = 0; y < grid.y; ++y)
    {
      const auto range = std::minmax_element(image.Row(planes, y, z), image.Row(planes, y, z) + grid.x);
      lowest = std::min(lowest, *range.first);
      highest = std::max(highest, *range.second);
    }
  // The fewest bits that hold the samples (two's complement): more bit planes measured worse at the
  // same size.
  image.precision = 2;
  while (lowest < -(1 << (image.precision - 1)) || highest > (1 << (image.precision - 1)) - 1)
    ++image.precision;
  if (arrangement == Arrangement::Mosaic)
  {
    // Empty tiles of the last row hold the most frequent sample (air in a CT): no edge against the
    // background of the slices beside them (measured: +0.15 dB on ct-avm-4mm over a fill with 0).
    std::vector<uint32_t> histogram(std::size_t(int64_t(highest) - lowest) + 1, 0);
    for (int32_t z = 0; z < grid.z; ++z)
      for (int32_t y = 0; y < grid.y; ++y)
        for (const int32_t *s = image.Row(planes, y, z), *end = s + grid.x; s < end; ++s)
          ++histogram[std::size_t(*s - lowest)];
    image.fill = int32_t(std::max_element(histogram.begin(), histogram.end()) - histogram.begin()) + lowest;
    image.FillEmptyTiles(planes);
  }
  image.pending = std::move(planes);
  // Every resolution level needs a sample, as OpenJPEG asks; six levels otherwise.
  image.resolutions = std::max(
    1, std::min(6, int(std::floor(std::log2(double(std::max<int64_t>(1, std::min(image.width, image.height)))))) + 1));
  image.raw = double(image.width) * double(image.height) * image.components * image.precision / 8.0;
  return true;
}

/** The image coded at `target` bytes (OpenJPEG's rate allocation aims at it; empty when OpenJPEG fails). */
std::vector<uint8_t>
EncodeAt(LayerImage & image, double target, Wavelet wavelet)
{
  return EncodeOnce(image.Take(),
                    image.components,
                    image.width,
                    image.height,
                    image.precision,
                    image.resolutions,
                    target < image.raw ? image.raw / target : 0.0,
                    wavelet);
}

/** The bytes a codestream takes: its size, or with `grid` its stored size (compact where it can be). */
std::size_t
Taken(const std::vector<uint8_t> & codestream, const GridSize * grid)
{
  return grid ? StoredLayerBytes(codestream, *grid) : codestream.size();
}

/** The first codestream that takes at most `maximumBytes` bytes (Taken() with `grid`), from a target of
 * `maximumBytes` plus `saving` down; `target` is the one that gave it. Empty when none fits. */
std::vector<uint8_t>
EncodeWithin(LayerImage & image, std::size_t maximumBytes, Wavelet wavelet, double & target,
             const GridSize * grid = nullptr, std::size_t saving = 0, double * backOff = nullptr)
{
  // OpenJPEG's rate allocation lands within a fraction of a percent of its target. `backOff` carries
  // the fraction the last coding of the same image had to come down by, so that the next one starts
  // there and spares the encode that overshoots.
  const double aim = double(maximumBytes + saving);
  target = backOff ? aim * (1.0 - *backOff) : aim;
  for (int attempt = 0; attempt < 4 && target >= 16.0; ++attempt)
  {
    std::vector<uint8_t> codestream = EncodeAt(image, target, wavelet);
    if (codestream.empty())
      return {};
    const std::size_t taken = Taken(codestream, grid);
    if (taken <= maximumBytes)
    {
      if (backOff)
        *backOff = std::max(0.0, 1.0 - target / aim);
      return codestream;
    }
    // Its size follows the target within a few bytes, now and then over it: back by the excess and 0.1%.
    target -= double(taken - maximumBytes) + 0.001 * double(maximumBytes) + 1.0;
  }
  return {};
}
} // namespace

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
  LayerImage image;
  const auto source = [&](int32_t y, int32_t z, int32_t * row) {
    std::copy_n(input.data() + grid.Offset(0, y, z), grid.x, row);
  };
  if (!PrepareImage(source, grid, arrangement, levels, image))
    return {};
  double target = 0.0;
  return EncodeWithin(image, maximumBytes, wavelet, target);
}

void
DecodeResidualRows(const std::vector<uint8_t> & codestream, const GridSize & grid, const std::string & name,
                   int32_t levels, const std::function<void(int32_t y, int32_t z, const int32_t * row)> & sink)
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
  // The inverse wavelet reads each slice's rows where OpenJPEG put them (in the mosaic, or the slice's
  // component): no copy of the volume laid out as the grid in between.
  InverseInterSlice(
    [&](int32_t y, int32_t z) -> const int32_t * {
      const int64_t x0 = planes ? 0 : int64_t(z % cols) * grid.x, y0 = planes ? 0 : int64_t(z / cols) * grid.y;
      return image->comps[planes ? z : 0].data + (y0 + y) * width + x0;
    },
    sink,
    grid,
    levels);
}

ResidualSamples
DecodeResidualLayer(const std::vector<uint8_t> & codestream, const GridSize & grid, const std::string & name,
                    int32_t levels)
{
  ResidualSamples samples(grid.NumberOfVoxels()); // not initialized: each written once below
  DecodeResidualRows(codestream, grid, name, levels, [&](int32_t y, int32_t z, const int32_t * row) {
    std::copy_n(row, grid.x, samples.data() + grid.Offset(0, y, z));
  });
  return samples;
}


double
ResidualStep(double peak, bool integer)
{
  const double step = peak / 16384.0;
  return integer ? std::max(1.0, std::ceil(step)) : step;
}

namespace
{
/** ResidualSearch::Fill tries the best coding with up to this many fewer 2D wavelet levels where its
 * codestream's steps leave the budget short (with every coding at three fewer, neghip, ironprot and
 * avg152t1 decoded worse at 0.03125 bpv than at two fewer, headsq-ct a little better). */
constexpr int32_t FillFewerResolutions = 2;

/** Whether the spline's values are all equal (the corners under a layer that takes the whole budget):
 * such a spline is that value everywhere, exactly as Rasterize() gives it (every cell's gradient is 0, so
 * each voxel is the converted value; test ResidualLayer.ConstantSplineIsFilled), and needs no volume. */
bool
IsConstant(const Approximation & spline)
{
  return !spline.values.empty() && spline.residual.samples.empty() &&
         std::all_of(spline.values.begin(), spline.values.end(), [&](double v) { return v == spline.values.front(); });
}

/** The spline's voxels, of the pixel type T, without its residual layer. */
template <typename T>
void
RasterizeSpline(const Approximation & spline, T * out)
{
  Approximation bare = spline;
  bare.residual = {};
  Rasterize(bare, out, CurrentThreads());
}

/** Sum over the grid of f(i) for every voxel i, slice by slice on the encoder's threads, added in slice
 * order: the same sum whatever the number of threads. */
template <typename F>
double
SumOverSlices(const GridSize & grid, F && f)
{
  std::vector<double> partial(std::size_t(grid.z), 0.0);
  const uint64_t      plane = uint64_t(grid.x) * uint64_t(grid.y);
  ParallelFor(std::size_t(grid.z), 1, [&](std::size_t z) {
    double s = 0.0;
    for (uint64_t i = z * plane, end = i + plane; i < end; ++i)
      s += f(i);
    partial[z] = s;
  });
  double sum = 0.0;
  for (double s : partial)
    sum += s;
  return sum;
}
} // namespace

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
    // A constant spline (the corners' candidate) is one voxel, read at every index: a volume less.
    const bool constant = IsConstant(spline);
    voxelMask = constant ? 0 : ~uint64_t(0);
    splineVoxels.resize((constant ? 1 : grid.NumberOfVoxels()) * sizeof(T));
    T * decoded = reinterpret_cast<T *>(splineVoxels.data());
    if (constant)
      decoded[0] = ConvertValue<T>(spline.values.front());
    else
      RasterizeSpline(spline, decoded);
    splineError = SumOverSlices(grid, [&](uint64_t i) {
      const double e = double(voxels[i]) - double(decoded[i & voxelMask]);
      return e * e;
    });
  });
}

std::function<void(int32_t y, int32_t z, int32_t * row)>
ResidualSearch::Source() const
{
  if (!(best.step > 0.0))
    throw std::invalid_argument("ResidualSearch: the residual step must be positive");
  return [this, step = best.step](int32_t y, int32_t z, int32_t * row) {
    VisitPixelType(type, [&](auto pixel) {
      using T = decltype(pixel);
      const T *      decoded = reinterpret_cast<const T *>(splineVoxels.data());
      const uint64_t first = grid.Offset(0, y, z);
      for (int32_t x = 0; x < grid.x; ++x)
      {
        const uint64_t i = first + uint64_t(x);
        const double   r = std::round((double(voxels[i]) - double(decoded[i & voxelMask])) / step);
        row[x] = int32_t(std::clamp(r, -32767.0, 32767.0));
      }
    });
  };
}

double
ResidualSearch::Measure(std::vector<uint8_t> && codestream, const ResidualCoding & coding, double target)
{
  const std::size_t stored = StoredLayerBytes(codestream, grid);
  // Summed row by row as the layer is decoded, without a volume of its samples; the rows' sums are added
  // in the grid's order.
  std::vector<double> rows(std::size_t(grid.y) * std::size_t(grid.z), 0.0);
  VisitPixelType(type, [&](auto pixel) {
    using T = decltype(pixel);
    const T * decoded = reinterpret_cast<const T *>(splineVoxels.data());
    DecodeResidualRows(
      codestream, grid, "residual layer", coding.levels, [&](int32_t y, int32_t z, const int32_t * row) {
        const uint64_t first = grid.Offset(0, y, z);
        double         sum = 0.0;
        for (int32_t x = 0; x < grid.x; ++x)
        {
          const uint64_t i = first + uint64_t(x);
          const double   e = double(voxels[i]) - double(AddResidual(decoded[i & voxelMask], best.step, row[x]));
          sum += e * e;
        }
        rows[std::size_t(z) * std::size_t(grid.y) + std::size_t(y)] = sum;
      });
  });
  double error = 0.0;
  for (double sum : rows)
    error += sum;
  ReturnFreedMemory(); // the decoder's buffers, freed on OpenJPEG's threads
  if (best.codestream.empty() || error < best.squaredError)
  {
    best.codestream = std::move(codestream);
    best.levels = coding.levels;
    best.squaredError = error;
    bestCoding = coding;
    bestTarget = target;
    bestStored = stored;
  }
  return error;
}

std::size_t
ResidualSearch::Limit(const ResidualCoding & coding) const
{
  // The levels byte comes out of the same budget.
  return maximumBytes - (coding.levels > 0 ? InterSliceLevelsFieldBytes : 0);
}

double
ResidualSearch::Try(const ResidualCoding & coding)
{
  if (maximumBytes <= InterSliceLevelsFieldBytes)
    return std::numeric_limits<double>::infinity();
  LayerImage image;
  if (!PrepareImage(Source(), grid, coding.arrangement, coding.levels, image) ||
      coding.fewerResolutions >= image.resolutions)
    return std::numeric_limits<double>::infinity();
  image.resolutions -= coding.fewerResolutions;
  double               target = 0.0;
  std::vector<uint8_t> codestream = EncodeWithin(
    image, Limit(coding), coding.wavelet, target, &grid, CompactLayerSaving(grid, coding.arrangement), &backOff);
  if (codestream.empty())
    return std::numeric_limits<double>::infinity();
  return Measure(std::move(codestream), coding, target);
}

std::size_t
ResidualSearch::Fill(std::size_t slack, int attempts)
{
  if (best.codestream.empty())
    return 0;
  const std::size_t limit = Limit(bestCoding);
  if (limit - bestStored <= slack)
    return 0;
  LayerImage image;
  if (!PrepareImage(Source(), grid, bestCoding.arrangement, bestCoding.levels, image))
    return 0;
  image.resolutions -= bestCoding.fewerResolutions; // Try() coded it so: at least one is left
  // OpenJPEG's size follows its target within a few bytes, not monotonically: aim at the bytes left from
  // the largest target that fit, then back from the smallest that did not by its excess, within the two.
  const ResidualCoding coding = bestCoding;
  double               fitTarget = bestTarget, fitSize = double(bestStored);
  double               overTarget = 0.0, overSize = 0.0;
  std::size_t          tried = 0;
  bool                 whole = false; // all of the image fits: no step is left to fill
  for (int attempt = 0; attempt<attempts && double(limit) - fitSize> double(slack); ++attempt)
  {
    double target =
      overTarget > 0.0 ? overTarget - (overSize - double(limit)) - 1.0 : fitTarget + (double(limit) - fitSize);
    if (overTarget > 0.0 && !(target > fitTarget && target < overTarget))
      target = 0.5 * (fitTarget + overTarget);
    std::vector<uint8_t> codestream = EncodeAt(image, target, coding.wavelet);
    ++tried;
    if (codestream.empty())
      break;
    const std::size_t stored = StoredLayerBytes(codestream, grid);
    if (stored <= limit)
    {
      // All of the image fits (no rate allocation past raw size), or a larger target gave no more bytes
      // with none too large yet: there is nothing to fill.
      const bool complete = target >= image.raw || (overTarget == 0.0 && double(stored) <= fitSize);
      whole = whole || complete;
      if (double(stored) > fitSize)
        fitSize = double(stored);
      fitTarget = std::max(fitTarget, target);
      Measure(std::move(codestream), coding, target);
      if (complete)
        break;
    }
    else
    {
      if (overTarget == 0.0 || target < overTarget)
      {
        overTarget = target;
        overSize = double(stored);
      }
    }
  }
  // No target lands inside one of the codestream's steps, which are large when the image is small (head-mr,
  // 48x62x42: 389 bytes, then 424, for a limit of 408). The same coding with fewer 2D wavelet levels has its
  // steps elsewhere: tried at the limit where they still leave more than `slack` (unless all of the image
  // fits), and kept where it fills more and decodes closer (head-mr at 0.03125 bpv: 401 bytes, 23.38 ->
  // 23.73 dB).
  const int32_t resolutions = image.resolutions;
  for (int32_t fewer = 1;
       fewer <= FillFewerResolutions && resolutions - fewer >= 1 && !whole && limit - bestStored > slack;
       ++fewer)
  {
    LayerImage coarser;
    if (!PrepareImage(Source(), grid, coding.arrangement, coding.levels, coarser))
      break;
    coarser.resolutions = resolutions - fewer;
    ResidualCoding coarserCoding = coding;
    coarserCoding.fewerResolutions += fewer;
    double               target = 0.0;
    std::vector<uint8_t> codestream =
      EncodeWithin(coarser, limit, coding.wavelet, target, &grid, CompactLayerSaving(grid, coding.arrangement));
    ++tried;
    if (!codestream.empty() && StoredLayerBytes(codestream, grid) > bestStored)
      Measure(std::move(codestream), coarserCoding, target);
  }
  return tried;
}

ResidualChoice
ResidualSearch::Best() &&
{
  // Decoded again rather than kept from Measure(): a volume of int32 less beside every later trial.
  if (!best.codestream.empty())
    best.samples = DecodeResidualLayer(best.codestream, grid, "residual layer", best.levels);
  return std::move(best);
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
