#include "kernels/core/manifold_cut.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge {

TriMesh split_vertices_by_fans(const TriMesh& mesh, const EdgeTopology& topo,
                               const std::function<bool(std::size_t)>& join,
                               std::vector<std::uint32_t>* source_vertex,
                               std::span<const std::array<std::uint32_t, 3>> sheets) {
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
  for (const auto& [f0, f1, e] : sheets)
    for (const std::uint32_t v : topo.edges[e]) corners.unite(corner_of(f0, v), corner_of(f1, v));
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

/// A face around an edge: its angle about the edge and its direction along it.
struct Around {
  std::uint32_t face;
  double angle;
  int direction;      // +1: the face runs u -> v, -1: v -> u
  std::uint32_t slot;  // its place among the edge's faces
};

/// Pairs the faces of one piece around edge e (sorted by angle) into sheets, appended to `pairs`. A face
/// running u -> v faces the side of growing angle (its normal is z × its direction across the edge): the
/// wedge after a face of direction -1 and before one of direction +1 lies behind both.
void pair_around(const std::vector<Around>& around, std::uint32_t e, std::vector<std::array<std::uint32_t, 3>>& pairs,
                 std::vector<std::uint8_t>& paired) {
  const std::size_t n = around.size();
  std::vector<std::uint8_t> taken(n, 0);
  for (const bool behind_only : {true, false})
    for (std::size_t i = 0; i < n; ++i) {
      if (taken[i] != 0) continue;
      std::size_t j = (i + 1) % n;
      while (j != i && taken[j] != 0) j = (j + 1) % n;
      if (j == i || around[i].direction == around[j].direction) continue;
      if (behind_only && around[i].direction != -1) continue;
      taken[i] = taken[j] = 1;
      paired[around[i].slot] = paired[around[j].slot] = 1;
      pairs.push_back({around[i].face, around[j].face, e});
    }
}

}  // namespace

std::vector<std::array<std::uint32_t, 3>> sheet_pairs(const TriMesh& mesh, const EdgeTopology& topo) {
  std::vector<std::array<std::uint32_t, 3>> pairs;
  // Only faces of one piece (connected over two-face edges) pair: a fin or another solid glued to the edge
  // is not a sheet of this one.
  UnionFind pieces(mesh.faces.size());
  for (std::size_t e = 0; e < topo.num_edges(); ++e)
    if (topo.valence(e) == 2)
      pieces.unite(topo.edge_halfedges[topo.edge_offsets[e]] / 3, topo.edge_halfedges[topo.edge_offsets[e] + 1] / 3);
  std::vector<std::pair<std::uint32_t, Around>> all;  // (piece, face)
  std::vector<Around> around;
  std::vector<std::uint8_t> paired;  // per slot of the edge's faces
  for (std::uint32_t e = 0; e < topo.num_edges(); ++e) {
    if (topo.valence(e) <= 2) continue;
    const auto [u, v] = topo.edges[e];
    const Vec3 axis = mesh.positions[v] - mesh.positions[u];
    const double length = axis.norm();
    if (!(length > 0.0)) continue;
    const Vec3 z = axis / length;
    const Vec3 x = z.unitOrthogonal(), y = z.cross(x);
    all.clear();
    for (std::uint32_t k = topo.edge_offsets[e]; k < topo.edge_offsets[e + 1]; ++k) {
      const std::uint32_t h = topo.edge_halfedges[k], f = h / 3;
      const std::uint32_t w = mesh.faces[f][(h % 3 + 2) % 3];
      const Vec3 d = mesh.positions[w] - mesh.positions[u];
      const Vec3 across = d - d.dot(z) * z;
      if (!(across.norm() > 1e-12 * std::max(length, d.norm()))) continue;  // no area across the edge
      all.push_back({pieces.find(f), {f, std::atan2(across.dot(y), across.dot(x)), halfedge_tail(mesh, h) == u ? 1 : -1, 0}});
    }
    std::sort(all.begin(), all.end(), [](const auto& a, const auto& b) {
      return a.first != b.first ? a.first < b.first : a.second.angle < b.second.angle;
    });
    for (std::size_t k = 0; k < all.size(); ++k) all[k].second.slot = static_cast<std::uint32_t>(k);
    paired.assign(all.size(), 0);
    for (std::size_t first = 0; first < all.size();) {  // each piece's faces in turn
      around.clear();
      std::size_t last = first;
      for (; last < all.size() && all[last].first == all[first].first; ++last) around.push_back(all[last].second);
      if (around.size() >= 2) pair_around(around, e, pairs, paired);
      first = last;
    }
    // Then what is left, whatever its piece (a surface that the edges of more than two faces cut in two,
    // as a wall inside a box cuts the box's surface).
    around.clear();
    for (const auto& [piece, face] : all)
      if (paired[face.slot] == 0) around.push_back(face);
    std::sort(around.begin(), around.end(), [](const Around& a, const Around& b) { return a.angle < b.angle; });
    if (around.size() >= 2) pair_around(around, e, pairs, paired);
  }
  return pairs;
}

namespace {

/// Reverses faces so that the faces of every edge-connected piece (over two-face edges) agree; returns the
/// number reversed. A piece that agrees already is left alone. Of one that does not, the orientation kept
/// is the one its stored vertex normals point to, else for a closed piece the one enclosing a positive
/// volume, else the one most of its faces have.
std::size_t orient_pieces(TriMesh& mesh, const EdgeTopology& topo) {
  const std::size_t num_faces = mesh.faces.size();
  std::vector<std::uint8_t> flip(num_faces, 0), seen(num_faces, 0);
  std::vector<std::uint32_t> piece;
  std::vector<std::uint32_t> uses(topo.num_edges(), 0);  // per piece, reset after it
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
    if (reversed == 0) continue;  // it agrees already: left as it is (an inward shell may be a cavity)
    bool invert = 2 * reversed > piece.size();
    // Stored vertex normals say which side is out: the orientation whose face normals agree with them.
    if (!mesh.normals.empty()) {
      double agree = 0.0;
      for (const std::uint32_t f : piece) {
        const Face& t = mesh.faces[f];
        const Vec3 n = (mesh.positions[t[1]] - mesh.positions[t[0]]).cross(mesh.positions[t[2]] - mesh.positions[t[0]]);
        const Vec3 stored = (mesh.normals[t[0]] + mesh.normals[t[1]] + mesh.normals[t[2]]).cast<double>();
        agree += flip[f] != 0 ? -n.dot(stored) : n.dot(stored);
      }
      if (agree != 0.0) invert = agree < 0.0;
    }
    // Without them, a closed piece (each edge of its faces used by exactly two of them) is turned to enclose a
    // positive volume, measured about its first corner with the faces as the flips make them.
    bool closed = mesh.normals.empty();
    for (const std::uint32_t f : piece)
      for (std::uint32_t h = 3 * f; h < 3 * f + 3; ++h) ++uses[topo.halfedge_edge[h]];
    for (const std::uint32_t f : piece)
      for (std::uint32_t h = 3 * f; h < 3 * f + 3; ++h) closed = closed && uses[topo.halfedge_edge[h]] == 2;
    for (const std::uint32_t f : piece)
      for (std::uint32_t h = 3 * f; h < 3 * f + 3; ++h) uses[topo.halfedge_edge[h]] = 0;
    if (closed) {
      const Vec3 centre = mesh.positions[mesh.faces[piece.front()][0]];
      double volume = 0.0;
      for (const std::uint32_t f : piece) {
        const Face& t = mesh.faces[f];
        const double v = (mesh.positions[t[0]] - centre)
                             .dot((mesh.positions[t[1]] - centre).cross(mesh.positions[t[2]] - centre));
        volume += flip[f] != 0 ? -v : v;
      }
      if (volume != 0.0) invert = volume < 0.0;
    }
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
  {
    // The edge table of the input: enough to tell a mesh that needs nothing, and to walk its pieces (a piece's
    // faces are reversed only after its walk, and no other piece's walk reads them).
    const EdgeTopology topo = build_edge_topology(mesh);
    const ManifoldCheck check = check_manifold(mesh, topo);
    if (check.nonmanifold_edges.empty() && check.inconsistent_edges.empty() && check.nonmanifold_vertices.empty()) return r;
    r.flipped_faces = orient_pieces(r.mesh, topo);
  }
  // A cut can leave an edge of more than two faces, or one whose faces disagree, where the corners around
  // its vertices join again through other faces: cut what is left until nothing is (two passes at most seen).
  for (int pass = 0;; ++pass) {
    const EdgeTopology topo = build_edge_topology(r.mesh);
    const ManifoldCheck check = check_manifold(r.mesh, topo);
    if (check.nonmanifold_edges.empty() && check.inconsistent_edges.empty() && check.nonmanifold_vertices.empty()) break;
    if (pass == 16)
      throw TopologyError(fmt::format("the mesh could not be cut into a 2-manifold ({} non-manifold edges left)",
                                      check.nonmanifold_edges.size()));
    if (pass == 0) {  // later passes cut the same input edges again where sheets met around a vertex
      r.nonmanifold_edges = check.nonmanifold_edges.size();
      r.orientation_cuts = check.inconsistent_edges.size();
    }
    std::vector<std::uint8_t> cut(topo.num_edges(), 0);
    for (const std::uint32_t e : check.nonmanifold_edges) cut[e] = 1;
    for (const std::uint32_t e : check.inconsistent_edges) cut[e] = 1;
    // The first cut keeps the sheets through edges of more than two faces; a later one (sheets that met again
    // around a vertex) cuts them apart.
    const std::vector<std::array<std::uint32_t, 3>> sheets = pass == 0 ? sheet_pairs(r.mesh, topo)
                                                                        : std::vector<std::array<std::uint32_t, 3>>{};
    std::vector<std::uint32_t> source;
    r.mesh = split_vertices_by_fans(r.mesh, topo, [&](std::size_t e) { return cut[e] == 0; }, &source, sheets);
    for (std::uint32_t& s : source) s = r.source_vertex[s];
    r.source_vertex = std::move(source);
  }
  r.split_vertices = r.mesh.positions.size() - mesh.positions.size();
  return r;
}

}  // namespace gimforge
