#include "kernels/param/stretch_optimizer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <queue>
#include <random>
#include <string>
#include <tuple>
#include <utility>

#include <Eigen/Geometry>

#include "kernels/core/errors.h"
#include "kernels/param/convex_polygon.h"
#include "kernels/param/floater.h"
#include "kernels/param/line_search.h"
#include "kernels/param/progressive_mesh.h"

namespace gimforge {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
/// Sweeps at the finest level with a free boundary (StretchOptimizerOptions::free_boundary).
constexpr int kFreeBoundarySweeps = 40;

double cross2(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

/// The two other corners (x, y) of face f, so that (v, x, y) is the face in its own cyclic order.
std::pair<std::uint32_t, std::uint32_t> opposite_edge(const Face& f, std::uint32_t v) {
  const std::size_t i = f[0] == v ? 0 : (f[1] == v ? 1 : 2);
  return {f[(i + 1) % 3], f[(i + 2) % 3]};
}

/// One triangle (v, a, b) of a vertex's ring, with its stretch energy L2² A' written as a function of the
/// vertex's parameter offset p from its current position: E(p) = area/2 · N(p) / det(p)², where
/// N(p) = k0 + ks p.x + kt p.y + kd |p|² and det(p) = cross(a - p, b - p) (twice the parameter area).
struct RingTriangle {
  Vec2 a, b;  // relative to the vertex's current position
  double k0, ks, kt, kd, area;
};

RingTriangle make_ring_triangle(const Vec2& a, const Vec2& b, const Vec3& qv, const Vec3& qa, const Vec3& qb) {
  // S_s·2A = qv (ta − tb) + qa (tb − tp) + qb (tp − ta) = cs + tp·d;  S_t·2A = ct − sp·d  (d = qb − qa).
  const Vec3 d = qb - qa;
  const Vec3 cs = qv * (a.y() - b.y()) + qa * b.y() - qb * a.y();
  const Vec3 ct = qv * (b.x() - a.x()) - qa * b.x() + qb * a.x();
  return {a, b, cs.squaredNorm() + ct.squaredNorm(), -2.0 * ct.dot(d), 2.0 * cs.dot(d), d.squaredNorm(),
          0.5 * (qa - qv).cross(qb - qv).norm()};
}

double ring_triangle_energy(const RingTriangle& r, const Vec2& p) {
  const double det = cross2(r.a - p, r.b - p);
  if (!(det > 0.0)) return kInf;
  return 0.5 * r.area * (r.k0 + r.ks * p.x() + r.kt * p.y() + r.kd * p.squaredNorm()) / (det * det);
}

/// Gradient of ring_triangle_energy at p (finite det assumed).
Vec2 ring_triangle_gradient(const RingTriangle& r, const Vec2& p) {
  const double det = cross2(r.a - p, r.b - p);
  const double n = r.k0 + r.ks * p.x() + r.kt * p.y() + r.kd * p.squaredNorm();
  const Vec2 dn(r.ks + 2.0 * r.kd * p.x(), r.kt + 2.0 * r.kd * p.y());
  const Vec2 ddet(r.a.y() - r.b.y(), r.b.x() - r.a.x());
  return 0.5 * r.area * (dn - 2.0 * n / det * ddet) / (det * det);
}

/// Twice the parameter area of a ring triangle with the vertex at offset p.
double ring_triangle_det(const RingTriangle& r, const Vec2& p) { return cross2(r.a - p, r.b - p); }

/// Vertex optimization on the current level of a progressive mesh (Sander et al. 2002): line searches that
/// minimize Σ L2(T)² A'(T) over the vertex's triangles and never cross a flip. In product mode (free
/// boundary) the objective is S·D, S = Σ L2² A' and D = Σ parameter area over the whole level: the optimizer
/// keeps both totals, so a move of one vertex is judged by its effect on the global product, written on the
/// ring's scale as (S + ΔS)(D + ΔD)/D − (S − S_ring).
class VertexOptimizer {
 public:
  VertexOptimizer(const ProgressiveMesh& pm, std::span<const char> fixed, std::vector<Vec2>& uv, std::uint64_t seed,
                  bool product)
      : pm_(pm), fixed_(fixed), uv_(uv), rng_(seed), product_(product) {}

  /// Product mode: recomputes S and D over the current level (removes the drift of incremental updates).
  void reset_totals() {
    if (!product_) return;
    total_s_ = total_d_ = 0.0;
    for (std::size_t f = 0; f < pm_.faces().size(); ++f)
      if (pm_.face_alive(f)) add_face(static_cast<std::uint32_t>(f), 1.0);
  }

  /// Product mode: adds (sign +1) or removes (−1) the contributions of faces to S and D; `skip` is a vertex
  /// whose faces are left out (kNoVertex: none).
  void add_faces(std::span<const std::uint32_t> faces, double sign, std::uint32_t skip = kNoVertex) {
    if (!product_) return;
    for (std::uint32_t f : faces) {
      const Face& c = pm_.faces()[f];
      if (skip != kNoVertex && (c[0] == skip || c[1] == skip || c[2] == skip)) continue;
      add_face(f, sign);
    }
  }

  /// Energy of v's triangles at its current position.
  double energy(std::uint32_t v) {
    load_ring(v);
    return ring_energy(Vec2::Zero());
  }

  /// Product mode: while set, boundary vertices stay where they are. They are never simplified, so on the
  /// coarse levels they sit among sliver triangles; moving them there leaves the re-inserted interior
  /// vertices tiny kernels and near-degenerate rings (and inflates S, so that the boundary — the only
  /// vertices whose moves change D — would shrink the whole domain to pay for it). The boundary is held
  /// through the hierarchy and freed for the sweeps at the finest level.
  void hold_boundary(bool hold) { hold_boundary_ = hold; }

  /// Moves v (if free) to lower its ring energy; returns the energy decrease (>= 0).
  double optimize(std::uint32_t v) {
    if (fixed_[v] || (product_ && hold_boundary_ && pm_.on_boundary(v))) return 0.0;
    load_ring(v);
    const double e0 = ring_energy(Vec2::Zero());
    if (!std::isfinite(e0)) return 0.0;
    Vec2 offset = Vec2::Zero();
    double e = e0;
    Vec2 g = Vec2::Zero();
    for (const RingTriangle& r : ring_) g += ring_triangle_gradient(r, offset);
    if (product_) {  // ∇(S·D)/D at the current position: ∇S_ring + (S/D)·∇D_ring
      for (const RingTriangle& r : ring_) g += 0.5 * (total_s_ / total_d_) * Vec2(r.a.y() - r.b.y(), r.b.x() - r.a.x());
    }
    if (g.squaredNorm() > 0.0) e = line_search(offset, -g.normalized(), e);
    const double angle = 2.0 * std::numbers::pi * static_cast<double>(rng_() >> 11) * 0x1.0p-53;
    e = line_search(offset, Vec2(std::cos(angle), std::sin(angle)), e);
    if (product_) {
      const auto [s, d] = ring_sums(offset);
      total_s_ += s - ring_s_;
      total_d_ += d - ring_d_;
    }
    uv_[v] += offset;
    return e0 - e;
  }

  /// True when every alive triangle of v has positive parameter area with v at p.
  bool valid_at(std::uint32_t v, const Vec2& p) const {
    for (std::uint32_t f : pm_.vertex_faces(v)) {
      const auto [x, y] = opposite_edge(pm_.faces()[f], v);
      if (!(cross2(uv_[x] - p, uv_[y] - p) > 0.0)) return false;
    }
    return true;
  }

 private:
  static constexpr std::uint32_t kNoVertex = 0xffffffffu;

  void load_ring(std::uint32_t v) {
    ring_.clear();
    const MeshView mesh = pm_.input();
    const Vec2 p0 = uv_[v];
    for (std::uint32_t f : pm_.vertex_faces(v)) {
      const auto [x, y] = opposite_edge(pm_.faces()[f], v);
      ring_.push_back(make_ring_triangle(uv_[x] - p0, uv_[y] - p0, mesh.positions[v], mesh.positions[x],
                                         mesh.positions[y]));
    }
    if (product_) std::tie(ring_s_, ring_d_) = ring_sums(Vec2::Zero());
  }

  /// Σ L2² A' and Σ parameter area of the ring with the vertex at offset p.
  std::pair<double, double> ring_sums(const Vec2& p) const {
    double s = 0.0, d = 0.0;
    for (const RingTriangle& r : ring_) {
      s += ring_triangle_energy(r, p);
      d += 0.5 * ring_triangle_det(r, p);
    }
    return {s, d};
  }

  double ring_energy(const Vec2& p) const {
    if (!product_) {
      double e = 0.0;
      for (const RingTriangle& r : ring_) e += ring_triangle_energy(r, p);
      return e;
    }
    const auto [s, d] = ring_sums(p);
    if (!std::isfinite(s)) return kInf;
    return (total_s_ + (s - ring_s_)) * (total_d_ + (d - ring_d_)) / total_d_ - (total_s_ - ring_s_);
  }

  /// Adds sign × face f's L2² A' and parameter area to the totals.
  void add_face(std::uint32_t f, double sign) {
    const Face& c = pm_.faces()[f];
    const MeshView mesh = pm_.input();
    const RingTriangle r = make_ring_triangle(uv_[c[1]] - uv_[c[0]], uv_[c[2]] - uv_[c[0]], mesh.positions[c[0]],
                                              mesh.positions[c[1]], mesh.positions[c[2]]);
    total_s_ += sign * ring_triangle_energy(r, Vec2::Zero());
    total_d_ += sign * 0.5 * ring_triangle_det(r, Vec2::Zero());
  }

  /// The open interval of τ for which offset + τ·dir keeps every triangle positive.
  std::pair<double, double> feasible_range(const Vec2& offset, const Vec2& dir) const {
    double lo = -kInf, hi = kInf, scale = 0.0;
    for (const RingTriangle& r : ring_) {
      const double det = cross2(r.a - offset, r.b - offset), rate = cross2(dir, r.a - r.b);
      scale = std::max({scale, (r.a - offset).norm(), (r.b - offset).norm()});
      if (rate < 0.0) hi = std::min(hi, det / -rate);
      if (rate > 0.0) lo = std::max(lo, -det / rate);
    }
    return {std::max(lo, -scale), std::min(hi, scale)};
  }

  /// Minimizes the ring energy along dir from offset (energy e there); updates offset, returns the energy.
  double line_search(Vec2& offset, const Vec2& dir, double e) {
    const auto [lo, hi] = feasible_range(offset, dir);
    if (!(hi > lo)) return e;
    const Vec2 base = offset;
    auto f = [&](double t) { return ring_energy(base + t * dir); };
    const auto [t, ft] = detail::brent_minimize(f, 0.999 * lo, 0.999 * hi, 0.0, e, 24);
    if (ft < e) {
      offset = base + t * dir;
      return ft;
    }
    return e;
  }

  const ProgressiveMesh& pm_;
  std::span<const char> fixed_;
  std::vector<Vec2>& uv_;
  std::mt19937_64 rng_;
  std::vector<RingTriangle> ring_;
  bool product_{false};
  bool hold_boundary_{false};
  double total_s_{0.0}, total_d_{0.0};  // product mode: S and D of the level
  double ring_s_{0.0}, ring_d_{0.0};    // product mode: the loaded ring's share of them
};

/// The kernel of v's ring (intersection of the half-planes left of each opposite edge), clipped from a box
/// (Sutherland–Hodgman); stores its area centroid and returns true, or returns false when it has no interior.
bool ring_kernel_centroid(const ProgressiveMesh& pm, const std::vector<Vec2>& uv, std::uint32_t v, Vec2& centroid) {
  Eigen::AlignedBox2d box;
  for (std::uint32_t f : pm.vertex_faces(v))
    for (std::uint32_t c : pm.faces()[f])
      if (c != v) box.extend(uv[c]);
  const Vec2 lo = box.min() - box.sizes(), hi = box.max() + box.sizes();
  std::vector<Vec2> poly{lo, Vec2(hi.x(), lo.y()), hi, Vec2(lo.x(), hi.y())}, scratch;
  for (std::uint32_t f : pm.vertex_faces(v)) {
    const auto [x, y] = opposite_edge(pm.faces()[f], v);
    const Vec2 a = uv[x], e = uv[y] - uv[x];
    // cross(e, p − a) ≥ 0: the left side of the ring edge a → a + e
    detail::clip_half_plane(poly, scratch, e.y() * a.x() - e.x() * a.y(), -e.y(), e.x());
    if (poly.size() < 3) return false;
  }
  return detail::polygon_centroid(poly, centroid);
}

/// A point just off the target w, inside the sector between the neighbours a and b that the split re-opens
/// (always valid for small enough steps, since w's coarse triangles were positive).
bool place_near_target(const ProgressiveMesh& pm, const VertexOptimizer& opt, std::vector<Vec2>& uv,
                       const VertexSplitRecord& rec) {
  const std::uint32_t v = rec.vertex, w = rec.target;
  std::uint32_t a = w, b = w;
  for (std::uint32_t f : rec.removed_faces) {
    const auto [x, y] = opposite_edge(pm.faces()[f], v);
    if (x == w) a = y;
    if (y == w) b = x;
  }
  if (a == w || b == w) return false;
  const Vec2 ua = (uv[a] - uv[w]).normalized(), ub = (uv[b] - uv[w]).normalized();
  double theta = std::atan2(cross2(ua, ub), ua.dot(ub));
  if (theta <= 0.0) theta += 2.0 * std::numbers::pi;
  const Vec2 dir = Eigen::Rotation2Dd(theta / 2.0) * ua;
  double step = 0.5 * std::min((uv[a] - uv[w]).norm(), (uv[b] - uv[w]).norm());
  for (int i = 0; i < 60; ++i, step *= 0.5)
    if (opt.valid_at(v, uv[w] + step * dir)) {
      uv[v] = uv[w] + step * dir;
      return true;
    }
  return false;
}

/// Puts a re-inserted vertex inside the kernel of its ring: the kernel centroid, else its input position,
/// else next to its parent.
void place_split_vertex(const ProgressiveMesh& pm, const VertexOptimizer& opt, std::vector<Vec2>& uv,
                        std::span<const Vec2> input_uv, const VertexSplitRecord& rec) {
  const std::uint32_t v = rec.vertex;
  Vec2 c;
  if (ring_kernel_centroid(pm, uv, v, c) && opt.valid_at(v, c)) {
    uv[v] = c;
  } else if (opt.valid_at(v, input_uv[v])) {
    uv[v] = input_uv[v];
  } else if (!place_near_target(pm, opt, uv, rec)) {
    throw NumericalError("optimize_stretch: no valid position for re-inserted vertex " + std::to_string(v));
  }
}

/// Priority-queue sweep: optimizes the queued vertices, re-queueing the neighbours of any vertex whose
/// energy dropped by more than `tolerance` (relative), highest drop first, for at most `max_pops` steps.
void priority_sweep(const ProgressiveMesh& pm, VertexOptimizer& opt, std::span<const char> fixed, double tolerance,
                    std::size_t max_pops) {
  using Entry = std::tuple<double, std::uint32_t, std::uint32_t>;  // priority, vertex, stamp
  std::priority_queue<Entry> queue;
  std::vector<std::uint32_t> stamp(fixed.size(), 0), ring;
  opt.reset_totals();
  for (std::uint32_t v = 0; v < fixed.size(); ++v)
    if (!fixed[v] && pm.vertex_alive(v)) queue.emplace(kInf, v, 0);
  for (std::size_t pops = 0; pops < max_pops && !queue.empty();) {
    const auto [priority, v, s] = queue.top();
    queue.pop();
    if (s != stamp[v]) continue;
    ++stamp[v];
    ++pops;
    const double e0 = opt.energy(v);
    const double gain = opt.optimize(v);
    if (!(gain > tolerance * e0)) continue;
    pm.neighbours(v, ring);
    for (std::uint32_t u : ring)
      if (!fixed[u]) queue.emplace(gain / e0, u, stamp[u]);
  }
}

void check_sizes(MeshView mesh, std::span<const Vec2> uv, std::span<const char> fixed) {
  if (uv.size() != mesh.positions.size() || fixed.size() != mesh.positions.size())
    throw InvalidInput("optimize_stretch: uv (" + std::to_string(uv.size()) + ") and fixed (" +
                       std::to_string(fixed.size()) + ") must have one entry per vertex (" +
                       std::to_string(mesh.positions.size()) + ")");
}

/// Collapse filter keeping the input parametrization valid on every level: the triangles that the collapse
/// re-points from vertex to target must stay positive.
ProgressiveMesh::CollapseFilter keeps_uv_valid(std::span<const Vec2> uv) {
  return [uv](const ProgressiveMesh& pm, std::uint32_t v, std::uint32_t w) {
    for (std::uint32_t f : pm.vertex_faces(v)) {
      const auto [x, y] = opposite_edge(pm.faces()[f], v);
      if (x != w && y != w && !(cross2(uv[x] - uv[w], uv[y] - uv[w]) > 0.0)) return false;
    }
    return true;
  };
}

/// Σ L2² A' over the current level's faces (+inf if one is flipped).
double level_energy(const ProgressiveMesh& pm, std::span<const Vec2> uv) {
  double e = 0.0;
  for (const Face& f : pm.alive_faces()) {
    const TriangleStretch s = triangle_stretch(uv[f[0]], uv[f[1]], uv[f[2]], pm.input().positions[f[0]],
                                               pm.input().positions[f[1]], pm.input().positions[f[2]]);
    e += s.l2 * s.l2 * 0.5 *
         (pm.input().positions[f[1]] - pm.input().positions[f[0]])
             .cross(pm.input().positions[f[2]] - pm.input().positions[f[0]])
             .norm();
  }
  return e;
}

/// Starting parametrization of the base mesh: mean-value Floater with the fixed vertices in place, when it
/// is valid and better than the input restricted to the base (which is valid by construction).
void parametrize_base(const ProgressiveMesh& pm, std::span<const char> fixed, std::vector<Vec2>& uv) {
  const std::vector<Face> faces = pm.alive_faces();
  std::vector<std::uint32_t> anchors;
  std::vector<Vec2> anchor_uv;
  for (std::uint32_t v = 0; v < fixed.size(); ++v)
    if (fixed[v] && pm.vertex_alive(v)) anchors.push_back(v), anchor_uv.push_back(uv[v]);
  if (anchors.size() < 3) return;
  std::vector<Vec2> floater;
  try {
    floater = floater_parametrization(MeshView(pm.input().positions, faces), anchors, anchor_uv,
                                      {FloaterOptions::Weights::MeanValue});
  } catch (const Error&) {
    return;
  }
  if (level_energy(pm, floater) < level_energy(pm, uv))
    for (std::uint32_t v = 0; v < fixed.size(); ++v)
      if (!fixed[v] && pm.vertex_alive(v)) uv[v] = floater[v];
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Applies all vertex splits coarse to fine, placing and optimizing each new vertex and its ring, with a
/// full sweep whenever the vertex count has grown by refine_factor.
std::size_t refine(ProgressiveMesh& pm, VertexOptimizer& opt, std::vector<Vec2>& uv, std::span<const Vec2> input_uv,
                   std::span<const char> fixed, const StretchOptimizerOptions& options) {
  const std::size_t total = pm.pending_splits();
  double next_sweep = static_cast<double>(pm.alive_vertices()) * std::max(1.01, options.refine_factor);
  std::vector<std::uint32_t> ring;
  for (std::size_t done = 0; pm.pending_splits() > 0; ++done) {
    const VertexSplitRecord rec = pm.next_split();
    opt.add_faces(pm.vertex_faces(rec.target), -1.0);  // product mode: the faces the split changes leave the totals
    const std::uint32_t v = pm.split();
    place_split_vertex(pm, opt, uv, input_uv, rec);
    opt.add_faces(pm.vertex_faces(v), 1.0);  // ... and come back as they are now
    opt.add_faces(pm.vertex_faces(rec.target), 1.0, v);
    opt.optimize(v);
    pm.neighbours(v, ring);
    for (std::uint32_t u : ring) opt.optimize(u);
    opt.optimize(v);
    if (static_cast<double>(pm.alive_vertices()) >= next_sweep && pm.pending_splits() > 0) {
      priority_sweep(pm, opt, fixed, options.tolerance, 2 * pm.alive_free_vertices());
      next_sweep *= std::max(1.01, options.refine_factor);
    }
    if ((done & 1023u) == 0) report_progress(options.progress, "refine", static_cast<double>(done) / static_cast<double>(total));
  }
  report_progress(options.progress, "refine", 1.0);
  return total;
}

}  // namespace

StretchOptimizerResult optimize_stretch(MeshView mesh, std::span<const Vec2> uv, std::span<const char> fixed,
                                        const StretchOptimizerOptions& options) {
  StretchOptimizerResult result;
  check_sizes(mesh, uv, fixed);
  result.initial = mesh_stretch(mesh, uv);
  if (result.initial.flipped > 0)
    throw InvalidInput("optimize_stretch: the input parametrization has " + std::to_string(result.initial.flipped) +
                       " flipped or degenerate triangles");
  result.uv.assign(uv.begin(), uv.end());

  auto t0 = std::chrono::steady_clock::now();
  ProgressiveMesh pm(mesh, fixed);
  pm.simplify(options.base_vertices, keeps_uv_valid(uv), options.progress, "simplify");
  result.base_free_vertices = pm.alive_free_vertices();
  result.seconds_simplify = seconds_since(t0);

  t0 = std::chrono::steady_clock::now();
  VertexOptimizer opt(pm, fixed, result.uv, options.seed, options.free_boundary);
  opt.hold_boundary(true);
  parametrize_base(pm, fixed, result.uv);
  opt.reset_totals();
  priority_sweep(pm, opt, fixed, options.tolerance, 20 * pm.alive_free_vertices() + 100);
  result.vertex_splits = refine(pm, opt, result.uv, uv, fixed, options);
  // A free boundary starts on Floater's circle and relaxes only here, at the finest level: it gets more
  // sweeps (each bounded by the vertex count; the queue empties sooner once nothing moves).
  opt.hold_boundary(false);
  const int sweeps = options.free_boundary ? std::max(options.final_sweeps, kFreeBoundarySweeps) : options.final_sweeps;
  for (int i = 0; i < sweeps; ++i) {
    report_progress(options.progress, "sweep", static_cast<double>(i) / static_cast<double>(sweeps));
    priority_sweep(pm, opt, fixed, options.tolerance,
                   options.free_boundary ? 4 * pm.alive_vertices() : pm.alive_free_vertices());
  }
  report_progress(options.progress, "sweep", 1.0);
  result.final = mesh_stretch(mesh, result.uv);
  const bool worse = options.free_boundary ? !(result.final.efficiency >= result.initial.efficiency)
                                           : !(result.final.l2 <= result.initial.l2);
  if (worse) {  // never hand back something worse than the input
    result.uv.assign(uv.begin(), uv.end());
    result.final = result.initial;
  }
  result.seconds_optimize = seconds_since(t0);
  return result;
}

}  // namespace gimforge
