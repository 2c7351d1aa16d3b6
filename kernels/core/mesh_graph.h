#pragma once
/// \file mesh_graph.h
/// Weighted graphs over a triangle mesh in compressed-sparse-row form — the vertex graph (vertices joined
/// along mesh edges) and the dual graph (faces joined across two-sided edges) — and Dijkstra's algorithm over
/// them with an arc filter and early exit. Used by the cutting kernels (cut.h) for geodesic peeling order,
/// constrained shortest paths and shortest paths to the cut.
#include <cstdint>
#include <functional>
#include <limits>
#include <queue>
#include <span>
#include <utility>
#include <vector>

#include "kernels/core/edge_topology.h"
#include "kernels/core/mesh.h"

namespace gimforge {

/// Undirected weighted graph, each undirected link stored as two arcs.
/// - Arcs leaving node n: indices [offsets[n], offsets[n+1]).
/// - `targets[a]`: head node of arc a; `edges[a]`: the mesh edge (index into EdgeTopology::edges) that arc a
///   runs along (vertex graph) or crosses (dual graph); `lengths[a]` >= 0.
struct WeightedGraph {
  std::vector<std::uint32_t> offsets;
  std::vector<std::uint32_t> targets;
  std::vector<std::uint32_t> edges;
  std::vector<double> lengths;

  [[nodiscard]] std::size_t num_nodes() const { return offsets.empty() ? 0 : offsets.size() - 1; }
};

/// Vertices of `mesh` (all of them, referenced or not) joined along every edge of `topo`; arc length is the
/// Euclidean edge length. Cost O(V + E).
[[nodiscard]] WeightedGraph vertex_graph(MeshView mesh, const EdgeTopology& topo);

/// Faces of `mesh` joined across every edge of `topo` that has exactly two face sides; arc length is the
/// distance between the two face centroids. Cost O(F + E).
[[nodiscard]] WeightedGraph dual_graph(MeshView mesh, const EdgeTopology& topo);

/// Index of the undirected edge {a, b} in `topo.edges` (binary search), or kInvalidIndex if absent.
[[nodiscard]] std::uint32_t find_edge(const EdgeTopology& topo, std::uint32_t a, std::uint32_t b);

/// Dijkstra's algorithm over a WeightedGraph (binary heap with lazy deletion; O((N + A) log N) per run).
/// The per-node arrays are allocated once and reset only where the previous run touched them, so many small
/// searches on a large graph cost in proportion to the part they explore. Ties are broken by node index,
/// so results are deterministic. Keeps a reference to the graph.
class DijkstraSearch {
 public:
  explicit DijkstraSearch(const WeightedGraph& graph);

  /// Searches from `sources` (distance 0).
  /// - `allowed(tail, arc)` -> bool: whether arc `arc` leaving node `tail` may be relaxed;
  /// - `on_settle(node)` -> bool: called once per node in order of distance; true stops the search.
  template <class ArcFilter, class OnSettle>
  void run(std::span<const std::uint32_t> sources, ArcFilter&& allowed, OnSettle&& on_settle);

  /// Searches from `sources` over every arc until all reachable nodes are settled.
  void run(std::span<const std::uint32_t> sources) {
    run(sources, [](std::uint32_t, std::uint32_t) { return true; }, [](std::uint32_t) { return false; });
  }

  /// Distance of `node` from the nearest source in the last run (+infinity where not reached).
  [[nodiscard]] double distance(std::uint32_t node) const { return distance_[node]; }
  /// Nodes settled in the last run, in order of distance.
  [[nodiscard]] const std::vector<std::uint32_t>& settled() const { return order_; }
  /// Mesh edge (WeightedGraph::edges) through which the last run reached `node` (kInvalidIndex for a source or
  /// a node not reached).
  [[nodiscard]] std::uint32_t parent_edge(std::uint32_t node) const {
    return parent_arc_[node] == kInvalidIndex ? kInvalidIndex : graph_.edges[parent_arc_[node]];
  }
  /// Mesh edges (WeightedGraph::edges) of the shortest path from `node` back to its source, in that order;
  /// empty for a source or a node not reached.
  [[nodiscard]] std::vector<std::uint32_t> path_edges(std::uint32_t node) const;

 private:
  void reset();

  const WeightedGraph& graph_;
  std::vector<double> distance_;
  std::vector<std::uint32_t> parent_arc_;  ///< arc that reached the node (kInvalidIndex: none)
  std::vector<std::uint32_t> parent_;      ///< tail of parent_arc_
  std::vector<char> settled_;
  std::vector<std::uint32_t> touched_;  ///< nodes whose entries differ from the reset state
  std::vector<std::uint32_t> order_;
};

template <class ArcFilter, class OnSettle>
void DijkstraSearch::run(std::span<const std::uint32_t> sources, ArcFilter&& allowed, OnSettle&& on_settle) {
  reset();
  using Item = std::pair<double, std::uint32_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> heap;
  for (std::uint32_t s : sources) {
    distance_[s] = 0.0;
    touched_.push_back(s);
    heap.emplace(0.0, s);
  }
  while (!heap.empty()) {
    const auto [d, u] = heap.top();
    heap.pop();
    if (settled_[u] || d > distance_[u]) continue;
    settled_[u] = 1;
    order_.push_back(u);
    if (on_settle(u)) break;
    for (std::uint32_t a = graph_.offsets[u]; a < graph_.offsets[u + 1]; ++a) {
      const std::uint32_t w = graph_.targets[a];
      const double nd = d + graph_.lengths[a];
      if (settled_[w] || !(nd < distance_[w]) || !allowed(u, a)) continue;
      if (distance_[w] == std::numeric_limits<double>::infinity()) touched_.push_back(w);
      distance_[w] = nd;
      parent_arc_[w] = a;
      parent_[w] = u;
      heap.emplace(nd, w);
    }
  }
}

}  // namespace gimforge
