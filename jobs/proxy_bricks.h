#pragma once
/// \file proxy_bricks.h
/// The proxy of a scan read from its binary PLY in bricks, without holding it whole (issue #17 items 4 and 5;
/// jobs/proxy.h makes the same proxy from a loaded mesh). The k-d bricks of the vertex histogram
/// (vertex_bricks) are decimated one by one with the vertices they share locked (decimate_piece), and the
/// welded pieces are then decimated whole (finish_pieces). A face belongs to the brick of its first vertex;
/// faces with a repeated vertex and the scan's dropped duplicates are left out, as the loader leaves them out.
/// `mpirun convert` deals the bricks out to its ranks (jobs/brick_convert.h), `batch` makes each a task
/// (jobs/brick_tasks.h); the pieces, and so the proxy, are the same either way.
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "jobs/bytes.h"
#include "jobs/scan_bricks.h"
#include "kernels/core/progress.h"
#include "kernels/scan/decimate.h"

namespace gimforge::jobs {

/// Marks of ProxyBricks.
inline constexpr std::uint8_t kNoBrick = 0xff;     ///< an unreferenced vertex
inline constexpr std::uint8_t kSeamVertex = 0xfe;  ///< a vertex used by faces of two bricks

/// Where the vertices of a scan lie among the proxy's bricks.
struct ProxyBricks {
  std::size_t bricks{0};
  std::vector<std::uint8_t> brick_of_vertex;  ///< per file vertex: its brick, kNoBrick when unreferenced
  /// Per file vertex: the brick of the faces that use it, kSeamVertex when faces of two bricks do (it is
  /// locked in its bricks' decimation), kNoBrick when no kept face does.
  std::vector<std::uint8_t> seam;
  std::vector<std::uint64_t> brick_faces;  ///< kept faces of each brick
};

/// Local: one pass over the vertices and one over the faces of `scanned`. `keep(brick, face)` sees every
/// kept face in file order (e.g. to collect a rank's bricks); it may be empty. Throws what reading throws.
[[nodiscard]] ProxyBricks assign_proxy_bricks(const ScannedMesh& scanned, const BrickPartition& partition,
                                              const Vec3& origin,
                                              const std::function<void(std::uint8_t, const Face&)>& keep);

/// Local: decimates the faces of one brick (file vertex ids, in file order) to its share of `target`
/// (brick_target of `scan_faces`), positions read from the file and translated by −origin.
[[nodiscard]] DecimatedPiece decimate_brick(const io::PlyTriangleFile& file, const std::vector<Face>& faces,
                                            const ProxyBricks& bricks, const Vec3& origin, std::size_t target,
                                            std::uint64_t scan_faces);

/// Welds the pieces present (in brick order) over `file_vertices` ids and decimates the whole to `target`;
/// records proxy_faces, proxy_vertices, proxy_rejected_faces and proxy_bricks (= `bricks`) in `numbers`.
/// Throws as finish_pieces, and InvalidInput when the proxy has no face left.
[[nodiscard]] TriMesh finish_proxy(std::vector<DecimatedPiece> pieces, std::uint64_t file_vertices,
                                   std::size_t target, std::size_t bricks, const ProgressCallback& progress,
                                   std::map<std::string, double>& numbers);

/// A piece in a Bytes buffer (brick id first) and back; get_piece throws FormatError for a short buffer.
void put_piece(Bytes& out, std::uint64_t brick, const DecimatedPiece& piece);
[[nodiscard]] std::pair<std::uint64_t, DecimatedPiece> get_piece(Bytes& in);

}  // namespace gimforge::jobs
