// Geometric stretch (Sander et al. 2001) on maps with known answers.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/param/stretch.h"

namespace gimforge {
namespace {

/// uv = A · (x, y) for every vertex of the grid.
std::vector<Vec2> linear_uv(const TriMesh& mesh, const Eigen::Matrix2d& a) {
  std::vector<Vec2> uv;
  for (const Vec3& p : mesh.positions) uv.push_back(a * p.head<2>());
  return uv;
}

TEST(Stretch, IsometricGridHasUnitStretch) {
  const TriMesh grid = make_grid(8, 5, 2.0);
  const MeshStretch s = mesh_stretch(grid, linear_uv(grid, Eigen::Matrix2d::Identity()));
  EXPECT_NEAR(s.l2, 1.0, 1e-12);
  EXPECT_NEAR(s.linf, 1.0, 1e-12);
  EXPECT_NEAR(s.efficiency, 1.0, 1e-12);
  EXPECT_NEAR(s.surface_area, 4.0, 1e-12);
  EXPECT_NEAR(s.domain_area, 4.0, 1e-12);
  EXPECT_EQ(s.flipped, 0u);
}

TEST(Stretch, ScaledMapScalesStretchButNotEfficiency) {
  const TriMesh grid = make_grid(6, 6, 1.0);
  const double scale = 2.5;
  const MeshStretch s = mesh_stretch(grid, linear_uv(grid, scale * Eigen::Matrix2d::Identity()));
  EXPECT_NEAR(s.l2, 1.0 / scale, 1e-12);
  EXPECT_NEAR(s.linf, 1.0 / scale, 1e-12);
  EXPECT_NEAR(s.efficiency, 1.0, 1e-12);
}

TEST(Stretch, ShearHasAnalyticStretch) {
  // uv = (x + k y, y): the Jacobian of uv -> surface is [[1, -k], [0, 1]], a = 1, b = -k, c = 1 + k².
  const double k = 0.7;
  const TriMesh grid = make_grid(5, 7, 1.0);
  Eigen::Matrix2d a;
  a << 1.0, k, 0.0, 1.0;
  const MeshStretch s = mesh_stretch(grid, linear_uv(grid, a));
  const double l2 = std::sqrt((2.0 + k * k) / 2.0);
  const double linf = std::sqrt(((2.0 + k * k) + std::sqrt(k * k * k * k + 4.0 * k * k)) / 2.0);
  EXPECT_NEAR(s.l2, l2, 1e-12);
  EXPECT_NEAR(s.linf, linf, 1e-12);
  EXPECT_NEAR(s.efficiency, 1.0 / (l2 * l2), 1e-12);
  const TriangleStretch t =
      triangle_stretch(Vec2(0, 0), Vec2(1, 0), Vec2(k, 1), Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0));
  EXPECT_NEAR(t.l2, l2, 1e-12);
  EXPECT_NEAR(t.linf, linf, 1e-12);
  EXPECT_NEAR(t.parametric_area, 0.5, 1e-15);
}

TEST(Stretch, FlippedTriangleIsInfinite) {
  const TriangleStretch t =
      triangle_stretch(Vec2(0, 0), Vec2(0, 1), Vec2(1, 0), Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0));
  EXPECT_TRUE(std::isinf(t.l2));
  EXPECT_TRUE(std::isinf(t.linf));
  EXPECT_NEAR(t.parametric_area, -0.5, 1e-15);
  const TriangleStretch degenerate =
      triangle_stretch(Vec2(0, 0), Vec2(1, 1), Vec2(2, 2), Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0));
  EXPECT_TRUE(std::isinf(degenerate.l2));

  const TriMesh grid = make_grid(4, 4, 1.0);
  std::vector<Vec2> uv = linear_uv(grid, Eigen::Matrix2d::Identity());
  uv[6] = Vec2(2.0, 2.0);  // an interior vertex pushed outside its ring flips some of its triangles
  const MeshStretch s = mesh_stretch(grid, uv);
  EXPECT_GT(s.flipped, 0u);
  EXPECT_TRUE(std::isinf(s.l2));
  EXPECT_EQ(s.efficiency, 0.0);
}

TEST(Stretch, RejectsSizeMismatch) {
  const TriMesh grid = make_grid(2, 2, 1.0);
  const std::vector<Vec2> uv(3, Vec2::Zero());
  EXPECT_THROW((void)mesh_stretch(grid, uv), InvalidInput);
}

}  // namespace
}  // namespace gimforge
