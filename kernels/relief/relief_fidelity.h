#pragma once
/// \file relief_fidelity.h
/// The papers' fidelity measure (symmetric RMS Hausdorff distance and PSNR, kernels/core/hausdorff.h)
/// between a mesh and the geometry-based reconstruction of its relief map (§3.5.1, reconstruct_relief),
/// computed without building the reconstruction.
///
/// The reconstruction has two triangles per 2×2 texel quad of every domain face: tens of millions of
/// triangles for a 100K-face input (N = 32, T = 64), which symmetric_hausdorff would store in double
/// precision, put into an Embree BVH and sample (vertices included). relief_fidelity computes the same
/// quantities from the texels:
///
/// - **Reconstruction → original.** The same stratified area samples as sample_surface draws on
///   reconstruct_relief(map) (face i of the reconstruction is enumerated in the same order with the same
///   area; sample_surface sums the cumulative area in integer quanta, this sums it per layer in double,
///   so the samples are the same points up to where that rounding moves a target across a triangle),
///   generated layer by layer, then exact distances to the original's BVH. The reconstruction's
///   vertices are stored texel points: each lies within half a quantization step (distance_scale / 2,
///   plus the sampler's 1e-10 segment and 1e-12 barycentric tolerances) of the original triangle its
///   texel hit, so they cannot raise the maximum above the area samples' one unless that maximum is below
///   this bound; only then are they measured (exactly, like symmetric_hausdorff does).
/// - **Original → reconstruction.** The same samples of the original (sample_surface plus its referenced
///   vertices), and exact closest points on the reconstruction's triangles: per domain face, a quadtree
///   of float bounding boxes over blocks of 4×4 texel quads, under an Embree BVH over the domain faces'
///   root boxes; each query starts from the smaller of two upper bounds, its predecessor's triangle and
///   the quad it projects to in its own grey cell (where it is represented, within about a texel).
///
/// Memory: one byte per quad (its triangulation), about 8 bytes per texel of boxes, and the samples — no
/// triangle list, no BVH over the reconstruction's triangles, and no stored texel points: passes over a
/// whole layer compute its points into a per-thread scratch, queries compute the few they visit.
///
/// The result agrees with symmetric_hausdorff(device, original, reconstruct_relief(map, max_edge_texels))
/// to rounding (tests/unit/relief/test_relief_fidelity.cpp), is deterministic and does not depend on the
/// number of threads (TBB).
#include <cstddef>
#include <functional>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "kernels/core/embree_device.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/mesh.h"
#include "kernels/relief/relief_map.h"

namespace gimforge {

/// Fidelity of a relief map's reconstruction and the size of that reconstruction.
struct ReliefFidelity {
  HausdorffResult hausdorff;               ///< A = the original, B = the reconstruction
  std::size_t reconstruction_vertices{0};  ///< reconstruct_relief(map).num_vertices(): the texels its faces use
  std::size_t reconstruction_faces{0};     ///< reconstruct_relief(map).num_faces()
};

/// The reconstruction of a relief map as relief_fidelity measures it, for callers that split the measurement
/// (jobs/brick_relief.h: each rank answers a share of the points). Holds a byte per quad, the quadtree boxes
/// and the layers' cumulative areas, and refers to `map`, which must outlive it.
class ReliefReconstructionIndex {
 public:
  /// Throws InvalidInput when the map reconstructs to no triangles (or only zero-area ones); LibraryError on
  /// Embree failures.
  ReliefReconstructionIndex(const EmbreeDevice& device, const ReliefMap& map, double max_edge_texels = 8.0);
  ~ReliefReconstructionIndex();
  ReliefReconstructionIndex(const ReliefReconstructionIndex&) = delete;
  ReliefReconstructionIndex& operator=(const ReliefReconstructionIndex&) = delete;

  [[nodiscard]] std::size_t faces() const;                ///< reconstruct_relief(map).num_faces()
  [[nodiscard]] std::size_t vertices() const;             ///< its vertices: the non-empty texels
  [[nodiscard]] std::size_t referenced_vertices() const;  ///< the texels that are a vertex of some triangle

  /// Exact distances from `points` to the reconstruction, in blocks of kDistanceBlock consecutive points
  /// (a caller splitting the points at multiples of it gets the same values). Throws after
  /// release_distances().
  [[nodiscard]] std::vector<double> distances(std::span<const Vec3> points, const ProgressCallback& progress,
                                              std::string_view stage) const;
  /// Frees what distances() needs.
  void release_distances();
  /// sample_surface's n area samples of the reconstruction with `seed` (see the file comment).
  [[nodiscard]] std::vector<Vec3> area_samples(std::size_t n, std::uint64_t seed) const;
  /// Every referenced vertex lies within this distance of the original the map was built from: below it,
  /// the vertices can raise a one-sided maximum and must be measured.
  [[nodiscard]] double vertex_bound() const;
  /// The referenced vertices, in layer order, in batches of about 2²⁰.
  void for_each_vertex_batch(const std::function<void(std::span<const Vec3>)>& batch) const;

 private:
  struct Impl;
  const ReliefMap* map_;
  std::unique_ptr<Impl> impl_;
};

/// Symmetric Hausdorff distance and PSNR between `original` (A) and reconstruct_relief(map,
/// max_edge_texels) (B), as symmetric_hausdorff computes them (options.samples area samples per
/// direction, options.seed, options.include_vertices; progress stages "distance A->B", "distance B->A"),
/// without building B. `map` must have been built from `original` (the bound on B's vertices relies on
/// it). ba.vertex_samples counts B's referenced vertices, whether they were measured or bounded. Throws InvalidInput when options.samples is 0, `original` has no faces or no area, or the map
/// reconstructs to no triangles (or only zero-area ones); LibraryError on Embree failures; Cancelled
/// through options.progress.
[[nodiscard]] ReliefFidelity relief_fidelity(const EmbreeDevice& device, MeshView original, const ReliefMap& map,
                                             const HausdorffOptions& options = {}, double max_edge_texels = 8.0);

}  // namespace gimforge
