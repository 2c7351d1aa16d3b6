#pragma once
/// \file point_triangle.h
/// The distance types of a point and a triangle (adaptive geometry images §3.3 (1), eq. (3)–(5)) and the
/// gradients of the squared distance that move the samples (eq. (8)–(17)).
///
/// Eq. (3)–(5): with p' the projection of p on the plane of abc and l_bc, l_ca, l_ab the lines of the edges,
/// λ1 = l_bc(a)·l_bc(p'), λ2 = l_ca(b)·l_ca(p'), λ3 = l_ab(c)·l_ab(p') say on which side of each edge p' lies.
/// The set of λ that are ≤ 0 names one of seven regions: none — point-face; {λ1} — beyond bc (point-edge
/// p–bc); {λ2}, {λ3} likewise; {λ2, λ3} — beyond both edges at a (point-point p–a); {λ3, λ1} at b;
/// {λ1, λ2} at c. (The printed eq. (5) reads min where the vertex cases need max.) The edge lines are not the
/// boundaries of the closest-feature (Voronoi) regions, so `closest_feature` finishes the classification:
/// beyond one edge the closest point is on that edge's closed segment, beyond two it is on one of the
/// two segments meeting at their vertex.
#include <cstdint>

#include "kernels/core/mesh.h"

namespace gimforge {

enum class DistanceType : std::uint8_t { PointFace, PointEdge, PointPoint };

/// A closest feature of triangle abc: its type, the closest point and its barycentric weights (zero for
/// the corners the feature does not contain; a point-edge hit has two non-zero weights, a point-point one).
struct FeatureHit {
  DistanceType type{DistanceType::PointFace};
  Vec3 closest{Vec3::Zero()};
  Vec3 weights{Vec3::Zero()};
  double squared_distance{0.0};
};

/// The λ region of eq. (3)–(5): bit k (k = 0, 1, 2 for λ1, λ2, λ3) set when λ_{k+1} ≤ 0. 0 is the inside;
/// 7 cannot occur for a non-degenerate triangle. Degenerate (zero-area) triangles give 7.
[[nodiscard]] unsigned lambda_region(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

/// The closest feature of abc to p, through the λ regions (exact; degenerate triangles are measured as their
/// three segments).
[[nodiscard]] FeatureHit closest_feature(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

/// Gradient of the squared distance from a fixed point p to the feature `hit` of abc with respect to the
/// triangle's corners (eq. (9), (16), (17)): −2·w_k·(p − closest) for corner k. Exact where the closest
/// feature does not change (envelope theorem: the distance to an edge's line or the face's plane is a
/// minimum over affine combinations).
[[nodiscard]] std::array<Vec3, 3> gradient_wrt_feature(const Vec3& p, const FeatureHit& hit);

/// Gradient of the squared distance from the point p = Σ bary_k·p_k of a moving triangle to a fixed
/// feature whose closest point is `closest` (eq. (10), (12), (15)): 2·bary_k·(p − closest) for corner k.
[[nodiscard]] std::array<Vec3, 3> gradient_wrt_container(const Vec3& p, const Vec3& bary, const Vec3& closest);

}  // namespace gimforge
