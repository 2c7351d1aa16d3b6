#include "kernels/codec/wavelet_coder.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>

#include <fmt/format.h>

#include "kernels/codec/geometry_codec.h"
#include "kernels/codec/range_coder.h"
#include "kernels/core/errors.h"
#include "kernels/core/hash.h"

namespace gimforge {
namespace {

constexpr std::array<char, 4> kMagic{'G', 'F', 'W', 'V'};
constexpr std::uint8_t kVersion = 1;
constexpr std::size_t kHeaderBytes = 21;
constexpr std::uint32_t kUnary = 14;       // magnitudes 1..15 in unary with their own models, then Exp-Golomb
constexpr std::uint32_t kMaxEscapeBits = 40;
constexpr double kDeadZone = 0.3;          // q = floor(|c|/step + 0.3): a zero bin of ±0.7 steps
constexpr double kReconstructionBias = 0.1;  // |c'| = (|q| + 0.1)·step: towards the Laplacian bin centroid

/// The adaptive models. Zero flag: component class (tangential / normal) × orientation × level class ×
/// significant causal neighbours (left, up, up-left, up-right: 0, 1, 2, 3+) × parent (zero, significant,
/// none) × the previous component of the same coefficient (zero, significant). Magnitude: component
/// class × level class × neighbourhood magnitude class × unary position.
struct Contexts {
  std::array<rc::BitModel, 2 * 3 * 4 * 4 * 3 * 2> zero{};
  std::array<rc::BitModel, 2 * 4 * 3 * (kUnary + 1)> magnitude{};
  std::array<rc::BitModel, kMaxEscapeBits + 1> escape{};
};

struct EncodeBits {
  rc::RangeEncoder coder;
  void check_row() const {}
  unsigned bit(rc::BitModel& m, bool b) {
    coder.encode(m, b ? 1u : 0u);
    return b ? 1u : 0u;
  }
  unsigned direct(bool b) {
    coder.encode_direct(b ? 1u : 0u);
    return b ? 1u : 0u;
  }
};

struct DecodeBits {
  rc::RangeDecoder coder;
  unsigned bit(rc::BitModel& m, bool) { return coder.decode(m); }
  unsigned direct(bool) { return coder.decode_direct(); }
  /// A payload that ends early is refused at once, not after decoding a whole image of zeros.
  void check_row() const {
    if (coder.overrun() > 4) throw FormatError("wavelet payload: truncated (the coder ran past the coded bytes)");
  }
};

/// Codes one signed integer (encoding: `q`; decoding: `q` is ignored and the decoded value returned).
template <class Bits>
std::int64_t code_value(Bits& bits, Contexts& ctx, std::size_t zero_ctx, std::size_t mag_ctx, std::int64_t q) {
  if (bits.bit(ctx.zero[zero_ctx], q != 0) == 0) return 0;
  const bool negative = bits.direct(q < 0) != 0;
  const std::uint64_t magnitude = q < 0 ? static_cast<std::uint64_t>(-q) - 1 : static_cast<std::uint64_t>(q) - 1;
  std::uint64_t m = 0;
  while (m < kUnary && bits.bit(ctx.magnitude[mag_ctx * (kUnary + 1) + m], magnitude > m) != 0) ++m;
  if (m == kUnary) {  // Exp-Golomb of magnitude − kUnary: (bits − 1) ones, a zero, then the bits below the top one
    const std::uint64_t v1 = magnitude >= kUnary ? magnitude - kUnary + 1 : 1;
    const auto width = static_cast<std::uint32_t>(std::bit_width(v1));
    std::uint32_t k = 0;
    while (bits.bit(ctx.escape[std::min(k, kMaxEscapeBits)], k + 1 < width) != 0)
      if (++k > kMaxEscapeBits) throw FormatError("wavelet payload: coefficient out of range (damaged payload)");
    std::uint64_t r = 1;
    for (std::uint32_t i = k; i-- > 0;) r = (r << 1) | bits.direct(((v1 >> i) & 1u) != 0);
    m = kUnary + r - 1;
  }
  const auto value = static_cast<std::int64_t>(m + 1);
  return negative ? -value : value;
}

/// The largest magnitude the coder writes (kUnary + an Exp-Golomb value of at most kMaxEscapeBits bits).
constexpr double kMaxMagnitude = 1099511627775.0;  // 2^40 − 1

std::int64_t quantize(double c, double step) {
  const double q = std::floor(std::abs(c) / step + kDeadZone);
  const auto v = static_cast<std::int64_t>(std::min(q, kMaxMagnitude));
  return c < 0 ? -v : v;
}
double dequantize(std::int64_t q, double step) {
  if (q == 0) return 0.0;
  const double magnitude = (static_cast<double>(q < 0 ? -q : q) + kReconstructionBias) * step;
  return q < 0 ? -magnitude : magnitude;
}

/// The local frame of a detail at (x, y) of the level-ℓ lattice from the low-pass surface (the samples at
/// stride 2s: a lattice of side n2 + 1, coordinates halved): tangents by differences across the sample, the normal their cross
/// product; the identity where the surface is degenerate.
std::array<Vec3, 3> frame_at(const std::vector<Vec3>& D, std::size_t side, std::size_t s2, std::int64_t n2,
                             LatticeExtension ext, std::int64_t x, std::int64_t y) {
  const auto low = [&](std::int64_t X, std::int64_t Y) -> const Vec3& {
    const LatticePoint p = extend_lattice(X, Y, n2, ext);
    return D[static_cast<std::size_t>(p.y) * s2 * side + static_cast<std::size_t>(p.x) * s2];
  };
  const std::int64_t x0 = x >> 1, x1 = (x + 1) >> 1, y0 = y >> 1, y1 = (y + 1) >> 1;
  const std::int64_t xa = x0 == x1 ? x0 - 1 : x0, xb = x0 == x1 ? x0 + 1 : x1;
  const std::int64_t ya = y0 == y1 ? y0 - 1 : y0, yb = y0 == y1 ? y0 + 1 : y1;
  const Vec3 tu = (low(xb, y0) - low(xa, y0)) + (low(xb, y1) - low(xa, y1));
  const Vec3 tv = (low(x0, yb) - low(x0, ya)) + (low(x1, yb) - low(x1, ya));
  const Vec3 n = tu.cross(tv);
  const double nn = n.norm(), tn = tu.norm();
  if (!(nn > 1e-12 * tn * tv.norm()) || !(tn > 0.0) || !std::isfinite(nn))
    return {Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  const Vec3 normal = n / nn;
  const Vec3 t1 = tu / tn;
  return {t1, normal.cross(t1), normal};
}

struct LoopSetup {
  std::uint32_t side{0};
  std::uint32_t levels{0};
  LatticeExtension extension{LatticeExtension::Mirror};
  double step{0.0};
  bool frames{true};
  std::uint8_t normal_weight{3};
};

/// The closed loop shared by encoder and decoder: coarse to fine, quantize (encoder) or read (decoder) the
/// coefficients of a level, dequantize them into D in world axes, symmetrize, invert the level. `coeffs` is
/// the forward transform of the input (encoder only). D ends as the decoded image.
template <class Bits>
void run_loop(Bits& bits, const LoopSetup& setup, std::span<const Vec3> coeffs, std::vector<Vec3>& D) {
  const std::size_t side = setup.side;
  const bool encoding = !coeffs.empty();
  const BandNorms norms = band_norms(setup.levels);
  D.assign(side * side, Vec3::Zero());
  std::vector<std::uint8_t> Q(side * side * 3, 0);  // capped magnitudes, for the contexts
  Contexts ctx, low_ctx;

  // The coarsest low-pass band: every component with its own step, no frame.
  const std::size_t S = std::size_t{1} << setup.levels;
  const double low_step = setup.step / norms.low;
  for (std::size_t y = 0; y < side; y += S)
    for (std::size_t x = 0; x < side; x += S)
      for (Eigen::Index c = 0; c < 3; ++c) {
        const std::size_t idx = y * side + x;
        const std::int64_t q =
            code_value(bits, low_ctx, 0, 0, encoding ? quantize(coeffs[idx][c], low_step) : std::int64_t{0});
        D[idx][c] = dequantize(q, low_step);
      }
  symmetrize_level(D, setup.side, setup.levels, setup.extension);

  for (std::uint32_t level = setup.levels; level-- > 0;) {
    const std::size_t s = std::size_t{1} << level;
    const auto m = static_cast<std::int64_t>((side - 1) / (2 * s));
    const std::size_t lclass = std::min<std::size_t>(level, 3);
    const bool has_parent = level + 1 < setup.levels;
    for (std::size_t o = 0; o < 3; ++o) {
      const std::int64_t px = o == 1 ? 0 : 1, py = o == 0 ? 0 : 1;
      const double band_step = setup.step / norms.detail[level][o];
      for (std::int64_t y = py; y <= 2 * m; y += 2, bits.check_row())
        for (std::int64_t x = px; x <= 2 * m; x += 2) {
          const std::size_t idx = static_cast<std::size_t>(y) * s * side + static_cast<std::size_t>(x) * s;
          const std::array<Vec3, 3> F = setup.frames ? frame_at(D, side, 2 * s, m, setup.extension, x, y)
                                                     : std::array<Vec3, 3>{Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
          const std::size_t left = x >= 2 ? idx - 2 * s : idx, up = y >= 2 ? idx - 2 * s * side : idx;
          const std::size_t up_left = x >= 2 && y >= 2 ? up - 2 * s : idx;
          const std::size_t up_right = x + 2 <= 2 * m && y >= 2 ? up + 2 * s : idx;
          std::size_t parent_idx = 0;
          bool parent_known = false;
          if (has_parent) {
            const std::int64_t X = ((x >> 1) & ~std::int64_t{1}) | px, Y = ((y >> 1) & ~std::int64_t{1}) | py;
            if (X <= m && Y <= m) {
              parent_known = true;
              parent_idx = static_cast<std::size_t>(Y) * 2 * s * side + static_cast<std::size_t>(X) * 2 * s;
            }
          }
          Vec3 value = Vec3::Zero();
          for (std::size_t c = 0; c < 3; ++c) {
            const std::size_t cclass = setup.frames && c == 2 ? 1 : 0;
            const double st = cclass == 1 ? band_step / setup.normal_weight : band_step;
            const unsigned a = left != idx ? Q[left * 3 + c] : 0u, b = up != idx ? Q[up * 3 + c] : 0u;
            const std::size_t diagonal = (up_left != idx && Q[up_left * 3 + c] != 0 ? 1u : 0u) +
                                         (up_right != idx && Q[up_right * 3 + c] != 0 ? 1u : 0u);
            const std::size_t nb = (a != 0 ? 1u : 0u) + (b != 0 ? 1u : 0u) + (diagonal > 0 ? 1u : 0u);
            const std::size_t previous = c > 0 && Q[idx * 3 + c - 1] != 0 ? 1u : 0u;
            const std::size_t parent = parent_known ? (Q[parent_idx * 3 + c] != 0 ? 1u : 0u) : 2u;
            const std::size_t mclass = a + b == 0 ? 0 : (a + b <= 2 ? 1 : 2);
            const std::size_t zi = ((((cclass * 3 + o) * 4 + lclass) * 4 + nb) * 3 + parent) * 2 + previous;
            const std::size_t mi = (cclass * 4 + lclass) * 3 + mclass;
            const std::int64_t q =
                code_value(bits, ctx, zi, mi, encoding ? quantize(coeffs[idx].dot(F[c]), st) : std::int64_t{0});
            Q[idx * 3 + c] = static_cast<std::uint8_t>(std::min<std::int64_t>(q < 0 ? -q : q, 255));
            value += dequantize(q, st) * F[c];
          }
          D[idx] = value;
        }
    }
    symmetrize_level(D, setup.side, level, setup.extension);
    inverse_level(D, setup.side, level, setup.extension);
  }
}

void put_u32(std::vector<std::uint8_t>& out, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v >> (8 * i));
}
std::uint32_t get_u32(std::span<const std::uint8_t> in, std::size_t at) {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= std::uint32_t{in[at + static_cast<std::size_t>(i)]} << (8 * i);
  return v;
}

struct Trial {
  std::vector<std::uint8_t> payload;
  std::vector<Vec3> decoded;
  double psnr{0.0};
};

}  // namespace

bool wavelet_codable(std::uint32_t side) { return side <= kMaxWaveletSide && lattice_levels(side) > 0; }

std::uint32_t wavelet_coarsest_side(std::uint32_t side) {
  const std::uint32_t levels = lattice_levels(side);
  return levels == 0 ? side : (side - 1) / (1u << levels) + 1;
}

WaveletCoded encode_wavelet(std::span<const Vec3> image, std::uint32_t side, std::span<const std::uint8_t> mask,
                            const WaveletCodeOptions& options) {
  const std::uint32_t levels = lattice_levels(side);
  if (levels == 0 || side > kMaxWaveletSide || image.size() != std::size_t{side} * side)
    throw InvalidInput(fmt::format("wavelet coder: a {0} × {0} image ({1} samples) has no wavelet levels (the side must "
                                   "be 2^k·q + 1 with k ≥ 1, at most {2})",
                                   side, image.size(), kMaxWaveletSide));
  if (!mask.empty() && mask.size() != image.size())
    throw InvalidInput(fmt::format("wavelet coder: {} mask entries for {} samples", mask.size(), image.size()));
  const int targets = (options.step > 0.0 ? 1 : 0) + (options.target_bytes > 0 ? 1 : 0) + (options.target_psnr > 0.0 ? 1 : 0);
  if (targets != 1) throw InvalidInput("wavelet coder: give exactly one of a step, a byte target or a PSNR target");
  if (options.target_bytes > 0 && options.target_bytes <= kHeaderBytes + 8)
    throw InvalidInput(fmt::format("wavelet coder: {} bytes do not hold the {}-byte header and a coefficient",
                                   options.target_bytes, kHeaderBytes));
  if (options.normal_weight < 1 || options.normal_weight > 16)
    throw InvalidInput(fmt::format("wavelet coder: normal weight {} is outside 1..16", options.normal_weight));
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  std::size_t defined = 0;
  for (std::size_t i = 0; i < image.size(); ++i) {
    if (!image[i].allFinite()) throw InvalidInput(fmt::format("wavelet coder: sample {} is not finite", i));
    if (mask.empty() || mask[i] != 0) lo = lo.cwiseMin(image[i]), hi = hi.cwiseMax(image[i]), ++defined;
  }
  const double diagonal = defined == 0 ? 0.0 : (hi - lo).norm();

  std::vector<Vec3> coeffs(image.begin(), image.end());
  forward_lattice(coeffs, side, levels, options.extension);

  const auto trial = [&](double step) {
    LoopSetup setup{side, levels, options.extension, static_cast<double>(static_cast<float>(step)), options.local_frames,
                    options.normal_weight};
    EncodeBits bits;
    Trial t;
    run_loop(bits, setup, coeffs, t.decoded);
    std::vector<std::uint8_t> body = bits.coder.finish();
    t.payload.assign(kHeaderBytes, 0);
    std::memcpy(t.payload.data(), kMagic.data(), 4);
    t.payload[4] = kVersion;
    t.payload[5] = static_cast<std::uint8_t>(options.extension);
    t.payload[6] = options.local_frames ? 1 : 0;
    t.payload[7] = static_cast<std::uint8_t>(levels);
    put_u32(t.payload, 8, side);
    const auto step32 = static_cast<float>(setup.step);
    put_u32(t.payload, 12, std::bit_cast<std::uint32_t>(step32));
    t.payload[16] = options.normal_weight;
    put_u32(t.payload, 17, crc32(body.data(), body.size(), crc32(t.payload.data(), 17)));
    t.payload.insert(t.payload.end(), body.begin(), body.end());
    t.psnr = image_psnr(image, t.decoded, mask);
    return t;
  };

  WaveletCoded result;
  const auto finish = [&](Trial t, double step) {
    result.payload = std::move(t.payload);
    result.decoded = std::move(t.decoded);
    result.psnr = t.psnr;
    result.step = static_cast<double>(static_cast<float>(step));
    return result;
  };
  if (options.step > 0.0) {
    result.trials = 1;
    return finish(trial(options.step), options.step);
  }
  // Rate control on log(step): bytes fall and PSNR falls as the step grows. Bracket, then bisect.
  const auto fits = [&](const Trial& t) {
    return options.target_bytes > 0 ? t.payload.size() <= options.target_bytes : t.psnr >= options.target_psnr;
  };
  // Bytes: the steps that fit are [s*, ∞) and s* is wanted; PSNR: (0, s*]. From a step that fits, move
  // towards the ones that do not (`towards`), and the other way; then bisect between the two nearest.
  const double towards = options.target_bytes > 0 ? 1.0 / 8.0 : 8.0;
  const double scale = diagonal > 0.0 ? diagonal : 1.0;
  double good = 0.0, bad = 0.0;  // the nearest step to s* that fits and the nearest one that does not
  Trial best;
  const auto nearer = [&](double a, double b) {  // a is nearer the boundary than b, on a step that fits
    return b == 0.0 || (options.target_bytes > 0 ? a < b : a > b);
  };
  // The finest step worth trying: every coefficient then takes at most 2^36 steps (the coder's range is
  // 2^40), far below float precision of the positions; a budget that fits it is spent on an exact image.
  double largest = 0.0;
  for (const Vec3& c : coeffs) largest = std::max(largest, c.cwiseAbs().maxCoeff());
  const BandNorms norms = band_norms(levels);
  double gain = norms.low;
  for (const auto& level : norms.detail) gain = std::max({gain, level[0], level[1], level[2]});
  const double finest = std::max(largest * gain * options.normal_weight / 68719476736.0, scale * 1e-12);
  double step = scale * 1e-4;
  std::optional<Trial> at_finest;
  for (int i = 0; i < 40 && (good == 0.0 || bad == 0.0); ++i) {
    step = std::max(step, finest);
    Trial t = trial(step);
    ++result.trials;
    if (fits(t)) {
      if (nearer(step, good)) good = step, best = std::move(t);
      if (step <= finest && options.target_bytes > 0) break;  // the finest step fits the budget
      step *= towards;
    } else {
      if (bad == 0.0 || nearer(bad, step)) bad = step;
      if (step <= finest && options.target_bytes == 0) {  // no finer step to try (it tried this one 34 times)
        at_finest = std::move(t);
        break;
      }
      step /= towards;
    }
    if (step < scale * 1e-12 || step > scale * 1e6) break;
  }
  // A PSNR the finest step misses here may still be met after the caller's fusing of the cut (compress: a
  // geometry image 190.8 dB here was 204 dB fused): the finest step is the best this coder gives.
  if (good == 0.0 && at_finest) return finish(std::move(*at_finest), finest);
  if (good == 0.0)
    throw NumericalError(options.target_bytes > 0
                             ? fmt::format("wavelet coder: {} bytes are too few for the coarsest band of a {} × {} image",
                                           options.target_bytes, side, side)
                             : fmt::format("wavelet coder: no quantization step reaches {} dB", options.target_psnr));
  if (bad == 0.0) return finish(std::move(best), good);
  for (int i = 0; i < 10 && std::max(good, bad) / std::min(good, bad) > 1.02; ++i) {
    const double mid = std::sqrt(good * bad);
    Trial t = trial(mid);
    ++result.trials;
    if (fits(t)) good = mid, best = std::move(t);
    else bad = mid;
  }
  return finish(std::move(best), good);
}

WaveletDecoded decode_wavelet(std::span<const std::uint8_t> payload, std::uint32_t expected_side) {
  if (payload.size() < kHeaderBytes || std::memcmp(payload.data(), kMagic.data(), 4) != 0)
    throw FormatError("wavelet payload: not a gimforge wavelet payload (no 'GFWV' header)");
  if (payload[4] != kVersion)
    throw FormatError(fmt::format("wavelet payload: version {} is not supported (this gimforge reads {})", payload[4], kVersion));
  if (payload[5] > 1) throw FormatError(fmt::format("wavelet payload: unknown extension rule {}", payload[5]));
  if (payload[6] > 1) throw FormatError(fmt::format("wavelet payload: unknown flags {}", payload[6]));
  LoopSetup setup;
  setup.extension = static_cast<LatticeExtension>(payload[5]);
  setup.frames = payload[6] == 1;
  setup.levels = payload[7];
  setup.side = get_u32(payload, 8);
  setup.step = static_cast<double>(std::bit_cast<float>(get_u32(payload, 12)));
  setup.normal_weight = payload[16];
  if (setup.side > kMaxWaveletSide || lattice_levels(setup.side) == 0 || setup.levels != lattice_levels(setup.side))
    throw FormatError(fmt::format("wavelet payload: side {} with {} levels is not a codable image (side 2^k·q + 1 up to {})",
                                  setup.side, setup.levels, kMaxWaveletSide));
  if (expected_side != 0 && setup.side != expected_side)
    throw FormatError(fmt::format("wavelet payload: a {0} × {0} image, expected {1} × {1}", setup.side, expected_side));
  if (!(setup.step > 0.0) || !std::isfinite(setup.step))
    throw FormatError(fmt::format("wavelet payload: quantization step {} is not positive and finite", setup.step));
  if (setup.normal_weight < 1 || setup.normal_weight > 16)
    throw FormatError(fmt::format("wavelet payload: normal weight {} is outside 1..16", setup.normal_weight));
  const std::span<const std::uint8_t> body = payload.subspan(kHeaderBytes);
  if (crc32(body.data(), body.size(), crc32(payload.data(), 17)) != get_u32(payload, 17))
    throw FormatError("wavelet payload: checksum mismatch (the coded bytes are damaged or truncated)");
  DecodeBits bits{rc::RangeDecoder(body)};
  WaveletDecoded out;
  out.side = setup.side;
  out.extension = setup.extension;
  run_loop(bits, setup, {}, out.image);
  if (bits.coder.overrun() > 4) throw FormatError("wavelet payload: truncated (the coder ran past the coded bytes)");
  for (const Vec3& v : out.image)
    if (!v.allFinite()) throw FormatError("wavelet payload: a decoded sample is not finite (damaged payload)");
  return out;
}

}  // namespace gimforge
