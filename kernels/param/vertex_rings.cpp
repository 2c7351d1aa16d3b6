#include "kernels/param/vertex_rings.h"

#include <string>
#include <utility>

#include "kernels/core/errors.h"

namespace gimforge {
namespace {

using Wedge = std::pair<std::uint32_t, std::uint32_t>;  // (next, previous) neighbour of a face corner

/// Index of the wedge to start the chain from: one whose first vertex ends no other wedge (open fan),
/// else 0 (closed fan).
std::size_t chain_start(std::span<const Wedge> wedges) {
  for (std::size_t i = 0; i < wedges.size(); ++i) {
    bool ends_other = false;
    for (const Wedge& w : wedges) ends_other = ends_other || w.second == wedges[i].first;
    if (!ends_other) return i;
  }
  return 0;
}

/// Orders the wedges of vertex v into one fan and appends its ring to `out`; returns true if open.
bool chain_fan(std::uint32_t v, std::span<Wedge> wedges, std::vector<std::uint32_t>& out) {
  std::swap(wedges[0], wedges[chain_start(wedges)]);
  out.push_back(wedges[0].first);
  for (std::size_t i = 1; i < wedges.size(); ++i) {
    std::size_t j = i;
    while (j < wedges.size() && wedges[j].first != wedges[i - 1].second) ++j;
    if (j == wedges.size()) throw TopologyError("vertex " + std::to_string(v) + " is not a manifold vertex");
    std::swap(wedges[i], wedges[j]);
    out.push_back(wedges[i].first);
  }
  const bool open = wedges.back().second != wedges.front().first;
  if (open) out.push_back(wedges.back().second);
  return open;
}

}  // namespace

VertexRings build_vertex_rings(MeshView mesh) {
  const std::size_t n = mesh.positions.size();
  std::vector<std::uint32_t> start(n + 1, 0);
  for (const Face& t : mesh.faces)
    if (!has_repeated_index(t))
      for (std::uint32_t c : t) ++start[c + 1];
  for (std::size_t v = 0; v < n; ++v) start[v + 1] += start[v];
  std::vector<Wedge> wedges(start[n]);
  std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
  for (const Face& t : mesh.faces) {
    if (has_repeated_index(t)) continue;
    for (std::size_t i = 0; i < 3; ++i) wedges[fill[t[i]]++] = {t[(i + 1) % 3], t[(i + 2) % 3]};
  }
  VertexRings rings;
  rings.offsets.assign(n + 1, 0);
  rings.open.assign(n, 0);
  rings.neighbours.reserve(wedges.size() + n);
  for (std::size_t v = 0; v < n; ++v) {
    if (start[v + 1] > start[v]) {
      const std::span<Wedge> fan(wedges.data() + start[v], start[v + 1] - start[v]);
      rings.open[v] = chain_fan(static_cast<std::uint32_t>(v), fan, rings.neighbours) ? 1 : 0;
    }
    rings.offsets[v + 1] = static_cast<std::uint32_t>(rings.neighbours.size());
  }
  return rings;
}

}  // namespace gimforge
