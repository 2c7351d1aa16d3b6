// Fuzz harness: a coded image payload (kernels/codec/geometry_codec.h decode_geometry) as readers meet it
// once its archive's `crc32` matched — a checksum anyone who writes an archive can compute, so it keeps
// damage out, not malice. The first byte picks the codec and the image: bits 0–1 the codec (J2k, Wavelet
// with the mirror rule, Wavelet with the spherical rule, J2kRoi), bits 2–3 the side (17, 33, 65, 129),
// bit 4 a JPEG 2000 image half as high (side × (side + 1) / 2); the rest is the payload. A wavelet payload's
// own CRC-32 (header bytes 17..20) is recomputed unless bit 5 is set, so that mutations reach the range
// decoder and the lattice transform instead of stopping at the checksum.
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

#include "kernels/codec/geometry_codec.h"
#include "kernels/core/hash.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  constexpr std::array<std::uint32_t, 4> kSides{17, 33, 65, 129};
  const std::uint8_t selector = data[0];
  const auto codec = static_cast<gimforge::GeometryCodec>((selector & 3u) == 2u ? 1u : (selector & 3u) == 3u ? 2u : (selector & 3u));
  const gimforge::LatticeExtension extension =
      (selector & 3u) == 2u ? gimforge::LatticeExtension::Sphere : gimforge::LatticeExtension::Mirror;
  const std::uint32_t width = kSides[(selector >> 2) & 3u];
  const bool half = codec != gimforge::GeometryCodec::Wavelet && (selector & 16u) != 0;
  const std::uint32_t height = half ? (width + 1) / 2 : width;

  std::vector<std::uint8_t> payload(data + 1, data + size);
  constexpr std::size_t kWaveletHeader = 21;
  if (codec == gimforge::GeometryCodec::Wavelet && (selector & 32u) == 0 && payload.size() >= kWaveletHeader &&
      std::memcmp(payload.data(), "GFWV", 4) == 0) {
    const std::uint32_t crc = gimforge::crc32(payload.data() + kWaveletHeader, payload.size() - kWaveletHeader,
                                              gimforge::crc32(payload.data(), 17));
    for (int i = 0; i < 4; ++i) payload[17 + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(crc >> (8 * i));
  }

  gimforge::Quantization quantization;
  quantization.offset = gimforge::Vec3(-1.0, -2.0, 3.0);
  quantization.scale = 1.0 / 65535.0;
  return gimforge::fuzz::expect_errors([&] {
    const std::vector<gimforge::Vec3> image =
        gimforge::decode_geometry(codec, std::span<const std::uint8_t>(payload), quantization, width, height, extension);
    // What decode_geometry promises: the size asked for, every sample finite.
    if (image.size() != std::size_t{width} * height) __builtin_trap();
    for (const gimforge::Vec3& p : image)
      if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || !std::isfinite(p.z())) __builtin_trap();
  });
}
