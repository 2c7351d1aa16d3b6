// Hierarchical stretch optimization: bijective, fixed boundary, better than Floater, deterministic.
#include <gtest/gtest.h>

#include <cstdio>
#include <vector>

#include "kernels/core/errors.h"
#include "kernels/param/floater.h"
#include "kernels/core/procedural.h"
#include "kernels/param/progressive_mesh.h"
#include "kernels/param/stretch_optimizer.h"
#include "param_test_meshes.h"

namespace gimforge {
namespace {

/// A disk with its boundary fixed and a Floater starting parametrization.
struct DiskProblem {
  TriMesh mesh;
  std::vector<Vec2> uv;
  std::vector<char> fixed;
};

DiskProblem make_problem(TriMesh mesh, const std::vector<std::uint32_t>& loop, const std::vector<Vec2>& boundary) {
  DiskProblem p{std::move(mesh), {}, {}};
  p.uv = floater_parametrization(p.mesh, loop, boundary);
  p.fixed.assign(p.mesh.positions.size(), 0);
  for (std::uint32_t v : loop) p.fixed[v] = 1;
  return p;
}

DiskProblem bumpy_square_problem() {
  TriMesh mesh = test::make_bumpy_grid(24);
  const std::vector<std::uint32_t> loop = test::boundary_loop(mesh);
  const std::vector<Vec2> square = test::square_boundary(mesh, loop, test::grid_corners(mesh, loop));
  return make_problem(std::move(mesh), loop, square);
}

DiskProblem hemisphere_problem() {
  TriMesh mesh = test::make_hemisphere(4);
  const std::vector<std::uint32_t> loop = test::boundary_loop(mesh);
  const std::vector<Vec2> circle = circle_boundary(mesh, loop);
  return make_problem(std::move(mesh), loop, circle);
}

void expect_improved(const DiskProblem& p, const char* name) {
  StretchOptimizerOptions options;
  options.base_vertices = 16;
  const StretchOptimizerResult r = optimize_stretch(p.mesh, p.uv, p.fixed, options);
  ASSERT_EQ(r.uv.size(), p.uv.size());
  EXPECT_EQ(test::count_flipped(p.mesh, r.uv), 0u);
  EXPECT_EQ(r.final.flipped, 0u);
  for (std::size_t v = 0; v < p.uv.size(); ++v)
    if (p.fixed[v]) {
      EXPECT_EQ(r.uv[v], p.uv[v]) << "fixed vertex " << v << " moved";
    }
  EXPECT_LT(r.final.l2, r.initial.l2);
  EXPECT_GT(r.final.efficiency, r.initial.efficiency);
  EXPECT_GT(r.vertex_splits, 0u);
  EXPECT_LE(r.base_free_vertices, 16u);
  const MeshStretch check = mesh_stretch(p.mesh, r.uv);
  EXPECT_DOUBLE_EQ(check.l2, r.final.l2);
  std::printf("[ stretch  ] %s: %zu faces, efficiency Floater %.4f -> optimized %.4f (L2 %.4f -> %.4f)\n", name,
              p.mesh.faces.size(), r.initial.efficiency, r.final.efficiency, r.initial.l2, r.final.l2);
}

TEST(StretchOptimizer, ImprovesBumpyDiskOnSquare) { expect_improved(bumpy_square_problem(), "bumpy disk / square"); }

TEST(StretchOptimizer, ImprovesHemisphereOnCircle) { expect_improved(hemisphere_problem(), "hemisphere / circle"); }

TEST(StretchOptimizer, KeepsIsometricGrid) {
  const TriMesh grid = make_grid(12, 12, 1.0);
  const std::vector<std::uint32_t> loop = test::boundary_loop(grid);
  std::vector<Vec2> uv;
  for (const Vec3& q : grid.positions) uv.push_back(q.head<2>());
  std::vector<char> fixed(grid.positions.size(), 0);
  for (std::uint32_t v : loop) fixed[v] = 1;
  const StretchOptimizerResult r = optimize_stretch(grid, uv, fixed);
  EXPECT_NEAR(r.final.efficiency, 1.0, 1e-6);
  EXPECT_EQ(r.final.flipped, 0u);
}

TEST(StretchOptimizer, DeterministicForFixedSeed) {
  const DiskProblem p = bumpy_square_problem();
  StretchOptimizerOptions options;
  options.seed = 7;
  const StretchOptimizerResult a = optimize_stretch(p.mesh, p.uv, p.fixed, options);
  const StretchOptimizerResult b = optimize_stretch(p.mesh, p.uv, p.fixed, options);
  EXPECT_EQ(a.uv, b.uv);
}

TEST(StretchOptimizer, ReportsProgressAndCancels) {
  const DiskProblem p = hemisphere_problem();
  StretchOptimizerOptions options;
  bool saw_refine = false;
  options.progress = [&](std::string_view stage, double) {
    saw_refine = saw_refine || stage == "refine";
    return stage != "sweep";
  };
  EXPECT_THROW((void)optimize_stretch(p.mesh, p.uv, p.fixed, options), Cancelled);
  EXPECT_TRUE(saw_refine);
}

TEST(StretchOptimizer, RejectsBadInput) {
  DiskProblem p = hemisphere_problem();
  std::vector<char> short_fixed(3, 0);
  EXPECT_THROW((void)optimize_stretch(p.mesh, p.uv, short_fixed), InvalidInput);
  std::swap(p.uv[p.mesh.faces[0][0]], p.uv[p.mesh.faces[0][1]]);  // flips triangles
  EXPECT_THROW((void)optimize_stretch(p.mesh, p.uv, p.fixed), InvalidInput);
}

TEST(ProgressiveMesh, SplitsRestoreTheMesh) {
  const TriMesh mesh = test::make_hemisphere(3);
  std::vector<char> locked(mesh.positions.size(), 0);
  for (std::uint32_t v : test::boundary_loop(mesh)) locked[v] = 1;
  ProgressiveMesh pm(mesh, locked);
  const std::size_t free_before = pm.alive_free_vertices();
  const std::size_t collapses = pm.simplify(5);
  EXPECT_EQ(pm.alive_free_vertices(), free_before - collapses);
  EXPECT_LE(pm.alive_free_vertices(), 5u);
  for (std::uint32_t v = 0; v < mesh.positions.size(); ++v)
    if (locked[v]) {
      EXPECT_TRUE(pm.vertex_alive(v));
    }
  while (pm.pending_splits() > 0) (void)pm.split();
  EXPECT_EQ(pm.alive_faces(), mesh.faces);
  EXPECT_EQ(pm.alive_free_vertices(), free_before);
}

}  // namespace
}  // namespace gimforge
