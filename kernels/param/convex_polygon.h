#pragma once
/// \file convex_polygon.h
/// Internal: the kernel of a vertex's 1-ring as a convex polygon (planar optimizer, stretch_optimizer.cpp;
/// spherical optimizer in a gnomonic chart, sphere_vertex_optimizer.h).
#include <vector>

#include "kernels/param/stretch.h"

namespace gimforge::detail {

/// Keeps the part of the convex polygon `poly` (counter-clockwise) where the affine function
/// k0 + k1·x + k2·y is ≥ 0 (Sutherland–Hodgman against one half-plane). `scratch` is reused storage.
inline void clip_half_plane(std::vector<Vec2>& poly, std::vector<Vec2>& scratch, double k0, double k1, double k2) {
  scratch.clear();
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Vec2& p = poly[i];
    const Vec2& q = poly[(i + 1) % poly.size()];
    const double sp = k0 + k1 * p.x() + k2 * p.y(), sq = k0 + k1 * q.x() + k2 * q.y();
    if (sp >= 0.0) scratch.push_back(p);
    if ((sp >= 0.0) != (sq >= 0.0)) scratch.push_back(p + (sp / (sp - sq)) * (q - p));
  }
  poly.swap(scratch);
}

/// Area centroid of a counter-clockwise polygon; false when it has no positive area.
inline bool polygon_centroid(const std::vector<Vec2>& poly, Vec2& centroid) {
  if (poly.size() < 3) return false;
  double area = 0.0;
  Vec2 c = Vec2::Zero();
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Vec2& a = poly[i];
    const Vec2& b = poly[(i + 1) % poly.size()];
    const double w = a.x() * b.y() - a.y() * b.x();
    area += w;
    c += w * (a + b);
  }
  if (!(area > 0.0)) return false;
  centroid = c / (3.0 * area);
  return true;
}

}  // namespace gimforge::detail
