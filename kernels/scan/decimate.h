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
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"

namespace gimforge {

struct DecimateOptions {
  std::size_t target_faces{0};              ///< stop at this many faces (or when no collapse is allowed)
  std::span<const std::uint8_t> locked{};   ///< empty, or one flag per input vertex: 1 = never moved
  double max_normal_turn_degrees{60.0};     ///< a collapse may turn no face normal by more (0 < x ≤ 180)
  /// More than 1: the faces are first cut into this many spatial bricks (recursive median splits of their
  /// centroids), each decimated on its own, in parallel, to twice its share of the target with the vertices
  /// it shares with other bricks locked; the welded result is then decimated as a whole. The result depends
  /// on `bricks`, never on the number of threads. Used only when the mesh has more than 4 × target faces.
  std::size_t bricks{1};
  ProgressCallback progress{};              ///< stage "decimate", fraction of the collapses needed
};

struct DecimateResult {
  TriMesh mesh;                              ///< the referenced vertices that remain, in input order
  std::vector<std::uint32_t> source_vertex;  ///< input index of each vertex of `mesh`
  /// Input faces OpenMesh could not insert (a face that would make a vertex's fan non-manifold): left out
  /// of the decimation and of the result, counted here so callers can say so.
  std::size_t rejected_faces{0};
};

/// Decimates `mesh` to at most options.target_faces faces where the topology and the locks allow (fewer
/// collapses may be possible: result.mesh.num_faces() says what was reached). Faces keep their
/// orientation. Throws InvalidInput for target_faces 0, a locked list of the wrong size, a normal bound out of
/// range or a face index out of range; Cancelled via progress.
[[nodiscard]] DecimateResult decimate_quadric(MeshView mesh, const DecimateOptions& options);

}  // namespace gimforge
