#include <gtest/gtest.h>

#include <limits>

#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/core/topology.h"
#include "kernels/core/validate.h"

using namespace gimforge;

namespace {
TriMesh two_triangles() {
  TriMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  m.faces = {{0, 1, 2}, {0, 2, 3}};
  return m;
}
}  // namespace

TEST(Validate, CleanMeshesHaveNoDefects) {
  EXPECT_TRUE(validate_mesh(make_icosphere(1.0, 2)).clean());
  EXPECT_TRUE(validate_mesh(make_torus(2, 1, 12, 8)).clean());
  EXPECT_TRUE(validate_mesh(make_grid(3, 3)).clean());
}

TEST(Validate, IndexOutOfRangeIsFatalAndSkipsTopology) {
  TriMesh m = two_triangles();
  m.faces.push_back({0, 2, 9});
  const auto r = validate_mesh(m);
  EXPECT_EQ(r.count(DefectKind::IndexOutOfRange), 1u);
  EXPECT_TRUE(r.has(Severity::Fatal));
  EXPECT_TRUE(r.topology_skipped);
  EXPECT_NE(r.first(Severity::Fatal)->message.find("face 2 references vertex 9"), std::string::npos);
}

TEST(Validate, NonFiniteIsFatal) {
  TriMesh m = two_triangles();
  m.positions[2].y() = std::numeric_limits<double>::quiet_NaN();
  const auto r = validate_mesh(m);
  EXPECT_EQ(r.count(DefectKind::NonFiniteCoordinate), 1u);
  EXPECT_EQ(r.first(Severity::Fatal)->kind, DefectKind::NonFiniteCoordinate);
}

TEST(Validate, NoFacesIsFatal) {
  TriMesh m;
  m.positions = {{0, 0, 0}};
  EXPECT_EQ(validate_mesh(m).count(DefectKind::NoFaces), 1u);
}

TEST(Validate, RepairableDefectsAreCountedAndRepaired) {
  TriMesh m = two_triangles();
  m.positions.push_back({5, 5, 5});  // unreferenced
  m.faces.push_back({2, 0, 1});      // duplicate of face 0 (rotated)
  m.faces.push_back({1, 1, 3});      // degenerate
  m.colors.assign(m.positions.size(), Vec3f(0.5f, 0.25f, 1.0f));
  m.colors[3] = Vec3f(0.1f, 0.2f, 0.3f);
  const auto r = validate_mesh(m);
  EXPECT_EQ(r.count(DefectKind::UnreferencedVertex), 1u);
  EXPECT_EQ(r.count(DefectKind::DuplicateFace), 1u);
  EXPECT_EQ(r.count(DefectKind::DegenerateFace), 1u);
  EXPECT_FALSE(r.has(Severity::Fatal));
  EXPECT_FALSE(r.has(Severity::Topological)) << "degenerate and duplicate faces must not look non-manifold";

  const RepairReport rep = repair_mesh(m);
  EXPECT_EQ(rep.removed_unreferenced_vertices, 1u);
  EXPECT_EQ(rep.removed_duplicate_faces, 1u);
  EXPECT_EQ(rep.removed_degenerate_faces, 1u);
  EXPECT_EQ(m.num_faces(), 2u);
  EXPECT_EQ(m.num_vertices(), 4u);
  EXPECT_EQ(m.colors.size(), 4u);
  EXPECT_EQ(m.colors[3], Vec3f(0.1f, 0.2f, 0.3f));
  EXPECT_TRUE(validate_mesh(m).clean());
}

TEST(Validate, RepairRemapsIndices) {
  TriMesh m;
  m.positions = {{9, 9, 9}, {0, 0, 0}, {8, 8, 8}, {1, 0, 0}, {0, 1, 0}};
  m.faces = {{1, 3, 4}};
  (void)repair_mesh(m);
  ASSERT_EQ(m.num_vertices(), 3u);
  EXPECT_EQ(m.faces[0], (Face{0, 1, 2}));
  EXPECT_EQ(m.positions[1], Vec3(1, 0, 0));
}

TEST(Validate, NonManifoldFan) {
  // Three triangles sharing the edge 0-1.
  TriMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}};
  m.faces = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  const auto r = validate_mesh(m);
  EXPECT_EQ(r.count(DefectKind::NonManifoldEdge), 1u);
  EXPECT_TRUE(r.has(Severity::Topological));
  EXPECT_NE(r.first(Severity::Topological)->message.find("vertices 0-1, 3 faces"), std::string::npos);
}

TEST(Validate, NonManifoldVertexOfTwoConesTouchingAtTheirTips) {
  TriMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 1}, {0, 1, 1}, {-1, -1, 1}, {1, 0, -1}, {0, 1, -1}, {-1, -1, -1}};
  m.faces = {{0, 1, 2}, {0, 2, 3}, {0, 3, 1}, {0, 5, 4}, {0, 6, 5}, {0, 4, 6}};
  const auto r = validate_mesh(m);
  EXPECT_EQ(r.count(DefectKind::NonManifoldEdge), 0u);
  EXPECT_EQ(r.count(DefectKind::NonManifoldVertex), 1u);
}

TEST(Validate, InconsistentOrientation) {
  TriMesh m = two_triangles();
  m.faces[1] = {0, 3, 2};  // traverses edge 0-2 in the same direction as face 0
  const auto r = validate_mesh(m);
  EXPECT_EQ(r.count(DefectKind::InconsistentOrientation), 1u);
}

TEST(Validate, ZeroAreaAndDuplicatePositionsAreInfo) {
  TriMesh m = two_triangles();
  m.positions.push_back({2, 0, 0});
  m.positions.push_back({1, 1, 0});  // same position as vertex 2
  m.faces.push_back({0, 1, 4});      // collinear: zero area
  m.faces.push_back({1, 5, 3});
  const auto r = validate_mesh(m);
  EXPECT_EQ(r.count(DefectKind::ZeroAreaFace), 1u);
  EXPECT_EQ(r.count(DefectKind::DuplicatePosition), 1u);
  EXPECT_FALSE(r.has(Severity::Fatal));
  EXPECT_FALSE(r.has(Severity::Repairable));
}

TEST(Validate, WeldPositionsJoinsASoupIntoOneSurface) {
  // A torus as a soup (three vertices of its own per face, -0 and +0 both present): welding gives the
  // torus's topology back, and a face whose corners collapse onto one position is left for repair_mesh.
  const TriMesh torus = make_torus(1.0, 0.4, 12, 6);
  TriMesh soup;
  for (const Face& f : torus.faces) {
    const auto base = static_cast<std::uint32_t>(soup.positions.size());
    for (const std::uint32_t v : f) soup.positions.push_back(torus.positions[v]);
    soup.faces.push_back({base, base + 1, base + 2});
  }
  std::size_t negative_zeros = 0;
  for (std::size_t v = 0; v < soup.positions.size(); v += 2)
    if (soup.positions[v].z() == 0.0) soup.positions[v].z() = -0.0, ++negative_zeros;
  ASSERT_GT(negative_zeros, 0u);
  soup.positions.push_back(torus.positions[0]);  // a sliver whose three corners are one position
  soup.positions.push_back(torus.positions[0]);
  soup.faces.push_back({0, static_cast<std::uint32_t>(soup.positions.size() - 2),
                        static_cast<std::uint32_t>(soup.positions.size() - 1)});
  EXPECT_EQ(analyze_topology(soup).components.size(), torus.faces.size());  // the sliver shares vertex 0
  EXPECT_EQ(weld_positions(soup), soup.positions.size() - torus.positions.size());
  const RepairReport r = repair_mesh(soup);
  EXPECT_EQ(r.removed_degenerate_faces, 1u);
  EXPECT_EQ(soup.num_vertices(), torus.num_vertices());
  ASSERT_EQ(soup.num_faces(), torus.num_faces());
  const TopologyReport t = analyze_topology(soup);
  EXPECT_EQ(t.components.size(), 1u);
  EXPECT_TRUE(t.closed);
  EXPECT_EQ(t.components[0].genus, 1.0);
  TriMesh bad = two_triangles();
  bad.faces.push_back({0, 1, 9});
  EXPECT_THROW((void)weld_positions(bad), InvalidInput);
}

TEST(Validate, RepairRejectsOutOfRange) {
  TriMesh m = two_triangles();
  m.faces.push_back({0, 1, 7});
  EXPECT_THROW((void)repair_mesh(m), InvalidInput);
}

TEST(Validate, IncompleteChecksFindOnlyFatalDefectsAndRepairKeepsDuplicates) {
  TriMesh m = two_triangles();
  m.positions.push_back({5, 5, 5});  // unreferenced
  m.faces.push_back({2, 0, 1});      // duplicate of face 0
  m.faces.push_back({1, 1, 3});      // degenerate
  m.faces.push_back({0, 1, 3});      // a third face on edge 0-1... with face 0 and the duplicate
  ValidateOptions fast;
  fast.complete = false;
  const auto r = validate_mesh(m, fast);
  EXPECT_TRUE(r.clean());  // nothing fatal; the repairable and topological defects are not sought
  EXPECT_TRUE(r.topology_skipped);
  EXPECT_FALSE(validate_mesh(m).clean());
  TriMesh bad = m;
  bad.positions[0].x() = std::numeric_limits<double>::infinity();
  EXPECT_EQ(validate_mesh(bad, fast).count(DefectKind::NonFiniteCoordinate), 1u);
  const RepairReport rep = repair_mesh(m, false);
  EXPECT_EQ(rep.removed_degenerate_faces, 1u);
  EXPECT_EQ(rep.removed_duplicate_faces, 0u);
  EXPECT_EQ(rep.removed_unreferenced_vertices, 1u);
  EXPECT_EQ(m.num_faces(), 4u);
}
