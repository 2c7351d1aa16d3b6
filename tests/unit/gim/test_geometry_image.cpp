// Geometry images: square boundary layout (Gu et al. §3.1), sideband (§3.3), sampling and
// reconstruction (§4), and the whole conversion on procedural meshes of genus 0-3 and a disk.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "kernels/gim/cut.h"
#include "kernels/core/embree_device.h"
#include "kernels/gim/geometry_image.h"
#include "kernels/gim/gim_convert.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/procedural.h"
#include "kernels/gim/square_boundary.h"
#include "kernels/core/surface_sampling.h"
#include "kernels/core/topology.h"
#include "kernels/core/validate.h"

using namespace gimforge;

namespace {

/// A disk as its own cut mesh: the grid's boundary loop, counter-clockwise.
CutMesh grid_as_cut_mesh(std::size_t nx, std::size_t ny) {
  CutMesh cm;
  cm.disk = make_grid(nx, ny);
  for (std::uint32_t v = 0; v < cm.disk.positions.size(); ++v) cm.original_vertex.push_back(v);
  auto id = [&](std::size_t i, std::size_t j) { return static_cast<std::uint32_t>(j * (nx + 1) + i); };
  for (std::size_t i = 0; i < nx; ++i) cm.boundary.push_back(id(i, 0));
  for (std::size_t j = 0; j < ny; ++j) cm.boundary.push_back(id(nx, j));
  for (std::size_t i = nx; i > 0; --i) cm.boundary.push_back(id(i, ny));
  for (std::size_t j = ny; j > 0; --j) cm.boundary.push_back(id(0, j));
  return cm;
}

bool bitwise_equal(const float* a, const float* b) { return std::memcmp(a, b, 3 * sizeof(float)) == 0; }

/// Every glued pair of boundary samples is bit-identical.
void expect_mates_identical(const GeometryImage& gi) {
  const auto rep = boundary_classes(gi.sideband, gi.size);
  std::size_t glued = 0;
  for (std::size_t p = 0; p < rep.size(); ++p) {
    if (rep[p] == p) continue;
    ++glued;
    ASSERT_TRUE(bitwise_equal(&gi.positions[3 * p], &gi.positions[3 * rep[p]])) << "pixel " << p;
  }
  EXPECT_GT(glued, 0u);
}

void expect_watertight_at_every_level(const GeometryImage& gi, double genus) {
  for (std::uint32_t level = 0; (gi.size - 1) >> level >= gi.sideband.units_per_side; ++level) {
    const TriMesh r = reconstruct_geometry_image(gi.positions, gi.size, &gi.sideband, level);
    const TopologyReport t = analyze_topology(r);
    EXPECT_EQ(t.boundary_edges, 0u) << "level " << level;
    EXPECT_EQ(t.nonmanifold_edges, 0u) << "level " << level;
    ASSERT_EQ(t.components.size(), 1u) << "level " << level;
    EXPECT_EQ(t.components[0].genus, genus) << "level " << level;
  }
}

}  // namespace

TEST(SquareBoundary, GridBoundaryLaidOutOnThePerimeter) {
  const SquareBoundary sb = map_boundary_to_square(grid_as_cut_mesh(7, 5));
  ASSERT_EQ(sb.paths.size(), 1u);
  EXPECT_EQ(sb.paths[0].mate, -1);
  EXPECT_EQ(sb.paths[0].units, 256u);
  int corners = 0;
  for (std::size_t i = 0; i < sb.boundary.size(); ++i) {
    const Vec2& p = sb.boundary_uv[i];
    const bool on_side = p.x() == 0.0 || p.x() == 1.0 || p.y() == 0.0 || p.y() == 1.0;
    EXPECT_TRUE(on_side) << i;
    if ((p.x() == 0.0 || p.x() == 1.0) && (p.y() == 0.0 || p.y() == 1.0)) ++corners;
    if (i > 0) {
      EXPECT_GT(sb.perimeter[i], sb.perimeter[i - 1]);
    }
  }
  EXPECT_EQ(corners, 4) << "edges spanning a corner are split so that every corner is a vertex";
  // No triangle keeps all three vertices on one side.
  std::vector<double> perim(sb.disk.positions.size(), -1.0);
  for (std::size_t i = 0; i < sb.boundary.size(); ++i) perim[sb.boundary[i]] = sb.perimeter[i];
  for (const Face& f : sb.disk.faces) {
    if (perim[f[0]] < 0 || perim[f[1]] < 0 || perim[f[2]] < 0) continue;
    for (int side = 0; side < 4; ++side) {
      auto on = [&](std::uint32_t v) { return perim[v] >= 64.0 * side && perim[v] <= 64.0 * (side + 1); };
      EXPECT_FALSE(on(f[0]) && on(f[1]) && on(f[2])) << "face on side " << side;
    }
  }
}

TEST(SquareBoundary, PerimeterPoint) {
  EXPECT_EQ(perimeter_point(0, 64), Vec2(0, 0));
  EXPECT_EQ(perimeter_point(32, 64), Vec2(0.5, 0));
  EXPECT_EQ(perimeter_point(64, 64), Vec2(1, 0));
  EXPECT_EQ(perimeter_point(96, 64), Vec2(1, 0.5));
  EXPECT_EQ(perimeter_point(160, 64), Vec2(0.5, 1));
  EXPECT_EQ(perimeter_point(224, 64), Vec2(0, 0.5));
  EXPECT_EQ(perimeter_point(256, 64), Vec2(0, 0));
}

TEST(Sideband, RoundTripAndClasses) {
  Sideband sb;
  sb.units_per_side = 64;
  sb.paths = {{1, 10, 100}, {-1, 110, 100}, {0, 210, 56}};
  EXPECT_NO_THROW(sb.check());
  const auto rep = boundary_classes(sb, 65);
  // Perimeter unit 10 + t is glued to 210 - t: e.g. unit 10 (bottom row, x = 10) with unit 210 (left column).
  auto pixel_of_unit = [](std::uint32_t g) -> std::uint32_t {
    const std::uint32_t side = g / 64, s = g % 64, n = 65;
    return side == 0 ? s : side == 1 ? s * n + 64 : side == 2 ? 64 * n + (64 - s) : (64 - s) * n;
  };
  EXPECT_EQ(rep[pixel_of_unit(10)], rep[pixel_of_unit(210)]);
  EXPECT_EQ(rep[pixel_of_unit(60)], rep[pixel_of_unit(160)]);
  EXPECT_NE(rep[pixel_of_unit(220)], rep[pixel_of_unit(5)]);
  Sideband bad = sb;
  bad.paths[1].units = 99;
  EXPECT_THROW(bad.check(), InvalidInput);
}

TEST(GeometryImage, FlatDiskSampledExactly) {
  const EmbreeDevice device;
  const SquareBoundary sb = map_boundary_to_square(grid_as_cut_mesh(8, 8));
  // The identity parametrization of the unit grid: uv = xy (boundary vertices are at their own xy).
  std::vector<Vec2> uv(sb.disk.positions.size());
  for (std::size_t v = 0; v < uv.size(); ++v) uv[v] = sb.disk.positions[v].head<2>();
  const GeometryImage gi = sample_geometry_image(device, sb, uv, {65, 0, {}});
  for (std::uint32_t j = 0; j < 65; ++j)
    for (std::uint32_t i = 0; i < 65; ++i) {
      const float* p = &gi.positions[(j * 65 + i) * 3];
      ASSERT_NEAR(p[0], i / 64.0, 1e-6);
      ASSERT_NEAR(p[1], j / 64.0, 1e-6);
      ASSERT_NEAR(p[2], 0.0, 1e-6);
    }
  const TriMesh r = reconstruct_geometry_image(gi.positions, gi.size, &gi.sideband);
  EXPECT_EQ(analyze_topology(r).boundary_loops, 1u);
  EXPECT_EQ(lod_sizes(257, 64), (std::vector<std::uint32_t>{257, 129, 65}));
}

TEST(GeometryImage, ColoursAndNormalsResampled) {
  const EmbreeDevice device;
  CutMesh cm = grid_as_cut_mesh(8, 8);
  // Colour = (x, y, 0.5): linear, so interpolation reproduces it exactly at every sample.
  for (const Vec3& p : cm.disk.positions)
    cm.disk.colors.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()), 0.5f);
  const SquareBoundary sb = map_boundary_to_square(cm);
  std::vector<Vec2> uv(sb.disk.positions.size());
  for (std::size_t v = 0; v < uv.size(); ++v) uv[v] = sb.disk.positions[v].head<2>();
  const GeometryImage gi = sample_geometry_image(device, sb, uv, {65, 33, {}});
  ASSERT_EQ(gi.color_size, 65u);
  for (std::uint32_t j = 0; j < 65; j += 8)
    for (std::uint32_t i = 0; i < 65; i += 8) {
      const float* c = &gi.colors[(j * 65 + i) * 3];
      EXPECT_NEAR(c[0], i / 64.0, 1e-5);
      EXPECT_NEAR(c[1], j / 64.0, 1e-5);
      EXPECT_NEAR(c[2], 0.5, 1e-6);
    }
  ASSERT_EQ(gi.normal_size, 33u);
  for (std::size_t p = 0; p < gi.normals.size(); p += 3) ASSERT_NEAR(std::abs(gi.normals[p + 2]), 1.0, 1e-6);
}

TEST(GeometryImage, ReconstructRejectsBadLevels) {
  std::vector<float> img(65 * 65 * 3, 0.0f);
  EXPECT_THROW((void)reconstruct_geometry_image(img, 65, nullptr, 7), InvalidInput);
  EXPECT_THROW((void)reconstruct_geometry_image(img, 64, nullptr, 0), InvalidInput);
}

class GimConvert : public ::testing::TestWithParam<int> {};

TEST_P(GimConvert, ClosedSurfacesOfGenusZeroToThreeReconstructWatertight) {
  const int genus = GetParam();
  const TriMesh mesh = genus == 0 ? make_icosphere(1.0, 3) : make_slab_with_holes(genus);
  ASSERT_EQ(analyze_topology(mesh).components[0].genus, genus);
  const EmbreeDevice device;
  GimOptions opt;
  opt.image = {129, 64, {}};
  opt.max_augmentations = 2;
  const GimResult r = convert_to_geometry_image(device, mesh, opt);
  EXPECT_EQ(r.stats.stretch.flipped, 0u);
  EXPECT_GT(r.stats.stretch.efficiency, 0.0);
  expect_mates_identical(r.image);
  expect_watertight_at_every_level(r.image, genus);
  const TriMesh recon = reconstruct_geometry_image(r.image.positions, r.image.size, &r.image.sideband);
  const HausdorffResult h = symmetric_hausdorff(device, mesh, recon, {50000});
  EXPECT_LT(h.rms, 0.01 * h.diag) << "PSNR " << h.psnr;
}

INSTANTIATE_TEST_SUITE_P(Genus, GimConvert, ::testing::Values(0, 1, 2, 3));

TEST(GimConvert, DiskKeepsItsBoundary) {
  TriMesh disk = make_grid(12, 12);
  for (Vec3& p : disk.positions) p.z() = 0.2 * std::sin(3 * p.x()) * std::cos(2 * p.y());
  const EmbreeDevice device;
  GimOptions opt;
  opt.image = {65, 0, {}};
  opt.max_augmentations = 1;
  const GimResult r = convert_to_geometry_image(device, disk, opt);
  const TriMesh recon = reconstruct_geometry_image(r.image.positions, r.image.size, &r.image.sideband);
  const TopologyReport t = analyze_topology(recon);
  EXPECT_EQ(t.boundary_loops, 1u);
  EXPECT_EQ(t.nonmanifold_edges, 0u);
}

TEST(GimConvert, SeveralComponentsNameTheMultiChartMethod) {
  const EmbreeDevice device;
  const TriMesh two = concatenate(make_icosphere(1.0, 1), make_torus(4.0, 1.0, 12, 8));
  try {
    (void)convert_to_geometry_image(device, two);
    FAIL() << "no error";
  } catch (const TopologyError& e) {
    EXPECT_NE(std::string(e.what()).find("multi-chart"), std::string::npos) << e.what();
  }
}

TEST(GeometryImage, FoldsAroundCutTipsStayManifold) {
  // The square's perimeter folded in half (a closed genus-0 layout): tips at unit 1 (one unit from the
  // corner) and unit 129. Random geometry makes every diagonal choice appear somewhere.
  Sideband sb;
  sb.units_per_side = 64;
  sb.paths = {{1, 1, 128}, {-1, 129, 128}};
  sb.check();
  for (std::uint64_t trial = 0; trial < 40; ++trial) {
    std::vector<float> img(65 * 65 * 3);
    for (std::size_t k = 0; k < img.size(); ++k) img[k] = static_cast<float>(uniform01(trial, k));
    const TriMesh r = reconstruct_geometry_image(img, 65, &sb);
    const TopologyReport t = analyze_topology(r);
    ASSERT_EQ(t.boundary_edges, 0u) << "trial " << trial;
    ASSERT_EQ(t.nonmanifold_edges, 0u) << "trial " << trial;
    ASSERT_EQ(t.components.size(), 1u);
    ASSERT_EQ(t.euler_characteristic, 2) << "trial " << trial;
  }
}
