#pragma once
/// \file surface_sampling.h
/// Deterministic area-weighted sampling of a triangle surface (for the Hausdorff metric).
#include <cstddef>
#include <cstdint>
#include <span>
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
/// The cumulative area is summed in integers (AreaQuanta), so that ranks that each hold a slice of the
/// faces draw exactly the samples that fall on their slice (sample_slice). Zero-area faces receive no
/// samples. Throws InvalidInput when the surface has zero area.
[[nodiscard]] SurfaceSamples sample_surface(MeshView mesh, const SurfaceSamplingOptions& options = {});

/// Face areas as integers: area · 2^exponent rounded to nearest, with the exponent chosen from the largest
/// face area and the face count so that the sum of all faces stays below 2^62. Integer sums do not depend
/// on how the faces are split, which makes the cumulative area of a slice exact on every rank. Faces
/// smaller than about 2^-62 · faces · largest area get no samples.
struct AreaQuanta {
  int exponent{0};
  double scale{1.0};  ///< 2^exponent
  /// Throws InvalidInput when `largest_area` is not positive and finite or `faces` is 0.
  AreaQuanta(double largest_area, std::uint64_t faces);
  [[nodiscard]] std::uint64_t operator()(double area) const;
};

/// The samples of sample_surface (same count n and seed, over a surface of `total` quanta) that land on a
/// slice of its faces: the slice's faces in order with their areas `areas` (quantized by `quantize`), and
/// the quanta of every face before the slice `before`. `faces` in the result index the slice. Samples come
/// in index order, with their global index in `index`.
struct SampleSlice {
  std::vector<Vec3> points;
  std::vector<std::uint32_t> faces;
  std::vector<std::uint64_t> index;
};
[[nodiscard]] SampleSlice sample_slice(MeshView slice, std::span<const double> areas, const AreaQuanta& quantize,
                                       std::uint64_t before, std::uint64_t total, const SurfaceSamplingOptions& options);

/// Counter-based random numbers: the `stream`-th double in [0, 1) for `seed`; no state, any order.
[[nodiscard]] double uniform01(std::uint64_t seed, std::uint64_t stream);

}  // namespace gimforge
