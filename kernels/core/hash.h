#pragma once
/// \file hash.h
/// Deterministic integer hashing for seeded choices that must not depend on a library's random engine.
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

}  // namespace gimforge
