#include "kernels/core/closest_point.h"

#include <algorithm>
#include <utility>

namespace gimforge {

TrianglePoint closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a;
  const Vec3 ac = c - a;
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
  if (!(sum > 0.0)) {
    // Degenerate (collinear or coincident) triangle that fell through: closest point on its three edges.
    auto on_segment = [&](const Vec3& s, const Vec3& t) {
      const Vec3 st = t - s;
      const double len2 = st.squaredNorm();
      const double x = len2 > 0.0 ? std::clamp((p - s).dot(st) / len2, 0.0, 1.0) : 0.0;
      return std::pair<Vec3, double>{s + x * st, x};
    };
    const auto [pab, xab] = on_segment(a, b);
    const auto [pbc, xbc] = on_segment(b, c);
    const auto [pca, xca] = on_segment(c, a);
    const double dab = (pab - p).squaredNorm(), dbc = (pbc - p).squaredNorm(), dca = (pca - p).squaredNorm();
    if (dab <= dbc && dab <= dca) return {pab, Vec3(1 - xab, xab, 0)};
    if (dbc <= dca) return {pbc, Vec3(0, 1 - xbc, xbc)};
    return {pca, Vec3(xca, 0, 1 - xca)};
  }
  const double v = vb / sum;  // face region
  const double w = vc / sum;
  return {a + ab * v + ac * w, Vec3(1 - v - w, v, w)};
}

}  // namespace gimforge
