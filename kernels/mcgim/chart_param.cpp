#include "kernels/mcgim/chart_param.h"

#include <chrono>
#include <cmath>
#include <numbers>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <string>
#include <unordered_map>

#include <fmt/format.h>

#include "kernels/core/edge_topology.h"
#include "kernels/core/errors.h"
#include "kernels/param/floater.h"
#include "kernels/param/lscm.h"

namespace gimforge {
namespace {

/// The boundary loop of a disk mesh, following its boundary halfedges (the face on their left).
std::vector<std::uint32_t> boundary_loop(const TriMesh& mesh, std::uint32_t chart) {
  const EdgeTopology topo = build_edge_topology(mesh);
  std::unordered_map<std::uint32_t, std::uint32_t> next;  // boundary halfedge tail -> head
  std::size_t boundary_edges = 0;
  for (std::size_t e = 0; e < topo.num_edges(); ++e) {
    if (topo.valence(e) > 2) throw InvalidInput(fmt::format("chart {} has a non-manifold edge", chart));
    if (topo.valence(e) != 1) continue;
    const std::uint32_t h = topo.edge_halfedges[topo.edge_offsets[e]];
    if (!next.emplace(halfedge_tail(mesh, h), halfedge_head(mesh, h)).second)
      throw InvalidInput(fmt::format("chart {} is not a disk: its boundary passes a vertex twice", chart));
    ++boundary_edges;
  }
  if (boundary_edges < 3) throw InvalidInput(fmt::format("chart {} is not a disk: it has no boundary", chart));
  std::vector<std::uint32_t> loop{next.begin()->first};
  for (std::uint32_t v = next.at(loop.front()); v != loop.front(); v = next.at(v)) {
    if (loop.size() > boundary_edges) break;
    loop.push_back(v);
  }
  if (loop.size() != boundary_edges)
    throw InvalidInput(fmt::format("chart {} is not a disk: it has more than one boundary loop", chart));
  return loop;
}

double cross2(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

/// True when two segments p0p1 and q0q1 that share no endpoint cross or touch.
bool segments_meet(const Vec2& p0, const Vec2& p1, const Vec2& q0, const Vec2& q1) {
  const double d1 = cross2(p1 - p0, q0 - p0), d2 = cross2(p1 - p0, q1 - p0);
  const double d3 = cross2(q1 - q0, p0 - q0), d4 = cross2(q1 - q0, p1 - q0);
  return ((d1 > 0) != (d2 > 0) || d1 == 0 || d2 == 0) && ((d3 > 0) != (d4 > 0) || d3 == 0 || d4 == 0);
}

/// The diameter of the shorter boundary arc from edge i to edge j (their endpoints included): the size of
/// the loop a crossing of the two edges closes.
double loop_diameter(const ChartMesh& chart, const std::vector<Vec2>& uv, std::size_t i, std::size_t j) {
  const std::size_t m = chart.boundary.size();
  const bool inner = j - i <= m - (j - i);
  const std::size_t first = inner ? i : j, count = (inner ? j - i : m - (j - i)) + 2;
  Eigen::AlignedBox2d box;
  for (std::size_t k = 0; k < count; ++k) box.extend(uv[chart.boundary[(first + k) % m]]);
  return box.diagonal().norm();
}

/// True when a chart's parametrization is not one-to-one although no triangle is flipped: its boundary
/// polygon crosses itself, or its triangles cover more than the polygon (a fan wound past 360° at a
/// boundary vertex). A free boundary can do both; the sampling would then mix two layers of the surface.
/// A crossing whose loop (loop_diameter) is below `fold` is a fold of the boundary too small for the
/// sampling to see (a scan's jagged hole rim: sliver faces folded back), and is counted in `*folds` instead.
bool overlaps(const ChartMesh& chart, const std::vector<Vec2>& uv, double fold = 0.0, std::size_t* folds = nullptr) {
  const std::size_t m = chart.boundary.size();
  double polygon = 0.0, triangles = 0.0;
  for (std::size_t i = 0; i < m; ++i) polygon += cross2(uv[chart.boundary[i]], uv[chart.boundary[(i + 1) % m]]);
  for (const Face& f : chart.mesh.faces) triangles += cross2(uv[f[1]] - uv[f[0]], uv[f[2]] - uv[f[0]]);
  if (std::abs(polygon - triangles) > 1e-9 * std::abs(triangles)) return true;
  // Boundary self-intersection, edges against non-adjacent edges (after a bounding-box reject).
  for (std::size_t i = 0; i < m; ++i) {
    const Vec2 &a = uv[chart.boundary[i]], &b = uv[chart.boundary[(i + 1) % m]];
    const Eigen::AlignedBox2d box_ab(a.cwiseMin(b), a.cwiseMax(b));
    for (std::size_t j = i + 2; j < m; ++j) {
      if (i == 0 && j + 1 == m) continue;  // adjacent through the loop's closing vertex
      const Vec2 &c = uv[chart.boundary[j]], &d = uv[chart.boundary[(j + 1) % m]];
      if (!box_ab.intersects(Eigen::AlignedBox2d(c.cwiseMin(d), c.cwiseMax(d)))) continue;
      if (!segments_meet(a, b, c, d)) continue;
      if (loop_diameter(chart, uv, i, j) >= fold) return true;
      if (folds != nullptr) ++*folds;
    }
  }
  return false;
}

/// The boundary of a one-to-one start on a convex curve: the circle of circle_boundary (spacing by arc
/// length), stretched into an ellipse of the aspect ratio of `hint`'s boundary (principal axes; a map that
/// overlaps but has the chart's shape) with the boundary vertex farthest along the major axis at its end.
/// An elongated chart on a circle is squeezed across: a scan's long charts measured 0.002-0.015 stretch
/// efficiency so, and the held-boundary fallback kept it.
std::vector<Vec2> convex_boundary(const ChartMesh& chart, std::span<const Vec2> hint) {
  std::vector<Vec2> uv = circle_boundary(chart.mesh, chart.boundary);
  const std::size_t m = chart.boundary.size();
  if (hint.size() != chart.mesh.num_vertices()) return uv;
  Vec2 mean = Vec2::Zero();
  for (std::uint32_t v : chart.boundary) mean += hint[v];
  mean /= static_cast<double>(m);
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (std::uint32_t v : chart.boundary) cov += (hint[v] - mean) * (hint[v] - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
  if (eig.info() != Eigen::Success || !(eig.eigenvalues()[0] > 0.0) || !std::isfinite(eig.eigenvalues()[1])) return uv;
  const double aspect = std::min(50.0, std::sqrt(eig.eigenvalues()[1] / eig.eigenvalues()[0]));
  const Vec2 major = eig.eigenvectors().col(1);
  std::size_t end = 0;
  for (std::size_t i = 1; i < m; ++i)
    if (major.dot(hint[chart.boundary[i]] - mean) > major.dot(hint[chart.boundary[end]] - mean)) end = i;
  const double shift = std::atan2(uv[end].y(), uv[end].x());
  for (Vec2& p : uv) {
    const double phi = std::atan2(p.y(), p.x()) - shift;
    p = Vec2(aspect * std::cos(phi), std::sin(phi));
  }
  return uv;
}

/// A one-to-one map of a disk chart with its boundary on a convex curve (convex_boundary): Floater's
/// shape-preserving map with the boundary spaced by arc length, or — where that one degenerates (coincident
/// vertices give zero-length boundary edges and undefined local polar maps; scanned meshes have them) —
/// Tutte's map, uniform weights with the boundary spaced evenly on a circle, which is one-to-one for any
/// disk triangulation (Floater 2003) whatever the geometry. Empty when neither is valid in floating point.
std::vector<Vec2> bijective_start(const ChartMesh& chart, bool* tutte, std::span<const Vec2> hint) {
  *tutte = false;
  try {
    std::vector<Vec2> uv = floater_parametrization(chart.mesh, chart.boundary, convex_boundary(chart, hint));
    if (mesh_stretch(chart.mesh, uv).flipped == 0) return uv;
  } catch (const Error&) {
    // Tutte's map below
  }
  const std::size_t m = chart.boundary.size();
  std::vector<Vec2> circle(m);
  for (std::size_t i = 0; i < m; ++i) {
    const double phi = 2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(m);
    circle[i] = Vec2(std::cos(phi), std::sin(phi));
  }
  FloaterOptions uniform;
  uniform.weights = FloaterOptions::Weights::Uniform;
  try {
    std::vector<Vec2> uv = floater_parametrization(chart.mesh, chart.boundary, circle, uniform);
    if (mesh_stretch(chart.mesh, uv).flipped == 0) {
      *tutte = true;
      return uv;
    }
  } catch (const Error&) {
    // neither
  }
  return {};
}

/// Σ L2² A' (S) and the parameter area (D) of a parametrized chart.
/// (Σ L2² A′, Σ parameter area) of a chart; a chart without surface area (every face degenerate, as some of a
/// raw scan's are) has no stretch: its L2 is 0/0, its first sum 0.
std::pair<double, double> stretch_sums(const MeshStretch& s) {
  const double sum = s.surface_area > 0.0 && std::isfinite(s.l2) ? s.l2 * s.l2 * s.surface_area : 0.0;
  return {sum, s.domain_area};
}

}  // namespace

std::vector<ChartMesh> extract_charts(MeshView mesh, const std::vector<std::uint32_t>& face_chart,
                                      std::uint32_t num_charts) {
  if (face_chart.size() != mesh.faces.size())
    throw InvalidInput("extract_charts: face_chart must have one entry per face");
  std::vector<ChartMesh> charts(num_charts);
  std::vector<std::uint32_t> local(mesh.positions.size(), 0xffffffffu);
  std::vector<std::vector<std::uint32_t>> members(num_charts);
  for (std::uint32_t f = 0; f < face_chart.size(); ++f) {
    if (face_chart[f] >= num_charts) throw InvalidInput(fmt::format("extract_charts: face {} has no chart", f));
    members[face_chart[f]].push_back(f);
  }
  for (std::uint32_t c = 0; c < num_charts; ++c) {
    ChartMesh& chart = charts[c];
    if (members[c].empty()) throw InvalidInput(fmt::format("extract_charts: chart {} has no face", c));
    for (std::uint32_t f : members[c]) {
      Face local_face{};
      for (int i = 0; i < 3; ++i) {
        const std::uint32_t v = mesh.faces[f][static_cast<std::size_t>(i)];
        if (local[v] == 0xffffffffu) {
          local[v] = static_cast<std::uint32_t>(chart.vertices.size());
          chart.vertices.push_back(v);
          chart.mesh.positions.push_back(mesh.positions[v]);
        }
        local_face[static_cast<std::size_t>(i)] = local[v];
      }
      chart.mesh.faces.push_back(local_face);
      chart.faces.push_back(f);
    }
    for (std::uint32_t v : chart.vertices) local[v] = 0xffffffffu;
    chart.boundary = boundary_loop(chart.mesh, c);
    const std::size_t euler = chart.vertices.size() + chart.faces.size() -
                              (3 * chart.faces.size() + chart.boundary.size()) / 2;
    if (euler != 1) throw InvalidInput(fmt::format("chart {} is not a disk (Euler characteristic {})", c, euler));
  }
  return charts;
}

void enlarge_chart(ChartParametrization& param, const ChartMesh& chart, std::size_t c, double factor) {
  if (c >= param.uv.size() || !(factor > 0.0) || !std::isfinite(factor))
    throw InvalidInput(fmt::format("enlarge_chart: chart {} of {}, factor {}", c, param.uv.size(), factor));
  const auto [s_before, d_before] = stretch_sums(param.stretch[c]);
  for (Vec2& p : param.uv[c]) p *= factor;
  param.stretch[c] = mesh_stretch(chart.mesh, param.uv[c]);
  const auto [s_after, d_after] = stretch_sums(param.stretch[c]);
  MeshStretch& t = param.total;
  const double total_s = t.l2 * t.l2 * t.surface_area - s_before + s_after;
  t.domain_area += d_after - d_before;
  t.l2 = std::sqrt(total_s / t.surface_area);
  t.efficiency = t.surface_area * t.surface_area / (t.domain_area * total_s);
}

ChartParametrization parametrize_charts(const std::vector<ChartMesh>& charts, const ChartParamOptions& options,
                                        const std::vector<std::vector<Vec2>>* reuse) {
  const auto t0 = std::chrono::steady_clock::now();
  ChartParametrization out;
  out.uv.resize(charts.size());
  out.stretch.resize(charts.size());
  out.split.assign(charts.size(), 0);
  std::vector<std::pair<double, double>> sums(charts.size());
  for (std::size_t c = 0; c < charts.size(); ++c) {
    const ChartMesh& chart = charts[c];
    if (reuse != nullptr && c < reuse->size() && (*reuse)[c].size() == chart.mesh.num_vertices()) {
      out.uv[c] = (*reuse)[c];
      out.stretch[c] = mesh_stretch(chart.mesh, out.uv[c]);
      sums[c] = stretch_sums(out.stretch[c]);
      continue;
    }
    // Start: least-squares conformal map (free boundary, keeps elongated charts elongated); where it folds,
    // Floater's map with the boundary on an ellipse of the conformal map's aspect (bijective).
    // The conformal map can also degenerate (a highly curved chart pinned at two far vertices shrinks to a
    // sliver): of the two starts, the one of higher stretch efficiency is kept.
    std::vector<Vec2> uv;
    double start_efficiency = 0.0;
    try {
      uv = lscm_parametrization(chart.mesh, chart.boundary);
      const MeshStretch s = mesh_stretch(chart.mesh, uv);
      if (s.flipped > 0) uv.clear();
      else start_efficiency = s.efficiency;
    } catch (const Error&) {
      uv.clear();
    }
    bool tutte = false;
    std::vector<Vec2> circle_map = bijective_start(chart, &tutte, uv);
    if (!circle_map.empty() && (uv.empty() || mesh_stretch(chart.mesh, circle_map).efficiency > start_efficiency)) {
      uv = std::move(circle_map);
      ++(tutte ? out.tutte_starts : out.floater_starts);
    }
    if (uv.empty()) throw NumericalError(fmt::format("chart {}: neither a conformal, a Floater nor a Tutte map is valid", c));
    StretchOptimizerOptions so = options.stretch;
    so.free_boundary = true;
    so.progress = {};
    try {
      const std::vector<char> fixed(chart.mesh.num_vertices(), 0);
      std::vector<Vec2> free = optimize_stretch(chart.mesh, uv, fixed, so).uv;
      std::size_t folds = 0;
      if (!overlaps(chart, free, options.fold_tolerance, &folds)) {
        out.small_folds += folds;
        uv = std::move(free);
      } else {
        // One-to-one above all: the boundary stays where a bijective start put it (Floater on a convex ellipse
        // unless the conformal start is itself one-to-one), and only the interior is optimized.
        ++out.overlap_fallbacks;
        out.split[c] = 1;
        if (overlaps(chart, uv)) {
          bool held_tutte = false;
          uv = bijective_start(chart, &held_tutte, free);
          if (uv.empty()) throw NumericalError(fmt::format("chart {}: no one-to-one map with a held boundary", c));
        }
        std::vector<char> held(chart.mesh.num_vertices(), 0);
        for (std::uint32_t v : chart.boundary) held[v] = 1;
        so.free_boundary = false;
        uv = optimize_stretch(chart.mesh, uv, held, so).uv;
      }
    } catch (const Cancelled&) {
      throw;
    } catch (const Error&) {
      ++out.optimizer_fallbacks;  // keep the start map: valid, only more stretched
    }
    out.uv[c] = std::move(uv);
    out.stretch[c] = mesh_stretch(chart.mesh, out.uv[c]);
    if (out.stretch[c].efficiency < kSplitEfficiency) out.split[c] = 1;
    sums[c] = stretch_sums(out.stretch[c]);
    report_progress(options.progress, "parametrize", static_cast<double>(c + 1) / static_cast<double>(charts.size()));
  }
  // Relative scale: parameter area of chart i ∝ sqrt(S_i D_i); then Σ parameter area = Σ surface area.
  double weight_sum = 0.0, surface = 0.0;
  for (std::size_t c = 0; c < charts.size(); ++c) {
    weight_sum += std::sqrt(sums[c].first * sums[c].second);
    surface += out.stretch[c].surface_area;
  }
  // uv scale factors; a chart without stretch (no surface area, or a parameter domain of zero area) gets the
  // median factor of the others, which keeps it samplable for the zipper.
  std::vector<double> factor(charts.size(), 0.0);
  std::vector<double> proper;
  for (std::size_t c = 0; c < charts.size(); ++c) {
    const double weight = std::sqrt(sums[c].first * sums[c].second);
    if (!(weight > 0.0) || !std::isfinite(weight) || !(weight_sum > 0.0)) continue;
    factor[c] = std::sqrt(surface * weight / weight_sum / sums[c].second);
    proper.push_back(factor[c]);
  }
  double fallback = 1.0;
  if (!proper.empty()) {
    std::nth_element(proper.begin(), proper.begin() + static_cast<std::ptrdiff_t>(proper.size() / 2), proper.end());
    fallback = proper[proper.size() / 2];
  }
  double total_s = 0.0, total_d = 0.0;
  for (std::size_t c = 0; c < charts.size(); ++c) {
    const double k = factor[c] > 0.0 ? factor[c] : fallback;
    const double area = sums[c].second * k * k;
    for (Vec2& p : out.uv[c]) p *= k;
    out.stretch[c] = mesh_stretch(charts[c].mesh, out.uv[c]);
    total_s += sums[c].first / (k * k);
    total_d += area;
  }
  out.total.surface_area = surface;
  out.total.domain_area = total_d;
  out.total.l2 = std::sqrt(total_s / surface);
  out.total.efficiency = surface * surface / (total_d * total_s);
  for (const MeshStretch& s : out.stretch) {
    out.total.linf = std::max(out.total.linf, s.linf);
    out.total.flipped += s.flipped;
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace gimforge
