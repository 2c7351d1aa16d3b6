#pragma once
/// \file brick_relief.h
/// `mpirun -n N gimforge convert SCAN.ply --method relief` of a scan no rank holds whole (issue #17 item 3;
/// ../shared/notes/huge-scans.md), equal to the one-process conversion bit for bit: the same map, the same
/// statistics and the same fidelity figures.
///
/// 1. **Bricks**: every rank scans the file (jobs/scan_bricks.h) and reads its brick: the faces whose first
///    vertex lies in it (its own faces; every face has exactly one owner) plus a ghost layer of faces within
///    0.5 % of the diagonal + 2 × the longest edge. Duplicate faces are dropped (see the end).
/// 2. **Inside test**: whether the whole scan is closed and edge-manifold (the flood fill decides) is the
///    conjunction of each rank's check of its own faces' edges, counted over its own and ghost faces (every
///    face around an own face's edge is held).
/// 3. **Cells, per grid level** (kernels/relief/relief_cells.h cell_face_parts / finish_cell_grid): each
///    rank classifies against its own faces; the grey cells (bitwise or) and the parity toggles (xor) are
///    combined over the ranks, and every rank finishes the same grid (n³ bytes each: grids up to 1024).
/// 4. **Sampling** (§3.3.2): each rank traces its own faces through the layers of the cells they overlap
///    and reports every hit (kernels/relief/relief_map.h sample_relief_hits); rank 0 sorts all hits by
///    texel and face and replays the depth test in the order one process meets them (resolve_relief_hits).
///    Its counts decide the next level of the automatic grid choice (§3.3.3), broadcast to every rank.
/// 5. **Fidelity** (kernels/relief/relief_fidelity.h, as relief_fidelity measures it): the texels go to
///    every rank. Scan → reconstruction: the scan's samples (brick_samples) split over the ranks in blocks,
///    each rank its slice of the scan's vertices for the maximum. Reconstruction → scan: the
///    reconstruction's samples answered by the bricks (brick_distances).
/// Rank 0 gathers and writes. Vertex colours are not read on this path: a PLY with more than x y z per
/// vertex is converted by rank 0 alone (converts_relief_in_bricks). What the loader's repair removes is left
/// out here too: faces with a repeated vertex, unreferenced vertices, and exact duplicate faces (the same
/// three vertices in any order; the first in the file stays), which each face's owner finds among the faces
/// it holds (every copy of an own face is held) and every rank then skips (ScannedMesh::dropped).
#include <filesystem>

#include "jobs/pipeline.h"
#include "kernels/core/embree_device.h"
#include "mpi/comm.h"

namespace gimforge::jobs {

/// Whether `convert` of `mesh` with `request` goes by bricks over `comm`: more than one rank, --method
/// relief, a binary PLY of triangles readable in pieces (io/ply_ranges.h) whose vertex records hold only
/// x y z. Throws what PlyTriangleFile::open throws.
[[nodiscard]] bool converts_relief_in_bricks(const mpi::Comm& comm, const std::filesystem::path& mesh,
                                             const ConversionRequest& request);

/// The conversion (see the file comment). Collective (any size, 1 included); rank 0 returns the whole
/// Conversion (ranks and rank_peak_rss_mb among its numbers), the others one without results. A failure on
/// any rank fails every rank (mpi::run_agreed; mpi::PeerFailed on the others).
[[nodiscard]] Conversion brick_relief(const mpi::Comm& comm, const EmbreeDevice& device, const std::filesystem::path& mesh,
                                      const ConversionRequest& request);

}  // namespace gimforge::jobs
