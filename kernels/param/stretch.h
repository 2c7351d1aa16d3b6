#pragma once
/// \file stretch.h
/// Geometric stretch of a parametrization (Sander, Snyder, Gortler, Hoppe 2001), as restated in
/// ../shared/notes/parametrization.md: per-triangle L2 and L∞ stretch, mesh L2 stretch and the scale-free
/// stretch efficiency used by all the papers.
#include <cstddef>
#include <limits>
#include <span>

#include "kernels/core/mesh.h"

namespace gimforge {

using Vec2 = Eigen::Vector2d;

/// Stretch of one triangle with parameter coordinates p1..p3 and surface points q1..q3.
/// `l2` = sqrt((a + c)/2), `linf` = Γ (largest singular value of the Jacobian of the map from parameter
/// to surface). For a flipped or degenerate parameter triangle (signed area <= 0) both are +infinity.
struct TriangleStretch {
  double l2{0.0};
  double linf{0.0};
  double parametric_area{0.0};  ///< signed
};

[[nodiscard]] TriangleStretch triangle_stretch(const Vec2& p1, const Vec2& p2, const Vec2& p3, const Vec3& q1,
                                               const Vec3& q2, const Vec3& q3);

/// Stretch of a whole parametrization.
/// - `l2` = sqrt(Σ L2(T)² A'(T) / Σ A'(T)) with A'(T) the surface area of T;
/// - `linf` = max Γ;
/// - `efficiency` = (A_M / A_D) / l2², A_M the surface area, A_D the (unsigned sum of) parameter area;
///   ≤ 1, 1 only for an isometry up to scale.
/// - `flipped`: triangles with non-positive parameter area (then l2 = linf = +inf, efficiency = 0).
struct MeshStretch {
  double l2{0.0};
  double linf{0.0};
  double efficiency{0.0};
  double surface_area{0.0};
  double domain_area{0.0};
  std::size_t flipped{0};
};

/// `uv` has one entry per vertex of `mesh`. Precondition: sizes match (throws InvalidInput otherwise).
[[nodiscard]] MeshStretch mesh_stretch(MeshView mesh, std::span<const Vec2> uv);

}  // namespace gimforge
