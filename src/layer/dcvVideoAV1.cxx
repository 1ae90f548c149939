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
// The video layer's AV1: libaom encodes, dav1d decodes (docs/format.md, "Video layer").
#include "dcvVideoCodecs.h"

#include "../core/dcvParallel.h"

#include <aom/aom_encoder.h>
#include <aom/aomcx.h>
#include <dav1d/dav1d.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <memory>
#include <stdexcept>

namespace dcv
{

namespace
{
/** The pictures' sides: the slices' rounded up to 8 samples (AV1's coding blocks are 8 x 8 at the least;
 * the decoder's pictures are the stream's frame size, any). */
int32_t
Padded(int32_t side)
{
  return (side + 7) / 8 * 8;
}

struct EncoderCloser
{
  void
  operator()(aom_codec_ctx_t * c) const
  {
    aom_codec_destroy(c);
    delete c;
  }
};
struct ImageFreer
{
  void
  operator()(aom_image_t * i) const
  {
    aom_img_free(i);
  }
};
struct DecoderCloser
{
  void
  operator()(Dav1dContext * c) const
  {
    dav1d_close(&c);
  }
};

void
Check(aom_codec_ctx_t & codec, aom_codec_err_t e, const std::string & what)
{
  if (e != AOM_CODEC_OK)
  {
    const char * detail = aom_codec_error_detail(&codec);
    throw std::runtime_error("libaom: " + what + ": " + aom_codec_err_to_string(e) +
                             (detail ? std::string(" (") + detail + ")" : std::string()));
  }
}

/** Takes the packets the encoder has ready; false when there were none. */
bool
Drain(aom_codec_ctx_t & codec, std::vector<uint8_t> & stream)
{
  bool                       any = false;
  aom_codec_iter_t           iter = nullptr;
  const aom_codec_cx_pkt_t * packet = nullptr;
  while ((packet = aom_codec_get_cx_data(&codec, &iter)) != nullptr)
    if (packet->kind == AOM_CODEC_CX_FRAME_PKT)
    {
      const auto * bytes = static_cast<const uint8_t *>(packet->data.frame.buf);
      stream.insert(stream.end(), bytes, bytes + packet->data.frame.sz);
      any = true;
    }
  return any;
}
} // namespace

std::vector<uint8_t>
EncodeAV1(const std::vector<uint16_t> & samples, const GridSize & grid, int32_t depth, double quality, bool search)
{
  const int32_t       width = Padded(grid.x), height = Padded(grid.y);
  aom_codec_iface_t * iface = aom_codec_av1_cx();
  aom_codec_enc_cfg_t cfg;
  if (aom_codec_enc_config_default(iface, &cfg, AOM_USAGE_GOOD_QUALITY) != AOM_CODEC_OK)
    throw std::runtime_error("libaom has no default configuration");
  cfg.g_w = unsigned(width);
  cfg.g_h = unsigned(height);
  cfg.g_bit_depth = aom_bit_depth_t(depth);
  cfg.g_input_bit_depth = unsigned(depth);
  cfg.g_profile = depth == 12 ? 2 : 0; // 12 bits need the professional profile; monochrome is in both
  cfg.monochrome = 1;
  cfg.g_timebase = { 1, 25 };
  // One thread codes another stream than two or more (same size; 2, 3, 4 and 8 gave one stream): at least
  // two, so that the stream does not depend on the machine.
  cfg.g_threads = std::max(2u, CurrentThreads());
  cfg.g_pass = AOM_RC_ONE_PASS;
  cfg.rc_end_usage = AOM_Q;
  cfg.kf_max_dist = uint32_t(std::max(grid.z, 1)); // one key frame: the first slice
  std::unique_ptr<aom_codec_ctx_t, EncoderCloser> codec(new aom_codec_ctx_t{});
  // On failure libaom has already destroyed the context (its error detail with it).
  if (const aom_codec_err_t e =
        aom_codec_enc_init(codec.get(), iface, &cfg, depth > 8 ? AOM_CODEC_USE_HIGHBITDEPTH : 0);
      e != AOM_CODEC_OK)
    throw std::runtime_error("libaom cannot open an encoder for " + std::to_string(width) + "x" +
                             std::to_string(height) + " " + std::to_string(depth) +
                             "-bit slices: " + aom_codec_err_to_string(e));
  aom_codec_ctx_t & c = *codec;
  // Speed 4 of libaom's good-quality mode; the search looks for the level at speed 6 (sizes alone).
  Check(c, aom_codec_control(&c, AOME_SET_CPUUSED, search ? 6 : 4), "speed");
  // Row-based threads.
  Check(c, aom_codec_control(&c, AV1E_SET_ROW_MT, 1u), "row threads");
  // libaom's quality is one of 64 levels (a level moves the size by 6% to 12%): changing it, or its
  // bounds, between slices moved the size by whole groups of pictures, not in proportion.
  if (quality == VideoLossless)
    Check(c, aom_codec_control(&c, AV1E_SET_LOSSLESS, 1u), "lossless");
  else
    Check(c, aom_codec_control(&c, AOME_SET_CQ_LEVEL, int(std::clamp(std::round(quality), 0.0, 63.0))), "level");
  std::unique_ptr<aom_image_t, ImageFreer> image(
    aom_img_alloc(nullptr, depth > 8 ? AOM_IMG_FMT_I42016 : AOM_IMG_FMT_I420, unsigned(width), unsigned(height), 32));
  if (!image)
    throw std::runtime_error("libaom cannot allocate a picture");
  image->bit_depth = unsigned(depth);
  image->monochrome = 1;
  // The chroma planes are not coded (monochrome); set, as the encoder may read them.
  for (int plane = 1; plane <= 2; ++plane)
    for (unsigned y = 0; y < (image->d_h + 1) / 2; ++y)
    {
      uint8_t * row = image->planes[plane] + std::ptrdiff_t(y) * image->stride[plane];
      if (depth > 8)
        std::fill_n(reinterpret_cast<uint16_t *>(row), (image->d_w + 1) / 2, uint16_t(1u << (depth - 1)));
      else
        std::fill_n(row, (image->d_w + 1) / 2, uint8_t(128));
    }
  std::vector<uint8_t> stream;
  for (int32_t z = 0; z < grid.z; ++z)
  {
    // The slice, its last column and row repeated into the padding (cheapest to code).
    for (int32_t y = 0; y < height; ++y)
    {
      const uint16_t * in = samples.data() + grid.Offset(0, std::min(y, grid.y - 1), z);
      uint8_t *        row = image->planes[0] + std::ptrdiff_t(y) * image->stride[0];
      for (int32_t x = 0; x < width; ++x)
      {
        const uint16_t s = in[std::min(x, grid.x - 1)];
        if (depth > 8)
          reinterpret_cast<uint16_t *>(row)[x] = s;
        else
          row[x] = uint8_t(s);
      }
    }
    Check(c, aom_codec_encode(&c, image.get(), z, 1, 0), "slice " + std::to_string(z));
    Drain(c, stream);
  }
  // Flush: the frames the encoder still holds (its look-ahead).
  do
    Check(c, aom_codec_encode(&c, nullptr, 0, 1, 0), "flush");
  while (Drain(c, stream));
  return stream;
}

void
DecodeAV1Rows(const std::vector<uint8_t> & stream, const GridSize & grid, const std::string & name,
              const std::function<void(int32_t y, int32_t z, const int32_t * row)> & sink)
{
  auto fail = [&](const std::string & what) { return FormatError(name + ": invalid video layer (" + what + ")"); };
  if (stream.empty())
    throw fail("empty");
  Dav1dSettings settings;
  dav1d_default_settings(&settings);
  settings.n_threads = 1; // pictures in order, one at a time
  settings.max_frame_delay = 1;
  settings.apply_grain = 0;           // a stream with film grain is refused below
  settings.strict_std_compliance = 1; // anything the encoder did not write is refused
  settings.logger.callback = nullptr;
  // No picture larger than the slices padded as a writer pads them (a damaged size allocates nothing).
  settings.frame_size_limit = unsigned(
    std::min<uint64_t>(uint64_t(Padded(grid.x)) * uint64_t(Padded(grid.y)), std::numeric_limits<unsigned>::max()));
  Dav1dContext * raw = nullptr;
  if (dav1d_open(&raw, &settings) < 0)
    throw std::runtime_error(name + ": dav1d cannot open a decoder");
  std::unique_ptr<Dav1dContext, DecoderCloser> decoder(raw);
  Dav1dData                                    data{};
  // The stream outlives the decoding: wrapped, not copied.
  if (dav1d_data_wrap(
        &data, stream.data(), stream.size(), [](const uint8_t *, void *) {}, nullptr) < 0)
    throw std::runtime_error(name + ": dav1d cannot take the stream");
  std::vector<int32_t> out(std::size_t(grid.x));
  int32_t              z = 0;
  auto                 take = [&](Dav1dPicture & picture) {
    struct Unref
    {
      Dav1dPicture & p;
      ~Unref() { dav1d_picture_unref(&p); }
    } unref{ picture };
    if (z >= grid.z)
      throw fail("more pictures than the " + std::to_string(grid.z) + " slices");
    if (picture.p.layout != DAV1D_PIXEL_LAYOUT_I400)
      throw fail("not monochrome");
    if (picture.p.bpc != 8 && picture.p.bpc != 10 && picture.p.bpc != 12)
      throw fail(std::to_string(picture.p.bpc) + "-bit samples");
    if (picture.p.w < grid.x || picture.p.h < grid.y)
      throw fail("pictures smaller than the slices");
    if (picture.frame_hdr && picture.frame_hdr->film_grain.present)
      throw fail("film grain");
    SendSliceRows(
      static_cast<const uint8_t *>(picture.data[0]), picture.stride[0], picture.p.bpc > 8, grid, z, out, sink);
    ++z;
  };
  struct DataUnref
  {
    Dav1dData & d;
    ~DataUnref()
    {
      if (d.sz > 0)
        dav1d_data_unref(&d);
    }
  } dataUnref{ data };
  auto error = [&](int e) { return fail("dav1d error " + std::to_string(-e)); };
  while (data.sz > 0)
  {
    const int sent = dav1d_send_data(decoder.get(), &data);
    if (sent < 0 && sent != DAV1D_ERR(EAGAIN))
      throw error(sent);
    Dav1dPicture picture{};
    const int    got = dav1d_get_picture(decoder.get(), &picture);
    if (got == 0)
      take(picture);
    else if (got != DAV1D_ERR(EAGAIN))
      throw error(got);
    else if (sent == DAV1D_ERR(EAGAIN))
      throw fail("the decoder takes no more data"); // neither data taken nor a picture given
  }
  // The pictures still held.
  for (;;)
  {
    Dav1dPicture picture{};
    const int    got = dav1d_get_picture(decoder.get(), &picture);
    if (got == DAV1D_ERR(EAGAIN))
      break;
    if (got < 0)
      throw error(got);
    take(picture);
  }
  if (z != grid.z)
    throw fail(std::to_string(z) + " pictures for " + std::to_string(grid.z) + " slices");
}

std::string
AV1LibraryVersions()
{
  // libaom says "v3.6.0".
  std::string aom = aom_codec_version_str();
  if (!aom.empty() && aom[0] == 'v')
    aom.erase(0, 1);
  return "libaom " + aom + ", dav1d " + dav1d_version();
}

} // namespace dcv
