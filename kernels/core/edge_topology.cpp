#include "kernels/core/edge_topology.h"

#include <numeric>

#include <tbb/parallel_sort.h>

namespace gimforge {

EdgeTopology build_edge_topology(MeshView mesh) {
  const std::size_t num_halfedges = 3 * mesh.faces.size();
  // (key, halfedge) pairs with key = min << 32 | max; sorting groups each edge's halfedges together.
  struct Entry {
    std::uint64_t key;
    std::uint32_t halfedge;
    bool operator<(const Entry& o) const { return key != o.key ? key < o.key : halfedge < o.halfedge; }
  };
  std::vector<Entry> entries;
  entries.reserve(num_halfedges);
  for (std::size_t h = 0; h < num_halfedges; ++h) {
    const Face& t = mesh.faces[h / 3];
    if (has_repeated_index(t)) continue;  // degenerate faces have no edges
    const std::uint32_t a = halfedge_tail(mesh, h);
    const std::uint32_t b = halfedge_head(mesh, h);
    const std::uint64_t key = (std::uint64_t{std::min(a, b)} << 32) | std::max(a, b);
    entries.push_back({key, static_cast<std::uint32_t>(h)});
  }
  tbb::parallel_sort(entries.begin(), entries.end());

  EdgeTopology topo;
  topo.halfedge_edge.assign(num_halfedges, kInvalidIndex);
  topo.edge_halfedges.reserve(entries.size());
  for (std::size_t i = 0; i < entries.size(); ++i) {
    if (i == 0 || entries[i].key != entries[i - 1].key) {
      topo.edge_offsets.push_back(static_cast<std::uint32_t>(i));
      topo.edges.push_back({static_cast<std::uint32_t>(entries[i].key >> 32),
                            static_cast<std::uint32_t>(entries[i].key & 0xffffffffu)});
    }
    topo.halfedge_edge[entries[i].halfedge] = static_cast<std::uint32_t>(topo.edges.size() - 1);
    topo.edge_halfedges.push_back(entries[i].halfedge);
  }
  topo.edge_offsets.push_back(static_cast<std::uint32_t>(entries.size()));
  return topo;
}

UnionFind::UnionFind(std::size_t n) : parent_(n), size_(n, 1) {
  std::iota(parent_.begin(), parent_.end(), std::uint32_t{0});
}

std::uint32_t UnionFind::find(std::uint32_t x) {
  while (parent_[x] != x) {
    parent_[x] = parent_[parent_[x]];
    x = parent_[x];
  }
  return x;
}

bool UnionFind::unite(std::uint32_t x, std::uint32_t y) {
  x = find(x);
  y = find(y);
  if (x == y) return false;
  if (size_[x] < size_[y]) std::swap(x, y);
  parent_[y] = x;
  size_[x] += size_[y];
  return true;
}

}  // namespace gimforge

namespace gimforge {

ManifoldCheck check_manifold(MeshView mesh, const EdgeTopology& topo) {
  ManifoldCheck check;
  // Corner c = 3*f + i sits at vertex faces[f][i]. Two corners at the same vertex belong to the same fan
  // when their faces share a two-sided edge through that vertex.
  UnionFind corners(3 * mesh.faces.size());
  auto corner_at = [&](std::uint32_t h, std::uint32_t v) {
    const std::uint32_t f = h / 3;
    for (std::uint32_t i = 0; i < 3; ++i)
      if (mesh.faces[f][i] == v) return 3 * f + i;
    return kInvalidIndex;
  };
  for (std::size_t e = 0; e < topo.num_edges(); ++e) {
    const std::uint32_t valence = topo.valence(e);
    if (valence > 2) check.nonmanifold_edges.push_back(static_cast<std::uint32_t>(e));
    if (valence != 2) continue;
    const std::uint32_t h0 = topo.edge_halfedges[topo.edge_offsets[e]];
    const std::uint32_t h1 = topo.edge_halfedges[topo.edge_offsets[e] + 1];
    if (halfedge_tail(mesh, h0) == halfedge_tail(mesh, h1))
      check.inconsistent_edges.push_back(static_cast<std::uint32_t>(e));
    for (std::uint32_t v : topo.edges[e]) corners.unite(corner_at(h0, v), corner_at(h1, v));
  }
  // Count distinct fans per vertex: a corner that is the root of its set starts a fan.
  check.vertex_fans.assign(mesh.positions.size(), 0);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const Face& t = mesh.faces[f];
    if (has_repeated_index(t)) continue;  // degenerate faces form no fan
    for (std::uint32_t i = 0; i < 3; ++i) {
      const auto c = static_cast<std::uint32_t>(3 * f + i);
      if (corners.find(c) == c) ++check.vertex_fans[t[i]];
    }
  }
  for (std::size_t v = 0; v < check.vertex_fans.size(); ++v)
    if (check.vertex_fans[v] > 1) check.nonmanifold_vertices.push_back(static_cast<std::uint32_t>(v));
  return check;
}

}  // namespace gimforge
