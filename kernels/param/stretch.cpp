#include "kernels/param/stretch.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "kernels/core/errors.h"

namespace gimforge {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

TriangleStretch triangle_stretch(const Vec2& p1, const Vec2& p2, const Vec2& p3, const Vec3& q1, const Vec3& q2,
                                 const Vec3& q3) {
  const double s1 = p1.x(), t1 = p1.y(), s2 = p2.x(), t2 = p2.y(), s3 = p3.x(), t3 = p3.y();
  const double area = ((s2 - s1) * (t3 - t1) - (s3 - s1) * (t2 - t1)) / 2.0;
  if (!(area > 0.0)) return {kInf, kInf, area};
  const Vec3 ss = (q1 * (t2 - t3) + q2 * (t3 - t1) + q3 * (t1 - t2)) / (2.0 * area);
  const Vec3 st = (q1 * (s3 - s2) + q2 * (s1 - s3) + q3 * (s2 - s1)) / (2.0 * area);
  const double a = ss.squaredNorm(), b = ss.dot(st), c = st.squaredNorm();
  const double root = std::sqrt((a - c) * (a - c) + 4.0 * b * b);
  return {std::sqrt((a + c) / 2.0), std::sqrt(((a + c) + root) / 2.0), area};
}

MeshStretch mesh_stretch(MeshView mesh, std::span<const Vec2> uv) {
  if (uv.size() != mesh.positions.size())
    throw InvalidInput("mesh_stretch: uv has " + std::to_string(uv.size()) + " entries for " +
                       std::to_string(mesh.positions.size()) + " vertices");
  MeshStretch out;
  double weighted = 0.0;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const Face& t = mesh.faces[f];
    if (has_repeated_index(t)) continue;
    if (std::max({t[0], t[1], t[2]}) >= uv.size())
      throw InvalidInput("mesh_stretch: face " + std::to_string(f) + " has a vertex index out of range");
    const TriangleStretch s = triangle_stretch(uv[t[0]], uv[t[1]], uv[t[2]], mesh.positions[t[0]],
                                               mesh.positions[t[1]], mesh.positions[t[2]]);
    const double area3d = triangle_area(mesh, f);
    out.surface_area += area3d;
    out.domain_area += std::abs(s.parametric_area);
    if (!(s.parametric_area > 0.0)) {
      ++out.flipped;
      continue;
    }
    weighted += s.l2 * s.l2 * area3d;
    out.linf = std::max(out.linf, s.linf);
  }
  if (out.flipped > 0) {
    out.l2 = out.linf = kInf;
    return out;
  }
  out.l2 = out.surface_area > 0.0 ? std::sqrt(weighted / out.surface_area) : 0.0;
  if (out.l2 > 0.0 && out.domain_area > 0.0)
    out.efficiency = (out.surface_area / out.domain_area) / (out.l2 * out.l2);
  return out;
}

}  // namespace gimforge
