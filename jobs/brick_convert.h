#pragma once
/// \file brick_convert.h
/// `mpirun -n N gimforge convert SCAN.ply --method gim|sphere|mcgim` of a scan no rank holds whole (issue #17
/// item 4; ../shared/notes/huge-scans.md). The image is made from a proxy, as one process makes it
/// (jobs/proxy.h), and every step that touches the full scan is split by bricks:
/// 1. **Proxy**: every rank scans the file (jobs/scan_bricks.h); the proxy_bricks k-d bricks of the vertex
///    histogram are dealt out (brick b to rank b mod N); a rank reads the faces of its bricks (a face
///    belongs to its first vertex's brick) and decimates each with its seams locked (decimate_piece); rank 0
///    welds the pieces in brick order and decimates the whole (finish_pieces). The bricks, the pieces and
///    their order do not depend on N: the proxy is the one a single process makes.
/// 2. **Method**: rank 0 runs it on the proxy; the proxy and the image's sample points go to every rank.
/// 3. **Transfer**: each rank reads its brick of the scan with a ghost layer (read_brick) and takes every
///    sample's candidates over the faces it owns (SurfaceTransfer::candidates; vertex normals over owned and
///    ghost faces, which hold every face around an owned face's vertices); per sample the least candidate
///    over the ranks wins (allreduce), and rank 0 assembles the moved samples.
/// 4. **Fidelity**: brick_hausdorff of the scan against the reconstruction, and against the proxy, written
///    by rank 0 as temporary binary PLY files (double) beside the output and removed afterwards.
/// Exact duplicate faces are dropped first, as the loader's repair drops them (drop_duplicate_faces), so the
/// proxy, the face count and the fidelity are those of the repaired mesh. Colours are not transferred on this
/// path (the scan is read as positions only).
#include <filesystem>
#include <optional>

#include "jobs/pipeline.h"
#include "kernels/core/embree_device.h"
#include "mpi/comm.h"

namespace gimforge::jobs {

/// Whether `convert` of `mesh` goes by bricks over `comm`: more than one rank, an image method without
/// --sphere-map, a binary PLY of triangles readable in pieces (io/ply_ranges.h) whose face count calls for
/// a proxy (MethodOptions::proxy_target of the file's face count). Throws what PlyTriangleFile::open throws.
[[nodiscard]] bool converts_in_bricks(const mpi::Comm& comm, const std::filesystem::path& mesh,
                                      const ConversionRequest& request);

/// The conversion (see the file comment). Collective; rank 0 returns the whole Conversion, the others one
/// without results; every rank returns std::nullopt, before any long work, when the scan without its
/// degenerate faces needs no proxy after all (MethodOptions::proxy_target 0: convert it whole). `scratch`
/// is a directory every rank can read where rank 0 may write the temporary files. A failure on any rank
/// fails every rank (mpi::run_agreed; mpi::PeerFailed on the others).
[[nodiscard]] std::optional<Conversion> brick_convert(const mpi::Comm& comm, const EmbreeDevice& device,
                                       const std::filesystem::path& mesh, const ConversionRequest& request,
                                       const std::filesystem::path& scratch);

}  // namespace gimforge::jobs
