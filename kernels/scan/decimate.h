#pragma once
/// \file decimate.h
/// Quadric-error decimation (Garland & Heckbert 1997) of a triangle mesh to a face budget, with OpenMesh's
/// Decimater: the proxies through which huge scans reach the image methods (issue #17 item 4). Collapses
/// are half-edge collapses (a vertex moves onto a neighbour), so every proxy vertex is an input vertex and
/// lies on the input surface; OpenMesh refuses collapses that would make the mesh non-manifold, and a
/// normal-flipping module refuses those that would turn a face over by more than 60°, and an aspect-ratio
/// module (bound 10) those that would make slivers, which parametrize badly (BENCHMARKS.md "Proxies").
/// Vertices can be locked (they stay, with all their faces' corners): brick borders, so that decimated
/// bricks fit back together.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"

namespace gimforge {

/// Brick ids are below this (the seam marks of seam_vertices use the bytes above).
inline constexpr std::uint8_t kMaxBricks = 254;

struct DecimateOptions {
  std::size_t target_faces{0};              ///< stop at this many faces (or when no collapse is allowed)
  std::span<const std::uint8_t> locked{};   ///< empty, or one flag per input vertex: 1 = never moved
  double max_normal_turn_degrees{60.0};     ///< a collapse may turn no face normal by more (0 < x ≤ 180)
  /// Empty, or one brick id per face (< kMaxBricks; the caller's spatial partition): every brick is then first
  /// decimated on its own, in parallel, to brick_target of the target with the vertices it shares with other
  /// bricks locked (decimate_piece), and the welded pieces are decimated as a whole (finish_pieces). The
  /// result depends on the bricks, never on the number of threads.
  std::span<const std::uint8_t> brick_of_face{};
  ProgressCallback progress{};              ///< stage "decimate", fraction of the collapses needed
};

struct DecimateResult {
  TriMesh mesh;                              ///< the referenced vertices that remain, in input order
  std::vector<std::uint32_t> source_vertex;  ///< input index of each vertex of `mesh`
  /// Input faces OpenMesh could not insert (a face that would make a vertex's fan non-manifold): left out
  /// of the decimation and of the result, counted here so callers can say so.
  std::size_t rejected_faces{0};
};

/// A brick's faces after its own decimation, over input vertex ids.
struct DecimatedPiece {
  std::vector<std::uint32_t> ids;  ///< input id of every vertex of the piece, ascending
  std::vector<Vec3> positions;
  std::vector<Face> faces;         ///< indices into ids / positions
  std::size_t rejected_faces{0};
};

/// Twice a brick's share of the target, so that the final pass has room to choose: max(1, 2·T·F_b / F).
[[nodiscard]] inline std::size_t brick_target(std::size_t target, std::size_t brick_faces, std::size_t faces) {
  return std::max<std::size_t>(1, static_cast<std::size_t>(2.0 * static_cast<double>(target) *
                                                           static_cast<double>(brick_faces) / static_cast<double>(faces)));
}

/// Per input vertex: 1 when faces of two bricks use it (a seam, locked in the bricks' own decimation).
[[nodiscard]] std::vector<std::uint8_t> seam_vertices(MeshView mesh, std::span<const std::uint8_t> brick_of_face);

/// Decimates one brick: `brick` over its vertices, whose input ids are `ids` (ascending), `locked` per
/// vertex (seams and the caller's locks), to `target_faces`. Throws as decimate_quadric.
[[nodiscard]] DecimatedPiece decimate_piece(MeshView brick, std::span<const std::uint32_t> ids,
                                            std::span<const std::uint8_t> locked, std::size_t target_faces,
                                            double max_normal_turn_degrees = 60.0);

/// Welds the pieces by input id (ids < id_count; the first piece that names an id gives its position) and
/// decimates the whole to options.target_faces (options.locked indexed by input id; brick_of_face ignored).
/// result.source_vertex holds input ids. Throws InvalidInput for ids out of range or no face.
[[nodiscard]] DecimateResult finish_pieces(std::span<const DecimatedPiece> pieces, std::size_t id_count,
                                           const DecimateOptions& options);

/// Decimates `mesh` to at most options.target_faces faces where the topology and the locks allow (fewer
/// collapses may be possible: result.mesh.num_faces() says what was reached). Faces keep their
/// orientation. Throws InvalidInput for target_faces 0, a locked list of the wrong size, a normal bound out of
/// range or a face index out of range; Cancelled via progress.
[[nodiscard]] DecimateResult decimate_quadric(MeshView mesh, const DecimateOptions& options);

}  // namespace gimforge
