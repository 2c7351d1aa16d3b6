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

TEST(ManifoldCut, ThreePagesOnOneSpineKeepOneSheetAndCutTheThird) {
  // No page belongs to another's piece; of what is left, the two of opposite directions make one sheet.
  TriMesh book;
  book.positions = {{0, 0, 0}, {0, 0, 1}, {1, 0, 0}, {-1, 0, 0}, {0, 1, 0}};
  book.faces = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};  // the third page runs the spine the first page's way
  const ManifoldCut r = cut_to_manifold(book);
  EXPECT_EQ(r.nonmanifold_edges, 1u);
  const TopologyReport t = analyze_topology(r.mesh);
  EXPECT_TRUE(t.manifold && t.oriented);
  EXPECT_EQ(t.components.size(), 2u);  // two pages of opposite directions are one sheet
  EXPECT_EQ(t.boundary_edges, 7u);
  EXPECT_EQ(sheet_pairs(book, build_edge_topology(book)).size(), 1u);
}

TEST(ManifoldCut, BoxesSharingALineOfEdgesStayClosed) {
  // Two subdivided boxes sharing a line of three edges: every vertex inside the line has both of its line
  // edges non-manifold. Each box's faces there pair into its own sheet, so both stay closed.
  TriMesh a;
  const auto box = [&](const Vec3& o) {
    // a 1 x 1 x 3 box from o, its long edges split in three: 4 rings of 4 vertices, closed with two caps
    const std::uint32_t first = static_cast<std::uint32_t>(a.positions.size());
    for (int k = 0; k < 4; ++k)
      for (const Vec3& c : {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)}) a.positions.push_back(o + c + Vec3(0, 0, k));
    for (std::uint32_t k = 0; k < 3; ++k)
      for (std::uint32_t i = 0; i < 4; ++i) {
        const std::uint32_t p = first + 4 * k + i, q = first + 4 * k + (i + 1) % 4;
        a.faces.push_back({p, q, q + 4});
        a.faces.push_back({p, q + 4, p + 4});
      }
    a.faces.push_back({first, first + 2, first + 1});
    a.faces.push_back({first, first + 3, first + 2});
    a.faces.push_back({first + 12, first + 13, first + 14});
    a.faces.push_back({first + 12, first + 14, first + 15});
  };
  box(Vec3::Zero());
  box(Vec3(1, 1, 0));  // its corner line (1,1,z) is the first box's
  // Weld the shared line: the second box's ring corner 0 is the first box's ring corner 2.
  for (Face& f : a.faces)
    for (std::uint32_t& v : f)
      if (v >= 16 && (v - 16) % 4 == 0) v = (v - 16) + 2;
  ASSERT_EQ(analyze_topology(a).nonmanifold_edges, 3u);
  const ManifoldCut r = cut_to_manifold(a);
  const TopologyReport t = analyze_topology(r.mesh);
  EXPECT_TRUE(t.manifold && t.oriented && t.closed);
  EXPECT_EQ(t.components.size(), 2u);
  EXPECT_EQ(t.boundary_edges, 0u);
}

TEST(ManifoldCut, FacesAgreeWithTheMajorityOfTheirPiece) {
  TriMesh cube = cube_at(Vec3::Zero());
  for (const std::size_t f : {1u, 4u, 9u}) std::swap(cube.faces[f][1], cube.faces[f][2]);
  ASSERT_FALSE(analyze_topology(cube).oriented);
  const ManifoldCut r = cut_to_manifold(cube);
  EXPECT_EQ(r.flipped_faces, 3u);
  EXPECT_EQ(r.mesh.faces, cube_at(Vec3::Zero()).faces);  // the three put back, the nine kept
  EXPECT_EQ(r.nonmanifold_edges + r.orientation_cuts + r.split_vertices, 0u);
  // A cube whose faces all point in agrees with itself (the cavity of a solid, say): it is left alone.
  TriMesh cavity = cube_at(Vec3::Zero());
  for (Face& f : cavity.faces) std::swap(f[1], f[2]);
  EXPECT_FALSE(cut_to_manifold(cavity).changed());
  // Nine reversed of twelve: a closed piece that needs mending is turned to enclose a positive volume.
  TriMesh inside_out = cube_at(Vec3::Zero());
  for (std::size_t f = 0; f < 9; ++f) std::swap(inside_out.faces[f][1], inside_out.faces[f][2]);
  const ManifoldCut s = cut_to_manifold(inside_out);
  EXPECT_EQ(s.flipped_faces, 9u);
  EXPECT_EQ(s.mesh.faces, cube_at(Vec3::Zero()).faces);
  // An open piece keeps its majority: a grid with 3 of its 12 faces reversed gets those 3 back.
  TriMesh grid = make_grid(3, 2);
  const TriMesh straight = grid;
  for (const std::size_t f : {0u, 3u, 5u}) std::swap(grid.faces[f][1], grid.faces[f][2]);
  const ManifoldCut g = cut_to_manifold(grid);
  EXPECT_EQ(g.flipped_faces, 3u);
  EXPECT_EQ(g.mesh.faces, straight.faces);
  // Stored vertex normals decide over the majority: normals along -z turn the grid the other way.
  grid.normals.assign(grid.positions.size(), Vec3f(0.0f, 0.0f, -1.0f));
  const ManifoldCut n = cut_to_manifold(grid);
  EXPECT_EQ(n.flipped_faces, 9u);
  for (std::size_t f = 0; f < straight.faces.size(); ++f) EXPECT_EQ(n.mesh.faces[f][1], straight.faces[f][2]) << f;
}

TEST(ManifoldCut, TheCountIsTheInputsNonManifoldEdges) {
  // Two cubes sharing an edge: one edge of four faces, counted once (a later pass that cut the same input
  // edges again, where sheets met around a vertex, used to add them a second time).
  TriMesh a = concatenate(cube_at(Vec3::Zero()), cube_at(Vec3(1, 1, 0)));
  for (Face& f : a.faces)
    for (std::uint32_t& v : f)
      if (v == 8) v = 6;  // the second cube's (1,1,0) and (1,1,1) are the first's
      else if (v == 9) v = 7;
  ASSERT_EQ(analyze_topology(a).nonmanifold_edges, 1u);
  EXPECT_EQ(cut_to_manifold(a).nonmanifold_edges, 1u);
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
