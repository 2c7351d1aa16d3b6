// Spherical stretch metric (Praun & Hoppe 2003, §3.4).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/sphere/spherical_stretch.h"

using namespace gimforge;

namespace {

std::vector<Vec3> normalized_positions(const TriMesh& m) {
  std::vector<Vec3> s;
  for (const Vec3& p : m.positions) s.push_back(p.normalized());
  return s;
}

}  // namespace

TEST(SphericalStretch, SphereToItselfIsNearlyIsometric) {
  for (int level : {3, 5}) {
    const TriMesh m = make_icosphere(1.0, level);
    const SphericalStretch r = spherical_stretch(m, normalized_positions(m));
    EXPECT_EQ(r.flipped, 0u);
    // The mesh is the chordal polyhedron of the sphere: finer meshes get closer to an isometry.
    EXPECT_GT(r.efficiency, level == 3 ? 0.98 : 0.999) << "level " << level;
    EXPECT_LE(r.efficiency, 1.0 + 1e-9);
  }
}

TEST(SphericalStretch, ScaleInvariantEfficiency) {
  const TriMesh unit = make_icosphere(1.0, 3);
  TriMesh big = unit;
  for (Vec3& p : big.positions) p *= 7.5;
  const auto a = spherical_stretch(unit, normalized_positions(unit));
  const auto b = spherical_stretch(big, normalized_positions(big));
  EXPECT_NEAR(a.efficiency, b.efficiency, 1e-9);
  EXPECT_NEAR(b.l2, 7.5 * a.l2, 1e-9 * b.l2);
}

TEST(SphericalStretch, AnisotropyLowersEfficiency) {
  TriMesh m = make_icosphere(1.0, 4);
  const auto sphere = normalized_positions(m);
  for (Vec3& p : m.positions) p.z() *= 3.0;  // an elongated ellipsoid mapped to the sphere radially
  const auto r = spherical_stretch(m, sphere);
  EXPECT_EQ(r.flipped, 0u);
  EXPECT_LT(r.efficiency, 0.95);
  EXPECT_GT(r.efficiency, 0.3);
  // The inverse-stretch regularizer adds to the energy.
  SphericalStretchOptions no_reg;
  no_reg.epsilon = 0.0;
  const auto plain = spherical_stretch(m, sphere, no_reg);
  EXPECT_GT(r.energy, plain.energy);
  EXPECT_NEAR(plain.energy, plain.l2 * plain.l2 * plain.surface_area, 1e-9 * plain.energy);
}

TEST(SphericalStretch, FlippedTrianglesAreInfinite) {
  const TriMesh m = make_icosphere(1.0, 2);
  auto sphere = normalized_positions(m);
  std::swap(sphere[m.faces[0][1]], sphere[m.faces[0][2]]);
  const auto r = spherical_stretch(m, sphere);
  EXPECT_GE(r.flipped, 1u);
  EXPECT_EQ(r.efficiency, 0.0);
  EXPECT_TRUE(std::isinf(r.energy));
}

TEST(SphericalStretch, NumericalIntegrationConverges) {
  const Vec3 q1(0, 0, 0), q2(1, 0, 0.2), q3(0.3, 0.8, 0.1);
  const Vec3 s1 = Vec3(1, 0.1, 0.2).normalized(), s2 = Vec3(0.2, 1, 0.1).normalized(), s3 = Vec3(0.1, 0.3, 1).normalized();
  SphericalStretchOptions coarse, fine;
  coarse.max_chord = 0.05;
  fine.max_chord = 0.005;
  const auto a = spherical_triangle_stretch(q1, q2, q3, s1, s2, s3, coarse);
  const auto b = spherical_triangle_stretch(q1, q2, q3, s1, s2, s3, fine);
  EXPECT_NEAR(a.stretch, b.stretch, 5e-3 * b.stretch);
  EXPECT_NEAR(a.inverse, b.inverse, 5e-3 * b.inverse);
  EXPECT_NEAR(a.area, 0.5 * (q2 - q1).cross(q3 - q1).norm(), 1e-15);
}

TEST(SphericalStretch, CapTriangleSplitKeepsCoarseIntegrationAccurate) {
  // A thin "cap": one angle close to 180 degrees. Without subdivision (huge max_chord) the planar
  // approximation of the whole cap would be badly off; the split by the perpendicular keeps it close to
  // the finely integrated value.
  const Vec3 a = Vec3(1, -0.2, 0).normalized(), b = Vec3(1, 0.2, 0).normalized(), c = Vec3(1, 0, 0.004).normalized();
  const Vec3 qa(0, 0, 0), qb(1, 0, 0), qc(0.5, 0.3, 0);
  SphericalStretchOptions single, reference;
  single.max_chord = 10.0;  // no subdivision: only the cap split
  reference.max_chord = 1e-3;
  const auto s = spherical_triangle_stretch(qa, qb, qc, a, b, c, single);
  const auto r = spherical_triangle_stretch(qa, qb, qc, a, b, c, reference);
  EXPECT_NEAR(s.stretch, r.stretch, 0.05 * r.stretch);
}

TEST(SphericalStretch, RejectsBadInput) {
  const TriMesh m = make_icosphere(1.0, 1);
  std::vector<Vec3> sphere(m.positions.size() - 1, Vec3(0, 0, 1));
  EXPECT_THROW((void)spherical_stretch(m, sphere), InvalidInput);
  std::vector<Vec3> not_unit = normalized_positions(m);
  not_unit[3] *= 2.0;
  EXPECT_THROW((void)spherical_stretch(m, not_unit), InvalidInput);
}
