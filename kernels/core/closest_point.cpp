#include "kernels/core/closest_point.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace gimforge {
namespace {

/// Below this squared sine of the angle at a, the region tests' 2×2 determinants (Gram determinants of
/// ab, ac in disguise) lose their digits to cancellation: 10^-6 is an angle of 0.06° from 0 or 180°.
constexpr double kSliverSine2 = 1e-6;

struct SegmentPoint {
  Vec3 point;
  double t;   // along the segment, 0 at its start
  double d2;  // squared distance to p
};

SegmentPoint closest_on_segment(const Vec3& p, const Vec3& s, const Vec3& e) {
  const Vec3 se = e - s;
  const double len2 = se.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - s).dot(se) / len2, 0.0, 1.0) : 0.0;
  const Vec3 q = s + t * se;
  return {q, t, (q - p).squaredNorm()};
}

/// Slivers and degenerate triangles: the nearest point of the three edges, unless p projects inside. The
/// inside test measures p against each edge from that edge's own nearest point, and the plane distance
/// from the nearest edge point, so the normal's rounding (10^-7 rad on a 10^8 × 0.1 sliver) is scaled by
/// p's in-plane offset from the edge, never by the triangle's length.
TrianglePoint closest_point_on_sliver(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const std::array<const Vec3*, 3> v{&a, &b, &c};
  const std::array<Vec3, 3> edge{b - a, c - b, a - c};  // edge i runs from v[i] to v[i + 1]
  std::array<SegmentPoint, 3> near{};
  std::size_t best = 0;
  for (std::size_t i = 0; i < 3; ++i) {
    near[i] = closest_on_segment(p, *v[i], *v[(i + 1) % 3]);
    if (near[i].d2 < near[best].d2) best = i;
  }
  Vec3 barycentric = Vec3::Zero();
  barycentric[static_cast<Eigen::Index>(best)] = 1.0 - near[best].t;
  barycentric[static_cast<Eigen::Index>((best + 1) % 3)] = near[best].t;
  const TrianglePoint on_boundary{near[best].point, barycentric};

  // The cross product of two consecutive edges is the same normal for any pair: the two shortest (which
  // leaves out the longest edge's rounding) are the most accurate.
  std::size_t longest = 0;
  for (std::size_t i = 1; i < 3; ++i)
    if (edge[i].squaredNorm() > edge[longest].squaredNorm()) longest = i;
  const Vec3 n = edge[(longest + 1) % 3].cross(edge[(longest + 2) % 3]);
  const double nn = n.squaredNorm();
  if (!(nn > 0.0) || !std::isfinite(nn)) return on_boundary;  // no plane: a segment or a point
  std::array<double, 3> side{};  // |n|² × the in-plane distance from edge i, positive inside
  for (std::size_t i = 0; i < 3; ++i) {
    side[i] = n.cross(edge[i]).dot(p - near[i].point);
    if (side[i] < 0.0) return on_boundary;
  }
  // Inside: the barycentric of the vertex opposite edge i is its distance from that edge over the altitude.
  const double total = side[0] + side[1] + side[2];
  if (!(total > 0.0)) return on_boundary;
  return {p - n * (n.dot(p - near[best].point) / nn), Vec3(side[1], side[2], side[0]) / total};
}

}  // namespace

TrianglePoint closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a;
  const Vec3 ac = c - a;
  const double ab2 = ab.squaredNorm();
  const double ac2 = ac.squaredNorm();
  const double abac = ab.dot(ac);
  if (ab2 * ac2 - abac * abac <= kSliverSine2 * ab2 * ac2) return closest_point_on_sliver(p, a, b, c);
  const Vec3 ap = p - a;
  const double d1 = ab.dot(ap);
  const double d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return {a, Vec3(1, 0, 0)};  // vertex region A

  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp);
  const double d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return {b, Vec3(0, 1, 0)};  // vertex region B

  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 && d1 - d3 > 0.0) {  // edge region AB
    const double v = d1 / (d1 - d3);
    return {a + v * ab, Vec3(1 - v, v, 0)};
  }

  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp);
  const double d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return {c, Vec3(0, 0, 1)};  // vertex region C

  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 && d2 - d6 > 0.0) {  // edge region AC
    const double w = d2 / (d2 - d6);
    return {a + w * ac, Vec3(1 - w, 0, w)};
  }

  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 && (d4 - d3) + (d5 - d6) > 0.0) {  // edge region BC
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {b + w * (c - b), Vec3(0, 1 - w, w)};
  }

  const double sum = va + vb + vc;
  if (!(sum > 0.0)) return closest_point_on_sliver(p, a, b, c);  // not finite
  const double v = vb / sum;  // face region
  const double w = vc / sum;
  return {a + ab * v + ac * w, Vec3(1 - v - w, v, w)};
}

}  // namespace gimforge
