#pragma once
/// \file surface_transfer.h
/// Moves points that lie on a coarse proxy of a surface onto the surface itself (issue #17 item 4): the
/// samples of an image made from a decimated proxy take the detail of the full-resolution scan.
///
/// A point p goes along the proxy's smooth normal n at p (the proxy's area-weighted vertex normals,
/// interpolated at p's closest point on the proxy) to the nearest crossing of the surface in either
/// direction — a crossing is taken when it is no farther than `ray_factor` × p's distance to the surface
/// (plus 1e-9 of the proxy's diagonal), and otherwise, or when there is none, p goes to its closest point on
/// the surface (a thin part whose other side is nearer along n, a fold of the proxy). The answer depends
/// on p alone, so equal points (a geometry image's glued mates, a multi-chart image's unified samples,
/// a spherical image's boundary copies) stay equal and a watertight image stays watertight.
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include "kernels/core/embree_device.h"
#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"

namespace gimforge {

struct TransferOptions {
  double ray_factor{2.0};       ///< a normal crossing at most this × the closest distance away is taken (≥ 1)
  ProgressCallback progress{};  ///< stage "transfer"
};

struct TransferStats {
  std::size_t points{0};        ///< finite points moved
  std::size_t along_normal{0};  ///< of which along the proxy normal
  std::size_t closest{0};       ///< of which to the closest point
  double max_move{0.0};         ///< largest distance a point moved
  double rms_move{0.0};         ///< root mean square of the distances moved
};

struct TransferResult {
  std::vector<Vec3> positions;  ///< one per input point; a non-finite input point is copied as it is
  std::vector<Vec3> normals;    ///< the surface's interpolated area-weighted vertex normal there (unit), NaN for non-finite input
  std::vector<std::uint32_t> faces;  ///< the surface face the point moved onto, kNoFace for non-finite input
  std::vector<Vec3> barycentric;     ///< the point's barycentric coordinates in that face
  TransferStats stats;
};

/// One way to move a point: where it lands, the surface's normal there, the face and its barycentric
/// coordinates, and how far it moves (∞: none).
struct TransferCandidate {
  double distance{std::numeric_limits<double>::infinity()};
  Vec3 point{Vec3::Zero()};
  Vec3 normal{Vec3::Zero()};
  std::uint32_t face{kNoFace};
  Vec3 barycentric{Vec3::Zero()};
};

/// Per point: its closest point on the surface, and the nearer crossing of the two rays from it along ±n.
struct TransferCandidates {
  std::vector<TransferCandidate> closest;
  std::vector<TransferCandidate> crossing;
};

/// The proxy's and the surface's search structures, built once for any number of point sets. Both meshes
/// must outlive it. Queries are thread-safe.
///
/// Split across processes: each builds it over the faces it owns (`query_faces`; the others around them
/// only lend their area to the vertex normals), takes candidates(), keeps per point the candidate of
/// least distance over all processes (for each of the two kinds), and assemble()s: the same result as one
/// process over the whole surface.
class SurfaceTransfer {
 public:
  /// `query_faces`: empty (every face) or one flag per surface face: the faces queries see. Throws
  /// InvalidInput for an empty proxy or surface, flags of the wrong size or a ray_factor below 1,
  /// LibraryError from Embree.
  SurfaceTransfer(const EmbreeDevice& device, MeshView proxy, MeshView surface, const TransferOptions& options = {},
                  std::span<const std::uint8_t> query_faces = {});
  ~SurfaceTransfer();
  SurfaceTransfer(const SurfaceTransfer&) = delete;
  SurfaceTransfer& operator=(const SurfaceTransfer&) = delete;

  /// Moves every finite point of `points` (near the proxy) onto the surface. Throws Cancelled via progress.
  [[nodiscard]] TransferResult operator()(std::span<const Vec3> points) const;
  /// The candidates of every point over the query faces (∞ distances for non-finite points, and for every
  /// point when no face is queried). Throws Cancelled via progress.
  [[nodiscard]] TransferCandidates candidates(std::span<const Vec3> points) const;
  /// The result from candidates (each the least over the faces): the crossing when it is no farther than
  /// ray_factor × the closest distance + tolerance, else the closest point. Throws NumericalError when a
  /// finite point has no closest point.
  [[nodiscard]] TransferResult assemble(std::span<const Vec3> points, const TransferCandidates& candidates) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// SurfaceTransfer(device, proxy, surface, options)(points), for one point set.
[[nodiscard]] TransferResult transfer_to_surface(const EmbreeDevice& device, MeshView proxy, MeshView surface,
                                                 std::span<const Vec3> points, const TransferOptions& options = {});

/// Area-weighted vertex normals (unit; zero for a vertex without area around it).
[[nodiscard]] std::vector<Vec3> area_weighted_vertex_normals(MeshView mesh);

}  // namespace gimforge
