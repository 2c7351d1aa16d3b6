// Quadric decimation to a proxy (kernels/scan/decimate.h): the budget is reached, the topology and the
// orientation stay, every proxy vertex is an input vertex, locked vertices stay, bad options are refused.
#include <gtest/gtest.h>

#include <cstdint>
#include <set>
#include <vector>

#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/core/topology.h"
#include "kernels/scan/decimate.h"

namespace gimforge {
namespace {

void expect_vertices_are_input_vertices(const TriMesh& input, const DecimateResult& r) {
  ASSERT_EQ(r.source_vertex.size(), r.mesh.num_vertices());
  for (std::size_t v = 0; v < r.source_vertex.size(); ++v) {
    ASSERT_LT(r.source_vertex[v], input.num_vertices());
    EXPECT_EQ(r.mesh.positions[v], input.positions[r.source_vertex[v]]) << v;
    if (v > 0) {
      EXPECT_LT(r.source_vertex[v - 1], r.source_vertex[v]) << "input order";
    }
  }
}

TEST(Decimate, TorusKeepsGenusOrientationAndReachesTheBudget) {
  const TriMesh torus = make_torus(1.0, 0.35, 96, 48);  // 9216 faces
  DecimateOptions options;
  options.target_faces = 1000;
  const DecimateResult r = decimate_quadric(torus, options);
  EXPECT_LE(r.mesh.num_faces(), 1000u);
  EXPECT_GE(r.mesh.num_faces(), 990u);
  EXPECT_EQ(r.rejected_faces, 0u);
  const TopologyReport t = analyze_topology(r.mesh);
  EXPECT_TRUE(t.closed);
  EXPECT_TRUE(t.manifold);
  EXPECT_TRUE(t.oriented);
  ASSERT_EQ(t.components.size(), 1u);
  EXPECT_DOUBLE_EQ(t.components[0].genus, 1.0);
  EXPECT_EQ(t.referenced_vertices, r.mesh.num_vertices());
  expect_vertices_are_input_vertices(torus, r);
  // Orientation: outward normals stay outward (the face normal points away from the core circle).
  for (const Face& f : r.mesh.faces) {
    const Vec3 a = r.mesh.positions[f[0]], b = r.mesh.positions[f[1]], c = r.mesh.positions[f[2]];
    const Vec3 centre = (a + b + c) / 3.0;
    const Vec3 core = Vec3(centre.x(), centre.y(), 0.0).normalized();
    EXPECT_GT((b - a).cross(c - a).dot(centre - core), 0.0);
  }
}

TEST(Decimate, LockedVerticesStayAndTheBoundaryStaysOnTheInput) {
  const TriMesh grid = make_grid(40, 40);
  std::vector<std::uint8_t> locked(grid.num_vertices(), 0);
  // Lock the column x = 0.5 (a brick border, say).
  std::set<std::uint32_t> wanted;
  for (std::uint32_t v = 0; v < grid.num_vertices(); ++v)
    if (grid.positions[v].x() == 0.5) {
      locked[v] = 1;
      wanted.insert(v);
    }
  ASSERT_EQ(wanted.size(), 41u);
  DecimateOptions options;
  options.target_faces = 200;
  options.locked = locked;
  const DecimateResult r = decimate_quadric(grid, options);
  expect_vertices_are_input_vertices(grid, r);
  const std::set<std::uint32_t> kept(r.source_vertex.begin(), r.source_vertex.end());
  for (const std::uint32_t v : wanted) EXPECT_TRUE(kept.count(v)) << "locked vertex " << v << " was collapsed";
  const TopologyReport t = analyze_topology(r.mesh);
  EXPECT_EQ(t.boundary_loops, 1u);
  EXPECT_EQ(t.components.size(), 1u);
  // Without the lock the same budget removes most of that column.
  options.locked = {};
  const DecimateResult free = decimate_quadric(grid, options);
  std::size_t column = 0;
  for (const std::uint32_t v : free.source_vertex) column += wanted.count(v);
  EXPECT_LT(column, 41u);
}

TEST(Decimate, RefusesBadOptionsAndCountsFacesOpenMeshCannotHold) {
  const TriMesh sphere = make_icosphere(1.0, 2);
  DecimateOptions options;
  EXPECT_THROW((void)decimate_quadric(sphere, options), InvalidInput);  // target 0
  options.target_faces = 10;
  const std::vector<std::uint8_t> short_list(3, 1);
  options.locked = short_list;
  EXPECT_THROW((void)decimate_quadric(sphere, options), InvalidInput);
  options.locked = {};
  options.max_normal_turn_degrees = 0.0;
  EXPECT_THROW((void)decimate_quadric(sphere, options), InvalidInput);
  options.max_normal_turn_degrees = 60.0;
  TriMesh bad = sphere;
  bad.faces.push_back({0, 1, static_cast<std::uint32_t>(bad.num_vertices())});
  EXPECT_THROW((void)decimate_quadric(bad, options), InvalidInput);
  // A third face on an edge (non-manifold) and a repeated index: left out and counted.
  TriMesh fan = sphere;
  const Face f0 = fan.faces[0];
  fan.positions.push_back(Vec3(2.0, 2.0, 2.0));
  fan.faces.push_back({f0[0], f0[1], static_cast<std::uint32_t>(fan.num_vertices() - 1)});
  fan.faces.push_back({1, 1, 2});
  options.target_faces = 100000;  // nothing to collapse: the faces come back as they went in
  const DecimateResult r = decimate_quadric(fan, options);
  EXPECT_EQ(r.rejected_faces, 2u);
  EXPECT_EQ(r.mesh.num_faces(), sphere.num_faces());
}

}  // namespace
}  // namespace gimforge
