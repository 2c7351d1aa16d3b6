#pragma once
/// \file surface_sampling.h
/// Deterministic area-weighted sampling of a triangle surface (for the Hausdorff metric).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "kernels/core/mesh.h"

namespace gimforge {

/// Options for sample_surface.
struct SurfaceSamplingOptions {
  std::size_t samples{1'000'000};           ///< number of area-weighted samples
  std::uint64_t seed{0x9e3779b97f4a7c15ull};  ///< fixed default: results are reproducible
};

/// Points on a surface with the face each lies on.
struct SurfaceSamples {
  std::vector<Vec3> points;
  std::vector<std::uint32_t> faces;
};

/// Draws `options.samples` points uniformly with respect to area, stratified along the cumulative area
/// (sample i picks the face at CDF position (i + u_i)/n), uniform inside the face. Samples come out in
/// face order, which keeps consecutive samples close in space. Deterministic: the same mesh, count and
/// seed give bit-identical samples on every machine and thread count (counter-based SplitMix64).
/// Zero-area faces receive no samples. Throws InvalidInput when the surface has zero area.
[[nodiscard]] SurfaceSamples sample_surface(MeshView mesh, const SurfaceSamplingOptions& options = {});

/// Counter-based random numbers: the `stream`-th double in [0, 1) for `seed`; no state, any order.
[[nodiscard]] double uniform01(std::uint64_t seed, std::uint64_t stream);

}  // namespace gimforge
