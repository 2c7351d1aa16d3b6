#include "kernels/relief/relief_projection.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

#include "kernels/relief/relief_cells.h"

namespace gimforge {
namespace {

/// The side (0 = low, 1 = high) of the single face of `bits` on `axis`; precondition: exactly one set.
constexpr int side_on_axis(std::uint8_t bits, int axis) { return has_cell_face(bits, 2 * axis + 1) ? 1 : 0; }

/// Axes (0..2) on which `bits` holds at least one face, and on which it holds both.
int axis_with_both(std::uint8_t bits) {
  for (int a = 0; a < 3; ++a)
    if (has_cell_face(bits, 2 * a) && has_cell_face(bits, 2 * a + 1)) return a;
  return -1;
}

/// Leaves the unit cube (restricted to the axes in `axes`, a bit mask) from `origin` along `d`: the
/// smallest t > 0 at which origin + t·d reaches a face, and that face. Axes where d is zero never bound.
/// Precondition: d has a non-zero component on some axis of `axes`.
std::pair<double, int> exit_unit_cube(const Vec3& origin, const Vec3& d, unsigned axes) {
  double best = std::numeric_limits<double>::infinity();
  int face = -1;
  for (int a = 0; a < 3; ++a) {
    if (((axes >> static_cast<unsigned>(a)) & 1u) == 0 || d[a] == 0.0) continue;
    const int side = d[a] > 0.0 ? 1 : 0;
    const double t = (static_cast<double>(side) - origin[a]) / d[a];
    if (t < best) {
      best = t;
      face = 2 * a + side;
    }
  }
  return {best, face};
}

void set_face_uv(int face, const Vec3& on_face, FaceProjection& out) {
  const int a = face / 2;
  out.face = face;
  out.u = std::clamp(on_face[(a + 1) % 3], 0.0, 1.0);
  out.v = std::clamp(on_face[(a + 2) % 3], 0.0, 1.0);
}

}  // namespace

std::string_view relief_case_name(ReliefCase c) {
  static constexpr std::string_view kNames[] = {"0", "1", "2a", "2b", "3a", "3b", "4a", "4b", "5", "6"};
  return kNames[static_cast<int>(c)];
}

std::string_view projection_type_name(ProjectionType t) {
  static constexpr std::string_view kNames[] = {"parallel", "planar", "perspective", "axial"};
  return kNames[static_cast<int>(t)];
}

CellProjection cell_projection(std::uint8_t external_faces) {
  const std::uint8_t external = external_faces & kAllCellFaces;
  const std::uint8_t internal = static_cast<std::uint8_t>(~external & kAllCellFaces);
  CellProjection p;
  p.domain_faces = external == 0 ? kAllCellFaces : external;
  p.point = Vec3::Constant(0.5);
  switch (std::popcount(internal)) {
    case 0:
      p.base_case = ReliefCase::k0;
      p.type = ProjectionType::Perspective;
      break;
    case 1: {  // CoP at the midpoint of the internal face
      const int f = std::countr_zero(internal);
      p.base_case = ReliefCase::k1;
      p.type = ProjectionType::Perspective;
      p.point[f / 2] = f % 2;
      break;
    }
    case 2: {
      const int both = axis_with_both(internal);
      if (both >= 0) {  // 2b: axis through the midpoints of the two opposite internal faces
        p.base_case = ReliefCase::k2b;
        p.type = ProjectionType::Axial;
        p.axis = static_cast<std::uint8_t>(both);
      } else {  // 2a: CoP at the midpoint of the internal edge shared by the two faces
        p.base_case = ReliefCase::k2a;
        p.type = ProjectionType::Perspective;
        for (int a = 0; a < 3; ++a)
          if (has_cell_face(internal, 2 * a) || has_cell_face(internal, 2 * a + 1)) p.point[a] = side_on_axis(internal, a);
      }
      break;
    }
    case 3: {
      const int both = axis_with_both(internal);
      if (both >= 0) {
        // 3a: internal faces = both faces on axis `both` and one face on axis b. The two internal edges lie
        // where that face meets the pair: both parallel to the third axis c, at coordinate b = side and
        // c-midpoint 0.5; the axis through their midpoints runs along `both`.
        p.base_case = ReliefCase::k3a;
        p.type = ProjectionType::Axial;
        p.axis = static_cast<std::uint8_t>(both);
        for (int b = 0; b < 3; ++b)
          if (b != both && (has_cell_face(internal, 2 * b) || has_cell_face(internal, 2 * b + 1)))
            p.point[b] = side_on_axis(internal, b);
      } else {  // 3b: one internal face per axis, meeting at a vertex: CoP at that vertex
        p.base_case = ReliefCase::k3b;
        p.type = ProjectionType::Perspective;
        for (int a = 0; a < 3; ++a) p.point[a] = side_on_axis(internal, a);
      }
      break;
    }
    case 4: {
      const int both = axis_with_both(external);
      if (both >= 0) {  // 4a: planar, plane through the centre parallel to the two external faces
        p.base_case = ReliefCase::k4a;
        p.type = ProjectionType::Planar;
        p.axis = static_cast<std::uint8_t>(both);
      } else {
        // 4b: external faces on axes a and b (sides sa, sb) share the external edge, parallel to the third
        // axis c; the axis of projection is the opposite edge, at (1 − sa, 1 − sb).
        p.base_case = ReliefCase::k4b;
        p.type = ProjectionType::Axial;
        for (int a = 0; a < 3; ++a) {
          if (has_cell_face(external, 2 * a) || has_cell_face(external, 2 * a + 1))
            p.point[a] = 1 - side_on_axis(external, a);
          else
            p.axis = static_cast<std::uint8_t>(a);
        }
      }
      break;
    }
    case 5: {  // parallel projection along the outward normal of the single external face
      const int f = std::countr_zero(external);
      p.base_case = ReliefCase::k5;
      p.type = ProjectionType::Parallel;
      p.axis = static_cast<std::uint8_t>(f / 2);
      p.direction = Vec3::Zero();
      p.direction[f / 2] = (f % 2) != 0 ? 1.0 : -1.0;
      p.point[f / 2] = f % 2;
      break;
    }
    default:  // 6: interior grey cell, perspective from the centre like case 0
      p.base_case = ReliefCase::k6;
      p.type = ProjectionType::Perspective;
      break;
  }
  return p;
}

ReliefCase relief_case(std::uint8_t external_faces) { return cell_projection(external_faces).base_case; }

bool project_point(const CellProjection& proj, const Vec3& p_in, FaceProjection& out) {
  const Vec3 p = p_in.cwiseMax(0.0).cwiseMin(1.0);
  switch (proj.type) {
    case ProjectionType::Parallel:
    case ProjectionType::Planar: {  // along ±e_axis onto the face on that side
      const int a = proj.axis;
      const bool high = proj.type == ProjectionType::Parallel ? proj.direction[a] > 0.0 : p[a] >= proj.point[a];
      const int side = high ? 1 : 0;
      Vec3 q = p;
      q[a] = side;
      set_face_uv(2 * a + side, q, out);
      out.distance = std::abs(q[a] - p[a]);
      return true;
    }
    case ProjectionType::Perspective: {
      const Vec3 d = p - proj.point;
      const auto [t, face] = exit_unit_cube(proj.point, d, 0b111u);
      if (face < 0) return false;
      const Vec3 q = proj.point + t * d;
      set_face_uv(face, q, out);
      out.distance = std::max(0.0, t - 1.0) * d.norm();
      return true;
    }
    case ProjectionType::Axial: {
      Vec3 d = p - proj.point;
      d[proj.axis] = 0.0;
      const unsigned axes = 0b111u & ~(1u << proj.axis);
      const auto [t, face] = exit_unit_cube(proj.point, d, axes);
      if (face < 0) return false;
      Vec3 q = proj.point + t * d;
      q[proj.axis] = p[proj.axis];
      set_face_uv(face, q, out);
      out.distance = std::max(0.0, t - 1.0) * d.norm();
      return true;
    }
  }
  return false;
}

Vec3 face_point(int face, double u, double v) {
  const int a = face / 2;
  Vec3 q;
  q[a] = face % 2;
  q[(a + 1) % 3] = u;
  q[(a + 2) % 3] = v;
  return q;
}

ProjectionRay projection_ray(const CellProjection& proj, const Vec3& on_face) {
  ProjectionRay r;
  switch (proj.type) {
    case ProjectionType::Parallel:
      r.direction = proj.direction;
      r.length = 1.0;
      return r;
    case ProjectionType::Planar: {
      const int a = proj.axis;
      r.direction = Vec3::Zero();
      r.direction[a] = on_face[a] >= proj.point[a] ? 1.0 : -1.0;
      r.length = std::abs(on_face[a] - proj.point[a]);
      return r;
    }
    case ProjectionType::Perspective:
    case ProjectionType::Axial: {
      Vec3 d = on_face - proj.point;
      if (proj.type == ProjectionType::Axial) d[proj.axis] = 0.0;
      r.length = d.norm();
      if (r.length > 0.0) r.direction = d / r.length;
      return r;
    }
  }
  return r;
}

}  // namespace gimforge
