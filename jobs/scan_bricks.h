#pragma once
/// \file scan_bricks.h
/// A huge mesh in a binary PLY read across the ranks of a communicator without any rank holding it whole
/// (issue #17 item 1; ../shared/notes/huge-scans.md):
/// - scan_mesh: every rank streams the face records once (which vertices faces use) and its slice of the
///   vertex records (the bounding box, allreduced);
/// - read_face_slice: rank r's slice of the faces in file order, with the positions they use;
/// - read_brick: a k-d partition of the vertices into one brick of equal vertex count per rank
///   (kernels/scan/bricks.h); rank r holds the faces whose first vertex lies in brick r (every face has
///   exactly one owner, whatever the rank count) plus a ghost layer: the faces with a vertex within the
///   margin of the brick.
/// Faces with a repeated vertex are skipped everywhere, as `metrics` and the loaders drop them. Positions
/// are translated by −origin (a local frame shared by the caller's meshes). Collective calls fail on every
/// rank together (mpi::run_agreed).
#include <algorithm>
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "io/ply_ranges.h"
#include "kernels/core/mesh.h"
#include "kernels/scan/bricks.h"
#include "mpi/comm.h"

namespace gimforge::jobs {

/// What every rank knows about a mesh file after scan_mesh.
struct ScannedMesh {
  const io::PlyTriangleFile* file{nullptr};
  std::vector<std::uint8_t> referenced;  ///< per vertex: 1 when a face with three distinct vertices uses it
  std::uint64_t faces{0};                ///< faces with three distinct vertices
  std::uint64_t vertices{0};             ///< referenced vertices
  BoundingBox box;                       ///< of the referenced vertices, in the file's frame
  /// File indices (sorted) of faces the caller removes as the loader's repair would (exact duplicates of an
  /// earlier face, jobs/brick_relief.cpp); read_face_slice and read_brick skip them, and `faces` excludes them.
  std::vector<std::uint64_t> dropped;
  [[nodiscard]] bool is_dropped(std::uint64_t face) const { return std::binary_search(dropped.begin(), dropped.end(), face); }
};

/// Collective. Throws (on the lowest failing rank; mpi::PeerFailed on the others) what reading throws, and
/// InvalidInput "FILE: no faces with three distinct vertices".
[[nodiscard]] ScannedMesh scan_mesh(const mpi::Comm& comm, const io::PlyTriangleFile& file);

/// Collective, after the last read of the file at `path` (shown as `shown`): throws InvalidInput "SHOWN: changed
/// while it was read ..." on every rank when its io::file_stamp (size, modification time) is no longer `stamp`,
/// taken before the first read. The ranks read a scan in pieces at different times, and some steps open it
/// again by its path: a file rewritten or replaced meanwhile gave a result mixed from two files, exit 0.
void require_unchanged(const mpi::Comm& comm, const std::filesystem::path& path, const std::string& shown,
                       const std::string& stamp);

/// The part [first, last) of `count` items that rank r of `size` takes.
[[nodiscard]] std::array<std::uint64_t, 2> slice_of(std::uint64_t count, int rank, int size);

/// Rank `rank`'s slice of the faces (slice_of the file's faces, degenerate ones skipped) with the positions
/// they use, translated by −origin. Local (not collective): wrap it in mpi::run_agreed.
[[nodiscard]] TriMesh read_face_slice(const ScannedMesh& mesh, int rank, int size, const Vec3& origin);

/// Collective: the longest edge of the scan's faces (each rank its slice of the file, then the maximum).
[[nodiscard]] double scan_longest_edge(const mpi::Comm& comm, const ScannedMesh& mesh, const Vec3& origin);

/// The longest edge of face f.
[[nodiscard]] double longest_edge(MeshView mesh, std::size_t f);

struct BrickOptions {
  double margin_fraction{0.005};  ///< ghost margin: this fraction of the box diagonal ...
  double longest_edge{0.0};       ///< ... plus twice the mesh's longest edge (see BrickMesh::certified)
  bool face_ids{false};           ///< also return each held face's index in the file
};

/// The faces rank r holds.
struct BrickMesh {
  TriMesh mesh;                         ///< brick and ghost faces, positions translated by −origin
  std::vector<std::uint8_t> owned;      ///< per face: 1 for the brick's own faces, 0 for ghosts
  std::vector<std::uint64_t> face_ids;  ///< per face: its file index (BrickOptions::face_ids)
  BrickPartition partition;             ///< every rank's bricks (rank r has brick r), in the local frame
  BoundingBox bounds;                   ///< brick r's box
  double margin{0.0};                   ///< g
  double longest_edge{0.0};             ///< L (BrickOptions::longest_edge)

  /// Whether distance d, found from point p to this rank's faces, is the distance to the whole mesh: every
  /// face not held has all its vertices farther than g from the brick, so all its points farther than
  /// g − L, and from p farther than g − L − dist(p, brick).
  [[nodiscard]] bool certified(const Vec3& p, double d) const;
};

/// The empty histogram every brick cut of a mesh with (local-frame) box `box` counts vertices in: cubic
/// cells, 64 along the box's longest side. One process and any number of ranks fill the same one.
[[nodiscard]] CentroidHistogram brick_histogram(const BoundingBox& box);

/// How many bricks a proxy of `target` faces of a mesh of `faces` faces is decimated in first
/// (kernels/scan/decimate.h brick_of_face): about 250K input faces each, and at least 2 × 4096 target faces
/// each so that the locked seams stay a small part of a brick's budget (with smaller shares the seams take
/// the budget and the proxy gets worse: BENCHMARKS.md "Proxies"). 1 to 64; a function of the sizes only,
/// never of the thread or rank count, so the proxy is the same on every machine.
[[nodiscard]] std::size_t proxy_bricks(std::uint64_t faces, std::size_t target);

/// Collective: the k-d cut of the mesh's referenced vertices (translated by −origin; brick_histogram) into
/// `bricks` bricks; the same on every rank and for any rank count.
[[nodiscard]] BrickPartition vertex_bricks(const mpi::Comm& comm, const ScannedMesh& mesh, const Vec3& origin,
                                           std::size_t bricks);

/// Collective: cuts the mesh into one brick per rank and reads this rank's (see the file comment).
[[nodiscard]] BrickMesh read_brick(const mpi::Comm& comm, const ScannedMesh& mesh, const Vec3& origin,
                                   const BrickOptions& options);

/// Collective: on rank 0 every rank's `mine` concatenated in rank order; elsewhere empty.
[[nodiscard]] std::vector<double> gather_at_root(const mpi::Comm& comm, std::vector<double> mine);

/// Collective: the faces of the scan that repeat an earlier face (the same three vertices in any order; the
/// loader's repair keeps the first), found by the owner of each among the faces `brick` holds (read_brick
/// with face_ids and a margin of at least the longest edge: every copy of an own face is held). Records them
/// in scanned.dropped on every rank (rank 0 warns as the loader does), takes them out of scanned.faces and of
/// the brick, and says whether there were any.
bool drop_duplicate_faces(const mpi::Comm& comm, ScannedMesh& scanned, BrickMesh& brick);

/// How far a scan read by bricks is from an oriented 2-manifold: what the loader's validation counts
/// (kernels/core/validate.h check_topology), each edge and vertex counted once over all ranks.
struct BrickTopology {
  std::uint64_t nonmanifold_edges{0};     ///< edges with more than two faces
  std::uint64_t nonmanifold_vertices{0};  ///< vertices where separate fans of faces meet
  std::uint64_t inconsistent_edges{0};    ///< two-face edges traversed in the same direction by both
  [[nodiscard]] bool manifold() const { return nonmanifold_edges == 0 && nonmanifold_vertices == 0; }
  [[nodiscard]] bool oriented() const { return inconsistent_edges == 0; }
  /// The first defect as the loader words it ("N non-manifold edges shared by more than two faces", ...).
  [[nodiscard]] std::string first_defect() const;
};

/// Collective: the topology of the scan from every rank's `brick` (read_brick with face_ids and a margin of at
/// least the longest edge, duplicates dropped: every face around an own face's vertices is held). An edge or
/// vertex is counted by the rank that owns its face of the smallest file index.
[[nodiscard]] BrickTopology brick_topology(const mpi::Comm& comm, const BrickMesh& brick);

/// What the loader would have said about the repairs a scan read by bricks got (jobs/load_mesh.cpp): degenerate
/// faces skipped, duplicate faces dropped, unreferenced vertices ignored. Call on one rank.
void warn_repairs(const ScannedMesh& mesh);

}  // namespace gimforge::jobs
