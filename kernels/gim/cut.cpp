#include "kernels/gim/cut.h"

#include <algorithm>

#include <fmt/format.h>

#include "kernels/core/edge_topology.h"
#include "kernels/core/errors.h"
#include "kernels/core/mesh_graph.h"
#include "kernels/core/topology.h"

namespace gimforge {
namespace {

/// Rings of vertices around a cut-path within which its straightened replacement must stay (Gu §3.2: the
/// constrained shortest path "stays within a neighborhood of the original cut-path").
constexpr int kStraightenRings = 3;
/// Straightening passes over all cut-paths (a second pass gains a few percent of cut length).
constexpr int kStraightenPasses = 2;

/// Halfedge following h in its face.
std::uint32_t next_halfedge(std::uint32_t h) { return h - h % 3 + (h % 3 + 1) % 3; }

// ---------------------------------------------------------------------------------------------------------
// Preconditions

/// Throws TopologyError for a mesh without faces, InvalidInput for out-of-range or repeated face indices.
void check_faces(const char* fn, MeshView mesh) {
  if (mesh.faces.empty()) throw TopologyError(fmt::format("{}: the mesh has no faces", fn));
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    for (std::uint32_t v : mesh.faces[f])
      if (v >= mesh.positions.size())
        throw InvalidInput(fmt::format("{}: face {} has vertex index {} out of range ({} vertices)", fn, f, v,
                                       mesh.positions.size()));
    if (has_repeated_index(mesh.faces[f]))
      throw InvalidInput(fmt::format("{}: face {} repeats a vertex index (degenerate; run repair_mesh first)", fn, f));
  }
}

/// Throws unless `mesh` is a single connected, manifold, orientable surface (consistently oriented too when
/// `need_oriented`). Returns its topology.
TopologyReport check_surface(const char* fn, MeshView mesh, bool need_oriented) {
  check_faces(fn, mesh);
  TopologyReport r = analyze_topology(mesh);
  if (r.components.size() != 1)
    throw TopologyError(
        fmt::format("{}: the mesh has {} connected components; cutting needs exactly one", fn, r.components.size()));
  if (!r.manifold)
    throw TopologyError(fmt::format("{}: the mesh is not a 2-manifold ({} non-manifold edges, {} non-manifold "
                                    "vertices)",
                                    fn, r.nonmanifold_edges, r.nonmanifold_vertices));
  if (!r.orientable) throw TopologyError(fmt::format("{}: the mesh is not orientable", fn));
  if (need_oriented && !r.oriented)
    throw TopologyError(fmt::format(
        "{}: the mesh is orientable but not consistently oriented ({} edges run the same way in both faces)", fn,
        r.inconsistent_edges));
  return r;
}

// ---------------------------------------------------------------------------------------------------------
// The cut as edge flags

/// A cut as flags over the edges of an EdgeTopology, with the cut valence of every vertex.
struct CutGraph {
  const EdgeTopology& topo;
  std::vector<char> in_cut;            ///< per edge of topo
  std::vector<std::uint32_t> valence;  ///< per vertex: number of cut edges at it

  CutGraph(const EdgeTopology& t, std::size_t num_vertices)
      : topo(t), in_cut(t.num_edges(), 0), valence(num_vertices, 0) {}

  [[nodiscard]] bool is_boundary(std::uint32_t e) const { return topo.valence(e) == 1; }
  [[nodiscard]] bool empty() const { return std::find(in_cut.begin(), in_cut.end(), 1) == in_cut.end(); }

  void set(std::uint32_t e, bool on) {
    if ((in_cut[e] != 0) == on) return;
    in_cut[e] = on ? 1 : 0;
    for (std::uint32_t v : topo.edges[e]) valence[v] = on ? valence[v] + 1 : valence[v] - 1;
  }
  void set(const std::vector<std::uint32_t>& edges, bool on) {
    for (std::uint32_t e : edges) set(e, on);
  }
};

/// The CutGraph of `cut` plus every original boundary edge. Throws InvalidInput for a pair that is no edge.
CutGraph make_cut_graph(const char* fn, const EdgeTopology& topo, std::size_t num_vertices, const Cut& cut) {
  CutGraph graph(topo, num_vertices);
  for (std::uint32_t e = 0; e < topo.num_edges(); ++e)
    if (graph.is_boundary(e)) graph.set(e, true);
  for (const auto& [a, b] : cut.edges) {
    const std::uint32_t e = find_edge(topo, a, b);
    if (e == kInvalidIndex) throw InvalidInput(fmt::format("{}: cut edge {}-{} is not an edge of the mesh", fn, a, b));
    graph.set(e, true);
  }
  return graph;
}

/// The cut edges as a Cut, sorted.
Cut to_cut(const CutGraph& graph) {
  Cut cut;
  for (std::size_t e = 0; e < graph.in_cut.size(); ++e)
    if (graph.in_cut[e]) cut.edges.push_back(graph.topo.edges[e]);
  return cut;
}

/// Number of connected pieces the mesh falls into when opened along the cut (faces joined across uncut
/// edges).
std::size_t opened_components(MeshView mesh, const CutGraph& cut) {
  UnionFind faces(mesh.faces.size());
  std::size_t components = mesh.faces.size();
  for (std::size_t e = 0; e < cut.in_cut.size(); ++e) {
    if (cut.in_cut[e] || cut.topo.valence(e) != 2) continue;
    const std::uint32_t* hs = &cut.topo.edge_halfedges[cut.topo.edge_offsets[e]];
    if (faces.unite(hs[0] / 3, hs[1] / 3)) --components;
  }
  return components;
}

// ---------------------------------------------------------------------------------------------------------
// Initial cut: peeling, trimming, two-edge cut

/// Phase 1 (Gu §3.2): removes the seed face, then repeatedly an edge not on the original boundary that has
/// one remaining face, together with that face, in order of geodesic distance from the seed (Dijkstra over
/// face centroids: each face is removed with the edge through which the shortest-path tree reaches it).
/// Returns the edges that remain.
CutGraph peel(MeshView mesh, const EdgeTopology& topo, std::uint32_t seed) {
  const WeightedGraph dual = dual_graph(mesh, topo);
  const std::uint32_t sources[] = {seed};
  DijkstraSearch search(dual);
  search.run(sources);
  CutGraph cut(topo, mesh.positions.size());
  for (std::uint32_t e = 0; e < topo.num_edges(); ++e) cut.set(e, true);
  for (std::uint32_t f : search.settled())
    if (search.parent_edge(f) != kInvalidIndex) cut.set(search.parent_edge(f), false);
  return cut;
}

/// Phase 2 (Gu §3.2): repeatedly removes a vertex with exactly one cut edge together with that edge, which
/// trims the dangling trees and leaves the loops. Original boundary edges are never removed (on a manifold
/// their vertices keep two of them). Returns the vertex the last removal left behind (the single remaining
/// vertex when everything is trimmed: closed genus 0), or kInvalidIndex when nothing was removed.
std::uint32_t trim_dangling_trees(const WeightedGraph& vg, CutGraph& cut) {
  std::vector<std::uint32_t> stack;
  for (std::uint32_t v = 0; v < cut.valence.size(); ++v)
    if (cut.valence[v] == 1) stack.push_back(v);
  std::uint32_t last = kInvalidIndex;
  while (!stack.empty()) {
    const std::uint32_t v = stack.back();
    stack.pop_back();
    if (cut.valence[v] != 1) continue;
    for (std::uint32_t a = vg.offsets[v]; a < vg.offsets[v + 1]; ++a) {
      const std::uint32_t e = vg.edges[a];
      if (!cut.in_cut[e] || cut.is_boundary(e)) continue;
      cut.set(e, false);
      last = vg.targets[a];
      if (cut.valence[last] == 1) stack.push_back(last);
      break;
    }
  }
  return last;
}

/// Cosine of the angle at p between the directions to a and b (1 when either direction is degenerate).
double cos_angle(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 da = a - p, db = b - p;
  const double n = da.norm() * db.norm();
  return n > 0.0 ? da.dot(db) / n : 1.0;
}

/// The two edges (v,a), (v,b) at `v` with the widest angle between them: the straightest two-edge path
/// a–v–b, a simple path, so cutting a closed genus-0 mesh along it gives a disk.
Cut straightest_two_edges(MeshView mesh, const WeightedGraph& vg, std::uint32_t v) {
  const std::uint32_t begin = vg.offsets[v], end = vg.offsets[v + 1];
  if (end - begin < 2) throw InvalidInput(fmt::format("two_edge_cut: vertex {} has {} edges", v, end - begin));
  std::uint32_t best_a = begin, best_b = begin + 1;
  double best = 2.0;
  for (std::uint32_t a = begin; a < end; ++a) {
    for (std::uint32_t b = a + 1; b < end; ++b) {
      const double c = cos_angle(mesh.positions[v], mesh.positions[vg.targets[a]], mesh.positions[vg.targets[b]]);
      if (c < best) {
        best = c;
        best_a = a;
        best_b = b;
      }
    }
  }
  auto edge = [&](std::uint32_t arc) { return std::array{std::min(v, vg.targets[arc]), std::max(v, vg.targets[arc])}; };
  Cut cut{{edge(best_a), edge(best_b)}};
  std::sort(cut.edges.begin(), cut.edges.end());
  return cut;
}

// ---------------------------------------------------------------------------------------------------------
// Straightening

/// A chain of cut edges: vertices[i] and vertices[i+1] are joined by edges[i].
struct CutPath {
  std::vector<std::uint32_t> vertices;
  std::vector<std::uint32_t> edges;
};

/// The cut arc at `v` other than the one along edge `from` (v has cut valence 2).
std::uint32_t other_cut_arc(const WeightedGraph& vg, const CutGraph& cut, std::uint32_t v, std::uint32_t from) {
  for (std::uint32_t a = vg.offsets[v]; a < vg.offsets[v + 1]; ++a)
    if (cut.in_cut[vg.edges[a]] && vg.edges[a] != from) return a;
  return kInvalidIndex;
}

/// Follows the cut from `start` along `arc` until the next cut-node (or back to `start`), marking edges used.
CutPath walk_cut_path(const WeightedGraph& vg, const CutGraph& cut, std::vector<char>& used, std::uint32_t start,
                      std::uint32_t arc) {
  CutPath path{{start}, {}};
  while (arc != kInvalidIndex) {
    const std::uint32_t e = vg.edges[arc];
    used[e] = 1;
    path.edges.push_back(e);
    const std::uint32_t v = vg.targets[arc];
    path.vertices.push_back(v);
    if (v == start || cut.valence[v] != 2) break;
    arc = other_cut_arc(vg, cut, v, e);
  }
  return path;
}

/// The cut-paths: maximal chains between cut-nodes (cut valence != 2); a loop without nodes starts at its
/// lowest-numbered vertex.
std::vector<CutPath> cut_paths(const WeightedGraph& vg, const CutGraph& cut) {
  std::vector<char> used(cut.in_cut.size(), 0);
  std::vector<CutPath> paths;
  auto walk_all_from = [&](std::uint32_t v) {
    for (std::uint32_t a = vg.offsets[v]; a < vg.offsets[v + 1]; ++a)
      if (cut.in_cut[vg.edges[a]] && !used[vg.edges[a]]) paths.push_back(walk_cut_path(vg, cut, used, v, a));
  };
  for (std::uint32_t v = 0; v < cut.valence.size(); ++v)
    if (cut.valence[v] != 0 && cut.valence[v] != 2) walk_all_from(v);
  for (std::uint32_t v = 0; v < cut.valence.size(); ++v)
    if (cut.valence[v] == 2) walk_all_from(v);
  return paths;
}

/// Corner (3f + i) of face f at vertex v (f must contain v).
std::uint32_t corner_of(MeshView mesh, std::uint32_t f, std::uint32_t v) {
  const Face& t = mesh.faces[f];
  return 3 * f + (t[0] == v ? 0u : t[1] == v ? 1u : 2u);
}

/// Straightens cut-paths one at a time (Gu §3.2) by a shortest path on one side of the path.
///
/// Let D be the mesh opened along the whole cut (a disk) and P+ one of the two copies of a cut-path P on its
/// boundary. Any simple path in D from the first to the last vertex of P+ that touches the boundary of D only
/// on P+ keeps the cut valid: it splits D into pieces that glue back along P into one disk. So the replacement
/// is searched on the vertex graph restricted to D near P+: a vertex of P may be used only through its
/// corners on the chosen side (its wedge of corners next to P+), other vertices of the cut not at all, free
/// vertices only within kStraightenRings rings of P+. Both sides are tried and the shorter result kept. The
/// search state is reused from path to path, so each costs in proportion to its neighbourhood.
class PathStraightener {
 public:
  PathStraightener(MeshView mesh, const WeightedGraph& vg, CutGraph& cut)
      : mesh_(mesh), vg_(vg), cut_(cut), search_(vg), plus_(3 * mesh.faces.size(), 0), band_(vg.num_nodes(), 0),
        on_path_(vg.num_nodes(), 0) {}

  /// Replaces `path` (at least two edges, not an original boundary, distinct end nodes) by the shorter
  /// of its one-sided shortest paths if that is shorter than the path.
  void straighten(const CutPath& path) {
    if (path.edges.size() < 2) return;
    double length = 0.0;
    for (std::uint32_t e : path.edges) length += edge_length(e);
    std::vector<std::uint32_t> best;
    const std::uint32_t first = path.edges.front();
    for (std::uint32_t k = 0; k < 2; ++k) {
      double side_length = 0.0;
      std::vector<std::uint32_t> side = shortest_on_side(path, face_of(first, k), side_length);
      if (!side.empty() && side_length < length * (1.0 - 1e-12)) {
        best = std::move(side);
        length = side_length;
      }
    }
    if (best.empty()) return;
    cut_.set(path.edges, false);
    cut_.set(best, true);
  }

 private:
  [[nodiscard]] double edge_length(std::uint32_t e) const {
    return (mesh_.positions[cut_.topo.edges[e][0]] - mesh_.positions[cut_.topo.edges[e][1]]).norm();
  }
  /// Face k (0 or 1) of an edge.
  [[nodiscard]] std::uint32_t face_of(std::uint32_t e, std::uint32_t k) const {
    const std::uint32_t i = cut_.topo.edge_offsets[e] + k;
    return i < cut_.topo.edge_offsets[e + 1] ? cut_.topo.edge_halfedges[i] / 3 : kInvalidIndex;
  }
  /// Whether a face of edge e has its corner at vertex x on the chosen side.
  [[nodiscard]] bool on_side(std::uint32_t x, std::uint32_t e) const {
    for (std::uint32_t k = 0; k < 2; ++k) {
      const std::uint32_t f = face_of(e, k);
      if (f != kInvalidIndex && plus_[corner_of(mesh_, f, x)]) return true;
    }
    return false;
  }

  /// Marks the wedge containing corner c: the corners at its vertex reached across uncut edges.
  void mark_wedge(std::uint32_t c) {
    const std::uint32_t v = mesh_.faces[c / 3][c % 3];
    if (plus_[c]) return;
    plus_[c] = 1;
    touched_corners_.push_back(c);
    for (std::size_t next = touched_corners_.size() - 1; next < touched_corners_.size(); ++next) {
      const std::uint32_t f = touched_corners_[next] / 3, i = touched_corners_[next] % 3;
      for (std::uint32_t h : {3 * f + i, 3 * f + (i + 2) % 3}) {  // the two halfedges of f at v
        const std::uint32_t e = cut_.topo.halfedge_edge[h];
        if (cut_.in_cut[e] || cut_.topo.valence(e) != 2) continue;
        const std::uint32_t g = face_of(e, 0) == f ? face_of(e, 1) : face_of(e, 0);
        const std::uint32_t cg = corner_of(mesh_, g, v);
        if (plus_[cg]) continue;
        plus_[cg] = 1;
        touched_corners_.push_back(cg);
      }
    }
  }

  /// Marks the wedges on one side of the path, starting from `face` (a face of its first edge). Returns
  /// false if the side cannot be followed (not expected on a manifold).
  bool mark_side(const CutPath& path, std::uint32_t face) {
    mark_wedge(corner_of(mesh_, face, path.vertices[0]));
    for (std::size_t i = 0; i < path.edges.size(); ++i) {
      const std::uint32_t v = path.vertices[i];
      const std::uint32_t e = path.edges[i];
      face = plus_[corner_of(mesh_, face_of(e, 0), v)] ? face_of(e, 0) : face_of(e, 1);
      if (face == kInvalidIndex || !plus_[corner_of(mesh_, face, v)]) return false;
      mark_wedge(corner_of(mesh_, face, path.vertices[i + 1]));
    }
    return true;
  }

  /// Free vertices within kStraightenRings rings of the path's side, reached without entering the cut.
  void grow_band(const CutPath& path) {
    std::vector<std::uint32_t> frontier;
    auto visit = [&](std::uint32_t w) {
      if (band_[w] || cut_.valence[w] != 0) return;
      band_[w] = 1;
      band_list_.push_back(w);
      frontier.push_back(w);
    };
    for (std::uint32_t x : path.vertices)
      for (std::uint32_t a = vg_.offsets[x]; a < vg_.offsets[x + 1]; ++a)
        if (!cut_.in_cut[vg_.edges[a]] && on_side(x, vg_.edges[a])) visit(vg_.targets[a]);
    for (int ring = 1; ring < kStraightenRings; ++ring) {
      const std::vector<std::uint32_t> current = std::move(frontier);
      frontier.clear();
      for (std::uint32_t v : current)
        for (std::uint32_t a = vg_.offsets[v]; a < vg_.offsets[v + 1]; ++a) visit(vg_.targets[a]);
    }
  }

  /// The shortest path between the path's end nodes on the side of `face`, and its length (empty if none).
  std::vector<std::uint32_t> shortest_on_side(const CutPath& path, std::uint32_t face, double& length) {
    std::vector<std::uint32_t> result;
    if (face != kInvalidIndex && mark_side(path, face)) {
      grow_band(path);
      result = search_side(path, length);
    }
    clear_marks();
    return result;
  }

  /// Dijkstra between the path's end nodes over the marked side and band; the path's own edges are free.
  std::vector<std::uint32_t> search_side(const CutPath& path, double& length) {
    for (std::uint32_t v : path.vertices) on_path_[v] = 1;
    cut_.set(path.edges, false);
    const std::uint32_t target = path.vertices.back();
    auto allowed = [&](std::uint32_t u, std::uint32_t a) {
      const std::uint32_t e = vg_.edges[a], w = vg_.targets[a];
      if (cut_.in_cut[e] || (on_path_[u] && !on_side(u, e))) return false;
      return on_path_[w] ? on_side(w, e) : band_[w] != 0;
    };
    const std::uint32_t sources[] = {path.vertices.front()};
    search_.run(sources, allowed, [&](std::uint32_t v) { return v == target; });
    length = search_.distance(target);
    cut_.set(path.edges, true);
    for (std::uint32_t v : path.vertices) on_path_[v] = 0;
    return search_.path_edges(target);
  }

  void clear_marks() {
    for (std::uint32_t c : touched_corners_) plus_[c] = 0;
    for (std::uint32_t v : band_list_) band_[v] = 0;
    touched_corners_.clear();
    band_list_.clear();
  }

  MeshView mesh_;
  const WeightedGraph& vg_;
  CutGraph& cut_;
  DijkstraSearch search_;
  std::vector<char> plus_;  ///< per corner: in a wedge on the chosen side of the path
  std::vector<std::uint32_t> touched_corners_;
  std::vector<char> band_;  ///< per vertex: free vertex near the chosen side
  std::vector<std::uint32_t> band_list_;
  std::vector<char> on_path_;  ///< per vertex: on the path being straightened
};

/// The sub-chain of `path` from vertex index `first` to vertex index `last`.
CutPath sub_path(const CutPath& path, std::size_t first, std::size_t last) {
  const auto v = path.vertices.begin();
  const auto e = path.edges.begin();
  return {{v + static_cast<std::ptrdiff_t>(first), v + static_cast<std::ptrdiff_t>(last) + 1},
          {e + static_cast<std::ptrdiff_t>(first), e + static_cast<std::ptrdiff_t>(last)}};
}

/// Straightens every cut-path that is not an original boundary (Gu §3.2), kStraightenPasses times. A closed
/// path (its two end nodes coincide) is straightened as two halves split at its middle vertex. The result is
/// checked once at the end (the opened mesh must stay connected; the Euler characteristic cannot change);
/// should that ever fail, the cut is left as it was.
void straighten_cut(MeshView mesh, const WeightedGraph& vg, CutGraph& cut) {
  const std::vector<char> before = cut.in_cut;
  PathStraightener straightener(mesh, vg, cut);
  for (int pass = 0; pass < kStraightenPasses; ++pass) {
    for (const CutPath& path : cut_paths(vg, cut)) {
      if (cut.is_boundary(path.edges.front())) continue;  // all or none of a path's edges are boundary edges
      if (path.vertices.front() != path.vertices.back()) {
        straightener.straighten(path);
        continue;
      }
      const std::size_t mid = path.edges.size() / 2;
      straightener.straighten(sub_path(path, 0, mid));
      straightener.straighten(sub_path(path, mid, path.edges.size()));
    }
  }
  if (opened_components(mesh, cut) == 1) return;
  for (std::uint32_t e = 0; e < before.size(); ++e) cut.set(e, before[e] != 0);
}

// ---------------------------------------------------------------------------------------------------------
// Opening

/// Disk vertex of every face corner (corner c = 3f + i): corners around an input vertex share a disk vertex
/// when their faces are joined across an uncut edge (a wedge of corners between cut edges). Disk vertices are
/// numbered in order of their first corner; `original` receives the input vertex of each.
std::vector<std::uint32_t> wedge_vertices(MeshView mesh, const CutGraph& cut, std::vector<std::uint32_t>& original) {
  const EdgeTopology& topo = cut.topo;
  UnionFind corners(3 * mesh.faces.size());
  for (std::size_t e = 0; e < topo.num_edges(); ++e) {
    if (cut.in_cut[e] || topo.valence(e) != 2) continue;
    const std::uint32_t h0 = topo.edge_halfedges[topo.edge_offsets[e]];
    const std::uint32_t h1 = topo.edge_halfedges[topo.edge_offsets[e] + 1];
    // Consistent orientation: h0 runs u->v, h1 runs v->u, so corner h0 (at u) pairs with next(h1) and so on.
    corners.unite(h0, next_halfedge(h1));
    corners.unite(h1, next_halfedge(h0));
  }
  std::vector<std::uint32_t> root_vertex(3 * mesh.faces.size(), kInvalidIndex);
  std::vector<std::uint32_t> corner_vertex(3 * mesh.faces.size());
  for (std::uint32_t c = 0; c < corner_vertex.size(); ++c) {
    std::uint32_t& id = root_vertex[corners.find(c)];
    if (id == kInvalidIndex) {
      id = static_cast<std::uint32_t>(original.size());
      original.push_back(mesh.faces[c / 3][c % 3]);
    }
    corner_vertex[c] = id;
  }
  return corner_vertex;
}

/// Boundary halfedges of the opened mesh as next[tail] = head over disk vertices (kInvalidIndex where none);
/// returns their number. Throws TopologyError if a disk vertex starts two of them.
std::size_t boundary_successors(MeshView mesh, const CutGraph& cut, const std::vector<std::uint32_t>& corner_vertex,
                                std::vector<std::uint32_t>& next) {
  std::size_t count = 0;
  for (std::uint32_t h = 0; h < 3 * mesh.faces.size(); ++h) {
    if (!cut.in_cut[cut.topo.halfedge_edge[h]]) continue;
    const std::uint32_t tail = corner_vertex[h];
    if (next[tail] != kInvalidIndex)
      throw TopologyError(
          fmt::format("open_cut: the opened mesh is pinched at input vertex {}", mesh.faces[h / 3][h % 3]));
    next[tail] = corner_vertex[next_halfedge(h)];
    ++count;
  }
  return count;
}

/// The boundary loop through the first boundary vertex, in the direction of the faces (interior on the left).
std::vector<std::uint32_t> first_boundary_loop(const std::vector<std::uint32_t>& next, std::size_t count) {
  std::vector<std::uint32_t> loop;
  const auto first = std::find_if(next.begin(), next.end(), [](std::uint32_t n) { return n != kInvalidIndex; });
  if (first == next.end()) return loop;
  const auto start = static_cast<std::uint32_t>(first - next.begin());
  std::uint32_t v = start;
  do {
    loop.push_back(v);
    v = next[v];
  } while (v != start && v != kInvalidIndex && loop.size() <= count);
  return loop;
}

/// Throws TopologyError unless the opened mesh is one disk: connected, all boundary edges in one loop, χ = 1.
void check_disk(MeshView mesh, const CutGraph& cut, const CutMesh& out, std::size_t boundary_edges) {
  std::size_t uncut_edges = 0;
  for (char c : cut.in_cut) uncut_edges += c ? 0 : 1;
  const long long chi = static_cast<long long>(out.disk.positions.size()) -
                        static_cast<long long>(uncut_edges + boundary_edges) +
                        static_cast<long long>(mesh.faces.size());
  const std::size_t components = opened_components(mesh, cut);
  if (boundary_edges == 0)
    throw TopologyError("open_cut: the cut is empty and the mesh is closed, so cutting does not open it");
  if (components != 1 || out.boundary.size() != boundary_edges || chi != 1)
    throw TopologyError(fmt::format(
        "open_cut: the cut does not open the mesh into a disk ({} pieces, first boundary loop has {} of {} boundary "
        "edges, Euler characteristic {})",
        components, out.boundary.size(), boundary_edges, chi));
}

// ---------------------------------------------------------------------------------------------------------
// Extremal vertex

/// Index of the face of `disk` with the largest L2 stretch under `uv` among faces with a vertex not in
/// `on_cut` (a flipped or degenerate parameter triangle counts as infinite stretch), or kInvalidIndex.
std::uint32_t max_stretch_face(const TriMesh& disk, std::span<const Vec2> uv, const std::vector<char>& on_cut) {
  std::uint32_t best = kInvalidIndex;
  double best_l2 = -1.0;
  for (std::uint32_t f = 0; f < disk.faces.size(); ++f) {
    const Face& t = disk.faces[f];
    if (on_cut[t[0]] && on_cut[t[1]] && on_cut[t[2]]) continue;
    const double l2 = triangle_stretch(uv[t[0]], uv[t[1]], uv[t[2]], disk.positions[t[0]], disk.positions[t[1]],
                                       disk.positions[t[2]])
                          .l2;
    if (l2 > best_l2) {
      best_l2 = l2;
      best = f;
    }
  }
  return best;
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------
// Public API

Cut initial_cut(MeshView mesh, const CutOptions& options) {
  check_surface("initial_cut", mesh, false);
  if (options.seed_face >= mesh.faces.size())
    throw InvalidInput(fmt::format("initial_cut: seed face {} out of range ({} faces)", options.seed_face,
                                   mesh.faces.size()));
  const EdgeTopology topo = build_edge_topology(mesh);
  const WeightedGraph vg = vertex_graph(mesh, topo);
  CutGraph cut = peel(mesh, topo, options.seed_face);
  const std::uint32_t last = trim_dangling_trees(vg, cut);
  if (cut.empty()) return straightest_two_edges(mesh, vg, last);
  if (options.straighten) straighten_cut(mesh, vg, cut);
  return to_cut(cut);
}

CutMesh open_cut(MeshView mesh, const Cut& cut) {
  check_surface("open_cut", mesh, true);
  const EdgeTopology topo = build_edge_topology(mesh);
  const CutGraph graph = make_cut_graph("open_cut", topo, mesh.positions.size(), cut);
  CutMesh out;
  const std::vector<std::uint32_t> corner_vertex = wedge_vertices(mesh, graph, out.original_vertex);
  out.disk.positions.reserve(out.original_vertex.size());
  for (std::uint32_t v : out.original_vertex) out.disk.positions.push_back(mesh.positions[v]);
  out.disk.faces.resize(mesh.faces.size());
  for (std::uint32_t c = 0; c < corner_vertex.size(); ++c) out.disk.faces[c / 3][c % 3] = corner_vertex[c];
  std::vector<std::uint32_t> next(out.original_vertex.size(), kInvalidIndex);
  const std::size_t boundary_edges = boundary_successors(mesh, graph, corner_vertex, next);
  out.boundary = first_boundary_loop(next, boundary_edges);
  check_disk(mesh, graph, out, boundary_edges);
  return out;
}

std::uint32_t extremal_vertex(const CutMesh& cut_mesh, std::span<const Vec2> uv) {
  const TriMesh& disk = cut_mesh.disk;
  if (uv.size() != disk.positions.size() || cut_mesh.original_vertex.size() != disk.positions.size())
    throw InvalidInput(fmt::format("extremal_vertex: {} uv and {} original-vertex entries for {} disk vertices",
                                   uv.size(), cut_mesh.original_vertex.size(), disk.positions.size()));
  check_faces("extremal_vertex", disk);
  std::vector<char> on_cut(disk.positions.size(), 0);
  for (std::uint32_t v : cut_mesh.boundary) on_cut.at(v) = 1;
  const std::uint32_t f = max_stretch_face(disk, uv, on_cut);
  if (f == kInvalidIndex) return kInvalidIndex;
  const EdgeTopology topo = build_edge_topology(disk);
  const WeightedGraph graph = vertex_graph(disk, topo);
  DijkstraSearch to_cut(graph);
  to_cut.run(cut_mesh.boundary);
  std::uint32_t best = kInvalidIndex;
  for (std::uint32_t v : disk.faces[f])
    if (!on_cut[v] && (best == kInvalidIndex || to_cut.distance(v) > to_cut.distance(best))) best = v;
  return cut_mesh.original_vertex[best];
}

Cut extend_cut(MeshView mesh, const Cut& cut, std::uint32_t vertex) {
  check_faces("extend_cut", mesh);
  if (vertex >= mesh.positions.size())
    throw InvalidInput(
        fmt::format("extend_cut: vertex {} out of range ({} vertices)", vertex, mesh.positions.size()));
  const EdgeTopology topo = build_edge_topology(mesh);
  CutGraph graph = make_cut_graph("extend_cut", topo, mesh.positions.size(), cut);
  if (graph.empty()) throw InvalidInput("extend_cut: the cut is empty");
  if (graph.valence[vertex] > 0) return to_cut(graph);
  const WeightedGraph vg = vertex_graph(mesh, topo);
  const std::uint32_t sources[] = {vertex};
  DijkstraSearch search(vg);
  search.run(sources, [](std::uint32_t, std::uint32_t) { return true; },
             [&](std::uint32_t v) { return graph.valence[v] > 0; });
  const std::uint32_t reached = search.settled().back();
  if (graph.valence[reached] == 0)
    throw TopologyError(fmt::format("extend_cut: vertex {} is not connected to the cut", vertex));
  graph.set(search.path_edges(reached), true);
  return to_cut(graph);
}

Cut two_edge_cut(MeshView mesh, std::uint32_t vertex) {
  const TopologyReport r = check_surface("two_edge_cut", mesh, false);
  if (!r.closed || r.components[0].genus != 0.0)
    throw TopologyError(fmt::format("two_edge_cut: needs a closed genus-0 mesh (got genus {}, {} boundary loops)",
                                    r.components[0].genus, r.boundary_loops));
  if (vertex >= mesh.positions.size())
    throw InvalidInput(
        fmt::format("two_edge_cut: vertex {} out of range ({} vertices)", vertex, mesh.positions.size()));
  const EdgeTopology topo = build_edge_topology(mesh);
  return straightest_two_edges(mesh, vertex_graph(mesh, topo), vertex);
}

}  // namespace gimforge
