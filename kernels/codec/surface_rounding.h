#pragma once
/// \file surface_rounding.h
/// Rounding a geometry image's positions to a quantization lattice so that the *surface* moves least.
///
/// A reconstruction is the mesh through the samples; moving a sample within the surface's tangent plane
/// changes that mesh only to second order (curvature × move × sample spacing), moving it along the normal
/// changes it to first order. Rounding each coordinate to the nearest lattice value moves a sample by a
/// uniform error in a cell of side s (normal component s/√12 RMS, whatever the orientation). The lattice
/// points around it have normal offsets n·(c − p) spread over several s: one of them is usually within a
/// small fraction of s of the tangent plane (bunny_closed at 257², 12 bits: the quantized image's surface
/// against the float image's, 90.6 dB with nearest rounding, 96.0 dB with this; BENCHMARKS.md). The decoder is unchanged (position =
/// offset + scale · q); only the encoder's choice among the candidates is. Samples with equal positions (the
/// sideband's mates, a spherical image's duplicated boundary, a multi-chart zipper cluster; −0 and +0 count
/// as equal) all take the normal and spacing of the first sample at that position, and therefore the same
/// code, so they stay equal after dequantization. Memory: 12 bytes a sample besides the codes.
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/mesh.h"

namespace gimforge {

/// The lattice: value(q) = offset[c] + scale[c] · q, q in [0, top].
struct PositionLattice {
  Vec3 offset{Vec3::Zero()};
  Vec3 scale{Vec3::Ones()};
  double top{4095.0};
};

struct SurfaceRoundingOptions {
  /// Weight of the whole move against its normal part: cost = (n·e)² + tangent_weight · |e|².
  /// (A tangential move of t changes the reconstruction by about κ·h·t, curvature κ times sample spacing
  /// h: a few hundredths of t on a sampled surface.)
  double tangent_weight{0.01};
  /// Candidates per axis: the 2·r lattice values around the position (r = 1: the 8 corners of its cell;
  /// r = 2: 64 candidates, whose normal offsets fill the gaps the 8 corners leave).
  std::uint32_t cell_radius{2};
  /// A corner farther than this fraction of the distance to the sample's nearest defined neighbour is never
  /// taken (where the image's samples are closer together than the lattice, nearest rounding stays).
  double max_move_fraction{0.25};
  /// Rows per block of an image of stacked faces (a spherical image of the tetrahedron or cube: faces ·
  /// height rows): no normal is estimated across two blocks. 0: one block.
  std::uint32_t block_rows{0};
};

/// Codes of `xyz` (width × height samples, interleaved x, y, z, row-major; samples with mask 0 are skipped
/// and coded 0; `mask` empty: all defined) on `lattice`, each sample's corner of its lattice cell chosen by
/// the cost above with the normal estimated from its grid neighbours. Where no normal can be estimated the
/// nearest lattice point is taken. Every code lies in [0, top]. Throws InvalidInput for mismatched sizes, a
/// lattice without finite offsets, positive scales and a whole top in [1, 65535], or a defined sample that is
/// not finite.
[[nodiscard]] std::vector<std::uint16_t> round_to_surface(std::span<const float> xyz, std::span<const std::uint8_t> mask,
                                                          std::uint32_t width, std::uint32_t height,
                                                          const PositionLattice& lattice,
                                                          const SurfaceRoundingOptions& options = {});

}  // namespace gimforge
