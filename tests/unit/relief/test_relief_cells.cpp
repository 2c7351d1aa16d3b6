// Cell classification for relief mapping (Apaza & Andújar §3.1): exact triangle-box overlap, grey / black
// / white cells, external faces, border and interior grey cells, the flood-fill and parity inside tests.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "io/mesh_io.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/relief/relief_cells.h"
#include "tests/unit/test_support.h"

namespace gimforge {
namespace {

// ---- triangle_box_overlap ----

/// Independent reference: clip the triangle by the six half-spaces of the box (Sutherland-Hodgman);
/// they overlap iff something is left.
bool overlap_by_clipping(const Vec3& bmin, const Vec3& bmax, const Vec3& a, const Vec3& b, const Vec3& c) {
  std::vector<Vec3> poly{a, b, c};
  for (int axis = 0; axis < 3; ++axis) {
    for (int side = 0; side < 2; ++side) {
      // Keep points with s(p) <= 0.
      const auto s = [&](const Vec3& p) { return side == 0 ? bmin[axis] - p[axis] : p[axis] - bmax[axis]; };
      std::vector<Vec3> out;
      for (std::size_t i = 0; i < poly.size(); ++i) {
        const Vec3& p = poly[i];
        const Vec3& q = poly[(i + 1) % poly.size()];
        const double sp = s(p), sq = s(q);
        if (sp <= 0) out.push_back(p);
        if ((sp < 0 && sq > 0) || (sp > 0 && sq < 0)) {
          Vec3 x = p + (sp / (sp - sq)) * (q - p);
          x[axis] = side == 0 ? bmin[axis] : bmax[axis];  // on the plane exactly
          out.push_back(x);
        }
      }
      poly = std::move(out);
      if (poly.empty()) return false;
    }
  }
  return true;
}

TEST(TriangleBoxOverlap, KnownCases) {
  const Vec3 lo(0, 0, 0), hi(1, 1, 1);
  // Triangle inside the box.
  EXPECT_TRUE(triangle_box_overlap(lo, hi, Vec3(0.2, 0.2, 0.2), Vec3(0.8, 0.3, 0.4), Vec3(0.5, 0.7, 0.6)));
  // Box inside the triangle's span: a huge triangle through the middle of the box.
  EXPECT_TRUE(triangle_box_overlap(lo, hi, Vec3(-10, -10, 0.5), Vec3(10, -10, 0.5), Vec3(0, 20, 0.5)));
  // Far away.
  EXPECT_FALSE(triangle_box_overlap(lo, hi, Vec3(5, 5, 5), Vec3(6, 5, 5), Vec3(5, 6, 5)));
  // Touching: a vertex on a box corner, a triangle lying in a box face, an edge along a box edge.
  EXPECT_TRUE(triangle_box_overlap(lo, hi, Vec3(1, 1, 1), Vec3(2, 1, 1), Vec3(1, 2, 3)));
  EXPECT_TRUE(triangle_box_overlap(lo, hi, Vec3(-1, -1, 1), Vec3(3, -1, 1), Vec3(0, 3, 1)));
  EXPECT_TRUE(triangle_box_overlap(lo, hi, Vec3(1, 0, 0), Vec3(1, 0, 1), Vec3(2, -1, 0.5)));
  // Just off a face.
  EXPECT_FALSE(triangle_box_overlap(lo, hi, Vec3(-1, -1, 1 + 1e-9), Vec3(3, -1, 1 + 1e-9), Vec3(0, 3, 1 + 1e-9)));
  // An edge crossing the box, all vertices outside.
  EXPECT_TRUE(triangle_box_overlap(lo, hi, Vec3(-1, 0.5, 0.5), Vec3(2, 0.5, 0.5), Vec3(0.5, 5, 5)));
  // Bounding boxes overlap and the plane cuts the box, but an edge x axis separates them: the footprint
  // x + y >= 2.1 misses the box corner (1, 1).
  EXPECT_FALSE(triangle_box_overlap(lo, hi, Vec3(1.6, 0.5, 0.5), Vec3(0.5, 1.6, 0.5), Vec3(1.6, 1.6, 0.5)));
  EXPECT_TRUE(triangle_box_overlap(lo, hi, Vec3(1.4, 0.5, 0.5), Vec3(0.5, 1.4, 0.5), Vec3(1.4, 1.4, 0.5)));
  // Plane separation only: x + y + z = 3.2 passes beyond the corner (1, 1, 1), where x + y + z = 3.
  EXPECT_FALSE(triangle_box_overlap(lo, hi, Vec3(3.2, 0, 0), Vec3(0, 3.2, 0), Vec3(0, 0, 3.2)));
  EXPECT_TRUE(triangle_box_overlap(lo, hi, Vec3(2.9, 0, 0), Vec3(0, 2.9, 0), Vec3(0, 0, 2.9)));
  EXPECT_TRUE(triangle_box_overlap(lo, hi, Vec3(3, 0, 0), Vec3(0, 3, 0), Vec3(0, 0, 3)));  // touches (1,1,1)
  // Degenerate triangles: segments and points.
  EXPECT_TRUE(triangle_box_overlap(lo, hi, Vec3(-1, 0.5, 0.5), Vec3(2, 0.5, 0.5), Vec3(2, 0.5, 0.5)));
  EXPECT_FALSE(triangle_box_overlap(lo, hi, Vec3(1.6, 0.5, 0.5), Vec3(0.5, 1.6, 0.5), Vec3(1.6, 0.5, 0.5)));
  EXPECT_TRUE(triangle_box_overlap(lo, hi, Vec3(0.5, 0.5, 0.5), Vec3(0.5, 0.5, 0.5), Vec3(0.5, 0.5, 0.5)));
  EXPECT_FALSE(triangle_box_overlap(lo, hi, Vec3(1.5, 0.5, 0.5), Vec3(1.5, 0.5, 0.5), Vec3(1.5, 0.5, 0.5)));
}

TEST(TriangleBoxOverlap, AgreesWithClippingOnRandomCases) {
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> near(-0.6, 1.6), size(0.05, 1.5), offset(-3, 3);
  int overlaps = 0, separated = 0;
  for (int t = 0; t < 100000; ++t) {
    // Boxes of random size and position; triangles near them (both outcomes frequent).
    const Vec3 bmin(offset(rng), offset(rng), offset(rng));
    const Vec3 bmax = bmin + Vec3(size(rng), size(rng), size(rng));
    const auto point = [&] {
      return Vec3(bmin.x() + near(rng) * (bmax.x() - bmin.x()), bmin.y() + near(rng) * (bmax.y() - bmin.y()),
                  bmin.z() + near(rng) * (bmax.z() - bmin.z()));
    };
    const Vec3 a = point(), b = point();
    const Vec3 c = t % 10 == 0 ? a + 0.3 * (b - a) : point();  // every tenth triangle is a segment
    const bool sat = triangle_box_overlap(bmin, bmax, a, b, c);
    const bool clip = overlap_by_clipping(bmin, bmax, a, b, c);
    ASSERT_EQ(sat, clip) << "case " << t;
    (sat ? overlaps : separated) += 1;
  }
  EXPECT_GT(overlaps, 15000);
  EXPECT_GT(separated, 15000);
}

// ---- classification ----

/// Brute force: for every cell, the faces overlapping it (bounding-box prefilter, exact test).
std::vector<std::vector<std::uint32_t>> brute_force_faces(const CellGrid& g, MeshView mesh) {
  const std::size_t ncells = g.cells.size();
  std::vector<std::vector<std::uint32_t>> faces(ncells);
  for (std::uint32_t f = 0; f < mesh.faces.size(); ++f) {
    const Vec3& a = mesh.positions[mesh.faces[f][0]];
    const Vec3& b = mesh.positions[mesh.faces[f][1]];
    const Vec3& c = mesh.positions[mesh.faces[f][2]];
    const Vec3 lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
    for (std::size_t cell = 0; cell < ncells; ++cell) {
      const Vec3 bmin = g.cell_min(cell), bmax = g.cell_max(cell);
      if ((hi.array() < bmin.array()).any() || (lo.array() > bmax.array()).any()) continue;
      if (triangle_box_overlap(bmin, bmax, a, b, c)) faces[cell].push_back(f);
    }
  }
  return faces;
}

/// External-face masks recomputed from the cell classes, per grey cell.
std::vector<std::uint8_t> expected_external_faces(const CellGrid& g) {
  std::vector<std::uint8_t> masks;
  const auto n = static_cast<int>(g.n);
  for (const std::uint32_t cell : g.grey_cells) {
    const auto c = g.coords(cell);
    std::uint8_t mask = 0;
    for (int f = 0; f < 6; ++f) {
      int q[3] = {static_cast<int>(c[0]), static_cast<int>(c[1]), static_cast<int>(c[2])};
      q[f / 2] += f % 2 ? 1 : -1;
      const bool outside_grid = q[f / 2] < 0 || q[f / 2] >= n;
      if (outside_grid || g.at(static_cast<std::uint32_t>(q[0]), static_cast<std::uint32_t>(q[1]),
                               static_cast<std::uint32_t>(q[2])) == CellClass::White)
        mask = static_cast<std::uint8_t>(mask | (1 << f));
    }
    masks.push_back(mask);
  }
  return masks;
}

/// Checks everything that must hold for any mesh: grey cells and their faces equal the brute force,
/// every face is listed, the arrays have matching sizes, external faces and border follow §3.1.
void expect_consistent(const CellGrid& g, MeshView mesh) {
  const std::size_t ncells = static_cast<std::size_t>(g.n) * g.n * g.n;
  ASSERT_EQ(g.cells.size(), ncells);
  ASSERT_EQ(g.grey_triangles.size(), g.grey_cells.size());
  ASSERT_EQ(g.external_faces.size(), g.grey_cells.size());
  ASSERT_EQ(g.border.size(), g.grey_cells.size());
  EXPECT_EQ(g.count(CellClass::Grey) + g.count(CellClass::Black) + g.count(CellClass::White), ncells);
  EXPECT_EQ(g.count(CellClass::Grey), g.grey_cells.size());
  EXPECT_TRUE(std::is_sorted(g.grey_cells.begin(), g.grey_cells.end()));

  const auto reference = brute_force_faces(g, mesh);
  std::size_t expected_grey = 0;
  for (std::size_t cell = 0; cell < ncells; ++cell) {
    const std::size_t gi = g.grey_index(cell);
    if (reference[cell].empty()) {
      EXPECT_NE(g.cells[cell], CellClass::Grey) << "cell " << cell;
      EXPECT_EQ(gi, g.grey_cells.size());
      continue;
    }
    ++expected_grey;
    ASSERT_EQ(g.cells[cell], CellClass::Grey) << "cell " << cell;
    ASSERT_LT(gi, g.grey_cells.size());
    EXPECT_EQ(g.grey_triangles[gi], reference[cell]) << "cell " << cell;
  }
  EXPECT_EQ(expected_grey, g.grey_cells.size());

  std::vector<char> listed(mesh.faces.size(), 0);
  for (const auto& faces : g.grey_triangles)
    for (const std::uint32_t f : faces) listed[f] = 1;
  EXPECT_EQ(std::count(listed.begin(), listed.end(), 1), static_cast<std::ptrdiff_t>(mesh.faces.size()));

  EXPECT_EQ(g.external_faces, expected_external_faces(g));
  for (std::size_t i = 0; i < g.grey_cells.size(); ++i) {
    EXPECT_EQ(g.border[i], g.external_faces[i] != 0 ? 1 : 0);
    EXPECT_EQ(g.domain_faces(i), g.border[i] ? g.external_faces[i] : kAllCellFaces);
  }
}

/// Distance from the origin to the nearest face plane of an icosphere (its inradius).
double inradius(const TriMesh& m) {
  double r = 1e300;
  for (const Face& f : m.faces) {
    const Vec3 &a = m.positions[f[0]], &b = m.positions[f[1]], &c = m.positions[f[2]];
    r = std::min(r, std::abs((b - a).cross(c - a).normalized().dot(a)));
  }
  return r;
}

class ReliefCellsSphere : public ::testing::TestWithParam<std::uint32_t> {};

TEST_P(ReliefCellsSphere, GreyExactBlackInsideWhiteOutside) {
  const TriMesh sphere = make_icosphere(1.0, 3);
  CellGridOptions o;
  o.n = GetParam();
  const CellGrid g = classify_cells(sphere, o);
  expect_consistent(g, sphere);
  EXPECT_TRUE(g.watertight_inside_test);
  EXPECT_NE(g.inside_method.find("OpenVDB"), std::string::npos) << g.inside_method;
  EXPECT_EQ(g.ambiguous_cells, 0u);
  const double r_in = inradius(sphere);
  std::size_t black = 0, white = 0;
  for (std::size_t cell = 0; cell < g.cells.size(); ++cell) {
    const double d = g.cell_center(cell).norm();
    if (g.cells[cell] == CellClass::Black) {
      EXPECT_LT(d, 1.0) << "black cell " << cell;
      ++black;
    } else if (g.cells[cell] == CellClass::White) {
      EXPECT_GT(d, r_in) << "white cell " << cell;
      ++white;
    }
  }
  EXPECT_GT(black, 0u);
  EXPECT_GT(white, 0u);
  // Bounding cube: centred, side (1 + padding)·2.
  EXPECT_NEAR(g.cell_size * g.n, 2.0 * (1.0 + o.padding), 1e-12);
  EXPECT_NEAR((g.origin + Vec3::Constant(0.5 * g.cell_size * g.n)).norm(), 0.0, 1e-12);

  // The parity votes agree with the flood fill cell for cell on a closed mesh without cavities.
  o.inside_test = InsideTest::ParityVotes;
  const CellGrid p = classify_cells(sphere, o);
  EXPECT_FALSE(p.watertight_inside_test);
  EXPECT_EQ(p.ambiguous_cells, 0u);
  EXPECT_EQ(p.cells, g.cells);
  EXPECT_EQ(p.external_faces, g.external_faces);
}

INSTANTIATE_TEST_SUITE_P(N, ReliefCellsSphere, ::testing::Values(8u, 16u));

TEST(ReliefCells, CubeFacesBetweenCellsAreExternalTowardsWhite) {
  // Unit cube [0,1]³, n = 7, padding 0.75: side 1.75, cell size 0.25, origin -0.375, so the cube's faces
  // run through the middle of cell layers 1 and 5; layers 0 and 6 are outside, 2..4 inside.
  const TriMesh cube = io::read_mesh(std::filesystem::path(GIMFORGE_TEST_DATA_DIR) / "cube.off");
  CellGridOptions o;
  o.n = 7;
  o.padding = 0.75;
  const CellGrid g = classify_cells(cube, o);
  ASSERT_DOUBLE_EQ(g.cell_size, 0.25);
  ASSERT_DOUBLE_EQ(g.origin.x(), -0.375);
  expect_consistent(g, cube);
  EXPECT_TRUE(g.watertight_inside_test);
  for (std::uint32_t k = 0; k < 7; ++k)
    for (std::uint32_t j = 0; j < 7; ++j)
      for (std::uint32_t i = 0; i < 7; ++i) {
        const auto in = [](std::uint32_t x, std::uint32_t lo, std::uint32_t hi) { return x >= lo && x <= hi; };
        const CellClass want = in(i, 2, 4) && in(j, 2, 4) && in(k, 2, 4)   ? CellClass::Black
                               : in(i, 1, 5) && in(j, 1, 5) && in(k, 1, 5) ? CellClass::Grey
                                                                            : CellClass::White;
        ASSERT_EQ(g.at(i, j, k), want) << i << " " << j << " " << k;
      }
  // Every grey cell is a border cell; its external faces are those towards layer 0 or 6.
  for (std::size_t gi = 0; gi < g.grey_cells.size(); ++gi) {
    const auto c = g.coords(g.grey_cells[gi]);
    std::uint8_t want = 0;
    for (int a = 0; a < 3; ++a) {
      if (c[static_cast<std::size_t>(a)] == 1) want = static_cast<std::uint8_t>(want | (1 << (2 * a)));
      if (c[static_cast<std::size_t>(a)] == 5) want = static_cast<std::uint8_t>(want | (1 << (2 * a + 1)));
    }
    EXPECT_EQ(g.external_faces[gi], want);
    EXPECT_EQ(g.border[gi], 1);
  }
  o.inside_test = InsideTest::ParityVotes;
  EXPECT_EQ(classify_cells(cube, o).cells, g.cells);
}

TEST(ReliefCells, ParityLinesThroughVerticesAndEdgesCountOnce) {
  // The unit cube with each face split into four triangles around a face vertex, placed so that parity
  // scanlines pass exactly through face vertices (all three axes) and exactly through a fan edge (x).
  // Grid as in CubeFacesBetweenCellsAreExternalTowardsWhite: n = 7, padding 0.75, origin -0.375, cell 0.25.
  const double origin = -0.375, cs = 0.25;
  const auto line_u = [&](int j) { return (origin + j * cs) + kParityLineOffsetU * cs; };
  const auto line_v = [&](int k) { return (origin + k * cs) + kParityLineOffsetV * cs; };
  TriMesh m;
  for (int z = 0; z < 2; ++z)
    for (int y = 0; y < 2; ++y)
      for (int x = 0; x < 2; ++x) m.positions.emplace_back(x, y, z);  // corner (x, y, z) = x + 2y + 4z
  // x-lines run through (y, z) = (line_u(j), line_v(k)); y-lines through (z, x); z-lines through (x, y).
  const Vec3 centre_px(1, line_u(3), line_v(3));   // x-line (3, 3) hits this vertex
  const double ey = line_u(4), ez = line_v(4);     // x-line (4, 4) hits the -x fan edge towards (y,z) = (1,1)
  const Vec3 centre_mx(0, 2 * ey - 1, 2 * ez - 1);
  const Vec3 centre_py(line_v(3), 1, line_u(2));   // y-line (2, 3)
  const Vec3 centre_my(line_v(3), 0, line_u(2));
  const Vec3 centre_pz(line_u(3), line_v(4), 1);   // z-line (3, 4)
  const Vec3 centre_mz(line_u(3), line_v(4), 0);
  // Outward quads (corner indices, counter-clockwise seen from outside) and their face vertices.
  const std::array<std::array<std::uint32_t, 4>, 6> quads{{{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                                            {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}}};
  const std::array<Vec3, 6> centres{Vec3(0.5, 0.5, 0), Vec3(0.5, 0.5, 1), centre_my, centre_py, centre_mx, centre_px};
  for (std::size_t q = 0; q < 6; ++q) {
    const auto c = static_cast<std::uint32_t>(m.positions.size());
    m.positions.push_back(q < 2 ? (q == 0 ? centre_mz : centre_pz) : centres[q]);
    for (std::size_t e = 0; e < 4; ++e) m.faces.push_back({quads[q][e], quads[q][(e + 1) % 4], c});
  }
  ASSERT_TRUE(is_closed_edge_manifold(m));
  // The -x fan edge from its face vertex to corner (0, 1, 1) passes exactly through the line point.
  EXPECT_EQ((1 - centre_mx.y()) * (ez - centre_mx.z()) - (1 - centre_mx.z()) * (ey - centre_mx.y()), 0.0);

  CellGridOptions o;
  o.n = 7;
  o.padding = 0.75;
  o.inside_test = InsideTest::ParityVotes;
  const CellGrid g = classify_cells(m, o);
  ASSERT_DOUBLE_EQ(g.origin.x(), origin);
  ASSERT_DOUBLE_EQ(g.cell_size, cs);
  EXPECT_EQ(g.ambiguous_cells, 0u);  // a line counted twice (or not at all) would split its cells' votes
  o.inside_test = InsideTest::Automatic;
  EXPECT_EQ(classify_cells(m, o).cells, g.cells);
  EXPECT_EQ(g.count(CellClass::Black), 27u);
}

TEST(ReliefCells, CubeFacesOnCellPlanesTouchBothNeighbours) {
  // Unit cube, n = 6, padding 0.5: cell size 0.25, origin -0.25; the cube's faces lie exactly on the planes
  // 0 and 1 between cell layers 0|1 and 4|5. Closed cells touching the surface are grey, so every cell but
  // the 2×2×2 block in the middle is grey, and no cell is white.
  const TriMesh cube = io::read_mesh(std::filesystem::path(GIMFORGE_TEST_DATA_DIR) / "cube.off");
  CellGridOptions o;
  o.n = 6;
  o.padding = 0.5;
  const CellGrid g = classify_cells(cube, o);
  ASSERT_DOUBLE_EQ(g.cell_size, 0.25);
  ASSERT_DOUBLE_EQ(g.origin.x(), -0.25);
  expect_consistent(g, cube);
  EXPECT_EQ(g.count(CellClass::Black), 8u);
  EXPECT_EQ(g.count(CellClass::White), 0u);
  EXPECT_EQ(g.count(CellClass::Grey), 208u);
  // Only faces on the grid boundary are external: 6³ - 4³ = 152 border cells, 56 interior grey cells.
  EXPECT_EQ(std::count(g.border.begin(), g.border.end(), 1), 152);
  EXPECT_EQ(std::count(g.border.begin(), g.border.end(), 0), 56);
  for (std::uint32_t i = 2; i <= 3; ++i) EXPECT_EQ(g.at(i, i, i), CellClass::Black);
}

TEST(ReliefCells, SingleCellHasSixExternalFaces) {
  // N = 1: the paper's case 0 (one G cell, all six faces external).
  const TriMesh sphere = make_icosphere(1.0, 2);
  CellGridOptions o;
  o.n = 1;
  const CellGrid g = classify_cells(sphere, o);
  ASSERT_EQ(g.grey_cells.size(), 1u);
  EXPECT_EQ(g.external_faces[0], kAllCellFaces);
  EXPECT_EQ(g.border[0], 1);
  EXPECT_EQ(g.domain_faces(0), kAllCellFaces);
  EXPECT_EQ(g.grey_triangles[0].size(), sphere.faces.size());
  EXPECT_EQ(g.regions, 0u);
}

TEST(ReliefCells, TorusFloodFillAndParityAgree) {
  const TriMesh torus = make_torus(1.0, 0.4, 48, 24);
  CellGridOptions o;
  o.n = 16;
  const CellGrid g = classify_cells(torus, o);
  expect_consistent(g, torus);
  EXPECT_TRUE(g.watertight_inside_test);
  EXPECT_GT(g.count(CellClass::Black), 0u);
  // The hole of the torus is outside: the cells around the z axis are white.
  EXPECT_EQ(g.at(7, 7, 7), CellClass::White);
  EXPECT_EQ(g.at(8, 8, 8), CellClass::White);
  o.inside_test = InsideTest::ParityVotes;
  const CellGrid p = classify_cells(torus, o);
  EXPECT_EQ(p.cells, g.cells);
  EXPECT_EQ(p.ambiguous_cells, 0u);
}

TEST(ReliefCells, NestedSpheresAreBothDecided) {
  // A sphere inside a sphere (both outward, closed): the exterior flood fill marks the shell
  // and the inner ball inside; the parity votes mark the shell inside and the inner ball outside. Both
  // report which they used; their grey cells are the same.
  const TriMesh outer = make_icosphere(1.0, 3);
  const TriMesh inner = make_icosphere(0.5, 3);
  const TriMesh both = concatenate(outer, inner);
  CellGridOptions o;
  o.n = 16;
  const CellGrid g = classify_cells(both, o);
  expect_consistent(g, both);
  EXPECT_TRUE(g.watertight_inside_test);
  o.inside_test = InsideTest::ParityVotes;
  const CellGrid p = classify_cells(both, o);
  EXPECT_EQ(p.grey_cells, g.grey_cells);
  const std::size_t centre = g.index(7, 7, 7);  // centre cell: inside the inner ball
  EXPECT_EQ(g.cells[centre], CellClass::Black);
  EXPECT_EQ(p.cells[centre], CellClass::White);
  // The shell between them (the cell holding x = 0.75 on the x axis) is inside for both.
  const auto shell = static_cast<std::uint32_t>(std::floor((0.75 - g.origin.x()) / g.cell_size));
  EXPECT_EQ(g.at(shell, 7, 7), CellClass::Black);
  EXPECT_EQ(p.at(shell, 7, 7), CellClass::Black);
}

TEST(ReliefCells, OpenMeshUsesTheFallbackAndSaysSo) {
  const TriMesh cathead = io::read_mesh(std::filesystem::path(GIMFORGE_TEST_DATA_DIR) / "cathead.ply");
  ASSERT_FALSE(is_closed_edge_manifold(cathead));
  CellGridOptions o;
  o.n = 16;
  const CellGrid g = classify_cells(cathead, o);
  expect_consistent(g, cathead);
  EXPECT_FALSE(g.watertight_inside_test);
  EXPECT_NE(g.inside_method.find("not watertight"), std::string::npos) << g.inside_method;
  EXPECT_GT(g.count(CellClass::White), 0u);
}

TEST(ReliefCells, OpenSquareHasNoBlackCells) {
  // A flat open sheet encloses nothing: every ray crosses it at most once, from one side only.
  const TriMesh sheet = make_grid(8, 8, 1.0);
  CellGridOptions o;
  o.n = 8;
  const CellGrid g = classify_cells(sheet, o);
  expect_consistent(g, sheet);
  EXPECT_FALSE(g.watertight_inside_test);
  EXPECT_EQ(g.count(CellClass::Black), 0u);
}

TEST(ReliefCells, ResultDoesNotDependOnThreads) {
  const TriMesh torus = make_torus(1.0, 0.3, 64, 32);
  CellGridOptions o;
  o.n = 24;
  o.inside_test = InsideTest::ParityVotes;
  const CellGrid many = classify_cells(torus, o);
  const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  const CellGrid single = classify_cells(torus, o);
  EXPECT_EQ(many.cells, single.cells);
  EXPECT_EQ(many.grey_triangles, single.grey_triangles);
  EXPECT_EQ(many.external_faces, single.external_faces);
}

TEST(ReliefCells, SharedTeapotIfPresent) {
  const std::filesystem::path path = std::filesystem::path(GIMFORGE_SHARED_MESHES_DIR) / "teapot.ply";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "no " << path;
  const TriMesh teapot = io::read_mesh(path);  // 4 components, holes, non-manifold vertices
  CellGridOptions o;
  o.n = 12;
  const CellGrid g = classify_cells(teapot, o);
  expect_consistent(g, teapot);
  EXPECT_FALSE(g.watertight_inside_test);
  EXPECT_GT(g.count(CellClass::Black), 0u);
}

TEST(ReliefCells, ProgressCanCancel) {
  const TriMesh sphere = make_icosphere(1.0, 2);
  CellGridOptions o;
  std::vector<double> seen;
  o.progress = [&](std::string_view stage, double fraction) {
    EXPECT_EQ(stage, "relief cells");
    seen.push_back(fraction);
    return true;
  };
  (void)classify_cells(sphere, o);
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back(), 1.0);
  o.progress = [](std::string_view, double) { return false; };
  EXPECT_THROW((void)classify_cells(sphere, o), Cancelled);
}

TEST(ReliefCells, RejectsBadInput) {
  const TriMesh sphere = make_icosphere(1.0, 1);
  CellGridOptions o;
  o.n = 0;
  EXPECT_NE(test::message_of<InvalidInput>([&] { (void)classify_cells(sphere, o); }).find("n = 0"), std::string::npos);
  o.n = 1025;
  EXPECT_THROW((void)classify_cells(sphere, o), InvalidInput);
  o.n = 4;
  o.padding = -0.1;
  EXPECT_THROW((void)classify_cells(sphere, o), InvalidInput);
  o.padding = 1e-3;
  EXPECT_NE(test::message_of<InvalidInput>([&] { (void)classify_cells(TriMesh{}, o); }).find("no faces"),
            std::string::npos);
  TriMesh bad = sphere;
  bad.faces[3][1] = 100000;
  EXPECT_NE(test::message_of<InvalidInput>([&] { (void)classify_cells(bad, o); }).find("face 3"), std::string::npos);
  bad = sphere;
  bad.positions[2].x() = std::nan("");
  EXPECT_THROW((void)classify_cells(bad, o), InvalidInput);
  TriMesh point;
  point.positions = {Vec3(1, 2, 3), Vec3(1, 2, 3), Vec3(1, 2, 3)};
  point.faces = {Face{0, 1, 2}};
  EXPECT_NE(test::message_of<InvalidInput>([&] { (void)classify_cells(point, o); }).find("zero extent"),
            std::string::npos);
}

TEST(IsClosedEdgeManifold, ClosedOpenAndNonManifold) {
  EXPECT_TRUE(is_closed_edge_manifold(make_icosphere(1.0, 2)));
  EXPECT_TRUE(is_closed_edge_manifold(make_torus(1.0, 0.3, 8, 6)));
  EXPECT_TRUE(is_closed_edge_manifold(concatenate(make_icosphere(1.0, 1), make_icosphere(0.5, 1))));
  EXPECT_FALSE(is_closed_edge_manifold(make_grid(3, 3)));
  TriMesh sphere = make_icosphere(1.0, 1);
  sphere.faces.pop_back();  // a hole
  EXPECT_FALSE(is_closed_edge_manifold(sphere));
  // Three faces on one edge (plus the tetrahedron they belong to): non-manifold edge.
  TriMesh fin;
  fin.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1), Vec3(0, -1, 0)};
  fin.faces = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}, {0, 1, 4}};
  EXPECT_FALSE(is_closed_edge_manifold(fin));
  fin.faces.pop_back();
  EXPECT_TRUE(is_closed_edge_manifold(fin));
  EXPECT_FALSE(is_closed_edge_manifold(TriMesh{}));
}

}  // namespace
}  // namespace gimforge
