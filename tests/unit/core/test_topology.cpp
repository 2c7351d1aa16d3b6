#include <gtest/gtest.h>

#include "kernels/core/procedural.h"
#include "kernels/core/topology.h"

using namespace gimforge;

TEST(Topology, IcosphereIsClosedGenusZero) {
  const auto r = analyze_topology(make_icosphere(1.0, 3));
  ASSERT_EQ(r.components.size(), 1u);
  EXPECT_EQ(r.euler_characteristic, 2);
  EXPECT_EQ(r.components[0].genus, 0.0);
  EXPECT_EQ(r.boundary_loops, 0u);
  EXPECT_TRUE(r.closed && r.manifold && r.orientable && r.oriented);
  EXPECT_NEAR(r.bbox.diagonal(), 2.0 * std::sqrt(3.0), 0.25);
}

TEST(Topology, TorusIsGenusOne) {
  const auto r = analyze_topology(make_torus(2.0, 0.5, 16, 8));
  ASSERT_EQ(r.components.size(), 1u);
  EXPECT_EQ(r.euler_characteristic, 0);
  EXPECT_EQ(r.components[0].genus, 1.0);
  EXPECT_TRUE(r.closed);
}

TEST(Topology, GridIsADisk) {
  const auto r = analyze_topology(make_grid(5, 4));
  ASSERT_EQ(r.components.size(), 1u);
  EXPECT_EQ(r.boundary_loops, 1u);
  EXPECT_EQ(r.boundary_edges, 18u);
  EXPECT_EQ(r.euler_characteristic, 1);
  EXPECT_EQ(r.components[0].genus, 0.0);
  EXPECT_FALSE(r.closed);
}

TEST(Topology, GridWithAHoleHasTwoLoops) {
  TriMesh g = make_grid(4, 4);
  // Remove the two triangles of the centre-ish quad (i=1, j=1) -> an inner hole.
  g.faces.erase(g.faces.begin() + 2 * (1 * 4 + 1), g.faces.begin() + 2 * (1 * 4 + 1) + 2);
  const auto r = analyze_topology(g);
  EXPECT_EQ(r.boundary_loops, 2u);
  EXPECT_EQ(r.components[0].genus, 0.0);
}

TEST(Topology, ComponentsSortedLargestFirst) {
  const TriMesh m = concatenate(make_icosphere(1.0, 1), make_torus(3.0, 1.0, 20, 10));
  const auto r = analyze_topology(m);
  ASSERT_EQ(r.components.size(), 2u);
  EXPECT_EQ(r.components[0].faces, 400u);
  EXPECT_EQ(r.components[0].genus, 1.0);
  EXPECT_EQ(r.components[1].faces, 80u);
  EXPECT_EQ(r.components[1].genus, 0.0);
  EXPECT_EQ(r.euler_characteristic, 2);
}

TEST(Topology, UnreferencedAndDegenerateAreIgnored) {
  TriMesh m = make_icosphere(1.0, 1);
  m.positions.push_back({7, 7, 7});
  m.faces.push_back({0, 0, 1});
  const auto r = analyze_topology(m);
  EXPECT_EQ(r.vertices, 43u);
  EXPECT_EQ(r.referenced_vertices, 42u);
  EXPECT_EQ(r.faces, 80u);
  EXPECT_EQ(r.components.size(), 1u);
  EXPECT_NEAR(r.bbox.max.x(), 1.0, 1e-9) << "unreferenced vertex must not enlarge the box";
}

TEST(Topology, MoebiusStripIsNotOrientable) {
  // A strip of n quads whose ends are glued with a half twist.
  const std::uint32_t n = 12;
  TriMesh m;
  for (std::uint32_t i = 0; i < n; ++i) {
    const double u = 2.0 * M_PI * i / n;
    for (int s : {-1, 1}) {
      const double w = 0.3 * s;
      m.positions.emplace_back((1 + w * std::cos(u / 2)) * std::cos(u), (1 + w * std::cos(u / 2)) * std::sin(u),
                               w * std::sin(u / 2));
    }
  }
  for (std::uint32_t i = 0; i < n; ++i) {
    std::uint32_t a = 2 * i, b = 2 * i + 1, c = 2 * ((i + 1) % n), d = c + 1;
    if (i == n - 1) std::swap(c, d);  // the half twist
    m.faces.push_back({a, c, d});
    m.faces.push_back({a, d, b});
  }
  const auto r = analyze_topology(m);
  EXPECT_FALSE(r.orientable);
  EXPECT_FALSE(r.oriented);
  EXPECT_TRUE(r.manifold);
  EXPECT_EQ(r.boundary_loops, 1u);  // a Moebius strip has one boundary curve
}

TEST(Topology, NonManifoldFlagged) {
  TriMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}};
  m.faces = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  const auto r = analyze_topology(m);
  EXPECT_FALSE(r.manifold);
  EXPECT_EQ(r.nonmanifold_edges, 1u);
}

namespace {

/// The icosphere of radius 1 without the faces whose centroid lies within `radius` of (0, 0, 1).
TriMesh sphere_with_hole(double radius) {
  TriMesh m = make_icosphere(1.0, 4);
  std::erase_if(m.faces, [&](const Face& f) {
    const Vec3 c = (m.positions[f[0]] + m.positions[f[1]] + m.positions[f[2]]) / 3.0;
    return (c - Vec3(0, 0, 1)).norm() < radius;
  });
  return m;
}

TriMesh moved(TriMesh m, const Eigen::Matrix3d& rotation, const Vec3& offset) {
  for (Vec3& p : m.positions) p = rotation * p + offset;
  return m;
}

}  // namespace

TEST(Topology, WidestHoleIsTheLoopsWidthAcrossAnyPlacement) {
  EXPECT_EQ(widest_hole(make_icosphere(1.0, 3)), 0.0);
  // An open 2 × 1 sheet: its rim is 1 wide (the second principal extent), however it is placed.
  TriMesh sheet = make_grid(20, 10, 1.0);
  for (Vec3& p : sheet.positions) p.x() *= 2.0;
  const Eigen::Matrix3d rotation = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  EXPECT_NEAR(widest_hole(sheet), 1.0, 1e-12);
  EXPECT_NEAR(widest_hole(moved(sheet, rotation, Vec3(5e5, 4.1e6, 300))), 1.0, 1e-9);
  // A round hole: about its diameter (the rim runs through the removed faces' outer vertices, an edge more).
  const TriMesh holed = sphere_with_hole(0.3);
  const double width = widest_hole(holed);
  EXPECT_GT(width, 0.6);
  EXPECT_LT(width, 0.8);
  EXPECT_NEAR(widest_hole(moved(holed, rotation, Vec3(-3e6, 2e5, 10))), width, 1e-9);
  // The widest of several holes.
  EXPECT_NEAR(widest_hole(concatenate(holed, moved(sheet, rotation, Vec3(9, 0, 0)))), 1.0, 1e-9);
}
