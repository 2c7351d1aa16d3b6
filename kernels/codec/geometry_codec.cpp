#include "kernels/codec/geometry_codec.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "kernels/codec/wavelet_coder.h"
#include "kernels/core/errors.h"

namespace gimforge {

std::vector<float> to_floats(std::span<const Vec3> image) {
  std::vector<float> xyz(3 * image.size());
  for (std::size_t i = 0; i < image.size(); ++i)
    for (Eigen::Index c = 0; c < 3; ++c) xyz[3 * i + static_cast<std::size_t>(c)] = static_cast<float>(image[i][c]);
  return xyz;
}
std::vector<Vec3> to_points(std::span<const float> xyz) {
  std::vector<Vec3> out(xyz.size() / 3);
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
  return out;
}

namespace {

CodedGeometry encode_j2k_geometry(const std::vector<Vec3>& filled, std::span<const Vec3> original, std::uint32_t width,
                                  std::uint32_t height, std::span<const std::uint8_t> mask, const CodingTarget& target) {
  CodedGeometry out;
  out.codec = GeometryCodec::J2k;
  const std::vector<float> xyz = to_floats(filled);
  const Planes16 planes = quantize_positions(xyz, width, height, out.quantization);
  const auto attempt = [&](std::size_t bytes) {
    CodedGeometry c = out;
    c.payload = encode_j2k(planes, J2kOptions{bytes, false});
    c.decoded = to_points(dequantize_positions(decode_j2k(c.payload), c.quantization));
    c.psnr = image_psnr(original, c.decoded, mask);
    return c;
  };
  if (target.lossless || target.bytes > 0) return attempt(target.lossless ? 0 : target.bytes);
  // A PSNR target: bisect the byte target between a rate that misses it and the lossless size.
  CodedGeometry best = attempt(0);
  if (best.psnr < target.psnr)
    throw NumericalError(fmt::format("JPEG 2000: even lossless coding of the 16-bit planes gives {:.1f} dB, below {} dB",
                                     best.psnr, target.psnr));
  std::size_t lo = 64, hi = best.payload.size();
  for (int i = 0; i < 12 && hi > lo + std::max<std::size_t>(16, hi / 100); ++i) {
    const std::size_t mid = lo + (hi - lo) / 2;
    CodedGeometry c = attempt(mid);
    if (c.psnr >= target.psnr) {
      hi = std::min(mid, c.payload.size());
      best = std::move(c);
    } else {
      lo = mid;
    }
  }
  return best;
}

}  // namespace

std::string_view codec_name(GeometryCodec codec) {
  switch (codec) {
    case GeometryCodec::J2k: return "j2k";
    case GeometryCodec::Wavelet: return "wavelet";
    case GeometryCodec::J2kRoi: return "j2k-roi";
  }
  return "j2k";
}

CodedGeometry encode_geometry_roi_first(std::span<const Vec3> image, std::uint32_t width, std::uint32_t height,
                                        std::span<const std::uint8_t> roi, std::size_t bytes) {
  if (image.size() != std::size_t{width} * height || roi.size() != image.size())
    throw InvalidInput(fmt::format("ROI coding: {} samples and {} ROI flags for a {} × {} image", image.size(), roi.size(),
                                   width, height));
  if (bytes <= kRoiPayloadHeader)
    throw InvalidInput(fmt::format("ROI coding: a budget of {} bytes holds no codestream", bytes));
  CodedGeometry out;
  out.codec = GeometryCodec::J2kRoi;
  const Planes16 planes = quantize_positions(to_floats(image), width, height, out.quantization);
  // Readers take at most twice the 16-bit planes plus 64 KiB (io/coded_image.cpp): a lossless window and an
  // incompressible image could pass that, so the budget stops there.
  const std::size_t cap = 2 * planes.samples.size() * sizeof(std::uint16_t) + 65536;
  const RoiCoded coded = encode_roi_priority(planes, roi, std::min(bytes, cap) - kRoiPayloadHeader);
  out.payload = roi_payload(coded);
  out.decoded = to_points(dequantize_positions(decode_roi_priority(coded), out.quantization));
  out.psnr = image_psnr(image, out.decoded, {});
  return out;
}

double image_psnr(std::span<const Vec3> original, std::span<const Vec3> decoded, std::span<const std::uint8_t> mask) {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  double sum = 0.0;
  std::size_t count = 0;
  for (std::size_t i = 0; i < original.size() && i < decoded.size(); ++i) {
    if (!mask.empty() && mask[i] == 0) continue;
    lo = lo.cwiseMin(original[i]), hi = hi.cwiseMax(original[i]);
    sum += (decoded[i] - original[i]).squaredNorm();
    ++count;
  }
  if (count == 0 || sum == 0.0) return std::numeric_limits<double>::infinity();
  return 20.0 * std::log10((hi - lo).norm() / std::sqrt(sum / static_cast<double>(count)));
}

double normal_psnr(std::span<const Vec3> original, std::span<const Vec3> decoded, std::uint32_t width,
                   std::uint32_t height, std::uint32_t face_height, std::span<const std::uint8_t> mask) {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  double sum = 0.0;
  std::size_t count = 0;
  const std::int64_t fh = std::max<std::int64_t>(1, face_height);
  for (std::int64_t y = 0; y < height; ++y) {
    const std::int64_t y0 = (y / fh) * fh, y1 = std::min<std::int64_t>(y0 + fh, height) - 1;
    const auto at = [&](std::int64_t x, std::int64_t row) -> const Vec3& {
      x = std::clamp<std::int64_t>(x, 0, std::int64_t{width} - 1), row = std::clamp(row, y0, y1);
      return original[static_cast<std::size_t>(row) * width + static_cast<std::size_t>(x)];
    };
    for (std::int64_t x = 0; x < width; ++x) {
      const std::size_t k = static_cast<std::size_t>(y) * width + static_cast<std::size_t>(x);
      if (!mask.empty() && mask[k] == 0) continue;
      const Vec3 n = (at(x + 1, y) - at(x - 1, y)).cross(at(x, y + 1) - at(x, y - 1));
      const Vec3 d = decoded[k] - original[k];
      const double nn = n.norm();
      const double e = nn > 0.0 && std::isfinite(nn) ? d.dot(n) / nn : d.norm();
      lo = lo.cwiseMin(original[k]), hi = hi.cwiseMax(original[k]);
      sum += e * e;
      ++count;
    }
  }
  if (count == 0 || !(sum > 0.0)) return std::numeric_limits<double>::infinity();
  return 20.0 * std::log10((hi - lo).norm() / std::sqrt(sum / static_cast<double>(count)));
}

void fill_undefined(std::vector<Vec3>& image, std::uint32_t width, std::uint32_t height,
                    std::span<const std::uint8_t> mask) {
  if (mask.empty()) return;
  const std::size_t count = std::size_t{width} * height;
  std::vector<std::uint8_t> known(mask.begin(), mask.end());
  if (std::none_of(known.begin(), known.end(), [](std::uint8_t m) { return m != 0; }))
    throw InvalidInput("fill: no sample of the image is defined");
  std::vector<std::size_t> layer;
  for (bool changed = true; changed;) {
    changed = false;
    layer.clear();
    for (std::size_t p = 0; p < count; ++p) {
      if (known[p] != 0) continue;
      const std::size_t x = p % width, y = p / width;
      Vec3 sum = Vec3::Zero();
      int k = 0;
      if (x > 0 && known[p - 1] != 0) sum += image[p - 1], ++k;
      if (x + 1 < width && known[p + 1] != 0) sum += image[p + 1], ++k;
      if (y > 0 && known[p - width] != 0) sum += image[p - width], ++k;
      if (y + 1 < height && known[p + width] != 0) sum += image[p + width], ++k;
      if (k > 0) {
        image[p] = sum / k;
        layer.push_back(p);
      }
    }
    for (const std::size_t p : layer) known[p] = 1;  // a layer at a time: the fill does not run along rows
    changed = !layer.empty();
  }
}

CodedGeometry encode_geometry(std::span<const Vec3> image, std::uint32_t width, std::uint32_t height,
                              std::span<const std::uint8_t> mask, GeometryCodec codec, LatticeExtension extension,
                              const CodingTarget& target) {
  const int targets = (target.lossless ? 1 : 0) + (target.bytes > 0 ? 1 : 0) + (target.psnr > 0.0 ? 1 : 0);
  if (targets != 1) throw InvalidInput("coding: give exactly one target (lossless, bytes or PSNR)");
  if (image.size() != std::size_t{width} * height || (!mask.empty() && mask.size() != image.size()))
    throw InvalidInput(fmt::format("coding: {} samples and {} mask entries for a {} × {} image", image.size(),
                                   mask.size(), width, height));
  std::vector<Vec3> filled(image.begin(), image.end());
  fill_undefined(filled, width, height, mask);
  if (codec == GeometryCodec::J2k) return encode_j2k_geometry(filled, image, width, height, mask, target);
  if (codec == GeometryCodec::J2kRoi)
    throw InvalidInput("coding: ROI-first JPEG 2000 needs the region of interest (encode_geometry_roi_first)");
  if (target.lossless)
    throw InvalidInput("coding: the wavelet coder is lossy only (use --codec j2k for lossless JPEG 2000)");
  if (width != height)
    throw InvalidInput(fmt::format("coding: the wavelet coder takes square images, not {} × {}", width, height));
  // The fill diffuses across the image, not across the sphere's seams: under the spherical rule a filled
  // sample and its mate on the other side of the boundary would differ, and the coder, which keeps the
  // mates equal at every level, would carry that difference into the defined samples nearby at any rate.
  symmetrize_level(filled, width, 0, extension);
  WaveletCodeOptions options;
  options.extension = extension;
  options.target_bytes = target.bytes;
  options.target_psnr = target.psnr;
  WaveletCoded w = encode_wavelet(filled, width, mask, options);
  CodedGeometry out;
  out.codec = GeometryCodec::Wavelet;
  out.payload = std::move(w.payload);
  out.decoded = std::move(w.decoded);
  out.psnr = w.psnr;
  return out;
}

std::vector<Vec3> decode_geometry(GeometryCodec codec, std::span<const std::uint8_t> payload,
                                  const Quantization& quantization, std::uint32_t width, std::uint32_t height,
                                  LatticeExtension extension) {
  if (codec == GeometryCodec::J2k) {
    const Planes16 planes = decode_j2k(payload, width, height, 3);
    if (planes.width != width || planes.height != height || planes.components != 3)
      throw FormatError(fmt::format("JPEG 2000 payload: {} × {} × {} planes, expected {} × {} × 3", planes.width,
                                    planes.height, planes.components, width, height));
    return to_points(dequantize_positions(planes, quantization));
  }
  if (codec == GeometryCodec::J2kRoi) return to_points(dequantize_positions(decode_roi_payload(payload, width, height, 3), quantization));
  if (width != height)
    throw FormatError(fmt::format("wavelet payload: the coder takes square images, not {} × {}", width, height));
  WaveletDecoded d = decode_wavelet(payload, width);
  if (d.side != width || d.side != height)
    throw FormatError(fmt::format("wavelet payload: a {0} × {0} image, expected {1} × {2}", d.side, width, height));
  if (d.extension != extension)
    throw FormatError(fmt::format("wavelet payload: coded with the {} extension rule, this image needs the {} rule",
                                  d.extension == LatticeExtension::Sphere ? "spherical" : "mirror",
                                  extension == LatticeExtension::Sphere ? "spherical" : "mirror"));
  return std::move(d.image);
}

}  // namespace gimforge
