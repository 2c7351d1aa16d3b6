#pragma once
/// \file hausdorff.h
/// Symmetric Hausdorff distance and PSNR between two surfaces, as the geometry-image papers measure
/// fidelity (Gu et al. 2002 §5, Sander et al. 2003, Praun & Hoppe 2003; ../shared/notes/parametrization.md):
///   d = sqrt((rms_ab² + rms_ba²) / 2),  PSNR = 20 log10(diag / d),  diag = A's bounding-box diagonal.
/// Each direction samples the source surface (area-weighted, plus all its referenced vertices) and takes
/// exact point-to-triangle distances to the target through Embree point queries.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "kernels/core/embree_device.h"
#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"

namespace gimforge {

/// Options for the Hausdorff metric.
struct HausdorffOptions {
  std::size_t samples{1'000'000};               ///< area-weighted samples per direction
  std::uint64_t seed{0x9e3779b97f4a7c15ull};    ///< fixed: the metric is deterministic
  bool include_vertices{true};                  ///< also measure every referenced vertex (for the max)
  ProgressCallback progress{};                  ///< stages "distance A->B", "distance B->A"
};

/// Distances from one surface to another.
/// - `max`: over area samples and vertices.
/// - `mean`, `rms`: over the area samples only, so they estimate the surface integrals
///   (1/|A|)∫ d and sqrt((1/|A|)∫ d²); vertices are not area-distributed and would bias them.
struct OneSidedDistance {
  double max{0.0};
  double mean{0.0};
  double rms{0.0};
  std::size_t area_samples{0};
  std::size_t vertex_samples{0};
};

/// Symmetric result. `psnr` is +infinity when rms == 0.
struct HausdorffResult {
  double diag{0.0};
  OneSidedDistance ab;
  OneSidedDistance ba;
  double max{0.0};
  double rms{0.0};
  double psnr{0.0};
};

/// Answers one block of consecutive points: out[i] = the distance of block[i] (the block's queries may
/// reuse each other's answers, e.g. as bounds).
using DistanceBlock = std::function<void(std::span<const Vec3> block, std::span<double> out)>;

/// Distances of `points`, computed by `block` over blocks of kDistanceBlock consecutive points in parallel (TBB),
/// with progress (64 steps of `stage`) and cancellation. Throws Cancelled when the callback stops it and
/// NumericalError "STAGE: no closest point found for point I (x, y, z); ..." for a non-finite distance
/// (float32 overflow: coordinates or distances beyond ~10^18).
[[nodiscard]] std::vector<double> distances_in_blocks(std::span<const Vec3> points, const DistanceBlock& block,
                                                      const ProgressCallback& progress, std::string_view stage);

/// Distances from every point in `points` to the surface behind `target` (exact, multi-threaded).
/// Consecutive points that lie close together are faster (each query starts from its predecessor's answer).
/// Returns one distance per point, in order.
[[nodiscard]] std::vector<double> distances_to_surface(std::span<const Vec3> points, const TriangleBvh& target,
                                                       const ProgressCallback& progress = {},
                                                       std::string_view stage = "distance");

/// The points one direction measures: `from`'s area samples (sample_surface with the options' count and
/// seed), then, with include_vertices, its referenced vertices in index order.
struct MeasuredPoints {
  std::vector<Vec3> points;
  std::size_t area_samples{0};
};
[[nodiscard]] MeasuredPoints measured_points(MeshView from, const HausdorffOptions& options);

/// Points per block of distances_in_blocks: a caller that splits the points (across ranks) at multiples of
/// it gets the same distances, bit for bit, as one call over all of them.
inline constexpr std::size_t kDistanceBlock = 2048;

/// The symmetric result of the two directions (diag: A's bounding-box diagonal).
[[nodiscard]] HausdorffResult combine_directions(double diag, const OneSidedDistance& ab, const OneSidedDistance& ba);

/// One-sided distance from surface `from` to the surface behind `to`.
/// Throws InvalidInput if `from` has no area.
[[nodiscard]] OneSidedDistance one_sided_distance(MeshView from, const TriangleBvh& to, const HausdorffOptions& options,
                                                  std::string_view stage = "distance");

/// Statistics of one direction from its distances: the first `area_samples` entries are area samples,
/// the rest vertices. Sums run in a fixed order, so the result does not depend on the thread count.
[[nodiscard]] OneSidedDistance summarize_distances(std::span<const double> distances, std::size_t area_samples);

/// Symmetric Hausdorff metric between A (the original) and B. Throws InvalidInput for meshes without
/// faces or area, LibraryError on Embree failures, Cancelled if the progress callback asks to stop.
[[nodiscard]] HausdorffResult symmetric_hausdorff(const EmbreeDevice& device, MeshView a, MeshView b,
                                                  const HausdorffOptions& options = {});

/// PSNR in dB for a distance d relative to diag: 20 log10(diag / d); +infinity for d == 0.
[[nodiscard]] double psnr_db(double diag, double d);

}  // namespace gimforge
