#pragma once
/// \file brick_metrics.h
/// The fidelity metric between two huge scans over the ranks of a communicator, without any rank holding
/// either mesh whole (issue #17 item 2; ../shared/notes/huge-scans.md). For each direction X→Y:
/// - **Samples of X**: rank r reads the r-th slice of X's faces in file order and draws exactly the samples
///   of sample_surface that land on it (integer cumulative areas: kernels/core/surface_sampling.h), so the
///   sample set does not depend on the number of ranks. Rank 0 gathers them in index order and broadcasts.
/// - **Bricks of Y** (jobs/scan_bricks.h): a histogram of Y's vertices is cut into one brick per rank;
///   rank r reads the faces whose first vertex lies in brick r plus a ghost layer (faces with a vertex
///   within g = 0.5 % of the diagonal + 2 L of the brick) and builds its BVH over them.
/// - **Answers**: each sample is answered by the brick that holds it. The answer d is exact when
///   d ≤ g − L − dist(p, brick) (L: Y's longest edge): every face not held lies farther. Other samples go to
///   every rank, and the minimum of their answers is taken.
/// - **Vertices of X** (for the maximum) are measured by the rank whose brick holds them.
/// Rank 0 reduces the distances in index order as summarize_distances does, so the result equals the one
/// rank's `metrics` bit for bit.
#include <filesystem>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "kernels/core/embree_device.h"
#include "kernels/core/hausdorff.h"
#include "jobs/scan_bricks.h"
#include "mpi/comm.h"

namespace gimforge::jobs {

/// Whether both files can be read in pieces (io/ply_ranges.h: binary PLY of triangles in this machine's
/// byte order). Throws what PlyTriangleFile::open throws (a truncated file, a bad header).
[[nodiscard]] bool readable_in_bricks(const std::filesystem::path& a, const std::filesystem::path& b);

/// The pieces, for other commands that measure against a scan no rank holds (jobs/brick_relief.h).
/// A mesh's area samples in index order (on every rank) and its longest edge.
struct BrickSamples {
  std::vector<Vec3> points;
  double longest_edge{0.0};
};
/// Collective: the samples of sample_surface (options.samples, options.seed) on the mesh in `x`, translated by
/// −origin, drawn per rank on its slice of the faces (see the file comment).
[[nodiscard]] BrickSamples brick_samples(const mpi::Comm& comm, const ScannedMesh& x, const Vec3& origin,
                                         const HausdorffOptions& options);
/// Collective: the distances from `samples` (the same on every rank) to the mesh that `brick` (read_brick) is
/// this rank's part of, `bvh` over brick.mesh (null when it has no faces): each sample answered by the rank
/// whose brick holds it when certified, by every rank otherwise (the minimum). Rank 0 gets them in index
/// order, the other ranks an empty vector; bit for bit the distances_to_surface of the whole mesh.
[[nodiscard]] std::vector<double> brick_distances(const mpi::Comm& comm, const BrickMesh& brick, const TriangleBvh* bvh,
                                                  std::span<const Vec3> samples, std::string_view stage);

/// symmetric_hausdorff of the meshes in files `a` and `b` as `metrics` loads them (degenerate faces dropped,
/// A's bounding-box centre as the common origin), computed by bricks over `comm` (collective; size ≥ 2,
/// both files readable_in_bricks). Every rank gets the result; progress on rank 0. A failure on any rank
/// fails every rank (mpi::run_agreed).
/// `dropped_a`: faces of A (file indices, sorted) to leave out, as `convert` measures against the mesh its
/// loader repaired (drop_duplicate_faces); `metrics` keeps every face. `warn`: rank 0 says what the loader
/// would repair in each file, as `metrics` does (convert, which has said so once already, passes false).
[[nodiscard]] HausdorffResult brick_hausdorff(const mpi::Comm& comm, const EmbreeDevice& device,
                                              const std::filesystem::path& a, const std::filesystem::path& b,
                                              const HausdorffOptions& options,
                                              const std::vector<std::uint64_t>& dropped_a = {}, bool warn = true);

}  // namespace gimforge::jobs
