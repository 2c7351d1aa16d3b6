#pragma once
/// \file closest_point.h
/// Exact closest point on a triangle (double precision), the primitive behind the Hausdorff metric.
#include "kernels/core/mesh.h"

namespace gimforge {

/// Closest point to `p` on the (closed) triangle abc and its barycentric coordinates (u, v, w) with
/// point = u*a + v*b + w*c. Handles degenerate (zero-area) triangles. Region classification after
/// Ericson, "Real-Time Collision Detection", §5.1.5.
struct TrianglePoint {
  Vec3 point;
  Vec3 barycentric;
};

[[nodiscard]] TrianglePoint closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

/// Squared distance from p to the triangle abc.
[[nodiscard]] inline double squared_distance_to_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  return (closest_point_on_triangle(p, a, b, c).point - p).squaredNorm();
}

}  // namespace gimforge
