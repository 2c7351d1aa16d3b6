#include "kernels/adaptive/point_triangle.h"

#include <algorithm>

namespace gimforge {
namespace {

/// Closest point of segment [a, b] to p: parameter t in [0, 1] and the squared distance.
std::pair<double, double> segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 e = b - a;
  const double len2 = e.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - a).dot(e) / len2, 0.0, 1.0) : 0.0;
  return {t, (a + t * e - p).squaredNorm()};
}

/// The hit on segment (corner i, corner j) of the triangle with corners `v`.
FeatureHit edge_hit(const Vec3& p, const std::array<const Vec3*, 3>& v, int i, int j) {
  const auto [t, d2] = segment(p, *v[static_cast<std::size_t>(i)], *v[static_cast<std::size_t>(j)]);
  FeatureHit h;
  h.squared_distance = d2;
  h.weights[i] = 1.0 - t;
  h.weights[j] = t;
  h.closest = h.weights[i] * *v[static_cast<std::size_t>(i)] + h.weights[j] * *v[static_cast<std::size_t>(j)];
  h.type = t <= 0.0 || t >= 1.0 ? DistanceType::PointPoint : DistanceType::PointEdge;
  if (t <= 0.0) h.weights[j] = 0.0, h.weights[i] = 1.0;
  if (t >= 1.0) h.weights[i] = 0.0, h.weights[j] = 1.0;
  return h;
}

const FeatureHit& nearer(const FeatureHit& x, const FeatureHit& y) { return y.squared_distance < x.squared_distance ? y : x; }

}  // namespace

unsigned lambda_region(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 n = (b - a).cross(c - a);
  const double n2 = n.squaredNorm();
  if (!(n2 > 0.0)) return 7;
  // In the plane, l_xy(q) = ((y − x) × (q − x))·n is the signed distance to the line xy (times |xy||n|);
  // the projection p' and p give the same value, so p is used directly.
  auto line = [&](const Vec3& x, const Vec3& y, const Vec3& q) { return (y - x).cross(q - x).dot(n); };
  const double l1 = line(b, c, a) * line(b, c, p);
  const double l2 = line(c, a, b) * line(c, a, p);
  const double l3 = line(a, b, c) * line(a, b, p);
  return (l1 <= 0.0 ? 1u : 0u) | (l2 <= 0.0 ? 2u : 0u) | (l3 <= 0.0 ? 4u : 0u);
}

FeatureHit closest_feature(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const std::array<const Vec3*, 3> v{&a, &b, &c};
  switch (lambda_region(p, a, b, c)) {
    case 0: {  // point-face: the projection, with its barycentric weights
      const Vec3 n = (b - a).cross(c - a);
      const double n2 = n.squaredNorm();
      FeatureHit h;
      h.type = DistanceType::PointFace;
      h.weights = Vec3((c - b).cross(p - b).dot(n), (a - c).cross(p - c).dot(n), (b - a).cross(p - a).dot(n)) / n2;
      h.closest = h.weights[0] * a + h.weights[1] * b + h.weights[2] * c;
      h.squared_distance = (p - h.closest).squaredNorm();
      return h;
    }
    case 1: return edge_hit(p, v, 1, 2);                               // beyond bc
    case 2: return edge_hit(p, v, 2, 0);                               // beyond ca
    case 4: return edge_hit(p, v, 0, 1);                               // beyond ab
    case 6: return nearer(edge_hit(p, v, 2, 0), edge_hit(p, v, 0, 1));  // at a
    case 5: return nearer(edge_hit(p, v, 0, 1), edge_hit(p, v, 1, 2));  // at b
    case 3: return nearer(edge_hit(p, v, 1, 2), edge_hit(p, v, 2, 0));  // at c
    default:  // degenerate: the three segments
      return nearer(nearer(edge_hit(p, v, 0, 1), edge_hit(p, v, 1, 2)), edge_hit(p, v, 2, 0));
  }
}

std::array<Vec3, 3> gradient_wrt_feature(const Vec3& p, const FeatureHit& hit) {
  const Vec3 r = p - hit.closest;
  return {-2.0 * hit.weights[0] * r, -2.0 * hit.weights[1] * r, -2.0 * hit.weights[2] * r};
}

std::array<Vec3, 3> gradient_wrt_container(const Vec3& p, const Vec3& bary, const Vec3& closest) {
  const Vec3 r = p - closest;
  return {2.0 * bary[0] * r, 2.0 * bary[1] * r, 2.0 * bary[2] * r};
}

}  // namespace gimforge
