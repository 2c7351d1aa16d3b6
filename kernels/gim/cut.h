#pragma once
/// \file cut.h
/// Cutting a 2-manifold into a topological disk (Gu, Gortler, Hoppe 2002, §3.2): the initial cut by
/// peeling triangles from a seed in order of geodesic distance and trimming dangling edge trees, original
/// boundaries frozen in the cut, cut-paths straightened by constrained shortest paths; the two-edge cut of
/// a closed genus-0 mesh; opening the mesh along a cut; and the pieces of iterated cut augmentation
/// (extremal vertex under a Floater parametrization, shortest path from it to the cut).
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/param/stretch.h"

namespace gimforge {

/// A cut: a set of undirected mesh edges {u, v} (u < v) of the input mesh. Always contains every original
/// boundary edge. Cutting along it turns the mesh into a topological disk.
struct Cut {
  std::vector<std::array<std::uint32_t, 2>> edges;
};

struct CutOptions {
  std::uint32_t seed_face{0};   ///< face removed first (peeling starts here)
  bool straighten{true};        ///< straighten cut-paths by constrained shortest paths
};

/// Initial cut of a single-component, manifold, orientable mesh (closed or with boundaries), Gu §3.2:
/// the seed face is removed, then faces are peeled across non-boundary edges in order of geodesic distance
/// from the seed (Dijkstra over face centroids); the remaining edges minus their dangling trees form the cut,
/// which contains every original boundary edge. For a closed genus-0 mesh (nothing remains but a vertex) the
/// result is two adjacent edges (see two_edge_cut). With `options.straighten`, every cut-path that is not an
/// original boundary is replaced by the shortest path between its cut-nodes within 3 rings of it on one side
/// of it in the opened mesh (two passes) — which keeps the cut valid by construction; the opened mesh is
/// checked once more at the end. Cost O(F log F).
/// Throws InvalidInput (index out of range, degenerate face, seed out of range) or TopologyError (no faces,
/// several components, non-manifold, non-orientable), naming what was found.
[[nodiscard]] Cut initial_cut(MeshView mesh, const CutOptions& options = {});

/// The mesh opened along a cut: M' (a topological disk) and its boundary ρ'.
/// - `disk`: vertices of M (replicated along the cut: a vertex of cut-valence k appears k times),
///   faces re-indexed; same orientation as the input.
/// - `original_vertex[v']`: the input vertex of disk vertex v'.
/// - `boundary`: the boundary loop ρ' of the disk as disk vertex indices, in order, each once, oriented so
///   the disk interior lies to the left (counter-clockwise when the disk is laid out with positive area).
struct CutMesh {
  TriMesh disk;
  std::vector<std::uint32_t> original_vertex;
  std::vector<std::uint32_t> boundary;
};

/// Opens `mesh` along `cut` (original boundary edges count as cut even if `cut` omits them). Disk vertices are
/// the wedges of face corners around each input vertex separated by cut edges; disk face f is input face f.
/// Precondition: single component, manifold, consistently oriented. Throws InvalidInput (a cut pair that is
/// no mesh edge, bad indices) or TopologyError (unsuitable mesh; result not one disk: several pieces, several
/// boundary loops or Euler characteristic != 1, e.g. an empty cut of a closed mesh). Cost O(F log F).
[[nodiscard]] CutMesh open_cut(MeshView mesh, const Cut& cut);

/// The input vertex at which to extend the cut: a vertex of the triangle with the largest L2 stretch
/// under the given parametrization `uv` of `cut_mesh.disk` (Gu §3.2), excluding vertices already on the
/// cut. Returns the input-mesh vertex index.
/// Details: triangles whose three vertices lie on the cut are skipped (extending from them would add
/// nothing); a flipped or degenerate parameter triangle counts as infinite stretch; of the chosen triangle's
/// vertices off the cut, the one farthest from the cut (shortest-path distance over disk edges) is returned.
/// Returns kInvalidIndex (edge_topology.h) when every disk vertex lies on the cut. Throws InvalidInput when
/// `uv` or `original_vertex` does not have one entry per disk vertex.
[[nodiscard]] std::uint32_t extremal_vertex(const CutMesh& cut_mesh, std::span<const Vec2> uv);

/// The cut extended by the shortest path (edge lengths, Dijkstra) on the input mesh from `vertex` to the
/// current cut. The result is still a valid cut (opens the mesh into a disk). Returns the cut (sorted, with
/// every original boundary edge) unchanged when `vertex` is already on it. Throws InvalidInput for a vertex
/// out of range, an empty cut or a cut pair that is no mesh edge.
[[nodiscard]] Cut extend_cut(MeshView mesh, const Cut& cut, std::uint32_t vertex);

/// The cut replaced by two adjacent edges at `vertex` (Gu §3.2, genus-0 first-extremum rule): the two edges
/// (vertex, a), (vertex, b) with the widest angle between them, a simple path, so the opened mesh is a disk.
/// Throws TopologyError unless the mesh is a single closed genus-0 manifold, InvalidInput for a vertex out of
/// range or on fewer than two edges.
[[nodiscard]] Cut two_edge_cut(MeshView mesh, std::uint32_t vertex);

}  // namespace gimforge
