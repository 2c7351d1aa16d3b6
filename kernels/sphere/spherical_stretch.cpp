#include "kernels/sphere/spherical_stretch.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge {
namespace {

/// A piece of the spherical triangle: its sphere points and the mesh points they come from.
struct Piece {
  Vec3 s[3];
  Vec3 m[3];
};

/// Sums of one triangle's pieces.
struct Sums {
  double stretch{0.0};
  double inverse{0.0};
};

/// The mesh triangle and its spherical triangle; maps sphere points back to the mesh (inverse of the
/// spherical triangle map: the ray from the centre meets the plane of s1 s2 s3 at barycentric (α, β, γ)).
class TriangleMap {
 public:
  TriangleMap(const Vec3& q1, const Vec3& q2, const Vec3& q3, const Vec3& s1, const Vec3& s2, const Vec3& s3)
      : q_{q1, q2, q3}, s_{s1, s2, s3}, normal_((s2 - s1).cross(s3 - s1)) {}

  [[nodiscard]] Vec3 mesh_point(const Vec3& x) const {
    const Vec3 y = x * (normal_.dot(s_[0]) / normal_.dot(x));  // on the plane of the spherical triangle
    const double area2 = normal_.squaredNorm();
    const double a = (s_[2] - s_[1]).cross(y - s_[1]).dot(normal_) / area2;
    const double b = (s_[0] - s_[2]).cross(y - s_[2]).dot(normal_) / area2;
    return a * q_[0] + b * q_[1] + (1.0 - a - b) * q_[2];
  }

 private:
  Vec3 q_[3];
  Vec3 s_[3];
  Vec3 normal_;
};

/// x^p for a small non-negative integer p (std::pow is several times slower and this is the inner loop).
double int_power(double x, int p) {
  double r = 1.0;
  for (double b = x; p > 0; p >>= 1, b *= b)
    if (p & 1) r *= b;
  return r;
}

/// Adds the integrals of a piece that is planar enough: the Jacobian of the map from the mesh piece to
/// the planar triangle spanning its sphere points. With the Gram matrices G_M = [A B; B C] of the mesh
/// piece's edge vectors and G_S = [a b; b c] of the sphere piece's, the squared singular values λ of
/// J_{φ⁻¹} are the roots of det(G_S − λ G_M) = 0, so 1/γ² + 1/Γ² = (λ₁ + λ₂)/(λ₁λ₂) = T / det G_S with
/// T = A c + C a − 2 B b, and Γ² is the larger root. No local frames, no square roots but one.
void integrate_planar(const Piece& p, int power, Sums& sums) {
  const Vec3 m1 = p.m[1] - p.m[0], m2 = p.m[2] - p.m[0];
  const Vec3 s1 = p.s[1] - p.s[0], s2 = p.s[2] - p.s[0];
  const double A = m1.squaredNorm(), B = m1.dot(m2), C = m2.squaredNorm();
  const double a = s1.squaredNorm(), b = s1.dot(s2), c = s2.squaredNorm();
  const double det_m = A * C - B * B, det_s = a * c - b * b;
  if (!(det_m > 0.0)) return;  // a degenerate mesh piece has no area to integrate over
  const double area = 0.5 * std::sqrt(det_m);
  if (!(det_s > 0.0)) {
    sums.stretch = sums.inverse = std::numeric_limits<double>::infinity();
    return;
  }
  const double t = A * c + C * a - 2.0 * B * b;
  const double disc = std::max(0.0, t * t - 4.0 * det_m * det_s);
  const double big2 = (t + std::sqrt(disc)) / (2.0 * det_m);  // Γ²
  sums.stretch += 0.5 * t / det_s * area;
  sums.inverse += ((power % 2 == 0) ? int_power(big2, power / 2) : std::pow(big2, 0.5 * power)) * area;
}

void integrate(const TriangleMap& map, const Piece& p, const SphericalStretchOptions& o, int depth, Sums& sums) {
  const double chord2 = std::max(
      {(p.s[1] - p.s[0]).squaredNorm(), (p.s[2] - p.s[1]).squaredNorm(), (p.s[0] - p.s[2]).squaredNorm()});
  if (chord2 <= o.max_chord * o.max_chord || depth >= 12) {
    integrate_planar(p, o.power, sums);
    return;
  }
  // 1-to-4 split on the sphere; mesh points follow through the inverse map.
  Vec3 ms[3], mm[3];
  for (int k = 0; k < 3; ++k) {
    ms[k] = (p.s[k] + p.s[(k + 1) % 3]).normalized();
    mm[k] = map.mesh_point(ms[k]);
  }
  integrate(map, {{p.s[0], ms[0], ms[2]}, {p.m[0], mm[0], mm[2]}}, o, depth + 1, sums);
  integrate(map, {{ms[0], p.s[1], ms[1]}, {mm[0], p.m[1], mm[1]}}, o, depth + 1, sums);
  integrate(map, {{ms[2], ms[1], p.s[2]}, {mm[2], mm[1], p.m[2]}}, o, depth + 1, sums);
  integrate(map, {{ms[0], ms[1], ms[2]}, {mm[0], mm[1], mm[2]}}, o, depth + 1, sums);
}

}  // namespace

SphericalTriangleStretch spherical_triangle_stretch(const Vec3& q1, const Vec3& q2, const Vec3& q3, const Vec3& s1,
                                                    const Vec3& s2, const Vec3& s3,
                                                    const SphericalStretchOptions& options) {
  SphericalTriangleStretch r;
  r.area = 0.5 * (q2 - q1).cross(q3 - q1).norm();
  if (!(s1.dot(s2.cross(s3)) > 0.0)) {
    r.flipped = true;
    r.stretch = r.inverse = std::numeric_limits<double>::infinity();
    return r;
  }
  const TriangleMap map(q1, q2, q3, s1, s2, s3);
  const Vec3 s[3] = {s1, s2, s3};
  const Vec3 q[3] = {q1, q2, q3};
  // Split by the perpendicular from the vertex opposite the longest edge (§3.4): caps become needles.
  int k = 0;  // longest edge runs from s[k] to s[k+1]
  double longest = -1.0;
  for (int i = 0; i < 3; ++i) {
    const double len = (s[(i + 1) % 3] - s[i]).squaredNorm();
    if (len > longest) longest = len, k = i;
  }
  const Vec3& a = s[k];
  const Vec3& b = s[(k + 1) % 3];
  const Vec3& c = s[(k + 2) % 3];
  Sums sums;
  // Only a triangle whose angle at c is obtuse can be a cap; the others integrate accurately unsplit (both
  // forms agree to second order in the triangle's size, and this is the optimizer's inner loop).
  if ((a - c).dot(b - c) >= 0.0) {
    integrate(map, {{s1, s2, s3}, {q1, q2, q3}}, options, 0, sums);
    r.stretch = sums.stretch;
    r.inverse = sums.inverse;
    return r;
  }
  const Vec3 n = a.cross(b).normalized();
  const Vec3 foot = (c - c.dot(n) * n).normalized();  // closest point to c on the great circle through a, b
  const bool inside = a.cross(foot).dot(n) > 0.0 && foot.cross(b).dot(n) > 0.0;
  if (inside) {
    const Vec3 mf = map.mesh_point(foot);
    const Vec3& qa = q[k];
    const Vec3& qb = q[(k + 1) % 3];
    const Vec3& qc = q[(k + 2) % 3];
    integrate(map, {{a, foot, c}, {qa, mf, qc}}, options, 0, sums);
    integrate(map, {{foot, b, c}, {mf, qb, qc}}, options, 0, sums);
  } else {
    integrate(map, {{s1, s2, s3}, {q1, q2, q3}}, options, 0, sums);
  }
  r.stretch = sums.stretch;
  r.inverse = sums.inverse;
  return r;
}

void check_sphere_points(MeshView mesh, std::span<const Vec3> sphere, std::string_view what) {
  if (sphere.size() != mesh.positions.size())
    throw InvalidInput(fmt::format("{}: {} sphere points for {} vertices", what, sphere.size(), mesh.positions.size()));
  for (std::size_t v = 0; v < sphere.size(); ++v)
    if (!(std::abs(sphere[v].squaredNorm() - 1.0) < 1e-9))
      throw InvalidInput(fmt::format("{}: sphere point {} is not a unit vector", what, v));
}

SphericalStretch spherical_stretch(MeshView mesh, std::span<const Vec3> sphere, const SphericalStretchOptions& options) {
  check_sphere_points(mesh, sphere, "spherical_stretch");
  SphericalStretch r;
  double stretch = 0.0, inverse = 0.0;
  for (const Face& f : mesh.faces) {
    const SphericalTriangleStretch t = spherical_triangle_stretch(
        mesh.positions[f[0]], mesh.positions[f[1]], mesh.positions[f[2]], sphere[f[0]], sphere[f[1]], sphere[f[2]],
        options);
    r.surface_area += t.area;
    r.flipped += t.flipped ? 1 : 0;
    stretch += t.stretch;
    inverse += t.inverse;
  }
  const double sphere_area = 4.0 * std::numbers::pi;
  r.l2 = std::sqrt(stretch / r.surface_area);
  r.efficiency = r.flipped ? 0.0 : (r.surface_area / sphere_area) / (r.l2 * r.l2);
  r.energy = stretch + options.epsilon * std::pow(r.surface_area / sphere_area, options.power / 2.0 + 1.0) * inverse;
  return r;
}

}  // namespace gimforge
