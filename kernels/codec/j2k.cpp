#include "kernels/codec/j2k.h"

#include <openjpeg.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge {
namespace {

/// Largest side and sample count decode_j2k accepts (2^28 samples: 1 GiB of OpenJPEG's int32 planes).
constexpr std::uint32_t kMaxSide = 65536;
constexpr std::uint64_t kMaxSamples = std::uint64_t{1} << 28;

/// OpenJPEG's messages of one codec, kept for the exception.
struct Messages {
  std::string text;
};
void collect(const char* msg, void* user) {
  auto* m = static_cast<Messages*>(user);
  std::string line(msg == nullptr ? "" : msg);
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
  if (line.empty()) return;
  if (!m->text.empty()) m->text += "; ";
  m->text += line;
}
void ignore(const char*, void*) {}

struct CodecDeleter {
  void operator()(opj_codec_t* c) const { opj_destroy_codec(c); }
};
struct StreamDeleter {
  void operator()(opj_stream_t* s) const { opj_stream_destroy(s); }
};
struct ImageDeleter {
  void operator()(opj_image_t* i) const { opj_image_destroy(i); }
};
using Codec = std::unique_ptr<opj_codec_t, CodecDeleter>;
using Stream = std::unique_ptr<opj_stream_t, StreamDeleter>;
using Image = std::unique_ptr<opj_image_t, ImageDeleter>;

/// A codec whose errors go to `messages` and whose warnings and information are dropped.
Codec quiet_codec(opj_codec_t* raw, Messages& messages) {
  Codec codec(raw);
  opj_set_error_handler(codec.get(), collect, &messages);
  opj_set_warning_handler(codec.get(), ignore, nullptr);
  opj_set_info_handler(codec.get(), ignore, nullptr);
  return codec;
}

/// A growing byte buffer as an OpenJPEG output stream.
struct Sink {
  std::vector<std::uint8_t> bytes;
  std::size_t pos{0};
};
OPJ_SIZE_T sink_write(void* buffer, OPJ_SIZE_T n, void* user) {
  auto* s = static_cast<Sink*>(user);
  if (s->pos + n > s->bytes.size()) s->bytes.resize(s->pos + n);
  std::memcpy(s->bytes.data() + s->pos, buffer, n);
  s->pos += n;
  return n;
}
OPJ_OFF_T sink_skip(OPJ_OFF_T n, void* user) {
  auto* s = static_cast<Sink*>(user);
  if (n < 0 && static_cast<std::size_t>(-n) > s->pos) return -1;
  s->pos = static_cast<std::size_t>(static_cast<OPJ_OFF_T>(s->pos) + n);
  if (s->pos > s->bytes.size()) s->bytes.resize(s->pos);
  return n;
}
OPJ_BOOL sink_seek(OPJ_OFF_T to, void* user) {
  auto* s = static_cast<Sink*>(user);
  if (to < 0) return OPJ_FALSE;
  s->pos = static_cast<std::size_t>(to);
  if (s->pos > s->bytes.size()) s->bytes.resize(s->pos);
  return OPJ_TRUE;
}

/// A byte span as an OpenJPEG input stream.
struct Source {
  std::span<const std::uint8_t> bytes;
  std::size_t pos{0};
};
OPJ_SIZE_T source_read(void* buffer, OPJ_SIZE_T n, void* user) {
  auto* s = static_cast<Source*>(user);
  if (s->pos >= s->bytes.size()) return static_cast<OPJ_SIZE_T>(-1);
  const std::size_t k = std::min<std::size_t>(n, s->bytes.size() - s->pos);
  std::memcpy(buffer, s->bytes.data() + s->pos, k);
  s->pos += k;
  return k;
}
OPJ_OFF_T source_skip(OPJ_OFF_T n, void* user) {
  auto* s = static_cast<Source*>(user);
  const auto to = std::clamp<OPJ_OFF_T>(static_cast<OPJ_OFF_T>(s->pos) + n, 0, static_cast<OPJ_OFF_T>(s->bytes.size()));
  const OPJ_OFF_T moved = to - static_cast<OPJ_OFF_T>(s->pos);
  s->pos = static_cast<std::size_t>(to);
  return moved;
}
OPJ_BOOL source_seek(OPJ_OFF_T to, void* user) {
  auto* s = static_cast<Source*>(user);
  if (to < 0 || static_cast<std::size_t>(to) > s->bytes.size()) return OPJ_FALSE;
  s->pos = static_cast<std::size_t>(to);
  return OPJ_TRUE;
}

/// Wavelet levels: 6, fewer for small images (each level halves the smaller side, which must stay >= 1).
int resolutions(std::uint32_t width, std::uint32_t height) {
  int r = 1;
  while (r < 6 && (std::min(width, height) >> r) >= 1) ++r;
  return r;
}

/// `codestream` without the comment segments (COM, 0xFF64) of its main header. OpenJPEG always writes one
/// ("Created by OpenJPEG version ...", 39 bytes); a decoder ignores it, and at a few hundred bytes a
/// codestream it is a tenth of the budget. Anything unexpected in the main header leaves the codestream as is.
std::vector<std::uint8_t> without_comments(std::vector<std::uint8_t> codestream) {
  const auto marker = [&](std::size_t at) { return (unsigned{codestream[at]} << 8) | codestream[at + 1]; };
  if (codestream.size() < 4 || marker(0) != 0xFF4F) return codestream;  // SOC
  std::vector<std::uint8_t> out(codestream.begin(), codestream.begin() + 2);
  std::size_t at = 2;
  while (at + 4 <= codestream.size()) {
    const unsigned m = marker(at);
    if (m == 0xFF90) {  // SOT: the main header ends
      out.insert(out.end(), codestream.begin() + static_cast<std::ptrdiff_t>(at), codestream.end());
      return out;
    }
    if ((m & 0xFF00) != 0xFF00) return codestream;
    const std::size_t length = marker(at + 2);
    if (length < 2 || at + 2 + length > codestream.size()) return codestream;
    if (m != 0xFF64)
      out.insert(out.end(), codestream.begin() + static_cast<std::ptrdiff_t>(at),
                 codestream.begin() + static_cast<std::ptrdiff_t>(at + 2 + length));
    at += 2 + length;
  }
  return codestream;
}

/// The length of a codestream's main header (the offset of its first SOT marker), 0 when it cannot be walked.
std::size_t main_header_length(std::span<const std::uint8_t> codestream) {
  const auto marker = [&](std::size_t at) { return (unsigned{codestream[at]} << 8) | codestream[at + 1]; };
  if (codestream.size() < 4 || marker(0) != 0xFF4F) return 0;  // SOC
  std::size_t at = 2;
  while (at + 4 <= codestream.size()) {
    const unsigned m = marker(at);
    if (m == 0xFF90) return at;  // SOT
    if ((m & 0xFF00) != 0xFF00) return 0;
    const std::size_t length = marker(at + 2);
    if (length < 2) return 0;
    at += 2 + length;
  }
  return 0;
}

/// `header` (a main header: SOC, then SIZ as the standard requires) with its image and tile sizes (Xsiz, Ysiz,
/// XTsiz, YTsiz; the origins stay 0) set to width × height; empty when it does not start so.
std::vector<std::uint8_t> resized_header(std::span<const std::uint8_t> header, std::uint32_t width, std::uint32_t height) {
  constexpr std::size_t kSizEnd = 40;  // SOC, SIZ marker and length, Rsiz, the eight 32-bit sizes and origins
  if (header.size() < kSizEnd || header[0] != 0xFF || header[1] != 0x4F || header[2] != 0xFF || header[3] != 0x51) return {};
  std::vector<std::uint8_t> out(header.begin(), header.end());
  const auto put = [&](std::size_t at, std::uint32_t v) {
    for (std::size_t b = 0; b < 4; ++b) out[at + b] = static_cast<std::uint8_t>(v >> (8 * (3 - b)));
  };
  put(8, width), put(12, height), put(24, width), put(28, height);
  return out;
}

std::vector<std::uint8_t> encode_once(const Planes16& planes, std::size_t target_bytes, bool reversible, int levels) {
  opj_cparameters_t p;
  opj_set_default_encoder_parameters(&p);
  p.tcp_numlayers = 1;
  p.cp_disto_alloc = 1;
  const double raw = 2.0 * planes.width * planes.height * planes.components;
  p.tcp_rates[0] = target_bytes == 0 ? 0.0f : static_cast<float>(std::max(1.0, raw / static_cast<double>(target_bytes)));
  p.irreversible = target_bytes != 0 && !reversible ? 1 : 0;
  p.tcp_mct = 0;
  p.numresolution = levels > 0 ? std::min(levels, resolutions(planes.width, planes.height)) : resolutions(planes.width, planes.height);
  std::vector<opj_image_cmptparm_t> parms(planes.components);
  for (opj_image_cmptparm_t& c : parms) {
    std::memset(&c, 0, sizeof c);
    c.dx = c.dy = 1;
    c.w = planes.width;
    c.h = planes.height;
    c.prec = 16;
    c.sgnd = 0;
  }
  Image image(opj_image_create(planes.components, parms.data(), OPJ_CLRSPC_UNSPECIFIED));
  if (!image) throw NumericalError("JPEG 2000: OpenJPEG could not allocate the image");
  image->x0 = image->y0 = 0;
  image->x1 = planes.width;
  image->y1 = planes.height;
  const std::size_t plane = std::size_t{planes.width} * planes.height;
  for (std::uint32_t c = 0; c < planes.components; ++c)
    for (std::size_t i = 0; i < plane; ++i) image->comps[c].data[i] = planes.samples[c * plane + i];
  Messages messages;
  const Codec codec = quiet_codec(opj_create_compress(OPJ_CODEC_J2K), messages);
  Sink sink;
  Stream stream(opj_stream_create(OPJ_J2K_STREAM_CHUNK_SIZE, OPJ_FALSE));
  opj_stream_set_user_data(stream.get(), &sink, nullptr);
  opj_stream_set_write_function(stream.get(), sink_write);
  opj_stream_set_skip_function(stream.get(), sink_skip);
  opj_stream_set_seek_function(stream.get(), sink_seek);
  if (!opj_setup_encoder(codec.get(), &p, image.get()) || !opj_start_compress(codec.get(), image.get(), stream.get()) ||
      !opj_encode(codec.get(), stream.get()) || !opj_end_compress(codec.get(), stream.get()))
    throw NumericalError(fmt::format("JPEG 2000: OpenJPEG could not encode a {} × {} × {} image: {}", planes.width,
                                     planes.height, planes.components, messages.text));
  return without_comments(std::move(sink.bytes));
}

void check_planes(const Planes16& planes) {
  if (planes.width < 2 || planes.height < 2 || planes.components == 0 ||
      planes.samples.size() != std::size_t{planes.width} * planes.height * planes.components)
    throw InvalidInput(fmt::format("JPEG 2000: {} samples for {} planes of {} × {} (each side at least 2)",
                                   planes.samples.size(), planes.components, planes.width, planes.height));
}

/// The window [x0, x1) × [y0, y1) of every plane.
Planes16 window_of(const Planes16& p, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1) {
  Planes16 w{x1 - x0, y1 - y0, p.components, {}};
  w.samples.reserve(std::size_t{w.width} * w.height * w.components);
  for (std::uint32_t c = 0; c < p.components; ++c)
    for (std::uint32_t y = y0; y < y1; ++y)
      for (std::uint32_t x = x0; x < x1; ++x) w.samples.push_back(p.samples[(std::size_t{c} * p.height + y) * p.width + x]);
  return w;
}

/// `p` with the window [x0, x1) × [y0, y1) filled smoothly from its surroundings by push–pull (a pyramid of
/// weighted 2 × 2 means of the known pixels, then each level's unknown pixels taken bilinearly from the
/// coarser one): the whole image's codestream then spends next to nothing on what the window's codestream
/// codes. O(pixels). A window covering the whole image is left as it is (nothing around it to fill from).
Planes16 fill_window(Planes16 p, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1) {
  if (x0 == 0 && y0 == 0 && x1 == p.width && y1 == p.height) return p;
  struct Level {
    std::uint32_t w, h;
    std::vector<double> v, k;  // value (weighted mean) and weight (1: known)
  };
  for (std::uint32_t c = 0; c < p.components; ++c) {
    std::vector<Level> pyramid(1);
    {
      Level& base = pyramid[0];  // (a reference only until the pyramid grows)
      base.w = p.width, base.h = p.height;
      base.v.resize(std::size_t{base.w} * base.h), base.k.resize(base.v.size());
      for (std::uint32_t y = 0; y < base.h; ++y)
        for (std::uint32_t x = 0; x < base.w; ++x) {
          const std::size_t i = std::size_t{y} * base.w + x;
          base.v[i] = p.samples[std::size_t{c} * base.v.size() + i];
          base.k[i] = (x >= x0 && x < x1 && y >= y0 && y < y1) ? 0.0 : 1.0;
        }
    }
    // Push: halve until one pixel.
    while (pyramid.back().w > 1 || pyramid.back().h > 1) {
      const Level& f = pyramid.back();
      Level coarse{(f.w + 1) / 2, (f.h + 1) / 2, {}, {}};
      coarse.v.assign(std::size_t{coarse.w} * coarse.h, 0.0), coarse.k.assign(coarse.v.size(), 0.0);
      for (std::uint32_t y = 0; y < f.h; ++y)
        for (std::uint32_t x = 0; x < f.w; ++x) {
          const std::size_t i = std::size_t{y} * f.w + x, o = std::size_t{y / 2} * coarse.w + x / 2;
          coarse.v[o] += f.k[i] * f.v[i];
          coarse.k[o] += f.k[i];
        }
      for (std::size_t o = 0; o < coarse.v.size(); ++o) {
        if (coarse.k[o] > 0.0) coarse.v[o] /= coarse.k[o];
        coarse.k[o] = std::min(1.0, coarse.k[o]);
      }
      pyramid.push_back(std::move(coarse));
    }
    // Pull: each finer level's unknown part from the coarser level, bilinearly.
    for (std::size_t l = pyramid.size() - 1; l-- > 0;) {
      Level& f = pyramid[l];
      const Level& g = pyramid[l + 1];
      for (std::uint32_t y = 0; y < f.h; ++y)
        for (std::uint32_t x = 0; x < f.w; ++x) {
          const std::size_t i = std::size_t{y} * f.w + x;
          if (f.k[i] >= 1.0) continue;
          const double gx = std::clamp((x + 0.5) / 2.0 - 0.5, 0.0, g.w - 1.0), gy = std::clamp((y + 0.5) / 2.0 - 0.5, 0.0, g.h - 1.0);
          const auto ix = std::min(static_cast<std::uint32_t>(gx), g.w > 1 ? g.w - 2 : 0);
          const auto iy = std::min(static_cast<std::uint32_t>(gy), g.h > 1 ? g.h - 2 : 0);
          const double fx = g.w > 1 ? gx - ix : 0.0, fy = g.h > 1 ? gy - iy : 0.0;
          const auto at = [&](std::uint32_t a, std::uint32_t b) { return g.v[std::size_t{std::min(b, g.h - 1)} * g.w + std::min(a, g.w - 1)]; };
          const double up = (1 - fy) * ((1 - fx) * at(ix, iy) + fx * at(ix + 1, iy)) + fy * ((1 - fx) * at(ix, iy + 1) + fx * at(ix + 1, iy + 1));
          f.v[i] = f.k[i] * f.v[i] + (1.0 - f.k[i]) * up;
        }
    }
    const Level& base = pyramid[0];
    for (std::uint32_t y = y0; y < y1; ++y)
      for (std::uint32_t x = x0; x < x1; ++x) {
        const std::size_t i = std::size_t{y} * base.w + x;
        p.samples[std::size_t{c} * base.v.size() + i] = static_cast<std::uint16_t>(std::clamp(std::round(base.v[i]), 0.0, 65535.0));
      }
  }
  return p;
}

}  // namespace

Planes16 quantize_positions(std::span<const float> xyz, std::uint32_t width, std::uint32_t height,
                            Quantization& quantization) {
  const std::size_t pixels = std::size_t{width} * height;
  if (xyz.size() != 3 * pixels) throw InvalidInput(fmt::format("quantization: {} values for {} × {} positions", xyz.size(), width, height));
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (std::size_t p = 0; p < pixels; ++p) {
    const Vec3 v(xyz[3 * p], xyz[3 * p + 1], xyz[3 * p + 2]);
    if (!v.allFinite()) throw InvalidInput(fmt::format("quantization: position {} is not finite", p));
    lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
  }
  const double extent = pixels == 0 ? 0.0 : (hi - lo).maxCoeff();
  quantization.offset = pixels == 0 ? Vec3::Zero() : lo;
  quantization.scale = extent > 0.0 ? extent / 65535.0 : 1.0;
  Planes16 planes{width, height, 3, std::vector<std::uint16_t>(3 * pixels)};
  for (std::size_t p = 0; p < pixels; ++p)
    for (std::size_t c = 0; c < 3; ++c) {
      const double q = std::round((double{xyz[3 * p + c]} - quantization.offset[static_cast<Eigen::Index>(c)]) / quantization.scale);
      planes.samples[c * pixels + p] = static_cast<std::uint16_t>(std::clamp(q, 0.0, 65535.0));
    }
  return planes;
}

std::vector<float> dequantize_positions(const Planes16& planes, const Quantization& quantization) {
  const std::size_t pixels = std::size_t{planes.width} * planes.height;
  if (planes.components != 3 || planes.samples.size() != 3 * pixels)
    throw InvalidInput(fmt::format("dequantization: {} planes of {} samples, not three positions", planes.components, pixels));
  std::vector<float> xyz(3 * pixels);
  for (std::size_t p = 0; p < pixels; ++p)
    for (std::size_t c = 0; c < 3; ++c)
      xyz[3 * p + c] = static_cast<float>(quantization.offset[static_cast<Eigen::Index>(c)] +
                                          quantization.scale * planes.samples[c * pixels + p]);
  return xyz;
}

std::vector<std::uint8_t> encode_j2k(const Planes16& planes, const J2kOptions& options) {
  check_planes(planes);
  if (options.target_bytes == 0) return encode_once(planes, 0, true, options.resolutions);
  // OpenJPEG's rate allocation aims at the target from below but headers can push it over: aim lower. Its
  // comment segment, counted by the allocation and then removed (without_comments), is given back first.
  constexpr std::size_t kComment = 39;
  std::size_t target = options.target_bytes + kComment;
  for (int attempt = 0;; ++attempt) {
    std::vector<std::uint8_t> out = encode_once(planes, target, options.reversible, options.resolutions);
    if (out.size() <= options.target_bytes || attempt == 8) return out;
    const double shrink = 0.97 * static_cast<double>(options.target_bytes) / static_cast<double>(out.size());
    target = std::max<std::size_t>(1, static_cast<std::size_t>(static_cast<double>(target) * shrink));
  }
}

Planes16 decode_j2k(std::span<const std::uint8_t> codestream, std::uint32_t expected_width,
                    std::uint32_t expected_height, std::uint32_t expected_components) {
  Messages messages;
  const Codec codec = quiet_codec(opj_create_decompress(OPJ_CODEC_J2K), messages);
  opj_dparameters_t p;
  opj_set_default_decoder_parameters(&p);
  Source source{codestream, 0};
  Stream stream(opj_stream_create(OPJ_J2K_STREAM_CHUNK_SIZE, OPJ_TRUE));
  opj_stream_set_user_data(stream.get(), &source, nullptr);
  opj_stream_set_user_data_length(stream.get(), codestream.size());
  opj_stream_set_read_function(stream.get(), source_read);
  opj_stream_set_skip_function(stream.get(), source_skip);
  opj_stream_set_seek_function(stream.get(), source_seek);
  opj_image_t* raw = nullptr;
  const auto fail = [&](const std::string& why) {
    return FormatError(fmt::format("JPEG 2000 codestream of {} bytes: {}", codestream.size(), why));
  };
  if (!opj_setup_decoder(codec.get(), &p) || !opj_decoder_set_strict_mode(codec.get(), OPJ_TRUE) ||
      !opj_read_header(stream.get(), codec.get(), &raw))
    throw fail(messages.text.empty() ? "not a J2K codestream" : messages.text);
  Image image(raw);
  const std::uint32_t width = image->x1 - image->x0, height = image->y1 - image->y0;
  if (image->numcomps == 0 || width < 2 || height < 2 || width > kMaxSide || height > kMaxSide ||
      std::uint64_t{width} * height * image->numcomps > kMaxSamples)
    throw fail(fmt::format("{} components of {} × {} (expected 16-bit planes, sides 2..{})", image->numcomps, width,
                           height, kMaxSide));
  if ((expected_width != 0 && width != expected_width) || (expected_height != 0 && height != expected_height))
    throw fail(fmt::format("a {} × {} image, expected {} × {}", width, height, expected_width, expected_height));
  if (expected_components != 0 && image->numcomps != expected_components)
    throw fail(fmt::format("{} components, expected {}", image->numcomps, expected_components));
  // One tile, as encode_once writes: OpenJPEG fills a declared tile that the stream does not carry with
  // zeros and reports success, so a SIZ of many small tiles over a one-tile stream decodes "fine".
  {
    opj_codestream_info_v2_t* info = opj_get_cstr_info(codec.get());
    const std::uint64_t tiles = info == nullptr ? 0 : std::uint64_t{info->tw} * info->th;
    opj_destroy_cstr_info(&info);
    if (tiles != 1) throw fail(fmt::format("{} tiles (gimforge writes and reads one)", tiles));
  }
  for (std::uint32_t c = 0; c < image->numcomps; ++c) {
    const opj_image_comp_t& comp = image->comps[c];
    if (comp.prec != 16 || comp.sgnd != 0 || comp.dx != 1 || comp.dy != 1)
      throw fail(fmt::format("component {} is {}{}-bit, subsampled {} × {} (expected unsigned 16-bit, full size)", c,
                             comp.sgnd ? "signed " : "", comp.prec, comp.dx, comp.dy));
  }
  if (!opj_decode(codec.get(), stream.get(), image.get()) || !opj_end_decompress(codec.get(), stream.get()))
    throw fail(messages.text.empty() ? "damaged" : messages.text);
  Planes16 out{width, height, image->numcomps, {}};
  const std::size_t plane = std::size_t{width} * height;
  out.samples.resize(plane * image->numcomps);
  for (std::uint32_t c = 0; c < image->numcomps; ++c) {
    const opj_image_comp_t& comp = image->comps[c];
    if (comp.data == nullptr || comp.w != width || comp.h != height) throw fail(fmt::format("component {} was not decoded whole", c));
    for (std::size_t i = 0; i < plane; ++i) out.samples[c * plane + i] = static_cast<std::uint16_t>(std::clamp(comp.data[i], 0, 65535));
  }
  return out;
}

RoiCoded encode_roi_priority(const Planes16& planes, std::span<const std::uint8_t> roi, std::size_t budget,
                             double background_floor) {
  check_planes(planes);
  if (roi.size() != std::size_t{planes.width} * planes.height)
    throw InvalidInput(fmt::format("ROI coding: {} flags for {} × {} pixels", roi.size(), planes.width, planes.height));
  if (!(background_floor > 0.0 && background_floor < 1.0))
    throw InvalidInput(fmt::format("ROI coding: background floor {} is outside (0, 1)", background_floor));
  std::uint32_t x0 = planes.width, y0 = planes.height, x1 = 0, y1 = 0;
  for (std::uint32_t y = 0; y < planes.height; ++y)
    for (std::uint32_t x = 0; x < planes.width; ++x)
      if (roi[std::size_t{y} * planes.width + x]) x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x + 1), y1 = std::max(y1, y + 1);
  if (x1 == 0) throw InvalidInput("ROI coding: the region of interest holds no pixel");
  // At least 2 × 2 (OpenJPEG's smallest useful image), inside the image.
  if (x1 - x0 < 2) x0 = std::min(x0, planes.width - 2), x1 = x0 + 2;
  if (y1 - y0 < 2) y0 = std::min(y0, planes.height - 2), y1 = y0 + 2;
  if (budget < kRoiLeastBudget)
    throw InvalidInput(fmt::format("ROI coding: a budget of {} bytes cannot hold two codestreams (at least {})", budget, kRoiLeastBudget));
  constexpr std::size_t kSmallest = kRoiLeastBudget / 2;  // the least a codestream is asked for
  RoiCoded out;
  out.x0 = x0, out.y0 = y0, out.width = x1 - x0, out.height = y1 - y0;
  out.image_width = planes.width, out.image_height = planes.height;
  const Planes16 window = window_of(planes, x0, y0, x1, y1);
  const Planes16 rest = fill_window(planes, x0, y0, x1, y1);
  // With as many wavelet levels as each other, the two codestreams' main headers differ in the SIZ sizes
  // alone (unless the window is coded losslessly, with the 5/3 wavelet), and the payload stores one of them.
  // A window too small or thin for the image's levels is not worth them: the image keeps its own levels.
  const int window_levels = resolutions(window.width, window.height);
  const int image_levels = resolutions(planes.width, planes.height);
  const std::vector<std::uint8_t> lossless = encode_j2k(window, {0, false, window_levels});  // all of the ROI's bits
  const auto shares = [&](std::size_t header) {
    if (main_header_length(out.background) != header) return false;
    const std::vector<std::uint8_t> rebuilt = resized_header(std::span(out.window).first(header), planes.width, planes.height);
    return rebuilt.size() == header && std::equal(rebuilt.begin(), rebuilt.end(), out.background.begin());
  };
  // The whole image's codestream has a smallest size (headers, its coarsest levels): when it overshoots
  // what the window left, the window gives the excess back. First with the image's main header shared (the
  // image's codestream may take that many more bytes), then, when it could not be, stored whole.
  for (const bool share : {true, false}) {
    if (share && window_levels != image_levels) continue;
    auto window_budget = std::max(kSmallest, static_cast<std::size_t>((1.0 - background_floor) * static_cast<double>(budget)));
    for (int attempt = 0;; ++attempt) {
      const bool whole = lossless.size() <= window_budget;
      out.window = whole ? lossless : encode_j2k(window, {window_budget, false, window_levels});
      // The window's main header is as long as the image's will be (same planes, wavelet and levels).
      const std::size_t allowance = share ? main_header_length(out.window) : 0;
      if (share && (whole || allowance == 0)) break;  // a lossless window's header is not the image's
      const std::size_t total = budget + allowance;
      constexpr std::size_t kLeast = 64;  // a target the whole image's codestream is asked for at least
      out.background.clear();
      out.shared_header = 0;
      if (out.window.size() + kLeast <= total) {
        out.background = encode_j2k(rest, {total - out.window.size(), false, image_levels});
        if (out.window.size() + out.background.size() <= total) {
          if (!share) return out;
          if (shares(allowance)) {
            out.shared_header = allowance;
            return out;
          }
          break;  // the headers differ after all: store both whole
        }
      }
      const std::size_t excess = out.window.size() + std::max(out.background.size(), kLeast) - total + 16;
      const std::size_t shrinkable = std::min(window_budget, out.window.size());
      if (attempt == 8 || shrinkable < kSmallest + excess) {
        if (share) break;
        throw InvalidInput(fmt::format("ROI coding: {} bytes do not hold the window and the image ({} bytes at least)",
                                       budget, out.window.size() + std::max(out.background.size(), kLeast)));
      }
      window_budget = shrinkable - excess;
    }
  }
  throw InvalidInput(fmt::format("ROI coding: {} bytes do not hold the window and the image", budget));
}

namespace {

/// Pastes `window` into `image` at (x0, y0) after checking that it fits.
void paste_window(Planes16& image, const Planes16& window, std::uint32_t x0, std::uint32_t y0) {
  if (window.components != image.components || window.width > image.width || window.height > image.height ||
      x0 > image.width - window.width || y0 > image.height - window.height)
    throw FormatError(fmt::format("ROI coding: a {} × {} window at ({}, {}) does not fit the {} × {} image", window.width,
                                  window.height, x0, y0, image.width, image.height));
  for (std::uint32_t c = 0; c < image.components; ++c)
    for (std::uint32_t y = 0; y < window.height; ++y)
      for (std::uint32_t x = 0; x < window.width; ++x)
        image.samples[(std::size_t{c} * image.height + y0 + y) * image.width + x0 + x] =
            window.samples[(std::size_t{c} * window.height + y) * window.width + x];
}

void put_u32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int b = 0; b < 4; ++b) out.push_back(static_cast<std::uint8_t>(v >> (8 * b)));
}
std::uint32_t get_u32(std::span<const std::uint8_t> in, std::size_t at) {
  std::uint32_t v = 0;
  for (int b = 0; b < 4; ++b) v |= std::uint32_t{in[at + static_cast<std::size_t>(b)]} << (8 * b);
  return v;
}
constexpr std::array<std::uint8_t, 4> kLegacyMagic{'R', 'O', 'I', '1'};  // 24-byte header, both codestreams whole
constexpr std::array<std::uint8_t, 4> kRoiMagic{'R', 'O', 'I', '2'};
constexpr std::size_t kLegacyHeader = 24;

/// The header of a ROI-first payload, or nullopt with the reason when it is short, foreign, of another image
/// size, or describes a window outside a width × height image or codestreams that do not split the payload.
struct RoiHeader {
  std::uint32_t x0, y0, w, h, window_bytes;
  std::size_t bytes;  ///< the header's own: 32, or 24 for "ROI1"
};
std::optional<RoiHeader> parse_roi_header(std::span<const std::uint8_t> payload, std::uint32_t width,
                                          std::uint32_t height, std::string& why) {
  const auto starts = [&](const std::array<std::uint8_t, 4>& magic, std::size_t bytes) {
    return payload.size() >= bytes && std::equal(magic.begin(), magic.end(), payload.begin());
  };
  const bool legacy = starts(kLegacyMagic, kLegacyHeader);
  if (!legacy && !starts(kRoiMagic, kRoiPayloadHeader)) {
    why = "it does not start with the 32-byte \"ROI2\" header (or the 24-byte \"ROI1\" one)";
    return std::nullopt;
  }
  const RoiHeader r{get_u32(payload, 4),  get_u32(payload, 8),  get_u32(payload, 12),
                    get_u32(payload, 16), get_u32(payload, 20), legacy ? kLegacyHeader : kRoiPayloadHeader};
  if (!legacy && (get_u32(payload, 24) != width || get_u32(payload, 28) != height)) {
    why = fmt::format("it codes a {} × {} image, expected {} × {}", get_u32(payload, 24), get_u32(payload, 28), width, height);
    return std::nullopt;
  }
  if (r.w < 2 || r.h < 2 || r.w > width || r.h > height || r.x0 > width - r.w || r.y0 > height - r.h) {
    why = fmt::format("a {} × {} window at ({}, {}) does not fit the {} × {} image", r.w, r.h, r.x0, r.y0, width, height);
    return std::nullopt;
  }
  if (r.window_bytes == 0 || r.window_bytes >= payload.size() - r.bytes) {
    why = fmt::format("the window's codestream of {} bytes leaves nothing of {} for the image's", r.window_bytes,
                      payload.size() - r.bytes);
    return std::nullopt;
  }
  return r;
}

}  // namespace

std::vector<std::uint8_t> roi_payload(const RoiCoded& coded) {
  std::vector<std::uint8_t> out(kRoiMagic.begin(), kRoiMagic.end());
  out.reserve(kRoiPayloadHeader + coded.bytes());
  for (const std::uint32_t v : {coded.x0, coded.y0, coded.width, coded.height, static_cast<std::uint32_t>(coded.window.size()),
                                coded.image_width, coded.image_height})
    put_u32(out, v);
  out.insert(out.end(), coded.window.begin(), coded.window.end());
  const std::size_t shared = std::min(coded.shared_header, coded.background.size());
  out.insert(out.end(), coded.background.begin() + static_cast<std::ptrdiff_t>(shared), coded.background.end());
  return out;
}

std::vector<std::uint8_t> roi_payload_window(std::span<const std::uint8_t> payload, std::uint32_t width,
                                             std::uint32_t height) {
  std::string why;
  const std::optional<RoiHeader> r = parse_roi_header(payload, width, height, why);
  if (!r) return {};
  std::vector<std::uint8_t> flags(std::size_t{width} * height, 0);
  for (std::uint32_t y = r->y0; y < r->y0 + r->h; ++y)
    std::fill_n(flags.begin() + static_cast<std::ptrdiff_t>(std::size_t{y} * width + r->x0), r->w, 1);
  return flags;
}

Planes16 decode_roi_payload(std::span<const std::uint8_t> payload, std::uint32_t width, std::uint32_t height,
                            std::uint32_t components) {
  const auto fail = [&](const std::string& why) {
    return FormatError(fmt::format("ROI-first JPEG 2000 payload of {} bytes: {}", payload.size(), why));
  };
  std::string why;
  const std::optional<RoiHeader> header = parse_roi_header(payload, width, height, why);
  if (!header) throw fail(why);
  const auto [x0, y0, w, h, window_bytes, header_bytes] = *header;
  const auto window_stream = payload.subspan(header_bytes, window_bytes);
  std::span<const std::uint8_t> image_stream = payload.subspan(header_bytes + window_bytes);
  std::vector<std::uint8_t> rebuilt;  // starting at SOT: the window's main header at the image's size, then it
  if (header_bytes != kLegacyHeader && image_stream.size() >= 2 && image_stream[0] == 0xFF && image_stream[1] == 0x90) {
    const std::size_t length = main_header_length(window_stream);
    rebuilt = length == 0 ? std::vector<std::uint8_t>{} : resized_header(window_stream.first(length), width, height);
    if (rebuilt.empty()) throw fail("the window's codestream has no main header to share");
    rebuilt.insert(rebuilt.end(), image_stream.begin(), image_stream.end());
    image_stream = rebuilt;
  }
  const auto decode = [&](std::span<const std::uint8_t> stream, std::uint32_t sw, std::uint32_t sh, std::string_view which) {
    try {
      return decode_j2k(stream, sw, sh, components);
    } catch (const FormatError& e) {
      throw fail(fmt::format("the {} codestream: {}", which, e.what()));
    }
  };
  Planes16 image = decode(image_stream, width, height, "image's");
  const Planes16 window = decode(window_stream, w, h, "window's");
  if (image.components != components || window.components != components)
    throw fail(fmt::format("{} and {} components, expected {}", window.components, image.components, components));
  paste_window(image, window, x0, y0);
  return image;
}

Planes16 decode_roi_priority(const RoiCoded& coded) {
  Planes16 image = decode_j2k(coded.background);  // whole in memory, shared or not
  const Planes16 window = decode_j2k(coded.window);
  paste_window(image, window, coded.x0, coded.y0);
  return image;
}

}  // namespace gimforge
