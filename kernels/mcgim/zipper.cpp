#include "kernels/mcgim/zipper.h"

#include <algorithm>
#include <limits>
#include <map>
#include <unordered_map>
#include <unordered_set>

#include <fmt/format.h>

#include "kernels/core/edge_topology.h"
#include "kernels/core/errors.h"
#include "kernels/core/mesh_graph.h"

namespace gimforge {
namespace {

constexpr std::uint32_t kNone = 0xffffffffu;
constexpr double kInf = std::numeric_limits<double>::infinity();

/// One stretch of a chart's boundary between two consecutive cut-nodes.
struct Segment {
  std::uint32_t label{kNone};               ///< the chart across it, kNone along a mesh boundary
  std::vector<std::uint32_t> vertices;      ///< mesh vertices, cut-node to cut-node (both included)
  std::vector<std::uint32_t> samples;       ///< discrete cut-path, cut-node sample to cut-node sample
  std::uint32_t key{kNone};                 ///< smallest mesh edge index on it: the same for both sides
};

Vec3 closest_on_polyline(const Vec3& p, std::span<const Vec3> line) {
  Vec3 best = line.front();
  double best_d = kInf;
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    const Vec3 a = line[i], e = line[i + 1] - a;
    const double len2 = e.squaredNorm();
    const double t = len2 > 0.0 ? std::clamp((p - a).dot(e) / len2, 0.0, 1.0) : 0.0;
    const Vec3 q = a + t * e;
    const double d = (p - q).squaredNorm();
    if (d < best_d) best_d = d, best = q;
  }
  return best;
}

/// The discrete boundary loop of every chart: boundary edges of the §3 triangulation (counter-clockwise
/// triangles, so each loop runs with its chart on the left, as the mesh loops do).
std::vector<std::vector<std::uint32_t>> discrete_loops(std::uint32_t width, std::uint32_t height,
                                                       const std::vector<Vec3>& positions,
                                                       std::span<const std::uint8_t> mask,
                                                       std::span<const std::uint32_t> chart, std::size_t num_charts) {
  std::unordered_set<std::uint64_t> directed;
  const auto add = [&](std::size_t a, std::size_t b, std::size_t c) {
    directed.insert(std::uint64_t{a} << 32 | b);
    directed.insert(std::uint64_t{b} << 32 | c);
    directed.insert(std::uint64_t{c} << 32 | a);
  };
  const std::size_t w = width;
  for (std::size_t y = 0; y + 1 < height; ++y)
    for (std::size_t x = 0; x + 1 < w; ++x) {
      const std::size_t s00 = y * w + x, s10 = s00 + 1, s01 = s00 + w, s11 = s01 + 1;
      const int n = int{mask[s00] != 0} + int{mask[s10] != 0} + int{mask[s01] != 0} + int{mask[s11] != 0};
      if (n < 3) continue;
      if (n == 4) {
        if ((positions[s00] - positions[s11]).squaredNorm() <= (positions[s10] - positions[s01]).squaredNorm())
          add(s00, s10, s11), add(s00, s11, s01);
        else
          add(s00, s10, s01), add(s10, s11, s01);
      } else if (!mask[s00]) add(s10, s11, s01);
      else if (!mask[s10]) add(s00, s11, s01);
      else if (!mask[s11]) add(s00, s10, s01);
      else add(s00, s10, s11);
    }
  std::unordered_map<std::uint32_t, std::uint32_t> next;
  for (std::uint64_t e : directed) {
    const auto a = static_cast<std::uint32_t>(e >> 32), b = static_cast<std::uint32_t>(e & 0xffffffffu);
    if (directed.count(std::uint64_t{b} << 32 | a)) continue;
    if (!next.emplace(a, b).second)
      throw NumericalError(fmt::format("chart {}: its samples pinch at ({}, {}); a larger --samples helps", chart[a],
                                       a % width, a / width));
  }
  std::vector<std::vector<std::uint32_t>> loops(num_charts);
  std::vector<std::uint32_t> starts;
  for (const auto& [a, b] : next) starts.push_back(a);
  std::sort(starts.begin(), starts.end());
  std::unordered_set<std::uint32_t> seen;
  for (std::uint32_t s : starts) {
    if (seen.count(s)) continue;
    const std::uint32_t c = chart[s];
    if (!loops[c].empty())
      throw NumericalError(fmt::format("chart {}: its samples enclose a hole at this resolution; a larger --samples or "
                                       "more --charts helps", c));
    for (std::uint32_t v = s;;) {
      loops[c].push_back(v);
      seen.insert(v);
      v = next.at(v);
      if (v == s) break;
      if (loops[c].size() > next.size()) throw NumericalError(fmt::format("chart {}: its boundary does not close", c));
    }
  }
  for (std::size_t c = 0; c < num_charts; ++c)
    if (loops[c].size() < 3) throw NumericalError(fmt::format("chart {}: too few boundary samples", c));
  return loops;
}

/// Cut-node samples: a distinct loop index per cut-node, increasing along the loop from the first cut-node's
/// closest sample, minimizing the sum of 3D distances (dynamic programming over the loop).
std::vector<std::size_t> place_cut_nodes(const std::vector<std::uint32_t>& loop, std::uint32_t width,
                                         const std::vector<Vec2>& nodes, std::uint32_t c) {
  const auto cell = [&](std::uint32_t s) { return Vec2(static_cast<double>(s % width), static_cast<double>(s / width)); };
  const std::size_t m = loop.size(), k = nodes.size();
  if (k > m) throw NumericalError(fmt::format("chart {}: {} cut-nodes but only {} boundary samples; a larger --samples helps", c, k, m));
  std::size_t t0 = 0;
  double best = kInf;
  for (std::size_t t = 0; t < m; ++t)
    if (const double d = (cell(loop[t]) - nodes[0]).norm(); d < best) best = d, t0 = t;
  const auto dist = [&](std::size_t j, std::size_t t) { return (cell(loop[(t0 + t) % m]) - nodes[j]).norm(); };
  // cost[j][t]: best total for cut-nodes 0..j with node j at rotated index t (t ≥ j, leaving room for the rest).
  std::vector<std::vector<double>> cost(k, std::vector<double>(m, kInf));
  std::vector<std::vector<std::size_t>> from(k, std::vector<std::size_t>(m, 0));
  cost[0][0] = dist(0, 0);
  for (std::size_t j = 1; j < k; ++j) {
    double run = kInf;
    std::size_t arg = 0;
    for (std::size_t t = j; t + (k - 1 - j) < m; ++t) {
      if (cost[j - 1][t - 1] < run) run = cost[j - 1][t - 1], arg = t - 1;
      if (run < kInf) cost[j][t] = run + dist(j, t), from[j][t] = arg;
    }
  }
  std::vector<std::size_t> at(k, 0);
  std::size_t t = 0;
  if (k > 1) {
    double b = kInf;
    for (std::size_t u = 0; u < m; ++u)
      if (cost[k - 1][u] < b) b = cost[k - 1][u], t = u;
  }
  for (std::size_t j = k; j-- > 0;) {
    at[j] = (t0 + t) % m;
    if (j > 0) t = from[j][t];
  }
  return at;
}

}  // namespace

ChartLoops chart_loops(MeshView mesh, const EdgeTopology& topo, const std::vector<std::uint32_t>& face_chart,
                       const std::vector<ChartMesh>& charts) {
  const std::size_t num_charts = charts.size();
  ChartLoops out;
  // Mesh loops (global vertices) with the chart across each edge and the edge's index.
  auto& loop = out.loop;
  auto& label = out.label;
  auto& edge = out.edge;
  loop.resize(num_charts), label.resize(num_charts), edge.resize(num_charts);
  for (std::size_t c = 0; c < num_charts; ++c) {
    const ChartMesh& ch = charts[c];
    for (std::size_t i = 0; i < ch.boundary.size(); ++i) {
      const std::uint32_t a = ch.vertices[ch.boundary[i]], b = ch.vertices[ch.boundary[(i + 1) % ch.boundary.size()]];
      const std::uint32_t e = find_edge(topo, a, b);
      std::uint32_t across = kNone;
      for (std::uint32_t k = topo.edge_offsets[e]; k < topo.edge_offsets[e + 1]; ++k) {
        const std::uint32_t f = topo.edge_halfedges[k] / 3;
        if (face_chart[f] != c) across = face_chart[f];
      }
      loop[c].push_back(a);
      label[c].push_back(across);
      edge[c].push_back(e);
    }
  }
  // Cut-nodes: where a loop changes neighbour; a closed two-chart boundary gets three.
  std::vector<char>& is_cut = out.is_cut;
  is_cut.assign(mesh.positions.size(), 0);
  for (std::size_t c = 0; c < num_charts; ++c)
    for (std::size_t i = 0, m = loop[c].size(); i < m; ++i)
      if (label[c][(i + m - 1) % m] != label[c][i]) is_cut[loop[c][i]] = 1;
  for (std::size_t c = 0; c < num_charts; ++c) {
    const auto& l = label[c];
    if (l.front() == kNone || l.front() < c || std::any_of(l.begin(), l.end(), [&](std::uint32_t x) { return x != l.front(); }))
      continue;
    const std::size_t m = loop[c].size();
    const std::size_t start = static_cast<std::size_t>(std::min_element(loop[c].begin(), loop[c].end()) - loop[c].begin());
    for (std::size_t j = 0; j < 3; ++j) is_cut[loop[c][(start + j * m / 3) % m]] = 1;
  }
  out.cut_nodes.assign(num_charts, 0);
  for (std::size_t c = 0; c < num_charts; ++c)
    for (std::uint32_t v : loop[c]) out.cut_nodes[c] += is_cut[v] ? 1u : 0u;
  return out;
}

ZipperStats zipper_charts(MeshView mesh, const ChartLoops& loops, const std::vector<ChartMesh>& charts, const std::vector<std::vector<Vec2>>& vertex_image,
                          std::uint32_t width, std::uint32_t height, std::vector<Vec3>& positions,
                          std::span<const std::uint8_t> mask, std::span<const std::uint32_t> chart,
                          std::vector<std::uint32_t>& unified) {
  ZipperStats stats;
  const std::size_t num_charts = charts.size();
  if (loops.loop.size() != num_charts || loops.is_cut.size() != mesh.positions.size())
    throw InvalidInput("zipper_charts: the chart loops do not belong to these charts and mesh");
  const auto& loop = loops.loop;
  const auto& label = loops.label;
  const auto& edge = loops.edge;
  const std::vector<char>& is_cut = loops.is_cut;
  stats.cut_nodes = static_cast<std::size_t>(std::count(is_cut.begin(), is_cut.end(), 1));

  const std::vector<std::vector<std::uint32_t>> dloop = discrete_loops(width, height, positions, mask, chart, num_charts);
  UnionFind clusters(positions.size());
  std::map<std::uint32_t, std::vector<std::uint32_t>> node_samples;   // cut-node vertex -> its samples
  std::map<std::uint32_t, std::vector<Segment>> by_key;               // cut-paths by their key
  for (std::uint32_t c = 0; c < num_charts; ++c) {
    const std::vector<std::uint32_t>& L = loop[c];
    const std::size_t m = L.size();
    std::vector<std::size_t> node_index;
    std::vector<Vec2> node_image;
    for (std::size_t i = 0; i < m; ++i)
      if (is_cut[L[i]]) node_index.push_back(i), node_image.push_back(vertex_image[c][charts[c].boundary[i]]);
    const std::vector<std::uint32_t>& D = dloop[c];
    std::vector<Segment> segments;
    if (node_index.empty()) {  // the whole loop is a mesh boundary: snap only
      Segment s;
      s.vertices = L;
      s.vertices.push_back(L.front());
      s.samples = D;
      segments.push_back(std::move(s));
    } else {
      const std::vector<std::size_t> at = place_cut_nodes(D, width, node_image, c);
      const std::size_t k = node_index.size();
      for (std::size_t j = 0; j < k; ++j) {
        const std::uint32_t v = L[node_index[j]], s = D[at[j]];
        positions[s] = mesh.positions[v];
        node_samples[v].push_back(s);
        Segment seg;
        seg.label = label[c][node_index[j]];
        seg.key = kNone;
        for (std::size_t i = node_index[j];; i = (i + 1) % m) {
          seg.vertices.push_back(L[i]);
          if (i != node_index[j] && is_cut[L[i]]) break;
          seg.key = std::min(seg.key, edge[c][i]);
        }
        const std::size_t end = at[(j + 1) % k];
        for (std::size_t t = at[j];; t = (t + 1) % D.size()) {
          seg.samples.push_back(D[t]);
          if (t != at[j] && t == end) break;
          if (k == 1 && seg.samples.size() > D.size()) break;
        }
        segments.push_back(std::move(seg));
      }
    }
    // Snap the samples strictly inside each segment to its continuous path.
    for (Segment& seg : segments) {
      std::vector<Vec3> line;
      for (std::uint32_t v : seg.vertices) line.push_back(mesh.positions[v]);
      const bool closed = node_index.empty();
      for (std::size_t i = closed ? 0 : 1; i + (closed ? 0 : 1) < seg.samples.size(); ++i) {
        positions[seg.samples[i]] = closest_on_polyline(positions[seg.samples[i]], line);
        ++stats.snapped_samples;
      }
      if (seg.label == kNone) {
        ++stats.boundary_paths;
      } else {
        by_key[seg.key].push_back(std::move(seg));
      }
    }
  }
  for (auto& [v, samples] : node_samples)
    for (std::uint32_t s : samples) clusters.unite(samples.front(), s);
  // Unify the two discrete cut-paths of every cut-path in lock-step.
  for (auto& [key, pair] : by_key) {
    if (pair.size() != 2)
      throw NumericalError(fmt::format("zipper: a cut-path between charts is seen from {} sides, not 2", pair.size()));
    const std::vector<std::uint32_t>& a = pair[0].samples;
    std::vector<std::uint32_t> b(pair[1].samples.rbegin(), pair[1].samples.rend());
    if (pair[0].vertices.front() != pair[1].vertices.back())
      throw NumericalError(fmt::format("zipper: the two sides of a cut-path do not start at the same cut-node ({} "
                                       "vertices {}..{} against {} vertices {}..{})",
                                       pair[0].vertices.size(), pair[0].vertices.front(), pair[0].vertices.back(),
                                       pair[1].vertices.size(), pair[1].vertices.front(), pair[1].vertices.back()));
    ++stats.cut_paths;
    const std::size_t p = a.size() - 1, q = b.size() - 1;
    std::size_t i = 0, j = 0;
    std::uint32_t current = a[0];
    Vec3 here = positions[a[0]];
    while (i + 1 < p || j + 1 < q) {
      const bool can_a = i + 1 < p, can_b = j + 1 < q;
      const double cost_a = can_a ? (positions[a[i + 1]] - here).norm() : kInf;
      const double cost_b = can_b ? (positions[b[j + 1]] - here).norm() : kInf;
      const double cost_ab = can_a && can_b ? (positions[a[i + 1]] - positions[b[j + 1]]).norm() : kInf;
      if (cost_ab <= cost_a && cost_ab <= cost_b) {
        current = a[++i];
        here = positions[current];
        positions[b[++j]] = here;
        clusters.unite(current, b[j]);
      } else if (cost_a <= cost_b) {
        positions[a[++i]] = here;
        clusters.unite(current, a[i]);
      } else {
        positions[b[++j]] = here;
        clusters.unite(current, b[j]);
      }
    }
  }
  // Representatives, and every sample at its representative's position.
  unified.assign(positions.size(), kNone);
  std::vector<std::uint32_t> cluster_size(positions.size(), 0);
  for (std::uint32_t s = 0; s < positions.size(); ++s)
    if (mask[s]) ++cluster_size[clusters.find(s)];
  for (std::uint32_t s = 0; s < positions.size(); ++s) {
    if (!mask[s]) continue;
    const std::uint32_t r = clusters.find(s);
    unified[s] = r;
    positions[s] = positions[r];
    if (cluster_size[r] > 1) ++stats.unified_samples;
  }
  return stats;
}

}  // namespace gimforge
