#include "kernels/mcgim/chartify.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <fmt/format.h>

#include "kernels/core/edge_topology.h"
#include "kernels/core/errors.h"
#include "kernels/core/hash.h"
#include "kernels/core/mesh_graph.h"

namespace gimforge {
namespace {

/// Lloyd rounds (after bootstrapping) that may add seeds where the disk rule leaves faces over.
constexpr int kSeedingLloydRounds = 3;

/// Marks a face that no chart holds yet.
constexpr std::uint32_t kUnassigned = kInvalidIndex;

/// The vertex of triangle `t` that is neither `a` nor `b` (t holds a and b, no repeated index).
std::uint32_t opposite_vertex(const Face& t, std::uint32_t a, std::uint32_t b) {
  for (std::uint32_t v : t)
    if (v != a && v != b) return v;
  return kInvalidIndex;
}

/// Checks the face indices and coordinates of `mesh` for chartify: at least one face, indices in range, no
/// repeated index, finite referenced positions. Throws InvalidInput naming the first offending item.
void check_faces(MeshView mesh) {
  if (mesh.faces.empty()) throw InvalidInput("chartify: the mesh has no faces");
  if (mesh.faces.size() >= kInvalidIndex)
    throw InvalidInput(fmt::format("chartify: {} faces exceed the 32-bit face index", mesh.faces.size()));
  const std::size_t n = mesh.positions.size();
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const Face& t = mesh.faces[f];
    for (std::uint32_t v : t) {
      if (v >= n)
        throw InvalidInput(fmt::format("chartify: face {} has vertex index {} out of range ({} vertices)", f, v, n));
      if (!mesh.positions[v].allFinite())
        throw InvalidInput(fmt::format("chartify: vertex {} (of face {}) has a non-finite coordinate", v, f));
    }
    if (has_repeated_index(t))
      throw InvalidInput(fmt::format("chartify: face {} repeats a vertex index ({}, {}, {})", f, t[0], t[1], t[2]));
  }
}

/// Checks that every edge of `topo` has one or two faces and that two faces of an edge traverse it in
/// opposite directions. Throws TopologyError naming the first offending edge.
void check_edges(MeshView mesh, const EdgeTopology& topo) {
  for (std::size_t e = 0; e < topo.num_edges(); ++e) {
    const auto [u, v] = topo.edges[e];
    const std::uint32_t valence = topo.valence(e);
    if (valence > 2)
      throw TopologyError(fmt::format("chartify: edge ({}, {}) has {} faces (non-manifold)", u, v, valence));
    if (valence != 2) continue;
    const std::uint32_t h0 = topo.edge_halfedges[topo.edge_offsets[e]];
    const std::uint32_t h1 = topo.edge_halfedges[topo.edge_offsets[e] + 1];
    if (halfedge_tail(mesh, h0) == halfedge_tail(mesh, h1))
      throw TopologyError(fmt::format("chartify: faces {} and {} disagree on orientation at edge ({}, {})", h0 / 3,
                                      h1 / 3, u, v));
  }
}

/// Connectivity and geometry that every round of the chartification reads; built once.
/// - `dual`: faces joined across two-sided edges, arc length = centroid distance |P_F' − P_F|.
/// - Faces at vertex v: `vertex_faces[vertex_offsets[v] .. vertex_offsets[v+1])`.
/// - `unit_normals[f]`: N_F (zero for a zero-area face); `area_normals[f]`: area · N_F.
struct ChartMesh {
  MeshView mesh;
  EdgeTopology topo;
  WeightedGraph dual;
  std::vector<std::uint32_t> vertex_offsets;
  std::vector<std::uint32_t> vertex_faces;
  std::vector<Vec3> unit_normals;
  std::vector<Vec3> area_normals;
};

/// Builds the ChartMesh of a checked mesh (see check_faces, check_edges). O(F log F).
ChartMesh build_chart_mesh(MeshView mesh, EdgeTopology topo) {
  ChartMesh m;
  m.mesh = mesh;
  m.topo = std::move(topo);
  m.dual = dual_graph(mesh, m.topo);
  const std::size_t num_faces = mesh.faces.size();
  m.vertex_offsets.assign(mesh.positions.size() + 1, 0);
  for (const Face& t : mesh.faces)
    for (std::uint32_t v : t) ++m.vertex_offsets[v + 1];
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) m.vertex_offsets[v + 1] += m.vertex_offsets[v];
  m.vertex_faces.resize(3 * num_faces);
  std::vector<std::uint32_t> fill(m.vertex_offsets.begin(), m.vertex_offsets.end() - 1);
  m.unit_normals.resize(num_faces);
  m.area_normals.resize(num_faces);
  for (std::size_t f = 0; f < num_faces; ++f) {
    const Face& t = mesh.faces[f];
    for (std::uint32_t v : t) m.vertex_faces[fill[v]++] = static_cast<std::uint32_t>(f);
    const Vec3& a = mesh.positions[t[0]];
    const Vec3 cross = (mesh.positions[t[1]] - a).cross(mesh.positions[t[2]] - a);
    const double len = cross.norm();
    m.unit_normals[f] = len > 0.0 ? Vec3(cross / len) : Vec3::Zero();
    m.area_normals[f] = 0.5 * cross;
  }
  return m;
}

/// A face offered to a chart during growth, with its tentative distance (the Dijkstra key).
struct Candidate {
  double key;
  std::uint32_t face;
  std::uint32_t chart;
};

/// Heap order: the smallest key on top; ties broken by face, then chart, so growth is deterministic.
struct CandidateAfter {
  bool operator()(const Candidate& a, const Candidate& b) const {
    if (a.key != b.key) return a.key > b.key;
    if (a.face != b.face) return a.face > b.face;
    return a.chart > b.chart;
  }
};

/// Phase 1 of §4.1 (chart growth): all charts grow at once from their seeds in one Dijkstra search on the
/// dual graph, with cost (λ − N_C·N_F′)·|P_F′ − P_F| (clamped at 0), under the chart topology constraint.
/// Buffers are allocated once and reused by every round.
class ChartGrower {
 public:
  ChartGrower(const ChartMesh& m, double lambda)
      : m_(m), lambda_(lambda), face_chart_(m.mesh.faces.size(), kUnassigned) {}

  /// Grows one chart per seed (`seeds` distinct faces; chart c from seeds[c]). Returns true when every face
  /// was assigned; otherwise next_seeds() names the faces to add as seeds.
  bool grow(const std::vector<std::uint32_t>& seeds);

  /// The faces to make new seeds after a grow() that left faces unassigned: one per connected region of
  /// unassigned faces — its first face that failed the disk rule, else (a component without a seed) its
  /// lowest face — in that order. Every region needs a seed of its own, so they are added together rather
  /// than one per whole growth (a scan with holes leaves a hundred such regions per round).
  [[nodiscard]] std::vector<std::uint32_t> next_seeds() const;

  /// The chart of every face after the last grow() (kUnassigned where none took it).
  [[nodiscard]] const std::vector<std::uint32_t>& face_chart() const { return face_chart_; }
  /// The last face the last grow() assigned by growth (not as a seed); kInvalidIndex if none.
  [[nodiscard]] std::uint32_t last_grown() const { return last_grown_; }

 private:
  /// The chart topology constraint: whether `face` may join the disk `chart` and leave it a disk. With k the
  /// edges of `face` shared with the chart: k = 1 needs the vertex opposite the shared edge to be new to
  /// the chart (else an annulus or a pinched vertex would form), k = 2 fills a notch, k = 3 would close it.
  [[nodiscard]] bool disk_rule_allows(std::uint32_t face, std::uint32_t chart) const;
  /// Puts `face` into `chart` at distance `dist`, updates N_C and offers the face's unassigned neighbours.
  void assign(std::uint32_t face, std::uint32_t chart, double dist);

  const ChartMesh& m_;
  double lambda_;
  std::vector<std::uint32_t> face_chart_;
  std::vector<Vec3> normal_sums_;          ///< per chart: area-weighted sum of its face normals
  std::vector<Candidate> heap_;
  std::vector<std::uint32_t> refused_;     ///< faces that failed the disk rule, in order of failure
  std::uint32_t last_grown_{kInvalidIndex};
};

bool ChartGrower::grow(const std::vector<std::uint32_t>& seeds) {
  std::fill(face_chart_.begin(), face_chart_.end(), kUnassigned);
  normal_sums_.assign(seeds.size(), Vec3::Zero());
  heap_.clear();
  refused_.clear();
  last_grown_ = kInvalidIndex;
  // Every seed is placed before any chart grows, so no chart offers another chart's seed to itself.
  for (std::size_t c = 0; c < seeds.size(); ++c) face_chart_[seeds[c]] = static_cast<std::uint32_t>(c);
  for (std::size_t c = 0; c < seeds.size(); ++c) assign(seeds[c], static_cast<std::uint32_t>(c), 0.0);
  std::size_t assigned = seeds.size();
  while (!heap_.empty()) {
    std::pop_heap(heap_.begin(), heap_.end(), CandidateAfter{});
    const Candidate cand = heap_.back();
    heap_.pop_back();
    if (face_chart_[cand.face] != kUnassigned) continue;
    if (!disk_rule_allows(cand.face, cand.chart)) {
      refused_.push_back(cand.face);  // offered again when another of its neighbours joins the chart
      continue;
    }
    face_chart_[cand.face] = cand.chart;
    assign(cand.face, cand.chart, cand.key);
    last_grown_ = cand.face;
    ++assigned;
  }
  return assigned == face_chart_.size();
}

std::vector<std::uint32_t> ChartGrower::next_seeds() const {
  const WeightedGraph& g = m_.dual;
  std::vector<char> seeded(face_chart_.size(), 0);  // faces of regions that already have their seed
  std::vector<std::uint32_t> out, stack;
  const auto take = [&](std::uint32_t f) {
    if (face_chart_[f] != kUnassigned || seeded[f]) return;
    out.push_back(f);
    seeded[f] = 1;
    stack.assign(1, f);
    while (!stack.empty()) {
      const std::uint32_t x = stack.back();
      stack.pop_back();
      for (std::uint32_t k = g.offsets[x]; k < g.offsets[x + 1]; ++k) {
        const std::uint32_t y = g.targets[k];
        if (face_chart_[y] == kUnassigned && !seeded[y]) seeded[y] = 1, stack.push_back(y);
      }
    }
  };
  for (std::uint32_t f : refused_) take(f);
  for (std::uint32_t f = 0; f < face_chart_.size(); ++f) take(f);
  return out;
}

bool ChartGrower::disk_rule_allows(std::uint32_t face, std::uint32_t chart) const {
  const WeightedGraph& g = m_.dual;
  std::uint32_t shared = 0;
  std::uint32_t shared_edge = kInvalidIndex;
  for (std::uint32_t a = g.offsets[face]; a < g.offsets[face + 1]; ++a)
    if (face_chart_[g.targets[a]] == chart) {
      ++shared;
      shared_edge = g.edges[a];
    }
  if (shared >= 3) return false;
  if (shared != 1) return true;
  const auto [u, v] = m_.topo.edges[shared_edge];
  const std::uint32_t w = opposite_vertex(m_.mesh.faces[face], u, v);
  for (std::uint32_t i = m_.vertex_offsets[w]; i < m_.vertex_offsets[w + 1]; ++i)
    if (face_chart_[m_.vertex_faces[i]] == chart) return false;
  return true;
}

void ChartGrower::assign(std::uint32_t face, std::uint32_t chart, double dist) {
  Vec3& sum = normal_sums_[chart];
  sum += m_.area_normals[face];
  const double len = sum.norm();
  const Vec3 chart_normal = len > 0.0 ? Vec3(sum / len) : Vec3::Zero();
  const WeightedGraph& g = m_.dual;
  for (std::uint32_t a = g.offsets[face]; a < g.offsets[face + 1]; ++a) {
    const std::uint32_t next = g.targets[a];
    if (face_chart_[next] != kUnassigned) continue;
    const double cost = std::max(0.0, lambda_ - chart_normal.dot(m_.unit_normals[next])) * g.lengths[a];
    heap_.push_back({dist + cost, next, chart});
    std::push_heap(heap_.begin(), heap_.end(), CandidateAfter{});
  }
}

/// Phase 2 of §4.1 (seed computation): a Dijkstra search with cost |P_F′ − P_F| from every face on a chart
/// boundary (an edge to another chart or on the mesh boundary), never leaving a chart; the last face
/// settled in each chart becomes its seed. A chart the search does not reach keeps its seed.
std::vector<std::uint32_t> move_seeds(const ChartMesh& m, DijkstraSearch& search,
                                      const std::vector<std::uint32_t>& face_chart,
                                      const std::vector<std::uint32_t>& seeds) {
  const WeightedGraph& g = m.dual;
  std::vector<std::uint32_t> sources;
  for (std::uint32_t f = 0; f < face_chart.size(); ++f) {
    bool boundary = g.offsets[f + 1] - g.offsets[f] < 3;
    for (std::uint32_t a = g.offsets[f]; a < g.offsets[f + 1] && !boundary; ++a)
      boundary = face_chart[g.targets[a]] != face_chart[f];
    if (boundary) sources.push_back(f);
  }
  search.run(
      sources,
      [&](std::uint32_t tail, std::uint32_t arc) { return face_chart[g.targets[arc]] == face_chart[tail]; },
      [](std::uint32_t) { return false; });
  std::vector<std::uint32_t> moved = seeds;
  for (std::uint32_t f : search.settled()) moved[face_chart[f]] = f;
  return moved;
}

/// Checks the options of chartify; throws InvalidInput naming the bad one.
void check_options(const ChartifyOptions& options) {
  if (options.charts < 1) throw InvalidInput("chartify: charts must be >= 1 (got 0)");
  if (!std::isfinite(options.lambda) || options.lambda < 0.0)
    throw InvalidInput(fmt::format("chartify: lambda must be finite and >= 0 (got {})", options.lambda));
  if (options.max_iterations < 0)
    throw InvalidInput(fmt::format("chartify: max_iterations must be >= 0 (got {})", options.max_iterations));
}

}  // namespace

Chartification chartify(MeshView mesh, const ChartifyOptions& options) {
  check_options(options);
  check_faces(mesh);
  EdgeTopology topo = build_edge_topology(mesh);
  check_edges(mesh, topo);
  const ChartMesh m = build_chart_mesh(mesh, std::move(topo));
  const std::size_t num_faces = mesh.faces.size();
  const std::size_t target = std::min<std::size_t>(options.charts, num_faces);

  Chartification result;
  ChartGrower grower(m, options.lambda);
  DijkstraSearch search(m.dual);
  std::vector<std::uint32_t> seeds{static_cast<std::uint32_t>(splitmix64(options.seed) % num_faces)};
  std::vector<std::vector<std::uint32_t>> history;  // sorted seed sets of the rounds after bootstrapping
  const double planned_rounds = static_cast<double>(target + static_cast<std::size_t>(options.max_iterations));
  std::vector<std::uint32_t> kept, kept_seeds;  // the last complete chartification of a Lloyd round, its seeds
  int seeding_rounds = 0;                       // Lloyd rounds that added seeds
  int rounds = 0;
  for (;;) {
    report_progress(options.progress, "chartify", std::min(1.0, static_cast<double>(rounds++) / planned_rounds));
    // Phase 1, with a new seed wherever the disk rule (or a component without a seed) leaves faces over —
    // in at most kSeedingLloydRounds of the Lloyd rounds; after that a growth that leaves faces over ends the
    // iteration with the last complete chartification (`kept`). Adding seeds in every round, as the paper
    // does, fragments scans with holes round after round (the dragon: 281 charts after the first growth,
    // 540 after 15 rounds) instead of converging.
    bool incomplete = false;
    bool seeded = false;
    while (!grower.grow(seeds)) {
      if (result.iterations > 0 && !seeded && seeding_rounds >= kSeedingLloydRounds) {
        incomplete = true;
        break;
      }
      if (result.iterations > 0 && !seeded) ++seeding_rounds;
      seeded = true;
      for (std::uint32_t f : grower.next_seeds()) {
        seeds.push_back(f);
        if (seeds.size() > target) ++result.extra_seeds;
      }
    }
    if (incomplete) {
      result.fragmenting = true;
      seeds = std::move(kept_seeds);
      break;
    }
    const std::vector<std::uint32_t>& face_chart = grower.face_chart();
    if (seeds.size() < target && grower.last_grown() != kInvalidIndex) {
      // Bootstrapping: the last face grown becomes a seed; phase 2 moves the others. Should a chart's new
      // seed be that very face, the chart keeps its old seed (a different face of the same chart).
      const std::uint32_t added = grower.last_grown();
      std::vector<std::uint32_t> moved = move_seeds(m, search, face_chart, seeds);
      const std::uint32_t host = face_chart[added];
      if (moved[host] == added) moved[host] = seeds[host];
      moved.push_back(added);
      seeds = std::move(moved);
      ++result.bootstrap_rounds;
      continue;
    }
    if (result.iterations >= options.max_iterations) break;
    ++result.iterations;
    const std::vector<std::uint32_t> moved = move_seeds(m, search, face_chart, seeds);
    if (moved == seeds) {
      result.converged = true;
      break;
    }
    std::vector<std::uint32_t> sorted = moved;
    std::sort(sorted.begin(), sorted.end());
    if (std::find(history.begin(), history.end(), sorted) != history.end()) {
      result.cycle = true;  // any chartification of the cycle will do: keep the one grown from `seeds`
      break;
    }
    std::vector<std::uint32_t> current = seeds;
    std::sort(current.begin(), current.end());
    history.push_back(std::move(current));
    kept = face_chart;
    kept_seeds = seeds;
    seeds = moved;
  }
  report_progress(options.progress, "chartify", 1.0);
  result.face_chart = result.fragmenting ? std::move(kept) : grower.face_chart();
  result.seeds = std::move(seeds);
  result.num_charts = static_cast<std::uint32_t>(result.seeds.size());
  return result;
}

bool is_topological_disk(MeshView mesh, const std::vector<std::uint32_t>& faces) {
  // The set, without repeats, in increasing order.
  std::vector<std::uint32_t> set = faces;
  std::sort(set.begin(), set.end());
  set.erase(std::unique(set.begin(), set.end()), set.end());
  if (set.empty()) return false;
  for (std::uint32_t f : set) {
    if (f >= mesh.faces.size())
      throw InvalidInput(
          fmt::format("is_topological_disk: face index {} out of range ({} faces)", f, mesh.faces.size()));
    for (std::uint32_t v : mesh.faces[f])
      if (v >= mesh.positions.size())
        throw InvalidInput(fmt::format("is_topological_disk: face {} has vertex index {} out of range ({} vertices)",
                                       f, v, mesh.positions.size()));
    if (has_repeated_index(mesh.faces[f])) return false;
  }
  const auto num_local = static_cast<std::uint32_t>(set.size());
  // Corner 3*l + i sits at vertex faces[set[l]][i]; side 3*l + i runs from corner i to corner (i+1)%3.
  auto vertex_of = [&](std::uint32_t corner) { return mesh.faces[set[corner / 3]][corner % 3]; };
  struct Side {
    std::uint64_t key;
    std::uint32_t side;
  };
  std::vector<Side> sides;
  sides.reserve(3 * set.size());
  for (std::uint32_t s = 0; s < 3 * num_local; ++s) {
    const std::uint32_t a = vertex_of(s);
    const std::uint32_t b = vertex_of(3 * (s / 3) + (s % 3 + 1) % 3);
    sides.push_back({(std::uint64_t{std::min(a, b)} << 32) | std::max(a, b), s});
  }
  std::sort(sides.begin(), sides.end(),
            [](const Side& x, const Side& y) { return x.key != y.key ? x.key < y.key : x.side < y.side; });

  UnionFind components(set.size());
  UnionFind corners(3 * set.size());
  std::size_t num_edges = 0;
  std::size_t boundary_edges = 0;
  for (std::size_t i = 0; i < sides.size();) {
    std::size_t j = i;
    while (j < sides.size() && sides[j].key == sides[i].key) ++j;
    ++num_edges;
    if (j - i > 2) return false;  // more than two faces of the set on one edge
    if (j - i == 1) {
      ++boundary_edges;
    } else {
      const std::uint32_t s = sides[i].side;
      const std::uint32_t t = sides[i + 1].side;
      components.unite(s / 3, t / 3);
      // Each endpoint's corner in one face joins its corner in the other: the faces are fan neighbours there.
      for (std::uint32_t cs : {s, 3 * (s / 3) + (s % 3 + 1) % 3})
        for (std::uint32_t ct : {t, 3 * (t / 3) + (t % 3 + 1) % 3})
          if (vertex_of(cs) == vertex_of(ct)) corners.unite(cs, ct);
    }
    i = j;
  }
  if (boundary_edges == 0) return false;
  const std::uint32_t root = components.find(0);
  for (std::uint32_t l = 1; l < num_local; ++l)
    if (components.find(l) != root) return false;
  // One fan per vertex: every vertex's corners fall in one corner set.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> vertex_fans;  // (vertex, corner set)
  vertex_fans.reserve(3 * set.size());
  for (std::uint32_t c = 0; c < 3 * num_local; ++c) vertex_fans.emplace_back(vertex_of(c), corners.find(c));
  std::sort(vertex_fans.begin(), vertex_fans.end());
  vertex_fans.erase(std::unique(vertex_fans.begin(), vertex_fans.end()), vertex_fans.end());
  std::size_t num_vertices = 0;
  for (std::size_t i = 0; i < vertex_fans.size(); ++i) {
    if (i > 0 && vertex_fans[i].first == vertex_fans[i - 1].first) return false;  // a second fan
    ++num_vertices;
  }
  const auto euler = static_cast<long long>(num_vertices) - static_cast<long long>(num_edges) +
                     static_cast<long long>(set.size());
  return euler == 1;
}

}  // namespace gimforge
