#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "kernels/core/errors.h"
#include "kernels/core/mesh.h"
#include "kernels/core/procedural.h"

using namespace gimforge;

TEST(Mesh, BoundingBoxIgnoresUnreferencedVertices) {
  TriMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 2, 0}, {100, 100, 100}};
  m.faces = {{0, 1, 2}};
  const BoundingBox box = bounding_box(m);
  EXPECT_EQ(box.max, Vec3(1, 2, 0));
  EXPECT_DOUBLE_EQ(box.diagonal(), std::sqrt(5.0));
}

TEST(Mesh, EmptyBoxHasZeroDiagonal) {
  BoundingBox box;
  EXPECT_TRUE(box.empty());
  EXPECT_EQ(box.diagonal(), 0.0);
}

TEST(Mesh, TriangleAndSurfaceArea) {
  const TriMesh grid = make_grid(4, 3, 2.0);
  EXPECT_NEAR(surface_area(grid), 4.0, 1e-12);
  EXPECT_NEAR(triangle_area(grid, 0), 4.0 / 24.0, 1e-12);
}

TEST(Procedural, IcosphereApproachesSphereArea) {
  const TriMesh s = make_icosphere(2.0, 5);
  EXPECT_EQ(s.num_faces(), 20u * 1024u);
  EXPECT_EQ(s.num_vertices(), 10u * 1024u + 2u);
  for (const Vec3& p : s.positions) ASSERT_NEAR(p.norm(), 2.0, 1e-12);
  EXPECT_NEAR(surface_area(s), 4.0 * std::numbers::pi * 4.0, 0.01 * 16.0 * std::numbers::pi);
}

TEST(Procedural, TorusCounts) {
  const TriMesh t = make_torus(2.0, 0.5, 24, 12);
  EXPECT_EQ(t.num_vertices(), 24u * 12u);
  EXPECT_EQ(t.num_faces(), 2u * 24u * 12u);
}

TEST(Procedural, RejectsBadParameters) {
  EXPECT_THROW((void)make_icosphere(-1.0, 2), InvalidInput);
  EXPECT_THROW((void)make_torus(1.0, 2.0, 8, 8), InvalidInput);
  EXPECT_THROW((void)make_grid(0, 3), InvalidInput);
}
