#include "kernels/spherical_stretch.h"

#include <cmath>
#include <limits>
#include <numbers>

#include <fmt/format.h>

#include "kernels/errors.h"
#include "kernels/stretch.h"

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

/// Adds the integrals of a piece that is planar enough: the Jacobian of the map from the mesh piece to
/// the planar triangle spanning its sphere points.
void integrate_planar(const Piece& p, int power, Sums& sums) {
  // A 2D orthonormal frame on the mesh piece.
  const Vec3 e1 = p.m[1] - p.m[0];
  const Vec3 e2 = p.m[2] - p.m[0];
  const double l1 = e1.norm();
  const double area = 0.5 * e1.cross(e2).norm();
  if (!(area > 0.0) || !(l1 > 0.0)) return;  // a degenerate mesh piece has no area to integrate over
  const Vec3 u = e1 / l1;
  const Vec2 p1(0, 0), p2(l1, 0), p3(e2.dot(u), 2.0 * area / l1);
  const TriangleStretch t = triangle_stretch(p1, p2, p3, p.s[0], p.s[1], p.s[2]);
  const double big2 = t.linf * t.linf;                        // Γ² of J_{φ⁻¹}
  const double small2 = std::max(0.0, 2.0 * t.l2 * t.l2 - big2);  // γ²
  sums.stretch += small2 > 0.0 ? 0.5 * (1.0 / small2 + 1.0 / big2) * area : std::numeric_limits<double>::infinity();
  sums.inverse += std::pow(t.linf, power) * area;
}

void integrate(const TriangleMap& map, const Piece& p, const SphericalStretchOptions& o, int depth, Sums& sums) {
  const double chord = std::max({(p.s[1] - p.s[0]).norm(), (p.s[2] - p.s[1]).norm(), (p.s[0] - p.s[2]).norm()});
  if (chord <= o.max_chord || depth >= 12) {
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
  const Vec3 n = a.cross(b).normalized();
  const Vec3 foot = (c - c.dot(n) * n).normalized();  // closest point to c on the great circle through a, b
  const bool inside = a.cross(foot).dot(n) > 0.0 && foot.cross(b).dot(n) > 0.0;
  Sums sums;
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

SphericalStretch spherical_stretch(MeshView mesh, std::span<const Vec3> sphere, const SphericalStretchOptions& options) {
  if (sphere.size() != mesh.positions.size())
    throw InvalidInput(fmt::format("spherical_stretch: {} sphere points for {} vertices", sphere.size(),
                                   mesh.positions.size()));
  for (std::size_t v = 0; v < sphere.size(); ++v)
    if (!(std::abs(sphere[v].squaredNorm() - 1.0) < 1e-9))
      throw InvalidInput(fmt::format("spherical_stretch: sphere point {} is not a unit vector", v));
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
