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
// The video layer's HEVC: x265 encodes, libde265 decodes (docs/format.md, "Video layer").
#include "dcvVideoCodecs.h"

#include "../core/dcvParallel.h"

#include <libde265/de265.h>
#include <x265.h>

#include <algorithm>
#include <malloc.h>
#include <mutex>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>

namespace dcv
{

namespace
{
/** x265's speed preset of the stream kept: "slower" decodes closer than "slow" at the same size (ct-avm-4mm
 * at --crf 26.6: 18,079 bytes and 42.98 dB against 18,987 and 42.43) and takes about 4 times as long. */
constexpr const char * Preset = "slower";

/** The preset that looks for the rate factor first: "medium" is about 8 times as fast as "slower", and its
 * stream's size follows the factor as the slower one's does. */
constexpr const char * SearchPreset = "medium";

/** x265's frame threads, fixed so that the stream does not depend on the machine (1, 2 and 3 gave the
 * same stream on norm-256 and four dev volumes; the worker threads never change it). One: with more, x265
 * 3.5's rate control makes each frame's end wait for a later frame's start, and an encode hung there for
 * good once in a test run (a frame encoder in rateControlEnd, the caller waiting for its picture); with one
 * that wait is never taken. The 5 mm CT series with HEVC alone codes 15% slower, norm-256 within its noise. */
constexpr int FrameThreads = 1;

/** The pictures' sides: the slice's rounded up to `unit` samples. */
int32_t
Padded(int32_t side, int32_t unit)
{
  return (side + unit - 1) / unit * unit;
}

/** The coding tree unit and the pictures' size for slices of `grid`: sides rounded up to 8 samples (HEVC's
 * smallest coding unit), at least 64 wide and 16 high, and the largest unit the pictures hold (x265 refuses
 * pictures smaller than one). Debian's x265 3.5 writes past its lookahead's buffers on pictures narrower
 * than 56 samples (valgrind: 24 x 24 to 48 x 80, at 8 and 12 bits, whatever the unit), never on the 64-wide
 * ones tried (64 x 16 to 200 x 40); it aborts on some. Padding costs bytes (ironprot's 68 x 68 slices as
 * 128 x 128: 38.89 dB at 0.125 bpv, as 72 x 72: 39.03). */
struct PictureSize
{
  int32_t ctu, width, height;
};
PictureSize
Pictures(const GridSize & grid)
{
  const int32_t width = std::max(Padded(grid.x, 8), 64), height = std::max(Padded(grid.y, 8), 16);
  const int32_t side = std::min(width, height);
  return { side >= 64 ? 64 : side >= 32 ? 32 : 16, width, height };
}

struct ParamDeleter
{
  const x265_api * api;
  void
  operator()(x265_param * p) const
  {
    api->param_free(p);
  }
};
struct PictureDeleter
{
  const x265_api * api;
  void
  operator()(x265_picture * p) const
  {
    api->picture_free(p);
  }
};
struct EncoderDeleter
{
  const x265_api * api;
  void
  operator()(x265_encoder * e) const
  {
    api->encoder_close(e);
  }
};
struct DecoderDeleter
{
  void
  operator()(de265_decoder_context * d) const
  {
    de265_free_decoder(d);
  }
};

void
Append(std::vector<uint8_t> & stream, const x265_nal * nals, uint32_t count)
{
  for (uint32_t i = 0; i < count; ++i)
    stream.insert(stream.end(), nals[i].payload, nals[i].payload + nals[i].sizeBytes);
}

/** One slice as a picture of `width` x `height` samples of type T, the slice's edges repeated into the
 * padding (cheapest to code). */
template <typename T>
void
FillPicture(const std::vector<uint16_t> & samples, const GridSize & grid, int32_t z, int32_t width, int32_t height,
            std::vector<T> & picture)
{
  picture.resize(std::size_t(width) * std::size_t(height));
  for (int32_t y = 0; y < height; ++y)
  {
    const uint16_t * row = samples.data() + grid.Offset(0, std::min(y, grid.y - 1), z);
    T *              out = picture.data() + std::size_t(y) * std::size_t(width);
    for (int32_t x = 0; x < width; ++x)
      out[x] = T(row[std::min(x, grid.x - 1)]);
  }
}
} // namespace

namespace
{
/** Debian's x265 3.5 reads heap memory it never wrote (valgrind: its inter analysis and residual search,
 * at every preset), so the same samples gave a different stream from one encode to the next within a
 * process (a fresh process's heap is zeros). glibc's perturbation fills every block malloc hands out with
 * one byte, which makes that memory the same every time: set once, before the first encode, for the
 * whole process (a memset of each small block allocated and freed from then on). */
void
MakeHeapDeterministic()
{
  static std::once_flag once;
  std::call_once(once, [] { mallopt(M_PERTURB, 0x5a); });
}
} // namespace

std::vector<uint8_t>
EncodeHEVC(const std::vector<uint16_t> & samples, const GridSize & grid, int32_t depth, double crf, bool search)
{
  const char * preset = search ? SearchPreset : Preset;
  MakeHeapDeterministic();
  const x265_api * api = x265_api_get(depth);
  if (api == nullptr)
    throw std::runtime_error("libx265 has no " + std::to_string(depth) + "-bit encoder");
  std::unique_ptr<x265_param, ParamDeleter> param(api->param_alloc(), ParamDeleter{ api });
  if (!param || api->param_default_preset(param.get(), preset, "psnr") < 0)
    throw std::runtime_error("libx265 refused its preset");
  const PictureSize pictures = Pictures(grid);
  const int32_t     ctu = pictures.ctu, width = pictures.width, height = pictures.height;
  const std::string pools = std::to_string(std::max(1u, CurrentThreads()));
  x265_param &      p = *param;
  p.logLevel = X265_LOG_NONE;
  p.internalCsp = X265_CSP_I400;
  p.internalBitDepth = depth;
  p.sourceWidth = width;
  p.sourceHeight = height;
  p.fpsNum = 25;
  p.fpsDenom = 1;
  p.totalFrames = grid.z;
  p.maxCUSize = uint32_t(ctu);
  p.maxTUSize = std::min<uint32_t>(p.maxTUSize, uint32_t(ctu));
  p.bEmitInfoSEI = 0;
  p.bRepeatHeaders = 0;
  p.bAnnexB = 1;
  p.frameNumThreads = FrameThreads;
  p.lookaheadSlices = 0;
  p.numaPools = pools.c_str();
  p.rc.rateControlMode = X265_RC_CRF;
  p.rc.rfConstant = std::clamp(crf, 0.0, 51.0);
  p.bLossless = crf == VideoLossless;
  std::unique_ptr<x265_encoder, EncoderDeleter> encoder(api->encoder_open(&p), EncoderDeleter{ api });
  if (!encoder)
    throw std::runtime_error("libx265 cannot open an encoder for " + std::to_string(width) + "x" +
                             std::to_string(height) + " " + std::to_string(depth) + "-bit slices");
  std::unique_ptr<x265_picture, PictureDeleter> picture(api->picture_alloc(), PictureDeleter{ api });
  api->picture_init(&p, picture.get());
  picture->bitDepth = depth;
  picture->colorSpace = X265_CSP_I400;
  std::vector<uint8_t> stream;
  x265_nal *           nals = nullptr;
  uint32_t             count = 0;
  if (api->encoder_headers(encoder.get(), &nals, &count) < 0)
    throw std::runtime_error("libx265 cannot write the stream's headers");
  Append(stream, nals, count);
  std::vector<uint8_t>  bytes;
  std::vector<uint16_t> words;
  for (int32_t z = 0; z <= grid.z; ++z)
  {
    x265_picture * in = nullptr;
    if (z < grid.z)
    {
      if (depth == 8)
      {
        FillPicture(samples, grid, z, width, height, bytes);
        picture->planes[0] = bytes.data();
        picture->stride[0] = width;
      }
      else
      {
        FillPicture(samples, grid, z, width, height, words);
        picture->planes[0] = words.data();
        picture->stride[0] = width * 2;
      }
      picture->pts = z;
      in = picture.get();
    }
    // After the last slice, flush: the frames x265 still holds come out one a call.
    for (;;)
    {
      const int got = api->encoder_encode(encoder.get(), &nals, &count, in, nullptr);
      if (got < 0)
        throw std::runtime_error("libx265 failed to code slice " + std::to_string(z));
      Append(stream, nals, count);
      if (in != nullptr || got == 0)
        break;
    }
  }
  return stream;
}

void
DecodeHEVCRows(const std::vector<uint8_t> & stream, const GridSize & grid, const std::string & name,
               const std::function<void(int32_t y, int32_t z, const int32_t * row)> & sink)
{
  std::unique_ptr<de265_decoder_context, DecoderDeleter> decoder(de265_new_decoder());
  if (!decoder)
    throw std::runtime_error(name + ": libde265 cannot open a decoder");
  // A damaged picture is an error, not a picture to show.
  de265_set_parameter_bool(decoder.get(), DE265_DECODER_PARAM_SUPPRESS_FAULTY_PICTURES, 1);
  // On one thread, in plain C++: libde265 1.0.11's SSE code reads uninitialised memory (valgrind, on every
  // stream of the fuzz seeds; its scalar code is clean), which a decoder that must give the encoder's
  // samples to the bit cannot risk. norm-256 at 0.03125 bpv: 0.20 s against 0.15 with SSE, the same samples.
  de265_set_parameter_int(decoder.get(), DE265_DECODER_PARAM_ACCELERATION_CODE, de265_acceleration_SCALAR);
  std::vector<int32_t> out(std::size_t(grid.x));
  int32_t              z = 0;
  auto fail = [&](const std::string & what) { return FormatError(name + ": invalid video layer (" + what + ")"); };
  auto take = [&]() {
    while (const de265_image * image = de265_get_next_picture(decoder.get()))
    {
      if (z >= grid.z)
        throw fail("more pictures than the " + std::to_string(grid.z) + " slices");
      if (de265_get_chroma_format(image) != de265_chroma_mono)
        throw fail("not monochrome");
      const int depth = de265_get_bits_per_pixel(image, 0);
      if (depth < 8 || depth > VideoMaximumDepth)
        throw fail(std::to_string(depth) + "-bit samples");
      if (de265_get_image_width(image, 0) < grid.x || de265_get_image_height(image, 0) < grid.y)
        throw fail("pictures smaller than the slices");
      int             stride = 0;
      const uint8_t * plane = de265_get_image_plane(image, 0, &stride);
      SendSliceRows(plane, stride, depth > 8, grid, z, out, sink);
      ++z;
    }
  };
  if (stream.size() > std::size_t(std::numeric_limits<int>::max()))
    throw fail("too long");
  de265_error e = de265_push_data(decoder.get(), stream.data(), int(stream.size()), 0, nullptr);
  if (de265_isOK(e))
    e = de265_flush_data(decoder.get());
  if (!de265_isOK(e))
    throw fail(de265_get_error_text(e));
  for (int more = 1; more;)
  {
    e = de265_decode(decoder.get(), &more);
    if (e == DE265_ERROR_WAITING_FOR_INPUT_DATA)
      break;
    if (!de265_isOK(e))
      throw fail(de265_get_error_text(e));
    take();
  }
  take();
  // A warning is a stream the encoder did not write: refused as damaged.
  const de265_error warning = de265_get_warning(decoder.get());
  if (warning != DE265_OK)
    throw fail(de265_get_error_text(warning));
  if (z != grid.z)
    throw fail(std::to_string(z) + " pictures for " + std::to_string(grid.z) + " slices");
}

std::string
HEVCLibraryVersions()
{
  const x265_api * api = x265_api_get(0);
  std::string      x265 = api ? api->version_str : "?";
  return "x265 " + x265 + ", libde265 " + std::string(de265_get_version());
}

} // namespace dcv
