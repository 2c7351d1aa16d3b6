#pragma once
/// \file distributed_metrics.h
/// The papers' fidelity metric (kernels/core/hausdorff.h) over the ranks of a communicator: `mpirun -n N
/// gimforge metrics A B` gives the single-rank result bit for bit.
///
/// The ranks form two groups, one per direction (A→B and B→A, sized by each direction's estimated work),
/// so each rank builds one BVH; within a group every rank draws the same seeded samples and answers a
/// contiguous run of whole distance blocks (kDistanceBlock points: the blocks, and so every distance, are the
/// ones one process computes), and rank 0 gathers the distances in index order and reduces them as
/// summarize_distances always does. This path splits the queries and the BVHs, not the meshes: every rank
/// reads both. `metrics` uses it for inputs that cannot be read in pieces; binary PLY triangle files go by
/// spatial bricks instead (jobs/brick_metrics.h).
#include <span>
#include <vector>

#include "kernels/core/embree_device.h"
#include "kernels/core/hausdorff.h"
#include "mpi/comm.h"

namespace gimforge::jobs {

/// One direction's statistics as 5 doubles (max, mean, rms, area samples, vertex samples), for a broadcast,
/// and back.
[[nodiscard]] std::vector<double> to_summary(const OneSidedDistance& d);
[[nodiscard]] OneSidedDistance from_summary(std::span<const double> v);

/// symmetric_hausdorff over `comm` (collective; every rank passes the same meshes and options, and every
/// rank gets the result). Progress is reported by rank 0 only. A failure on any rank fails every rank
/// (mpi::run_agreed): the lowest failing rank throws its error, the others mpi::PeerFailed.
[[nodiscard]] HausdorffResult distributed_hausdorff(const mpi::Comm& comm, const EmbreeDevice& device, MeshView a,
                                                    MeshView b, const HausdorffOptions& options);

}  // namespace gimforge::jobs
