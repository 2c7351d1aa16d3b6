#pragma once
/// \file hash.h
/// Deterministic integer hashing for seeded choices that must not depend on a library's random engine.
#include <array>
#include <cstddef>
#include <cstdint>

namespace gimforge {

/// SplitMix64 (Steele, Lea, Flood 2014): a bijective 64-bit mix with good avalanche; seeds and per-item
/// hashes (chart orders, seed faces, synthetic noise).
[[nodiscard]] constexpr std::uint64_t splitmix64(std::uint64_t x) {
  x += std::uint64_t{0x9e3779b97f4a7c15};
  x = (x ^ (x >> 30)) * std::uint64_t{0xbf58476d1ce4e5b9};
  x = (x ^ (x >> 27)) * std::uint64_t{0x94d049bb133111eb};
  return x ^ (x >> 31);
}

/// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320, as zlib and PNG): the checksum of coded payloads,
/// so that a damaged one is refused instead of decoded into a wrong surface.
namespace detail {
inline constexpr std::array<std::uint32_t, 256> kCrc32Table = [] {
  std::array<std::uint32_t, 256> t{};
  for (std::uint32_t n = 0; n < 256; ++n) {
    std::uint32_t c = n;
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (std::uint32_t{0xEDB88320} & (0u - (c & 1u)));
    t[n] = c;
  }
  return t;
}();
}  // namespace detail

/// `crc` continues an earlier CRC (of the bytes before `data`).
[[nodiscard]] constexpr std::uint32_t crc32(const std::uint8_t* data, std::size_t size, std::uint32_t crc = 0) {
  crc = ~crc;
  for (std::size_t i = 0; i < size; ++i) crc = detail::kCrc32Table[(crc ^ data[i]) & 0xFFu] ^ (crc >> 8);
  return ~crc;
}

}  // namespace gimforge
