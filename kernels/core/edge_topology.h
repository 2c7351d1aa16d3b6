#pragma once
/// \file edge_topology.h
/// Undirected edges of a triangle soup and their incident face corners: the connectivity that the
/// validation and topology kernels share. Works on any input (non-manifold, inconsistently oriented).
#include <cstdint>
#include <vector>

#include "kernels/core/mesh.h"

namespace gimforge {

/// Marks a missing index (an edge of a degenerate face, say).
inline constexpr std::uint32_t kInvalidIndex = 0xffffffffu;

/// Edge connectivity.
/// - Halfedge h = 3*f + i runs from faces[f][i] to faces[f][(i+1)%3].
/// - `edges[e]` = {u, v} with u < v; edges are sorted lexicographically.
/// - `halfedge_edge[h]` = the edge of halfedge h, or kInvalidIndex when h belongs to a degenerate face
///   (a face with a repeated vertex index): such faces contribute no edges.
/// - Halfedges of edge e: `edge_halfedges[edge_offsets[e] .. edge_offsets[e+1])`, in increasing order.
struct EdgeTopology {
  std::vector<std::array<std::uint32_t, 2>> edges;
  std::vector<std::uint32_t> halfedge_edge;
  std::vector<std::uint32_t> edge_offsets;
  std::vector<std::uint32_t> edge_halfedges;

  [[nodiscard]] std::size_t num_edges() const { return edges.size(); }
  /// Number of face sides on edge e (1: boundary, 2: manifold interior, >2: non-manifold).
  [[nodiscard]] std::uint32_t valence(std::size_t e) const { return edge_offsets[e + 1] - edge_offsets[e]; }
};

/// Builds the edge table. Precondition: every index < positions.size() (see validate.h).
/// O(F log F); the sort runs in parallel.
[[nodiscard]] EdgeTopology build_edge_topology(MeshView mesh);

/// Tail and head vertex of halfedge h.
[[nodiscard]] inline std::uint32_t halfedge_tail(MeshView mesh, std::size_t h) { return mesh.faces[h / 3][h % 3]; }
[[nodiscard]] inline std::uint32_t halfedge_head(MeshView mesh, std::size_t h) {
  return mesh.faces[h / 3][(h % 3 + 1) % 3];
}

/// Disjoint-set forest with path halving and union by size.
class UnionFind {
 public:
  explicit UnionFind(std::size_t n);
  std::uint32_t find(std::uint32_t x);
  /// Returns true if x and y were in different sets.
  bool unite(std::uint32_t x, std::uint32_t y);

 private:
  std::vector<std::uint32_t> parent_;
  std::vector<std::uint32_t> size_;
};

}  // namespace gimforge

namespace gimforge {

/// Edges and vertices where the surface is not a 2-manifold, and edges where neighbouring faces disagree
/// on orientation.
/// - `nonmanifold_edges`: edges with more than two incident face sides.
/// - `nonmanifold_vertices`: vertices whose incident faces form more than one fan (edge-connected
///   umbrella) — e.g. two cones touching at their tips, or any vertex of a non-manifold edge.
/// - `inconsistent_edges`: two-sided edges whose two faces traverse them in the same direction.
/// - `vertex_fans[v]`: number of fans at vertex v (0 for an unreferenced vertex).
struct ManifoldCheck {
  std::vector<std::uint32_t> nonmanifold_edges;
  std::vector<std::uint32_t> nonmanifold_vertices;
  std::vector<std::uint32_t> inconsistent_edges;
  std::vector<std::uint32_t> vertex_fans;
};

/// Computes the ManifoldCheck from the edge table (corner union-find, O(F α)).
[[nodiscard]] ManifoldCheck check_manifold(MeshView mesh, const EdgeTopology& topo);

}  // namespace gimforge
