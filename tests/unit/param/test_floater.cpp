// Floater's parametrization: bijectivity on disks, fixed vertices, linear reproduction.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "kernels/core/errors.h"
#include "kernels/param/floater.h"
#include "kernels/core/procedural.h"
#include "param_test_meshes.h"

namespace gimforge {
namespace {

using Weights = FloaterOptions::Weights;

class FloaterWeights : public ::testing::TestWithParam<Weights> {};

/// Parametrizes `mesh` with its boundary on the unit circle and checks bijectivity and the fixed vertices.
void expect_bijective_on_circle(const TriMesh& mesh, Weights weights) {
  const std::vector<std::uint32_t> loop = test::boundary_loop(mesh);
  ASSERT_GE(loop.size(), 3u);
  const std::vector<Vec2> circle = circle_boundary(mesh, loop);
  for (const Vec2& p : circle) EXPECT_NEAR(p.norm(), 1.0, 1e-12);
  const std::vector<Vec2> uv = floater_parametrization(mesh, loop, circle, {weights});
  ASSERT_EQ(uv.size(), mesh.positions.size());
  EXPECT_EQ(test::count_flipped(mesh, uv), 0u);
  for (std::size_t i = 0; i < loop.size(); ++i) EXPECT_EQ(uv[loop[i]], circle[i]);
  const MeshStretch s = mesh_stretch(mesh, uv);
  EXPECT_EQ(s.flipped, 0u);
  EXPECT_GT(s.efficiency, 0.0);
  EXPECT_LE(s.efficiency, 1.0 + 1e-12);
}

TEST_P(FloaterWeights, GridOnCircleIsBijective) { expect_bijective_on_circle(make_grid(12, 9, 1.0), GetParam()); }

TEST_P(FloaterWeights, HemisphereOnCircleIsBijective) { expect_bijective_on_circle(test::make_hemisphere(3), GetParam()); }

INSTANTIATE_TEST_SUITE_P(AllWeights, FloaterWeights,
                         ::testing::Values(Weights::ShapePreserving, Weights::MeanValue, Weights::Uniform));

/// A planar grid with jittered interior vertices, boundary fixed at its own xy coordinates.
TEST(Floater, ReproducesPlanarIdentity) {
  TriMesh grid = make_grid(10, 10, 1.0);
  const std::vector<std::uint32_t> loop = test::boundary_loop(grid);
  std::vector<char> on_boundary(grid.positions.size(), 0);
  for (std::uint32_t v : loop) on_boundary[v] = 1;
  for (std::size_t v = 0; v < grid.positions.size(); ++v)
    if (!on_boundary[v])
      grid.positions[v] += 0.03 * Vec3(std::sin(7.0 * static_cast<double>(v)), std::cos(5.0 * static_cast<double>(v)), 0);
  std::vector<Vec2> fixed;
  for (std::uint32_t v : loop) fixed.push_back(grid.positions[v].head<2>());
  for (Weights w : {Weights::ShapePreserving, Weights::MeanValue}) {
    const std::vector<Vec2> uv = floater_parametrization(grid, loop, fixed, {w});
    for (std::size_t v = 0; v < grid.positions.size(); ++v)
      EXPECT_NEAR((uv[v] - grid.positions[v].head<2>()).norm(), 0.0, 1e-9) << "vertex " << v;
    EXPECT_NEAR(mesh_stretch(grid, uv).efficiency, 1.0, 1e-9);
  }
  const std::vector<Vec2> uniform = floater_parametrization(grid, loop, fixed, {Weights::Uniform});
  double error = 0.0;
  for (std::size_t v = 0; v < grid.positions.size(); ++v) error += (uniform[v] - grid.positions[v].head<2>()).norm();
  EXPECT_GT(error, 1e-3);  // uniform weights do not reproduce linear functions
}

TEST(Floater, FreeBoundaryVerticesStayInside) {
  // Only three boundary vertices fixed; the other boundary vertices are free (mean-value weights).
  const TriMesh grid = make_grid(6, 6, 1.0);
  const std::vector<std::uint32_t> loop = test::boundary_loop(grid);
  const std::vector<std::uint32_t> fixed{loop[0], loop[loop.size() / 3], loop[2 * loop.size() / 3]};
  const std::vector<Vec2> uv = floater_parametrization(grid, fixed, std::vector<Vec2>{{0, 0}, {1, 0}, {0, 1}});
  for (const Vec2& p : uv) EXPECT_TRUE(p.allFinite());
}

TEST(Floater, RejectsBadArguments) {
  const TriMesh grid = make_grid(3, 3, 1.0);
  const std::vector<std::uint32_t> two{0, 1};
  const std::vector<Vec2> two_uv{{0, 0}, {1, 0}};
  EXPECT_THROW((void)floater_parametrization(grid, two, two_uv), InvalidInput);
  const std::vector<std::uint32_t> three{0, 1, 2};
  EXPECT_THROW((void)floater_parametrization(grid, three, two_uv), InvalidInput);
  const std::vector<std::uint32_t> repeated{0, 1, 1};
  const std::vector<Vec2> three_uv{{0, 0}, {1, 0}, {0, 1}};
  EXPECT_THROW((void)floater_parametrization(grid, repeated, three_uv), InvalidInput);
  const std::vector<std::uint32_t> short_loop{0, 1};
  EXPECT_THROW((void)circle_boundary(grid, short_loop), InvalidInput);
}

}  // namespace
}  // namespace gimforge
