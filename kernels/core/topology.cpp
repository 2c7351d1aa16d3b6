#include "kernels/core/topology.h"

#include <algorithm>
#include <limits>

#include <Eigen/Eigenvalues>

#include "kernels/core/edge_topology.h"

namespace gimforge {
namespace {

/// Component id per face (faces joined through shared vertices), numbered 0.. in order of first face.
std::vector<std::uint32_t> face_components(MeshView mesh, std::uint32_t& count) {
  UnionFind sets(mesh.positions.size());
  for (const Face& t : mesh.faces) {
    if (has_repeated_index(t)) continue;
    sets.unite(t[0], t[1]);
    sets.unite(t[1], t[2]);
  }
  std::vector<std::uint32_t> root_id(mesh.positions.size(), kInvalidIndex);
  std::vector<std::uint32_t> comp(mesh.faces.size(), kInvalidIndex);
  count = 0;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    if (has_repeated_index(mesh.faces[f])) continue;
    const std::uint32_t r = sets.find(mesh.faces[f][0]);
    if (root_id[r] == kInvalidIndex) root_id[r] = count++;
    comp[f] = root_id[r];
  }
  return comp;
}

/// Tries to orient every face consistently by flood fill over two-sided edges; returns per component
/// whether that succeeded.
std::vector<char> orientability(MeshView mesh, const EdgeTopology& topo, const std::vector<std::uint32_t>& comp,
                                std::uint32_t num_components) {
  std::vector<char> orientable(num_components, 1);
  std::vector<signed char> flip(mesh.faces.size(), -1);  // -1 unvisited, 0 keep, 1 flipped
  std::vector<std::uint32_t> stack;
  for (std::size_t seed = 0; seed < mesh.faces.size(); ++seed) {
    if (comp[seed] == kInvalidIndex || flip[seed] >= 0) continue;
    flip[seed] = 0;
    stack.push_back(static_cast<std::uint32_t>(seed));
    while (!stack.empty()) {
      const std::uint32_t f = stack.back();
      stack.pop_back();
      for (std::uint32_t i = 0; i < 3; ++i) {
        const std::uint32_t h = 3 * f + i;
        const std::uint32_t e = topo.halfedge_edge[h];
        if (e == kInvalidIndex || topo.valence(e) != 2) continue;
        const std::uint32_t* hs = &topo.edge_halfedges[topo.edge_offsets[e]];
        const std::uint32_t other = hs[0] == h ? hs[1] : hs[0];
        const std::uint32_t g = other / 3;
        // Same direction along the edge means g must be flipped relative to f.
        const bool same_dir = halfedge_tail(mesh, h) == halfedge_tail(mesh, other);
        const signed char want = static_cast<signed char>(flip[f] ^ (same_dir ? 1 : 0));
        if (flip[g] < 0) {
          flip[g] = want;
          stack.push_back(g);
        } else if (flip[g] != want) {
          orientable[comp[f]] = 0;
        }
      }
    }
  }
  return orientable;
}

}  // namespace

TopologyReport analyze_topology(MeshView mesh) {
  TopologyReport report;
  report.vertices = mesh.positions.size();
  report.bbox = bounding_box(mesh);

  std::uint32_t num_components = 0;
  const std::vector<std::uint32_t> comp = face_components(mesh, num_components);
  const EdgeTopology topo = build_edge_topology(mesh);
  const ManifoldCheck check = check_manifold(mesh, topo);
  std::vector<ComponentTopology> comps(num_components);

  // Faces, referenced vertices, area.
  std::vector<std::uint32_t> vertex_comp(mesh.positions.size(), kInvalidIndex);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    if (comp[f] == kInvalidIndex) continue;
    ++comps[comp[f]].faces;
    report.surface_area += triangle_area(mesh, f);
    for (std::uint32_t v : mesh.faces[f]) {
      if (vertex_comp[v] == kInvalidIndex) {
        vertex_comp[v] = comp[f];
        ++comps[comp[f]].vertices;
      }
    }
  }
  // Edges, boundary edges, boundary-vertex degrees.
  std::vector<std::uint32_t> boundary_degree(mesh.positions.size(), 0);
  UnionFind boundary_graph(mesh.positions.size());
  for (std::size_t e = 0; e < topo.num_edges(); ++e) {
    ComponentTopology& c = comps[vertex_comp[topo.edges[e][0]]];
    ++c.edges;
    if (topo.valence(e) == 1) {
      ++c.boundary_edges;
      ++boundary_degree[topo.edges[e][0]];
      ++boundary_degree[topo.edges[e][1]];
      boundary_graph.unite(topo.edges[e][0], topo.edges[e][1]);
    }
  }
  // Boundary loops: connected components of the boundary-edge graph.
  for (std::uint32_t v = 0; v < mesh.positions.size(); ++v)
    if (boundary_degree[v] > 0 && boundary_graph.find(v) == v) ++comps[vertex_comp[v]].boundary_loops;
  // Manifold and orientation flags per component.
  for (auto& c : comps) c.manifold = c.oriented = true;
  for (std::uint32_t e : check.nonmanifold_edges) comps[vertex_comp[topo.edges[e][0]]].manifold = false;
  for (std::uint32_t v : check.nonmanifold_vertices) comps[vertex_comp[v]].manifold = false;
  for (std::uint32_t e : check.inconsistent_edges) comps[vertex_comp[topo.edges[e][0]]].oriented = false;
  const std::vector<char> orientable = orientability(mesh, topo, comp, num_components);

  for (std::uint32_t i = 0; i < num_components; ++i) {
    ComponentTopology& c = comps[i];
    c.orientable = orientable[i] != 0;
    c.oriented = c.oriented && c.orientable;
    c.closed = c.boundary_edges == 0;
    c.euler_characteristic = static_cast<long long>(c.vertices) - static_cast<long long>(c.edges) +
                             static_cast<long long>(c.faces);
    c.genus = (2.0 - static_cast<double>(c.euler_characteristic) - static_cast<double>(c.boundary_loops)) / 2.0;
  }
  std::stable_sort(comps.begin(), comps.end(),
                   [](const ComponentTopology& a, const ComponentTopology& b) { return a.faces > b.faces; });

  report.components = std::move(comps);
  report.edges = topo.num_edges();
  report.nonmanifold_edges = check.nonmanifold_edges.size();
  report.nonmanifold_vertices = check.nonmanifold_vertices.size();
  report.inconsistent_edges = check.inconsistent_edges.size();
  report.closed = report.manifold = report.orientable = report.oriented = true;
  for (const auto& c : report.components) {
    report.faces += c.faces;
    report.referenced_vertices += c.vertices;
    report.boundary_edges += c.boundary_edges;
    report.boundary_loops += c.boundary_loops;
    report.euler_characteristic += c.euler_characteristic;
    report.closed = report.closed && c.closed;
    report.manifold = report.manifold && c.manifold;
    report.orientable = report.orientable && c.orientable;
    report.oriented = report.oriented && c.oriented;
  }
  return report;
}

double widest_hole(MeshView mesh) {
  const EdgeTopology topo = build_edge_topology(mesh);
  const std::size_t n = mesh.positions.size();
  UnionFind graph(n);
  std::vector<char> on_boundary(n, 0);
  for (std::size_t e = 0; e < topo.num_edges(); ++e) {
    if (topo.valence(e) != 1) continue;
    graph.unite(topo.edges[e][0], topo.edges[e][1]);
    on_boundary[topo.edges[e][0]] = on_boundary[topo.edges[e][1]] = 1;
  }
  // Per loop (by its root vertex): the moments of its vertices relative to the root's position, so that a
  // loop far from the origin loses no digits.
  struct Loop {
    std::size_t count{0};
    Vec3 sum{Vec3::Zero()};
    Eigen::Matrix3d outer{Eigen::Matrix3d::Zero()};
    Vec3 axis{Vec3::Zero()};
    double lo{std::numeric_limits<double>::infinity()}, hi{-std::numeric_limits<double>::infinity()};
  };
  std::vector<std::uint32_t> loop_of_root(n, kInvalidIndex);
  std::vector<Loop> loops;
  std::vector<std::uint32_t> root(n, kInvalidIndex);
  for (std::uint32_t v = 0; v < n; ++v) {
    if (!on_boundary[v]) continue;
    root[v] = graph.find(v);
    if (loop_of_root[root[v]] == kInvalidIndex) {
      loop_of_root[root[v]] = static_cast<std::uint32_t>(loops.size());
      loops.emplace_back();
    }
    Loop& l = loops[loop_of_root[root[v]]];
    const Vec3 d = mesh.positions[v] - mesh.positions[root[v]];
    ++l.count;
    l.sum += d;
    l.outer += d * d.transpose();
  }
  for (Loop& l : loops) {
    const Vec3 mean = l.sum / static_cast<double>(l.count);
    const Eigen::Matrix3d cov = l.outer / static_cast<double>(l.count) - mean * mean.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    l.axis = eig.eigenvectors().col(1);  // eigenvalues ascending: the middle one
  }
  for (std::uint32_t v = 0; v < n; ++v) {
    if (!on_boundary[v]) continue;
    Loop& l = loops[loop_of_root[root[v]]];
    const double t = l.axis.dot(mesh.positions[v] - mesh.positions[root[v]]);
    l.lo = std::min(l.lo, t);
    l.hi = std::max(l.hi, t);
  }
  double widest = 0.0;
  for (const Loop& l : loops) widest = std::max(widest, l.hi - l.lo);
  return widest;
}

}  // namespace gimforge
