#include "kernels/core/manifold_cut.h"

#include <numeric>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge {

TriMesh split_vertices_by_fans(const TriMesh& mesh, const EdgeTopology& topo,
                               const std::function<bool(std::size_t)>& join,
                               std::vector<std::uint32_t>* source_vertex) {
  const std::size_t num_corners = 3 * mesh.faces.size();
  UnionFind corners(num_corners);
  const auto corner_of = [&](std::uint32_t f, std::uint32_t v) {
    const Face& t = mesh.faces[f];
    return 3 * f + (t[0] == v ? 0u : (t[1] == v ? 1u : 2u));
  };
  for (std::size_t e = 0; e < topo.num_edges(); ++e) {
    if (topo.valence(e) != 2 || !join(e)) continue;
    const std::uint32_t f0 = topo.edge_halfedges[topo.edge_offsets[e]] / 3,
                        f1 = topo.edge_halfedges[topo.edge_offsets[e] + 1] / 3;
    for (const std::uint32_t v : topo.edges[e]) corners.unite(corner_of(f0, v), corner_of(f1, v));
  }
  // Every vertex keeps its index for the first class of corners that uses it; further classes are new
  // vertices after the input's.
  TriMesh out;
  out.positions = mesh.positions;
  out.colors = mesh.colors;
  out.normals = mesh.normals;
  out.faces = mesh.faces;
  std::vector<std::uint32_t> source(mesh.positions.size());
  std::iota(source.begin(), source.end(), 0u);
  std::vector<std::uint32_t> vertex_of_root(num_corners, kInvalidIndex);
  std::vector<std::uint8_t> taken(mesh.positions.size(), 0);
  for (std::uint32_t c = 0; c < num_corners; ++c) {
    const std::uint32_t r = corners.find(c);
    const std::uint32_t v = mesh.faces[c / 3][c % 3];
    if (vertex_of_root[r] == kInvalidIndex) {
      if (taken[v] == 0) {
        taken[v] = 1;
        vertex_of_root[r] = v;
      } else {
        vertex_of_root[r] = static_cast<std::uint32_t>(out.positions.size());
        out.positions.push_back(mesh.positions[v]);
        if (!mesh.colors.empty()) out.colors.push_back(mesh.colors[v]);
        if (!mesh.normals.empty()) out.normals.push_back(mesh.normals[v]);
        source.push_back(v);
      }
    }
    out.faces[c / 3][c % 3] = vertex_of_root[r];
  }
  if (source_vertex != nullptr) *source_vertex = std::move(source);
  return out;
}

namespace {

/// Reverses faces so that the faces of every edge-connected piece (over two-face edges) agree with the
/// piece's majority; returns the number reversed.
std::size_t orient_pieces(TriMesh& mesh) {
  const EdgeTopology topo = build_edge_topology(mesh);
  const std::size_t num_faces = mesh.faces.size();
  std::vector<std::uint8_t> flip(num_faces, 0), seen(num_faces, 0);
  std::vector<std::uint32_t> piece;
  std::size_t flipped = 0;
  for (std::uint32_t start = 0; start < num_faces; ++start) {
    if (seen[start] != 0) continue;
    piece.assign(1, start);
    seen[start] = 1;
    std::size_t reversed = 0;
    for (std::size_t k = 0; k < piece.size(); ++k) {
      const std::uint32_t f = piece[k];
      for (std::uint32_t h = 3 * f; h < 3 * f + 3; ++h) {
        const std::uint32_t e = topo.halfedge_edge[h];
        if (e == kInvalidIndex || topo.valence(e) != 2) continue;
        const std::uint32_t h0 = topo.edge_halfedges[topo.edge_offsets[e]];
        const std::uint32_t other = h0 == h ? topo.edge_halfedges[topo.edge_offsets[e] + 1] : h0;
        const std::uint32_t g = other / 3;
        if (seen[g] != 0) continue;
        seen[g] = 1;
        // The two run the same way (u -> v twice) unless exactly one of them is reversed.
        const bool same_way = halfedge_tail(mesh, h) == halfedge_tail(mesh, other);
        flip[g] = static_cast<std::uint8_t>(flip[f] ^ (same_way ? 1u : 0u));
        reversed += flip[g];
        piece.push_back(g);
      }
    }
    const bool invert = 2 * reversed > piece.size();
    for (const std::uint32_t f : piece) {
      if ((flip[f] != 0) == invert) continue;
      std::swap(mesh.faces[f][1], mesh.faces[f][2]);
      ++flipped;
    }
  }
  return flipped;
}

}  // namespace

ManifoldCut cut_to_manifold(const TriMesh& mesh) {
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const Face& t = mesh.faces[f];
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
      throw InvalidInput(fmt::format("face {} repeats a vertex: remove degenerate faces before cutting", f));
  }
  ManifoldCut r;
  r.mesh = mesh;
  r.source_vertex.resize(mesh.positions.size());
  std::iota(r.source_vertex.begin(), r.source_vertex.end(), 0u);
  r.flipped_faces = orient_pieces(r.mesh);
  // A cut can leave an edge of more than two faces, or one whose faces disagree, where the corners around
  // its vertices join again through other faces: cut what is left until nothing is (two passes at most seen).
  for (int pass = 0;; ++pass) {
    const EdgeTopology topo = build_edge_topology(r.mesh);
    const ManifoldCheck check = check_manifold(r.mesh, topo);
    if (check.nonmanifold_edges.empty() && check.inconsistent_edges.empty() && check.nonmanifold_vertices.empty()) break;
    if (pass == 16)
      throw TopologyError(fmt::format("the mesh could not be cut into a 2-manifold ({} non-manifold edges left)",
                                      check.nonmanifold_edges.size()));
    r.nonmanifold_edges += check.nonmanifold_edges.size();
    r.orientation_cuts += check.inconsistent_edges.size();
    std::vector<std::uint8_t> cut(topo.num_edges(), 0);
    for (const std::uint32_t e : check.nonmanifold_edges) cut[e] = 1;
    for (const std::uint32_t e : check.inconsistent_edges) cut[e] = 1;
    std::vector<std::uint32_t> source;
    r.mesh = split_vertices_by_fans(r.mesh, topo, [&](std::size_t e) { return cut[e] == 0; }, &source);
    for (std::uint32_t& s : source) s = r.source_vertex[s];
    r.source_vertex = std::move(source);
  }
  r.split_vertices = r.mesh.positions.size() - mesh.positions.size();
  return r;
}

}  // namespace gimforge
