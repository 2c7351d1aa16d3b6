#include "kernels/core/mesh_graph.h"

#include <algorithm>
#include <array>

namespace gimforge {
namespace {

/// One undirected link of a graph under construction.
struct Link {
  std::uint32_t a;
  std::uint32_t b;
  std::uint32_t edge;
  double length;
};

/// CSR graph over `num_nodes` nodes from undirected links (two arcs each, in link order per node).
WeightedGraph build_csr(std::size_t num_nodes, const std::vector<Link>& links) {
  WeightedGraph g;
  g.offsets.assign(num_nodes + 1, 0);
  for (const Link& l : links) {
    ++g.offsets[l.a + 1];
    ++g.offsets[l.b + 1];
  }
  for (std::size_t i = 0; i < num_nodes; ++i) g.offsets[i + 1] += g.offsets[i];
  const std::size_t num_arcs = 2 * links.size();
  g.targets.resize(num_arcs);
  g.edges.resize(num_arcs);
  g.lengths.resize(num_arcs);
  std::vector<std::uint32_t> fill(g.offsets.begin(), g.offsets.end() - 1);
  auto add_arc = [&](std::uint32_t from, std::uint32_t to, const Link& l) {
    const std::uint32_t a = fill[from]++;
    g.targets[a] = to;
    g.edges[a] = l.edge;
    g.lengths[a] = l.length;
  };
  for (const Link& l : links) {
    add_arc(l.a, l.b, l);
    add_arc(l.b, l.a, l);
  }
  return g;
}

Vec3 centroid(MeshView mesh, std::uint32_t f) {
  const Face& t = mesh.faces[f];
  return (mesh.positions[t[0]] + mesh.positions[t[1]] + mesh.positions[t[2]]) / 3.0;
}

}  // namespace

WeightedGraph vertex_graph(MeshView mesh, const EdgeTopology& topo) {
  std::vector<Link> links;
  links.reserve(topo.num_edges());
  for (std::size_t e = 0; e < topo.num_edges(); ++e) {
    const auto [a, b] = topo.edges[e];
    links.push_back({a, b, static_cast<std::uint32_t>(e), (mesh.positions[a] - mesh.positions[b]).norm()});
  }
  return build_csr(mesh.positions.size(), links);
}

WeightedGraph dual_graph(MeshView mesh, const EdgeTopology& topo) {
  std::vector<Link> links;
  links.reserve(topo.num_edges());
  for (std::size_t e = 0; e < topo.num_edges(); ++e) {
    if (topo.valence(e) != 2) continue;
    const std::uint32_t f = topo.edge_halfedges[topo.edge_offsets[e]] / 3;
    const std::uint32_t g = topo.edge_halfedges[topo.edge_offsets[e] + 1] / 3;
    links.push_back({f, g, static_cast<std::uint32_t>(e), (centroid(mesh, f) - centroid(mesh, g)).norm()});
  }
  return build_csr(mesh.faces.size(), links);
}

std::uint32_t find_edge(const EdgeTopology& topo, std::uint32_t a, std::uint32_t b) {
  const std::array<std::uint32_t, 2> key{std::min(a, b), std::max(a, b)};
  const auto it = std::lower_bound(topo.edges.begin(), topo.edges.end(), key);
  if (it == topo.edges.end() || *it != key) return kInvalidIndex;
  return static_cast<std::uint32_t>(it - topo.edges.begin());
}

DijkstraSearch::DijkstraSearch(const WeightedGraph& graph)
    : graph_(graph),
      distance_(graph.num_nodes(), std::numeric_limits<double>::infinity()),
      parent_arc_(graph.num_nodes(), kInvalidIndex),
      parent_(graph.num_nodes(), kInvalidIndex),
      settled_(graph.num_nodes(), 0) {}

void DijkstraSearch::reset() {
  for (std::uint32_t n : touched_) {
    distance_[n] = std::numeric_limits<double>::infinity();
    parent_arc_[n] = parent_[n] = kInvalidIndex;
    settled_[n] = 0;
  }
  touched_.clear();
  order_.clear();
}

std::vector<std::uint32_t> DijkstraSearch::path_edges(std::uint32_t node) const {
  std::vector<std::uint32_t> path;
  for (std::uint32_t v = node; parent_arc_[v] != kInvalidIndex; v = parent_[v]) path.push_back(parent_edge(v));
  return path;
}

}  // namespace gimforge
