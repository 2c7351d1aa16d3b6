// Per-cell projections of relief mapping (Apaza & Andújar §3.2): the ten base cases over the 64 face
// configurations, the paper's projection parameters, projection onto domain faces only, and the inverse
// map (projection_ray) used by reconstruction and ray casting.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "kernels/relief/relief_cells.h"
#include "kernels/relief/relief_projection.h"

namespace gimforge {
namespace {

constexpr int kNumConfigurations = 64;


int count_bits(std::uint8_t bits) {
  int n = 0;
  for (int f = 0; f < 6; ++f) n += has_cell_face(bits, f) ? 1 : 0;
  return n;
}

/// True when `bits` holds both faces of some axis.
bool has_opposite_pair(std::uint8_t bits) {
  for (int a = 0; a < 3; ++a)
    if (has_cell_face(bits, 2 * a) && has_cell_face(bits, 2 * a + 1)) return true;
  return false;
}

std::uint8_t internal_of(std::uint8_t external) { return static_cast<std::uint8_t>(~external & kAllCellFaces); }

std::uint8_t config(int c) { return static_cast<std::uint8_t>(c); }

/// Independent classification, from the counts and arrangement of internal / external faces (§3.2).
struct ExpectedCase {
  ReliefCase base_case;
  ProjectionType type;
};
ExpectedCase expected_case(std::uint8_t external) {
  const std::uint8_t internal = internal_of(external);
  switch (count_bits(internal)) {
    case 0:
      return {ReliefCase::k0, ProjectionType::Perspective};
    case 1:
      return {ReliefCase::k1, ProjectionType::Perspective};
    case 2:  // adjacent (one internal edge) or opposite
      return has_opposite_pair(internal) ? ExpectedCase{ReliefCase::k2b, ProjectionType::Axial}
                                         : ExpectedCase{ReliefCase::k2a, ProjectionType::Perspective};
    case 3:  // an opposite pair plus one (two internal edges) or one per axis (meeting at a vertex)
      return has_opposite_pair(internal) ? ExpectedCase{ReliefCase::k3a, ProjectionType::Axial}
                                         : ExpectedCase{ReliefCase::k3b, ProjectionType::Perspective};
    case 4:  // two external faces, opposite or adjacent
      return has_opposite_pair(external) ? ExpectedCase{ReliefCase::k4a, ProjectionType::Planar}
                                         : ExpectedCase{ReliefCase::k4b, ProjectionType::Axial};
    case 5:
      return {ReliefCase::k5, ProjectionType::Parallel};
    default:
      return {ReliefCase::k6, ProjectionType::Perspective};
  }
}

/// Points of the unit cell: the 21³ lattice (boundary included) and 2000 random interior points.
std::vector<Vec3> sample_points() {
  std::vector<Vec3> pts;
  constexpr int n = 20;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j)
      for (int k = 0; k <= n; ++k) pts.emplace_back(i / double{n}, j / double{n}, k / double{n});
  std::mt19937 rng(20240611u);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (int i = 0; i < 2000; ++i) {
    const double x = uni(rng), y = uni(rng), z = uni(rng);
    pts.emplace_back(x, y, z);
  }
  return pts;
}

/// Distance of p to the projection's degenerate set: the CoP (perspective) or the axis (axial); infinite
/// for the projection types without one.
double distance_to_degenerate_set(const CellProjection& proj, const Vec3& p) {
  if (proj.type == ProjectionType::Perspective) return (p - proj.point).norm();
  if (proj.type == ProjectionType::Axial) {
    Vec3 d = p - proj.point;
    d[proj.axis] = 0.0;
    return d.norm();
  }
  return std::numeric_limits<double>::infinity();
}

std::string describe(std::uint8_t external, const Vec3& p) {
  return "external=" + std::to_string(external) + " p=(" + std::to_string(p.x()) + ", " + std::to_string(p.y()) +
         ", " + std::to_string(p.z()) + ")";
}

// ---- classification ----

TEST(ReliefProjection, AllConfigurationsGetTheirBaseCase) {
  std::map<ReliefCase, int> counts;
  for (int c = 0; c < kNumConfigurations; ++c) {
    const std::uint8_t external = config(c);
    const CellProjection proj = cell_projection(external);
    const ExpectedCase want = expected_case(external);
    SCOPED_TRACE("external=" + std::to_string(c));
    EXPECT_EQ(proj.base_case, want.base_case) << relief_case_name(proj.base_case) << " vs "
                                              << relief_case_name(want.base_case);
    EXPECT_EQ(proj.type, want.type) << projection_type_name(proj.type) << " vs " << projection_type_name(want.type);
    EXPECT_EQ(relief_case(external), proj.base_case);
    // Domain faces: the external faces, or all six for an interior grey cell.
    EXPECT_EQ(proj.domain_faces, c == 0 ? kAllCellFaces : external);
    ++counts[proj.base_case];
  }
  const std::map<ReliefCase, int> want{{ReliefCase::k0, 1},  {ReliefCase::k1, 6},   {ReliefCase::k2a, 12},
                                       {ReliefCase::k2b, 3}, {ReliefCase::k3a, 12}, {ReliefCase::k3b, 8},
                                       {ReliefCase::k4a, 3}, {ReliefCase::k4b, 12}, {ReliefCase::k5, 6},
                                       {ReliefCase::k6, 1}};
  EXPECT_EQ(counts, want);
  EXPECT_EQ(cell_projection(0).base_case, ReliefCase::k6);
  EXPECT_EQ(cell_projection(0).domain_faces, kAllCellFaces);
  EXPECT_EQ(cell_projection(kAllCellFaces).base_case, ReliefCase::k0);
  EXPECT_EQ(cell_projection(kAllCellFaces).domain_faces, kAllCellFaces);
}

TEST(ReliefProjection, BitsOutsideTheSixFacesAreIgnored) {
  for (int c = 0; c < kNumConfigurations; ++c) {
    const CellProjection a = cell_projection(config(c));
    const CellProjection b = cell_projection(static_cast<std::uint8_t>(c | 0xc0));
    EXPECT_EQ(a.base_case, b.base_case) << c;
    EXPECT_EQ(a.domain_faces, b.domain_faces) << c;
  }
}

/// Face permutation of a rotation by 90° about `axis` (faces indexed 2·axis + side).
std::array<int, 6> quarter_turn(int axis) {
  // About axis a, with (b, c) the next axes: e_b → e_c, e_c → −e_b.
  const int b = (axis + 1) % 3, c = (axis + 2) % 3;
  std::array<int, 6> perm{};
  const auto set = [&perm](int from, int to) { perm[static_cast<std::size_t>(from)] = to; };
  set(2 * axis, 2 * axis);
  set(2 * axis + 1, 2 * axis + 1);
  set(2 * b + 1, 2 * c + 1);
  set(2 * b, 2 * c);
  set(2 * c + 1, 2 * b);
  set(2 * c, 2 * b + 1);
  return perm;
}

std::uint8_t apply(const std::array<int, 6>& perm, std::uint8_t bits) {
  unsigned out = 0;
  for (int f = 0; f < 6; ++f)
    if (has_cell_face(bits, f)) out |= 1u << perm[static_cast<std::size_t>(f)];
  return static_cast<std::uint8_t>(out);
}

TEST(ReliefProjection, BaseCasesAreTheRotationOrbits) {
  // The rotation group of the cube, generated by quarter turns about x and z.
  std::set<std::array<int, 6>> group{{0, 1, 2, 3, 4, 5}};
  const std::array<std::array<int, 6>, 2> gens{quarter_turn(0), quarter_turn(2)};
  for (bool grew = true; grew;) {
    grew = false;
    const auto current = group;
    for (const auto& g : current)
      for (const auto& h : gens) {
        std::array<int, 6> gh{};
        for (std::size_t f = 0; f < 6; ++f) gh[f] = h[static_cast<std::size_t>(g[f])];
        if (group.insert(gh).second) grew = true;
      }
  }
  ASSERT_EQ(group.size(), 24u);
  std::set<std::set<int>> orbits;
  for (int c = 0; c < kNumConfigurations; ++c) {
    std::set<int> orbit;
    for (const auto& g : group) {
      const std::uint8_t r = apply(g, config(c));
      orbit.insert(r);
      EXPECT_EQ(relief_case(r), relief_case(config(c))) << c << " rotated to " << int{r};
    }
    orbits.insert(orbit);
  }
  EXPECT_EQ(orbits.size(), std::size_t{kNumReliefCases});
}

// ---- parameters ----

TEST(ReliefProjection, PaperParametersPerBaseCase) {
  const auto near = [](const Vec3& a, const Vec3& b) { return (a - b).norm() < 1e-15; };
  constexpr std::uint8_t all = kAllCellFaces;
  const auto ext = [](unsigned internal) { return static_cast<std::uint8_t>(~internal & kAllCellFaces); };

  {  // 0: perspective from the centre.
    const CellProjection p = cell_projection(all);
    EXPECT_EQ(p.base_case, ReliefCase::k0);
    EXPECT_EQ(p.type, ProjectionType::Perspective);
    EXPECT_TRUE(near(p.point, Vec3(0.5, 0.5, 0.5)));
  }
  {  // 1: internal −x, CoP at its midpoint.
    const CellProjection p = cell_projection(ext(kFaceMinusX));
    EXPECT_EQ(p.base_case, ReliefCase::k1);
    EXPECT_EQ(p.type, ProjectionType::Perspective);
    EXPECT_TRUE(near(p.point, Vec3(0, 0.5, 0.5))) << p.point.transpose();
    EXPECT_EQ(p.domain_faces, kFacePlusX | kFaceMinusY | kFacePlusY | kFaceMinusZ | kFacePlusZ);
  }
  {  // 1: internal +z, CoP at its midpoint.
    const CellProjection p = cell_projection(ext(kFacePlusZ));
    EXPECT_EQ(p.base_case, ReliefCase::k1);
    EXPECT_TRUE(near(p.point, Vec3(0.5, 0.5, 1))) << p.point.transpose();
  }
  {  // 2a: internal −x, −y: CoP at the midpoint of their common edge.
    const CellProjection p = cell_projection(ext(kFaceMinusX | kFaceMinusY));
    EXPECT_EQ(p.base_case, ReliefCase::k2a);
    EXPECT_EQ(p.type, ProjectionType::Perspective);
    EXPECT_TRUE(near(p.point, Vec3(0, 0, 0.5))) << p.point.transpose();
  }
  {  // 2a: internal +y, −z.
    const CellProjection p = cell_projection(ext(kFacePlusY | kFaceMinusZ));
    EXPECT_EQ(p.base_case, ReliefCase::k2a);
    EXPECT_TRUE(near(p.point, Vec3(0.5, 1, 0))) << p.point.transpose();
  }
  {  // 2b: internal ±z: axial along z through (0.5, 0.5).
    const CellProjection p = cell_projection(ext(kFaceMinusZ | kFacePlusZ));
    EXPECT_EQ(p.base_case, ReliefCase::k2b);
    EXPECT_EQ(p.type, ProjectionType::Axial);
    EXPECT_EQ(p.axis, 2);
    EXPECT_DOUBLE_EQ(p.point.x(), 0.5);
    EXPECT_DOUBLE_EQ(p.point.y(), 0.5);
  }
  {  // 3a: internal ±x and −y: axial along x through the edge midpoints (0, 0, 0.5) and (1, 0, 0.5).
    const CellProjection p = cell_projection(ext(kFaceMinusX | kFacePlusX | kFaceMinusY));
    EXPECT_EQ(p.base_case, ReliefCase::k3a);
    EXPECT_EQ(p.type, ProjectionType::Axial);
    EXPECT_EQ(p.axis, 0);
    EXPECT_DOUBLE_EQ(p.point.y(), 0.0);
    EXPECT_DOUBLE_EQ(p.point.z(), 0.5);
    EXPECT_EQ(p.domain_faces, kFacePlusY | kFaceMinusZ | kFacePlusZ);
  }
  {  // 3a: internal ±y and +z: axial along y through (x = 0.5, z = 1).
    const CellProjection p = cell_projection(ext(kFaceMinusY | kFacePlusY | kFacePlusZ));
    EXPECT_EQ(p.base_case, ReliefCase::k3a);
    EXPECT_EQ(p.axis, 1);
    EXPECT_DOUBLE_EQ(p.point.x(), 0.5);
    EXPECT_DOUBLE_EQ(p.point.z(), 1.0);
  }
  {  // 3b: internal −x, −y, −z: CoP at their common vertex.
    const CellProjection p = cell_projection(ext(kFaceMinusX | kFaceMinusY | kFaceMinusZ));
    EXPECT_EQ(p.base_case, ReliefCase::k3b);
    EXPECT_EQ(p.type, ProjectionType::Perspective);
    EXPECT_TRUE(near(p.point, Vec3(0, 0, 0))) << p.point.transpose();
  }
  {  // 3b: internal +x, −y, +z.
    const CellProjection p = cell_projection(ext(kFacePlusX | kFaceMinusY | kFacePlusZ));
    EXPECT_EQ(p.base_case, ReliefCase::k3b);
    EXPECT_TRUE(near(p.point, Vec3(1, 0, 1))) << p.point.transpose();
  }
  {  // 4a: external ±y: planar, normal y, through the centre.
    const CellProjection p = cell_projection(kFaceMinusY | kFacePlusY);
    EXPECT_EQ(p.base_case, ReliefCase::k4a);
    EXPECT_EQ(p.type, ProjectionType::Planar);
    EXPECT_EQ(p.axis, 1);
    EXPECT_TRUE(near(p.point, Vec3(0.5, 0.5, 0.5))) << p.point.transpose();
    EXPECT_EQ(p.domain_faces, kFaceMinusY | kFacePlusY);
  }
  {  // 4b: external +y, +z (external edge y = 1, z = 1): axial along x through the opposite edge y = z = 0.
    const CellProjection p = cell_projection(kFacePlusY | kFacePlusZ);
    EXPECT_EQ(p.base_case, ReliefCase::k4b);
    EXPECT_EQ(p.type, ProjectionType::Axial);
    EXPECT_EQ(p.axis, 0);
    EXPECT_DOUBLE_EQ(p.point.y(), 0.0);
    EXPECT_DOUBLE_EQ(p.point.z(), 0.0);
  }
  {  // 4b: external −x, +z: axial along y through x = 1, z = 0.
    const CellProjection p = cell_projection(kFaceMinusX | kFacePlusZ);
    EXPECT_EQ(p.base_case, ReliefCase::k4b);
    EXPECT_EQ(p.axis, 1);
    EXPECT_DOUBLE_EQ(p.point.x(), 1.0);
    EXPECT_DOUBLE_EQ(p.point.z(), 0.0);
  }
  {  // 5: external +z: parallel along +z.
    const CellProjection p = cell_projection(kFacePlusZ);
    EXPECT_EQ(p.base_case, ReliefCase::k5);
    EXPECT_EQ(p.type, ProjectionType::Parallel);
    EXPECT_EQ(p.axis, 2);
    EXPECT_TRUE(near(p.direction, Vec3(0, 0, 1))) << p.direction.transpose();
    EXPECT_EQ(p.domain_faces, kFacePlusZ);
  }
  {  // 5: external −x: parallel along −x.
    const CellProjection p = cell_projection(kFaceMinusX);
    EXPECT_EQ(p.base_case, ReliefCase::k5);
    EXPECT_EQ(p.axis, 0);
    EXPECT_TRUE(near(p.direction, Vec3(-1, 0, 0))) << p.direction.transpose();
  }
  {  // 6: interior grey cell, perspective from the centre.
    const CellProjection p = cell_projection(0);
    EXPECT_EQ(p.base_case, ReliefCase::k6);
    EXPECT_EQ(p.type, ProjectionType::Perspective);
    EXPECT_TRUE(near(p.point, Vec3(0.5, 0.5, 0.5)));
  }
}

TEST(ReliefProjection, ParametersLieOnTheInternalFaces) {
  // The constraint of §3.2 that keeps rays off the internal faces, checked on all 64 configurations.
  for (int c = 0; c < kNumConfigurations; ++c) {
    const CellProjection p = cell_projection(config(c));
    const std::uint8_t internal = internal_of(config(c));
    SCOPED_TRACE("external=" + std::to_string(c));
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(p.point[a], 0.0);
      EXPECT_LE(p.point[a], 1.0);
    }
    switch (p.type) {
      case ProjectionType::Perspective:
        if (c == 0 || c == kAllCellFaces) {
          EXPECT_TRUE((p.point - Vec3::Constant(0.5)).norm() == 0.0);
        } else {
          for (int f = 0; f < 6; ++f) {
            if (has_cell_face(internal, f)) {
              EXPECT_EQ(p.point[f / 2], static_cast<double>(f % 2)) << "CoP off internal face " << f;
            }
          }
        }
        break;
      case ProjectionType::Axial:
        // Faces perpendicular to the axis are internal; any other internal face contains the axis.
        EXPECT_TRUE(has_cell_face(internal, 2 * p.axis) && has_cell_face(internal, 2 * p.axis + 1));
        for (int f = 0; f < 6; ++f) {
          if (f / 2 != p.axis && has_cell_face(internal, f)) {
            EXPECT_EQ(p.point[f / 2], static_cast<double>(f % 2)) << "axis off face " << f;
          }
        }
        break;
      case ProjectionType::Planar:
        EXPECT_EQ(int{p.domain_faces}, 3 << (2 * p.axis));
        EXPECT_DOUBLE_EQ(p.point[p.axis], 0.5);
        break;
      case ProjectionType::Parallel: {
        const int side = p.direction[p.axis] > 0 ? 1 : 0;
        EXPECT_EQ(int{p.domain_faces}, 1 << (2 * p.axis + side));
        EXPECT_DOUBLE_EQ(p.direction.norm(), 1.0);
        break;
      }
    }
  }
}

// ---- projection ----

TEST(ReliefProjection, EveryCaseProjectsOntoItsDomainFacesOnly) {
  const std::vector<Vec3> pts = sample_points();
  std::array<int, kNumReliefCases> degenerate{};
  for (int c = 0; c < kNumConfigurations; ++c) {
    const CellProjection proj = cell_projection(config(c));
    int failures = 0;
    for (const Vec3& p : pts) {
      FaceProjection fp;
      const bool ok = project_point(proj, p, fp);
      if (!ok) {
        ++degenerate[static_cast<std::size_t>(proj.base_case)];
        EXPECT_LT(distance_to_degenerate_set(proj, p), 1e-12) << "false away from the CoP / axis, "
                                                              << describe(config(c), p);
        continue;
      }
      const bool good = fp.face >= 0 && fp.face < 6 && has_cell_face(proj.domain_faces, fp.face) && fp.u >= 0.0 &&
                        fp.u <= 1.0 && fp.v >= 0.0 && fp.v <= 1.0 && fp.distance >= 0.0 &&
                        fp.distance <= kMaxProjectionLength + 1e-12;
      if (!good && ++failures <= 5)
        ADD_FAILURE() << "case " << relief_case_name(proj.base_case) << ' ' << describe(config(c), p)
                      << " -> face " << fp.face << " (u, v) = (" << fp.u << ", " << fp.v << ") distance "
                      << fp.distance;
    }
    EXPECT_EQ(failures, 0) << "external=" << c;
  }
  // The lattice holds the CoP / axis points of every case but parallel and planar (which have none).
  for (const ReliefCase rc : {ReliefCase::k0, ReliefCase::k1, ReliefCase::k2a, ReliefCase::k2b, ReliefCase::k3a,
                              ReliefCase::k3b, ReliefCase::k4b, ReliefCase::k6})
    EXPECT_GT(degenerate[static_cast<std::size_t>(rc)], 0) << relief_case_name(rc);
  EXPECT_EQ(degenerate[static_cast<std::size_t>(ReliefCase::k4a)], 0);
  EXPECT_EQ(degenerate[static_cast<std::size_t>(ReliefCase::k5)], 0);
}

TEST(ReliefProjection, DegeneratePointsReturnFalse) {
  for (int c = 0; c < kNumConfigurations; ++c) {
    const CellProjection proj = cell_projection(config(c));
    FaceProjection fp;
    if (proj.type == ProjectionType::Perspective) {
      EXPECT_FALSE(project_point(proj, proj.point, fp)) << c;
    } else if (proj.type == ProjectionType::Axial) {
      for (const double s : {0.0, 0.3, 1.0}) {
        Vec3 q = proj.point;
        q[proj.axis] = s;
        EXPECT_FALSE(project_point(proj, q, fp)) << c << " axis point " << q.transpose();
      }
    } else {
      EXPECT_TRUE(project_point(proj, proj.point, fp)) << c;
    }
  }
}

TEST(ReliefProjection, ProjectionFollowsTheProjectionType) {
  // Independent of projection_ray: P' lies on the boundary face reported, and P → P' runs along the
  // direction the projection type prescribes at P.
  const std::vector<Vec3> pts = sample_points();
  for (int c = 0; c < kNumConfigurations; ++c) {
    const CellProjection proj = cell_projection(config(c));
    int failures = 0;
    for (const Vec3& p : pts) {
      FaceProjection fp;
      if (!project_point(proj, p, fp)) continue;
      const Vec3 q = face_point(fp.face, fp.u, fp.v);
      Vec3 want_dir = Vec3::Zero();  // direction of P' − P (up to a non-negative scale)
      switch (proj.type) {
        case ProjectionType::Parallel:
          want_dir = proj.direction;
          break;
        case ProjectionType::Planar:
          want_dir = Vec3::Zero();
          want_dir[proj.axis] = p[proj.axis] >= 0.5 ? 1.0 : -1.0;
          break;
        case ProjectionType::Perspective:
          want_dir = (p - proj.point).normalized();
          break;
        case ProjectionType::Axial:
          want_dir = p - proj.point;
          want_dir[proj.axis] = 0.0;
          want_dir.normalize();
          break;
      }
      const Vec3 step = q - p;
      const double along = step.dot(want_dir);
      const double off = (step - along * want_dir).norm();
      const bool good = along >= -1e-12 && off < 1e-9 && std::abs(fp.distance - step.norm()) < 1e-9;
      if (!good && ++failures <= 5)
        ADD_FAILURE() << "case " << relief_case_name(proj.base_case) << ' ' << describe(config(c), p) << " -> "
                      << q.transpose() << " distance " << fp.distance;
    }
    EXPECT_EQ(failures, 0) << "external=" << c;
  }
}

TEST(ReliefProjection, FaceCoordinates) {
  // (u, v) = (p[(a + 1) % 3], p[(a + 2) % 3]) on the face of axis a.
  EXPECT_TRUE(face_point(0, 0.2, 0.7).isApprox(Vec3(0, 0.2, 0.7)));
  EXPECT_TRUE(face_point(1, 0.2, 0.7).isApprox(Vec3(1, 0.2, 0.7)));
  EXPECT_TRUE(face_point(2, 0.2, 0.7).isApprox(Vec3(0.7, 0, 0.2)));
  EXPECT_TRUE(face_point(3, 0.2, 0.7).isApprox(Vec3(0.7, 1, 0.2)));
  EXPECT_TRUE(face_point(4, 0.2, 0.7).isApprox(Vec3(0.2, 0.7, 0)));
  EXPECT_TRUE(face_point(5, 0.2, 0.7).isApprox(Vec3(0.2, 0.7, 1)));
  // Parallel along +z: P = (0.3, 0.6, 0.25) → face +z, (u, v) = (x, y), distance 0.75.
  FaceProjection fp;
  ASSERT_TRUE(project_point(cell_projection(kFacePlusZ), Vec3(0.3, 0.6, 0.25), fp));
  EXPECT_EQ(fp.face, 5);
  EXPECT_DOUBLE_EQ(fp.u, 0.3);
  EXPECT_DOUBLE_EQ(fp.v, 0.6);
  EXPECT_DOUBLE_EQ(fp.distance, 0.75);
  // Perspective from the centre: P = (0.5, 0.75, 0.5) → face +y at (u, v) = (z, x) = (0.5, 0.5).
  ASSERT_TRUE(project_point(cell_projection(0), Vec3(0.5, 0.75, 0.5), fp));
  EXPECT_EQ(fp.face, 3);
  EXPECT_DOUBLE_EQ(fp.u, 0.5);
  EXPECT_DOUBLE_EQ(fp.v, 0.5);
  EXPECT_DOUBLE_EQ(fp.distance, 0.25);
  // Perspective from the vertex (0, 0, 0) (case 3b): P = (0.5, 0.25, 0.25) → face +x at (0.5, 0.5).
  ASSERT_TRUE(project_point(cell_projection(kFacePlusX | kFacePlusY | kFacePlusZ), Vec3(0.5, 0.25, 0.25), fp));
  EXPECT_EQ(fp.face, 1);
  EXPECT_DOUBLE_EQ(fp.u, 0.5);
  EXPECT_DOUBLE_EQ(fp.v, 0.5);
  EXPECT_NEAR(fp.distance, std::sqrt(0.375), 1e-15);
  // Points outside the cell are clamped first.
  ASSERT_TRUE(project_point(cell_projection(kFacePlusZ), Vec3(-0.5, 1.5, -2), fp));
  EXPECT_EQ(fp.face, 5);
  EXPECT_DOUBLE_EQ(fp.u, 0.0);
  EXPECT_DOUBLE_EQ(fp.v, 1.0);
  EXPECT_DOUBLE_EQ(fp.distance, 1.0);
}

// ---- the inverse map ----

TEST(ReliefProjection, ProjectionRayInvertsTheProjection) {
  const std::vector<Vec3> pts = sample_points();
  for (int c = 0; c < kNumConfigurations; ++c) {
    const CellProjection proj = cell_projection(config(c));
    int failures = 0;
    for (const Vec3& p : pts) {
      FaceProjection fp;
      if (!project_point(proj, p, fp)) continue;
      const Vec3 q = face_point(fp.face, fp.u, fp.v);
      const ProjectionRay ray = projection_ray(proj, q);
      const Vec3 back = q - fp.distance * ray.direction;
      FaceProjection again;
      const bool again_ok = project_point(proj, q, again);
      const bool good = (back - p).norm() < 1e-9 && fp.distance <= ray.length + 1e-9 &&
                        std::abs(ray.direction.norm() - 1.0) < 1e-12 && again_ok &&
                        std::abs(again.distance) < 1e-12 &&
                        (face_point(again.face, again.u, again.v) - q).norm() < 1e-12;
      if (!good && ++failures <= 5)
        ADD_FAILURE() << "case " << relief_case_name(proj.base_case) << ' ' << describe(config(c), p) << " -> "
                      << q.transpose() << " distance " << fp.distance << "; back " << back.transpose()
                      << " ray length " << ray.length << "; reprojection ok " << again_ok << " distance "
                      << again.distance;
    }
    EXPECT_EQ(failures, 0) << "external=" << c;
  }
}

TEST(ReliefProjection, ProjectionRaysOfDomainFacePoints) {
  // On every domain face of every configuration: the ray has positive length, its points inside the
  // segment lie in the cell and project back onto the face point at distance t.
  constexpr int n = 20;
  for (int c = 0; c < kNumConfigurations; ++c) {
    const CellProjection proj = cell_projection(config(c));
    int failures = 0;
    for (int f = 0; f < 6; ++f) {
      if (!has_cell_face(proj.domain_faces, f)) continue;
      for (int i = 0; i <= n; ++i)
        for (int j = 0; j <= n; ++j) {
          const Vec3 q = face_point(f, i / double{n}, j / double{n});
          const ProjectionRay ray = projection_ray(proj, q);
          if (!(ray.length > 0.0)) {
            if (++failures <= 5)
              ADD_FAILURE() << "zero-length ray at face " << f << ' ' << describe(config(c), q);
            continue;
          }
          EXPECT_LE(ray.length, kMaxProjectionLength + 1e-12);
          // The interior of the segment (its far end is the CoP / axis / plane, ambiguous there).
          for (const double s : {0.0, 0.1, 0.25, 0.5, 0.75, 0.9, 0.999}) {
            const double t = s * ray.length;
            const Vec3 p = q - t * ray.direction;
            FaceProjection fp;
            const bool inside = (p.array() >= -1e-12).all() && (p.array() <= 1.0 + 1e-12).all();
            const bool ok = project_point(proj, p, fp);
            const bool good = inside && ok && (face_point(fp.face, fp.u, fp.v) - q).norm() < 1e-9 &&
                              std::abs(fp.distance - t) < 1e-9;
            if (!good && ++failures <= 5)
              ADD_FAILURE() << "face " << f << " q=" << q.transpose() << " t=" << t << ' '
                            << describe(config(c), p) << " -> ok " << ok << " face " << fp.face << " distance "
                            << fp.distance;
          }
        }
    }
    EXPECT_EQ(failures, 0) << "external=" << c;
  }
}

// ---- names ----

TEST(ReliefProjection, Names) {
  const std::array<std::string, kNumReliefCases> cases{"0", "1", "2a", "2b", "3a", "3b", "4a", "4b", "5", "6"};
  for (int i = 0; i < kNumReliefCases; ++i)
    EXPECT_EQ(relief_case_name(static_cast<ReliefCase>(i)), cases[static_cast<std::size_t>(i)]);
  EXPECT_EQ(relief_case_name(ReliefCase::k2b), "2b");
  EXPECT_EQ(relief_case_name(ReliefCase::k4a), "4a");
  EXPECT_EQ(projection_type_name(ProjectionType::Parallel), "parallel");
  EXPECT_EQ(projection_type_name(ProjectionType::Planar), "planar");
  EXPECT_EQ(projection_type_name(ProjectionType::Perspective), "perspective");
  EXPECT_EQ(projection_type_name(ProjectionType::Axial), "axial");
}

}  // namespace
}  // namespace gimforge
