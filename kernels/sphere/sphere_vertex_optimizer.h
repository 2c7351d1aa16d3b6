#pragma once
/// \file sphere_vertex_optimizer.h
/// Internal: moving one vertex of a spherical triangulation at a time (Praun & Hoppe 2003, §3.5), shared by
/// the surface map S → M (sphere_map.cpp) and the domain maps D → S (domain_map.cpp).
///
/// A vertex at s is moved in the gnomonic chart of the plane tangent at s: a chart point p stands for the
/// unit vector (s + p)/‖s + p‖, so straight lines through 0 are great circles through s (the paper's
/// great-circle searches). The triangle (x, a, b) is positively oriented iff x·(a × b) > 0, which is
/// linear in p, so the kernel of the 1-ring (the set of positions where no triangle flips) is an
/// intersection of half-planes in the chart and each line search knows its feasible interval exactly.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <queue>
#include <random>
#include <span>
#include <tuple>
#include <utility>
#include <vector>

#include "kernels/param/convex_polygon.h"
#include "kernels/param/line_search.h"
#include "kernels/core/mesh.h"
#include "kernels/param/stretch.h"

namespace gimforge::detail {

/// Orthonormal tangent frame (e1, e2) at unit vector s with e1 × e2 = s (counter-clockwise seen from
/// outside).
inline std::pair<Vec3, Vec3> tangent_frame(const Vec3& s) {
  const Vec3 helper = std::abs(s.x()) < 0.6 ? Vec3::UnitX() : (std::abs(s.y()) < 0.6 ? Vec3::UnitY() : Vec3::UnitZ());
  const Vec3 e1 = s.cross(helper).normalized();
  return {e1, s.cross(e1)};
}

/// Index of v in face f (precondition: f contains v).
inline std::size_t corner_of(const Face& f, std::uint32_t v) { return f[0] == v ? 0 : (f[1] == v ? 1 : 2); }

/// A mesh whose connectivity does not change, with the interface of ProgressiveMesh that the optimizer
/// uses (vertex_faces, faces, neighbours, vertex_alive).
class StaticTopology {
 public:
  StaticTopology(std::span<const Face> faces, std::size_t vertices) : faces_(faces), vertex_faces_(vertices) {
    for (std::size_t f = 0; f < faces.size(); ++f)
      for (std::uint32_t c : faces[f]) vertex_faces_[c].push_back(static_cast<std::uint32_t>(f));
  }
  [[nodiscard]] std::span<const Face> faces() const { return faces_; }
  [[nodiscard]] std::span<const std::uint32_t> vertex_faces(std::size_t v) const { return vertex_faces_[v]; }
  [[nodiscard]] bool vertex_alive(std::size_t v) const { return !vertex_faces_[v].empty(); }
  void neighbours(std::uint32_t v, std::vector<std::uint32_t>& out) const {
    out.clear();
    for (std::uint32_t f : vertex_faces_[v])
      for (std::uint32_t c : faces_[f])
        if (c != v && std::find(out.begin(), out.end(), c) == out.end()) out.push_back(c);
  }

 private:
  std::span<const Face> faces_;
  std::vector<std::vector<std::uint32_t>> vertex_faces_;
};

/// Vertex optimizer over a topology `Topo` (ProgressiveMesh or StaticTopology) and a per-face energy
/// `Energy`: double(std::uint32_t face, const Vec3& s0, const Vec3& s1, const Vec3& s2) with the sphere
/// points of the face's corners in face order; +infinity (or any non-finite value) marks an invalid face.
template <class Topo, class Energy>
class SphereVertexOptimizer {
 public:
  SphereVertexOptimizer(const Topo& topo, std::vector<Vec3>& sphere, Energy energy, std::uint64_t seed)
      : topo_(topo), sphere_(sphere), energy_(std::move(energy)), rng_(seed) {}

  /// Energy of v's faces at its current position.
  double energy(std::uint32_t v) {
    load_ring(v);
    return ring_energy(Vec2::Zero());
  }

  /// Moves v along great circles to lower its ring energy (never leaving the kernel); returns the
  /// decrease (≥ 0).
  double optimize(std::uint32_t v, int random_searches = 1) {
    load_ring(v);
    const double e0 = ring_energy(Vec2::Zero());
    if (!std::isfinite(e0)) return 0.0;
    Vec2 p = Vec2::Zero();
    double e = e0;
    const Vec2 g = gradient(p);
    if (g.squaredNorm() > 0.0 && std::isfinite(g.squaredNorm())) e = line_search(p, -g.normalized(), e);
    for (int k = 0; k < random_searches; ++k) {
      const double angle = 2.0 * std::numbers::pi * static_cast<double>(rng_() >> 11) * 0x1.0p-53;
      e = line_search(p, Vec2(std::cos(angle), std::sin(angle)), e);
    }
    if (!(e < e0)) return 0.0;
    const Vec3 x = chart_point(p);
    if (!valid_at(v, x)) return 0.0;  // rounding at the kernel's edge: keep the old position
    sphere_[v] = x;
    return e0 - e;
  }

  /// True when every face of v is positively oriented with v at x.
  [[nodiscard]] bool valid_at(std::uint32_t v, const Vec3& x) const {
    for (std::uint32_t f : topo_.vertex_faces(v)) {
      const Face& t = topo_.faces()[f];
      const std::size_t c = corner_of(t, v);
      if (!(x.dot(sphere_[t[(c + 1) % 3]].cross(sphere_[t[(c + 2) % 3]])) > 0.0)) return false;
    }
    return true;
  }

  /// A point strictly inside the kernel of v's ring near its area centroid (computed in the gnomonic chart
  /// at `inside`, which must itself be inside the kernel); returns `inside` if the centroid is not valid.
  [[nodiscard]] Vec3 kernel_centroid(std::uint32_t v, const Vec3& inside) const {
    const auto [e1, e2] = tangent_frame(inside);
    constexpr double kBox = 4.0;  // the chart up to ~76° from `inside`
    std::vector<Vec2> poly{Vec2(-kBox, -kBox), Vec2(kBox, -kBox), Vec2(kBox, kBox), Vec2(-kBox, kBox)}, scratch;
    for (std::uint32_t f : topo_.vertex_faces(v)) {
      const Face& t = topo_.faces()[f];
      const std::size_t c = corner_of(t, v);
      const Vec3 n = sphere_[t[(c + 1) % 3]].cross(sphere_[t[(c + 2) % 3]]);
      // (inside + u e1 + w e2)·n > 0  <=>  k0 + u k1 + w k2 > 0
      clip_half_plane(poly, scratch, inside.dot(n), e1.dot(n), e2.dot(n));
      if (poly.size() < 3) return inside;
    }
    Vec2 centroid;
    if (!polygon_centroid(poly, centroid)) return inside;
    const Vec3 x = (inside + centroid.x() * e1 + centroid.y() * e2).normalized();
    return valid_at(v, x) ? x : inside;
  }

  /// Priority-queue sweep over `vertices`: optimizes the vertex whose neighbourhood changed most, re-queueing
  /// the neighbours of every vertex whose energy dropped by more than `tolerance` (relative), until the
  /// queue is empty or `max_pops` optimizations were done. Returns the number of optimizations.
  std::size_t priority_sweep(std::span<const std::uint32_t> vertices, double tolerance, std::size_t max_pops) {
    using Entry = std::tuple<double, std::uint32_t, std::uint32_t>;  // priority, vertex, stamp
    std::priority_queue<Entry> queue;
    if (stamp_.size() < sphere_.size()) stamp_.resize(sphere_.size(), 0);
    for (std::uint32_t v : vertices) queue.emplace(std::numeric_limits<double>::infinity(), v, ++stamp_[v]);
    std::size_t pops = 0;
    while (pops < max_pops && !queue.empty()) {
      const auto [priority, v, s] = queue.top();
      queue.pop();
      if (s != stamp_[v]) continue;
      ++stamp_[v];
      ++pops;
      const double e0 = energy(v);
      const double gain = optimize(v);
      if (!(gain > tolerance * e0)) continue;
      topo_.neighbours(v, ring_vertices_);
      for (std::uint32_t u : ring_vertices_) queue.emplace(gain / e0, u, ++stamp_[u]);
    }
    return pops;
  }

 private:
  struct RingFace {
    std::uint32_t face;
    std::size_t corner;  // v's corner in the face
    Vec3 a, b;   // the other two sphere points in face order after v
    Vec3 n;      // a × b
  };

  void load_ring(std::uint32_t v) {
    ring_.clear();
    s_ = sphere_[v];
    std::tie(e1_, e2_) = tangent_frame(s_);
    double scale = 0.0;
    for (std::uint32_t f : topo_.vertex_faces(v)) {
      const Face& t = topo_.faces()[f];
      const std::size_t c = corner_of(t, v);
      const Vec3& a = sphere_[t[(c + 1) % 3]];
      const Vec3& b = sphere_[t[(c + 2) % 3]];
      ring_.push_back({f, c, a, b, a.cross(b)});
      scale = std::max({scale, (a - s_).norm(), (b - s_).norm()});
    }
    scale_ = std::min(scale, 4.0);
  }

  [[nodiscard]] Vec3 chart_point(const Vec2& p) const { return (s_ + p.x() * e1_ + p.y() * e2_).normalized(); }

  [[nodiscard]] double ring_energy(const Vec2& p) const {
    const Vec3 x = chart_point(p);
    double e = 0.0;
    for (const RingFace& r : ring_) {
      if (!(x.dot(r.n) > 0.0)) return std::numeric_limits<double>::infinity();
      // the face's corners in face order with v's corner at x
      const double fe = r.corner == 0 ? energy_(r.face, x, r.a, r.b)
                                      : (r.corner == 1 ? energy_(r.face, r.b, x, r.a) : energy_(r.face, r.a, r.b, x));
      e += fe;
    }
    return std::isfinite(e) ? e : std::numeric_limits<double>::infinity();
  }

  /// Central-difference gradient in the chart (zero when a probe leaves the kernel).
  Vec2 gradient(const Vec2& p) const {
    const double h = 1e-5 * std::max(scale_, 1e-12);
    Vec2 g;
    for (int k = 0; k < 2; ++k) {
      const Vec2 d = k == 0 ? Vec2(h, 0.0) : Vec2(0.0, h);
      const double ep = ring_energy(p + d), em = ring_energy(p - d);
      if (!std::isfinite(ep) || !std::isfinite(em)) return Vec2::Zero();
      g[k] = (ep - em) / (2.0 * h);
    }
    return g;
  }

  /// The open interval of t for which p + t·dir stays in the kernel, clipped to the chart's useful range.
  [[nodiscard]] std::pair<double, double> feasible_range(const Vec2& p, const Vec2& dir) const {
    const Vec3 base = s_ + p.x() * e1_ + p.y() * e2_;
    const Vec3 d3 = dir.x() * e1_ + dir.y() * e2_;
    double lo = -scale_, hi = scale_;
    for (const RingFace& r : ring_) {
      const double k0 = base.dot(r.n), k1 = d3.dot(r.n);
      if (k1 < 0.0) hi = std::min(hi, k0 / -k1);
      if (k1 > 0.0) lo = std::max(lo, -k0 / k1);
    }
    return {lo, hi};
  }

  double line_search(Vec2& p, const Vec2& dir, double e) {
    const auto [lo, hi] = feasible_range(p, dir);
    if (!(hi > lo) || !(lo < 0.0) || !(hi > 0.0)) return e;
    const Vec2 base = p;
    auto f = [&](double t) { return ring_energy(base + t * dir); };
    const auto [t, ft] = brent_minimize(f, 0.999 * lo, 0.999 * hi, 0.0, e, 20);
    if (ft < e) {
      p = base + t * dir;
      return ft;
    }
    return e;
  }

  const Topo& topo_;
  std::vector<Vec3>& sphere_;
  Energy energy_;
  std::mt19937_64 rng_;
  std::vector<RingFace> ring_;
  std::vector<std::uint32_t> ring_vertices_;
  std::vector<std::uint32_t> stamp_;
  Vec3 s_{Vec3::UnitZ()}, e1_{Vec3::UnitX()}, e2_{Vec3::UnitY()};
  double scale_{1.0};
};

}  // namespace gimforge::detail
