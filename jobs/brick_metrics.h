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

#include "kernels/core/embree_device.h"
#include "kernels/core/hausdorff.h"
#include "mpi/comm.h"

namespace gimforge::jobs {

/// Whether both files can be read in pieces (io/ply_ranges.h: binary PLY of triangles in this machine's
/// byte order). Throws what PlyTriangleFile::open throws (a truncated file, a bad header).
[[nodiscard]] bool readable_in_bricks(const std::filesystem::path& a, const std::filesystem::path& b);

/// symmetric_hausdorff of the meshes in files `a` and `b` as `metrics` loads them (degenerate faces dropped,
/// A's bounding-box centre as the common origin), computed by bricks over `comm` (collective; size ≥ 2,
/// both files readable_in_bricks). Every rank gets the result; progress on rank 0. A failure on any rank
/// fails every rank (mpi::run_agreed).
[[nodiscard]] HausdorffResult brick_hausdorff(const mpi::Comm& comm, const EmbreeDevice& device,
                                              const std::filesystem::path& a, const std::filesystem::path& b,
                                              const HausdorffOptions& options);

}  // namespace gimforge::jobs
