// Cutting any triangle mesh into an oriented 2-manifold over the same surface (kernels/core/manifold_cut.h).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "kernels/core/errors.h"
#include "kernels/core/manifold_cut.h"
#include "kernels/core/procedural.h"
#include "kernels/core/topology.h"

namespace gimforge {
namespace {

/// A closed unit cube at `o`, 12 outward faces.
TriMesh cube_at(const Vec3& o) {
  TriMesh m;
  for (int x = 0; x < 2; ++x)
    for (int y = 0; y < 2; ++y)
      for (int z = 0; z < 2; ++z) m.positions.push_back(o + Vec3(x, y, z));
  m.faces = {{0, 1, 3}, {0, 3, 2}, {4, 6, 7}, {4, 7, 5}, {0, 4, 5}, {0, 5, 1},
             {2, 3, 7}, {2, 7, 6}, {0, 2, 6}, {0, 6, 4}, {1, 5, 7}, {1, 7, 3}};
  return m;
}

/// Two cubes that share one edge (from (1,1,0) to (1,1,1)): that edge has four faces.
TriMesh two_cubes_on_an_edge() {
  TriMesh a = cube_at(Vec3::Zero());
  const TriMesh b = cube_at(Vec3(1, 1, 0));
  std::vector<std::uint32_t> index;
  for (const Vec3& p : b.positions) {
    std::uint32_t found = static_cast<std::uint32_t>(a.positions.size());
    for (std::uint32_t v = 0; v < 8; ++v)
      if (a.positions[v] == p) found = v;
    if (found == a.positions.size()) a.positions.push_back(p);
    index.push_back(found);
  }
  for (const Face& f : b.faces) a.faces.push_back({index[f[0]], index[f[1]], index[f[2]]});
  return a;
}

/// A Möbius strip of n quads around (two triangles each): not orientable.
TriMesh moebius(std::size_t n) {
  TriMesh m;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = 2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(n);
    for (const double s : {-0.3, 0.3})
      m.positions.emplace_back((1 + s * std::cos(t / 2)) * std::cos(t), (1 + s * std::cos(t / 2)) * std::sin(t), s * std::sin(t / 2));
  }
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t a = 2 * i, b = 2 * i + 1;
    // The last quad joins the first with the sides exchanged: the half twist.
    const bool last = i + 1 == n;
    const std::uint32_t c = last ? 1 : 2 * i + 2, d = last ? 0 : 2 * i + 3;
    m.faces.push_back({a, c, d});
    m.faces.push_back({a, d, b});
  }
  return m;
}

}  // namespace

TEST(ManifoldCut, AnOrientedManifoldComesBackUnchanged) {
  const TriMesh torus = make_torus(1.0, 0.3, 24, 12);
  const ManifoldCut r = cut_to_manifold(torus);
  EXPECT_FALSE(r.changed());
  EXPECT_EQ(r.mesh.faces, torus.faces);
  EXPECT_EQ(r.mesh.positions, torus.positions);
  EXPECT_EQ(r.source_vertex.size(), torus.positions.size());
}

TEST(ManifoldCut, AnEdgeOfFourFacesSeparatesTwoClosedCubes) {
  const TriMesh in = two_cubes_on_an_edge();
  ASSERT_EQ(analyze_topology(in).nonmanifold_edges, 1u);
  const ManifoldCut r = cut_to_manifold(in);
  EXPECT_EQ(r.nonmanifold_edges, 1u);
  EXPECT_EQ(r.flipped_faces, 0u);
  EXPECT_EQ(r.split_vertices, 2u);  // the shared edge's two ends, once per cube
  EXPECT_EQ(r.mesh.faces.size(), in.faces.size());
  const TopologyReport t = analyze_topology(r.mesh);
  EXPECT_TRUE(t.manifold && t.oriented && t.closed);  // each cube gets its own copy of the edge back
  EXPECT_EQ(t.components.size(), 2u);
  for (std::size_t v = 0; v < r.mesh.positions.size(); ++v) EXPECT_EQ(r.mesh.positions[v], in.positions[r.source_vertex[v]]);
}

TEST(ManifoldCut, ThreePagesOnOneSpineBecomeThreeSheets) {
  TriMesh book;
  book.positions = {{0, 0, 0}, {0, 0, 1}, {1, 0, 0}, {-1, 0, 0}, {0, 1, 0}};
  book.faces = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};  // the third page runs the spine the first page's way
  const ManifoldCut r = cut_to_manifold(book);
  EXPECT_EQ(r.nonmanifold_edges, 1u);
  const TopologyReport t = analyze_topology(r.mesh);
  EXPECT_TRUE(t.manifold && t.oriented);
  EXPECT_EQ(t.components.size(), 3u);
  EXPECT_EQ(t.boundary_edges, 9u);
}

TEST(ManifoldCut, FacesAgreeWithTheMajorityOfTheirPiece) {
  TriMesh cube = cube_at(Vec3::Zero());
  for (const std::size_t f : {1u, 4u, 9u}) std::swap(cube.faces[f][1], cube.faces[f][2]);
  ASSERT_FALSE(analyze_topology(cube).oriented);
  const ManifoldCut r = cut_to_manifold(cube);
  EXPECT_EQ(r.flipped_faces, 3u);
  EXPECT_EQ(r.mesh.faces, cube_at(Vec3::Zero()).faces);  // the three put back, the nine kept
  EXPECT_EQ(r.nonmanifold_edges + r.orientation_cuts + r.split_vertices, 0u);
  // Nine reversed of twelve: the majority is now the reversed cube, and it stays reversed.
  TriMesh inside_out = cube_at(Vec3::Zero());
  for (std::size_t f = 0; f < 9; ++f) std::swap(inside_out.faces[f][1], inside_out.faces[f][2]);
  const ManifoldCut s = cut_to_manifold(inside_out);
  EXPECT_EQ(s.flipped_faces, 3u);
  EXPECT_TRUE(analyze_topology(s.mesh).oriented);
}

TEST(ManifoldCut, AMoebiusStripIsCutWhereItsFacesCannotAgree) {
  const TriMesh strip = moebius(24);
  ASSERT_FALSE(analyze_topology(strip).orientable);
  const ManifoldCut r = cut_to_manifold(strip);
  EXPECT_EQ(r.orientation_cuts, 1u);
  const TopologyReport t = analyze_topology(r.mesh);
  EXPECT_TRUE(t.manifold && t.oriented && t.orientable);
  EXPECT_EQ(t.components.size(), 1u);
  EXPECT_EQ(t.boundary_loops, 1u);  // a disk now: the strip's one boundary and the cut, one loop
}

TEST(ManifoldCut, PinchedVerticesBecomeOneVertexPerFan) {
  // Two tetrahedra touching at a vertex.
  TriMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {-1, 0, 0}, {0, -1, 0}, {0, 0, -1}};
  m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}, {0, 4, 5}, {0, 6, 4}, {0, 5, 6}, {4, 6, 5}};
  const ManifoldCut r = cut_to_manifold(m);
  EXPECT_EQ(r.split_vertices, 1u);
  EXPECT_EQ(r.nonmanifold_edges, 0u);
  EXPECT_EQ(r.source_vertex.back(), 0u);
  const TopologyReport t = analyze_topology(r.mesh);
  EXPECT_TRUE(t.manifold && t.closed);
  EXPECT_EQ(t.components.size(), 2u);
}

TEST(ManifoldCut, RefusesFacesThatRepeatAVertex) {
  TriMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.faces = {{0, 1, 1}};
  EXPECT_THROW((void)cut_to_manifold(m), InvalidInput);
}

}  // namespace gimforge
