#pragma once
/// \file lattice_wavelet.h
/// The CDF 9/7 image wavelet (JPEG 2000's irreversible filter, as lifting steps) on square images of side
/// 2m + 1 whose boundary is extended either by mirroring (a disk: geometry images, JPEG 2000's own rule) or by
/// the spherical extension rules of Praun & Hoppe §4.1 (octahedral and flattened-octahedral images: the
/// lattice is continued by 180° rotations about the midpoints of the image edges).
///
/// The transform is in place and interleaved (Mallat's lifting layout): level ℓ works on the samples at
/// stride s = 2^ℓ, a lattice of side 2m_ℓ + 1 with m_ℓ = m / 2^ℓ; its low-pass samples are those at stride
/// 2s, its three detail bands those with an odd coordinate (in units of s). A separable symmetric filter
/// commutes with the lattice's symmetries (§4.1: "the lattice symmetries are preserved"), and every lifting
/// step reads only samples of the other parity, so the extension is applied to the coefficients of the
/// same step and the 180° rotation of level ℓ is again a 180° rotation of the low-pass lattice (m_ℓ even).
/// Under the spherical rule the samples that the rule identifies (left edge (0, y) ~ (0, 2m − y), right edge,
/// top (x, 0) ~ (2m − x, 0), bottom edge; the four corners) hold equal coefficients at every level;
/// symmetrize_level enforces it after lossy coding, so the decoded image's duplicated samples — one point of
/// the sphere each — are bit-identical: the decoded surface is watertight by construction.
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/mesh.h"

namespace gimforge {

enum class LatticeExtension : std::uint8_t {
  Mirror,  ///< whole-sample symmetric: x[−k] = x[k] along each row and column (a disk)
  Sphere,  ///< Praun & Hoppe §4.1: (−k, y) = (k, 2m − y), (2m + k, y) = (2m − k, 2m − y), likewise for rows
};

/// Levels of the transform of a side × side image: the largest L ≤ 10 with m = (side − 1)/2 divisible by
/// 2^(L−1) (so every level's lattice is odd with an even half-side below the last); 0 when side < 3 or even.
[[nodiscard]] std::uint32_t lattice_levels(std::uint32_t side);

/// One analysis level ℓ (stride 2^ℓ) in place: rows, then columns. Precondition: side odd, ℓ < levels.
void forward_level(std::span<Vec3> image, std::uint32_t side, std::uint32_t level, LatticeExtension extension);
/// The exact inverse of forward_level (columns, then rows).
void inverse_level(std::span<Vec3> image, std::uint32_t side, std::uint32_t level, LatticeExtension extension);
/// Every level 0 .. levels − 1, and back.
void forward_lattice(std::span<Vec3> image, std::uint32_t side, std::uint32_t levels, LatticeExtension extension);
void inverse_lattice(std::span<Vec3> image, std::uint32_t side, std::uint32_t levels, LatticeExtension extension);

/// Under LatticeExtension::Sphere: replaces every group of samples of the level-ℓ lattice that the rule
/// identifies by their average (pairs on the edges, the four corners together). Nothing under Mirror.
void symmetrize_level(std::span<Vec3> image, std::uint32_t side, std::uint32_t level, LatticeExtension extension);

/// The sample of the level-ℓ lattice (coordinates in units of 2^ℓ, side 2m + 1) that lattice position (x, y)
/// stands for, for x, y in [−1, 2m + 1]: the extension rule applied once.
struct LatticePoint {
  std::int64_t x{0};
  std::int64_t y{0};
};
[[nodiscard]] LatticePoint extend(std::int64_t x, std::int64_t y, std::int64_t m, LatticeExtension extension);
/// The same on a lattice of side n + 1 for any n ≥ 1 (the low-pass band below a level: n = m), for x, y in
/// [−n, 2n].
[[nodiscard]] LatticePoint extend_lattice(std::int64_t x, std::int64_t y, std::int64_t n, LatticeExtension extension);

/// L2 norms of the synthesis functions of one coefficient of every band, for steps that spread the
/// quantization error evenly: `detail[ℓ][o]` for level ℓ and orientation o (0: high along x, 1: high along y,
/// 2: both), `low` for the coarsest low-pass band after `levels` levels.
struct BandNorms {
  std::vector<std::array<double, 3>> detail;
  double low{1.0};
};
[[nodiscard]] BandNorms band_norms(std::uint32_t levels);

}  // namespace gimforge
