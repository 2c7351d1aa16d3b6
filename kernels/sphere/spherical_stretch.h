#pragma once
/// \file spherical_stretch.h
/// Stretch of a spherical parametrization φ: S → M (Praun & Hoppe 2003, §3.4). Each mesh triangle T maps
/// to the spherical triangle of its vertices' sphere points by the spherical triangle map
/// x = (α s1 + β s2 + γ s3)/‖·‖ (barycentric α, β, γ on T). The inverse map T → S is analysed: with Γ ≥ γ
/// the singular values of J_{φ⁻¹}, distances on the sphere grow by 1/γ … 1/Γ on the mesh, so the L2
/// stretch integrand is (1/γ² + 1/Γ²)/2 (the 1/2 keeps an isometry at stretch 1, as in the planar metric).
/// J_{φ⁻¹} varies over T, so T is integrated numerically: the spherical triangle is first split by the
/// perpendicular to its longest edge (cap triangles become needles), then subdivided until its pieces are
/// nearly planar, and each piece's Jacobian is that of the planar triangle spanning its vertices.
#include <span>
#include <string_view>

#include "kernels/core/mesh.h"

namespace gimforge {

struct SphericalStretchOptions {
  double max_chord{0.05};  ///< pieces are subdivided until their longest chord on the unit sphere is below this
  double epsilon{1e-4};    ///< weight of the inverse-stretch regularizer ε (A_M/4π)^(p/2+1) Γ^p
  int power{6};            ///< p
};

/// Integrals over one mesh triangle. `stretch` = ∫ (1/γ² + 1/Γ²)/2 dA, `inverse` = ∫ Γ^p dA, `area` = area
/// of the mesh triangle. A spherical triangle with non-positive orientation (s1·(s2×s3) ≤ 0) is flipped:
/// `flipped` is set and both integrals are +infinity.
struct SphericalTriangleStretch {
  double stretch{0.0};
  double inverse{0.0};
  double area{0.0};
  bool flipped{false};
};

/// Stretch integrals of mesh triangle (q1, q2, q3) mapped to unit sphere points (s1, s2, s3).
[[nodiscard]] SphericalTriangleStretch spherical_triangle_stretch(const Vec3& q1, const Vec3& q2, const Vec3& q3,
                                                                  const Vec3& s1, const Vec3& s2, const Vec3& s3,
                                                                  const SphericalStretchOptions& options = {});

/// Stretch of a whole spherical parametrization.
/// - `l2` = sqrt(Σ stretch / A_M): the L2 stretch of S → M;
/// - `efficiency` = (A_M / 4π) / l2² (≤ 1; 1 for an isometry up to scale);
/// - `energy` = Σ stretch + ε (A_M/4π)^(p/2+1) Σ inverse: the objective the optimizer minimizes;
/// - `flipped`: spherical triangles with non-positive orientation (then l2 and energy are +infinity).
struct SphericalStretch {
  double l2{0.0};
  double efficiency{0.0};
  double energy{0.0};
  double surface_area{0.0};
  std::size_t flipped{0};
};

/// Throws InvalidInput "<what>: ..." unless `sphere` has one unit vector (|‖x‖² − 1| < 1e-9) per vertex of
/// `mesh`. Shared by everything that takes a spherical parametrization.
void check_sphere_points(MeshView mesh, std::span<const Vec3> sphere, std::string_view what);

/// `sphere` has one unit vector per vertex of `mesh`. Throws InvalidInput for a size mismatch or a
/// non-unit sphere point.
[[nodiscard]] SphericalStretch spherical_stretch(MeshView mesh, std::span<const Vec3> sphere,
                                                 const SphericalStretchOptions& options = {});

}  // namespace gimforge
