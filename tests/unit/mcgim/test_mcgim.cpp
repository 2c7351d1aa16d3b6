// Multi-chart geometry images (Sander et al. 2003): the reconstruction rules of §3 on hand-made masks, the
// free-boundary chart parametrization, the chart rasterization, and whole conversions that must come out
// watertight (procedural closed meshes of genus 0-3 and several components).
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>

#include <gtest/gtest.h>

#include "kernels/core/edge_topology.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/procedural.h"
#include "kernels/mcgim/chart_param.h"
#include "kernels/mcgim/chart_raster.h"
#include "kernels/mcgim/chartify.h"
#include "kernels/mcgim/mcgim_convert.h"
#include "kernels/mcgim/mcgim_image.h"
#include "kernels/param/floater.h"

namespace gimforge {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

/// A W x H image whose defined samples (mask) lie at (x, y, z(x, y)), one chart, nothing unified.
MultiChartImage flat_image(std::uint32_t w, std::uint32_t h, const std::vector<std::uint8_t>& mask,
                           float (*z)(std::uint32_t, std::uint32_t) = nullptr) {
  MultiChartImage im;
  im.width = w;
  im.height = h;
  im.mask = mask;
  im.positions.assign(3 * std::size_t{w} * h, kNaN);
  im.chart.assign(std::size_t{w} * h, kNoChart);
  im.unified.assign(std::size_t{w} * h, kNoSample);
  for (std::uint32_t y = 0; y < h; ++y)
    for (std::uint32_t x = 0; x < w; ++x) {
      const std::size_t s = std::size_t{y} * w + x;
      if (!mask[s]) continue;
      im.positions[3 * s] = static_cast<float>(x);
      im.positions[3 * s + 1] = static_cast<float>(y);
      im.positions[3 * s + 2] = z ? z(x, y) : 0.0f;
      im.chart[s] = 0;
      im.unified[s] = static_cast<std::uint32_t>(s);
    }
  return im;
}

struct EdgeCounts {
  std::size_t boundary{0}, nonmanifold{0}, inconsistent{0};
};

EdgeCounts edge_counts(const TriMesh& mesh) {
  const EdgeTopology topo = build_edge_topology(mesh);
  EdgeCounts c;
  for (std::size_t e = 0; e < topo.num_edges(); ++e) {
    if (topo.valence(e) == 1) ++c.boundary;
    if (topo.valence(e) > 2) ++c.nonmanifold;
  }
  c.inconsistent = check_manifold(mesh, topo).inconsistent_edges.size();
  return c;
}

TEST(McgimReconstruct, FewerThanThreeDefinedGiveNoFaceThreeGiveOneFourGiveTwo) {
  // 2x2 quads: all four, three, two.
  EXPECT_EQ(reconstruct_multichart(flat_image(2, 2, {1, 1, 1, 1})).num_faces(), 2u);
  for (int missing = 0; missing < 4; ++missing) {
    std::vector<std::uint8_t> m{1, 1, 1, 1};
    m[static_cast<std::size_t>(missing)] = 0;
    const TriMesh t = reconstruct_multichart(flat_image(2, 2, m));
    ASSERT_EQ(t.num_faces(), 1u) << "missing " << missing;
    // Counter-clockwise in (column, row): the normal points to +z.
    const Vec3 n = (t.positions[t.faces[0][1]] - t.positions[t.faces[0][0]])
                       .cross(t.positions[t.faces[0][2]] - t.positions[t.faces[0][0]]);
    EXPECT_GT(n.z(), 0.0) << "missing " << missing;
  }
  EXPECT_EQ(reconstruct_multichart(flat_image(2, 2, {1, 1, 0, 0})).num_faces(), 0u);
  EXPECT_EQ(reconstruct_multichart(flat_image(2, 2, {1, 0, 0, 1})).num_faces(), 0u);
}

TEST(McgimReconstruct, FourDefinedSplitAlongTheShorterDiagonal) {
  // Lift sample (1,1) so that the diagonal (0,0)-(1,1) is longer than (1,0)-(0,1): the split must use the latter.
  const MultiChartImage im = flat_image(2, 2, {1, 1, 1, 1}, [](std::uint32_t x, std::uint32_t y) {
    return x == 1 && y == 1 ? 3.0f : 0.0f;
  });
  const TriMesh t = reconstruct_multichart(im);
  ASSERT_EQ(t.num_faces(), 2u);
  // Vertices in sample order: 0 = (0,0), 1 = (1,0), 2 = (0,1), 3 = (1,1). No face may hold both 0 and 3.
  for (const Face& f : t.faces) {
    const bool has0 = f[0] == 0 || f[1] == 0 || f[2] == 0, has3 = f[0] == 3 || f[1] == 3 || f[2] == 3;
    EXPECT_FALSE(has0 && has3);
  }
  // Lower it instead: now (0,0)-(1,1) is the shorter one and both faces hold it.
  const MultiChartImage flat = flat_image(2, 2, {1, 1, 1, 1}, [](std::uint32_t x, std::uint32_t y) {
    return x == 0 && y == 1 ? 3.0f : 0.0f;
  });
  for (const Face& f : reconstruct_multichart(flat).faces) {
    const bool has0 = f[0] == 0 || f[1] == 0 || f[2] == 0, has3 = f[0] == 3 || f[1] == 3 || f[2] == 3;
    EXPECT_TRUE(has0 && has3);
  }
}

TEST(McgimReconstruct, UnifiedSamplesAreOneVertexAndDegenerateFacesGo) {
  // Two 2x3 strips side by side with a gutter column; the strips' facing columns are unified pairwise, so
  // the reconstruction is one 2-row strip without a crack.
  std::vector<std::uint8_t> mask(5 * 2, 0);
  for (std::uint32_t y = 0; y < 2; ++y)
    for (std::uint32_t x : {0u, 1u, 3u, 4u}) mask[y * 5 + x] = 1;
  MultiChartImage im = flat_image(5, 2, mask);
  for (std::uint32_t y = 0; y < 2; ++y) {
    const std::size_t a = y * 5 + 1, b = y * 5 + 3;
    im.unified[b] = static_cast<std::uint32_t>(a);
    for (int c = 0; c < 3; ++c) im.positions[3 * b + static_cast<std::size_t>(c)] = im.positions[3 * a + static_cast<std::size_t>(c)];
    im.chart[y * 5 + 3] = im.chart[y * 5 + 4] = 1;
  }
  check_multichart_image(im, "test");
  const TriMesh t = reconstruct_multichart(im);
  EXPECT_EQ(t.num_vertices(), 6u);
  EXPECT_EQ(t.num_faces(), 4u);
  EXPECT_EQ(edge_counts(t).boundary, 6u);  // a 3x1 quad strip: 6 boundary edges, the zipper edge inside
  EXPECT_EQ(edge_counts(t).nonmanifold, 0u);
  // A cluster that swallows a quad's edge leaves a degenerate triangle, which is dropped.
  MultiChartImage d = flat_image(2, 2, {1, 1, 1, 0});
  d.unified[1] = 0;
  for (int c = 0; c < 3; ++c) d.positions[3 + static_cast<std::size_t>(c)] = d.positions[static_cast<std::size_t>(c)];
  EXPECT_EQ(reconstruct_multichart(d).num_faces(), 0u);
}

TEST(McgimReconstruct, PinnedQuadsTakeTheirSplitFromTheStoredBits) {
  // Four samples alone in their clusters: no quad is pinned, whatever the positions.
  EXPECT_EQ(pinned_quads(flat_image(2, 2, {1, 1, 1, 1})), std::vector<std::uint8_t>{0});
  EXPECT_TRUE(zipper_diagonal_bits(flat_image(2, 2, {1, 1, 1, 1})).empty());
  // 3 x 2, samples (0,0) and (2,0) one cluster: the pair {cluster, (1,1)} is a diagonal of both quads, so
  // both are pinned; their split then decides which faces the cluster gets.
  MultiChartImage im = flat_image(3, 2, {1, 1, 1, 1, 1, 1}, [](std::uint32_t x, std::uint32_t y) {
    return x == 1 && y == 1 ? 0.5f : 0.0f;
  });
  im.unified[2] = 0;
  for (std::size_t c = 0; c < 3; ++c) im.positions[6 + c] = im.positions[c];
  check_multichart_image(im, "test");
  EXPECT_EQ(pinned_quads(im), (std::vector<std::uint8_t>{1, 1}));
  const TriMesh shorter = reconstruct_multichart(im);
  const std::vector<std::uint8_t> bits = zipper_diagonal_bits(im);
  ASSERT_EQ(bits.size(), 1u);
  // The stored splits of the image as it is reconstruct it the same; the opposite ones differently, whatever
  // the positions say.
  MultiChartImage pinned = im;
  pinned.zipper_diagonals = bits;
  check_multichart_image(pinned, "test");
  EXPECT_EQ(reconstruct_multichart(pinned).faces, shorter.faces);
  pinned.zipper_diagonals = {static_cast<std::uint8_t>(bits[0] ^ 3u)};
  const TriMesh flipped = reconstruct_multichart(pinned);
  EXPECT_NE(flipped.faces, shorter.faces);
  pinned.zipper_diagonals = {static_cast<std::uint8_t>(bits[0] ^ 1u)};
  EXPECT_EQ(zipper_diagonal_bits(pinned), pinned.zipper_diagonals);  // the stored split is the one it reports
  // Bits for another number of pinned quads, or padding bits set, are refused.
  pinned.zipper_diagonals = {0, 0};
  EXPECT_THROW(check_multichart_image(pinned, "test"), FormatError);
  pinned.zipper_diagonals = {4};
  EXPECT_THROW(check_multichart_image(pinned, "test"), FormatError);
}

TEST(McgimReconstruct, DamagedImagesAreRefused) {
  MultiChartImage im = flat_image(3, 3, std::vector<std::uint8_t>(9, 1));
  im.positions[4] = kNaN;  // a defined sample that is not finite
  EXPECT_THROW(check_multichart_image(im, "x"), FormatError);
  im = flat_image(3, 3, std::vector<std::uint8_t>(9, 1));
  im.unified[2] = 99;  // out of range
  EXPECT_THROW(check_multichart_image(im, "x"), FormatError);
  im = flat_image(3, 3, std::vector<std::uint8_t>(9, 1));
  im.unified[2] = 0;  // unified with a sample elsewhere
  EXPECT_THROW(check_multichart_image(im, "x"), FormatError);
  im = flat_image(3, 3, std::vector<std::uint8_t>(9, 1));
  im.mask[0] = 0;  // undefined but with a position
  EXPECT_THROW(check_multichart_image(im, "x"), FormatError);
}

/// One chart: the whole mesh (a disk).
std::vector<ChartMesh> one_chart(const TriMesh& mesh) {
  return extract_charts(mesh, std::vector<std::uint32_t>(mesh.num_faces(), 0), 1);
}

TEST(McgimChartParam, FreeBoundaryMakesAFlatDiskIsometric) {
  // A flat square: Floater onto a circle distorts it (efficiency well below 1); the free boundary lets the
  // optimizer find the square again.
  const TriMesh grid = make_grid(16, 16, 1.0);
  const std::vector<ChartMesh> charts = one_chart(grid);
  const ChartMesh& c = charts.front();
  const MeshStretch floater =
      mesh_stretch(c.mesh, floater_parametrization(c.mesh, c.boundary, circle_boundary(c.mesh, c.boundary)));
  const ChartParametrization p = parametrize_charts(charts);
  EXPECT_LT(floater.efficiency, 0.95);
  EXPECT_GT(p.stretch[0].efficiency, 0.99);
  EXPECT_EQ(p.stretch[0].flipped, 0u);
  // Relative scaling normalizes the atlas to parameter area = surface area.
  EXPECT_NEAR(p.total.domain_area, p.total.surface_area, 1e-9 * p.total.surface_area);
}

/// A disk whose boundary vertex v carries 400° of faces (a ruffled fan, as a scan's jagged hole rim has):
/// any map that keeps the fan's angles winds it past 360°, so its first and last boundary edges cross in a
/// loop about as wide as the fan's edges (`fan` long).
TriMesh ruffled_rim(double fan) {
  TriMesh m;
  constexpr int kFan = 5;         // five faces around v
  const double z = 0.3397 * fan;  // alternating heights that make each face's angle at v 80°
  m.positions.push_back(Vec3(0, 0, 0));  // v
  for (int k = 0; k <= kFan; ++k) {
    const double phi = 2.0 * std::numbers::pi * k / kFan;
    m.positions.push_back(Vec3(fan * std::cos(phi), fan * std::sin(phi), k % 2 == 0 ? z : -z));
  }
  for (int k = 0; k < kFan; ++k) m.faces.push_back({0u, static_cast<std::uint32_t>(k + 1), static_cast<std::uint32_t>(k + 2)});
  return m;
}

TEST(McgimChartParam, SmallBoundaryFoldsAreKeptLargeOnesHoldTheBoundary) {
  const TriMesh rim = ruffled_rim(0.05);
  ASSERT_EQ(rim.faces.size(), 5u);
  const std::vector<ChartMesh> charts = one_chart(rim);
  // Strict: the crossing holds the boundary and asks for a split.
  const ChartParametrization strict = parametrize_charts(charts);
  EXPECT_EQ(strict.overlap_fallbacks, 1u);
  EXPECT_EQ(strict.split[0], 1);
  EXPECT_EQ(strict.small_folds, 0u);
  // A fold narrower than the tolerance is kept: the free map stays, no split.
  ChartParamOptions loose;
  loose.fold_tolerance = 1.0;
  const ChartParametrization kept = parametrize_charts(charts, loose);
  EXPECT_EQ(kept.overlap_fallbacks, 0u);
  EXPECT_EQ(kept.split[0], 0);
  EXPECT_GE(kept.small_folds, 1u);
  EXPECT_GT(kept.stretch[0].efficiency, strict.stretch[0].efficiency);
  // A tolerance below the fold's size refuses it again.
  ChartParamOptions tight;
  tight.fold_tolerance = 0.001;
  EXPECT_EQ(parametrize_charts(charts, tight).overlap_fallbacks, 1u);
}

TEST(McgimChartParam, EnlargingAChartKeepsTheTotalsTrue) {
  // Two charts (a bent grid cut in halves); chart 0 scaled by 3: its parameter area ×9, its L2 stretch /3,
  // and the totals equal those summed afresh.
  TriMesh grid = make_grid(12, 6, 1.0);
  for (Vec3& q : grid.positions) q.z() = 0.3 * q.x() * q.x();
  std::vector<std::uint32_t> face_chart(grid.faces.size());
  for (std::size_t f = 0; f < grid.faces.size(); ++f) face_chart[f] = grid.positions[grid.faces[f][0]].x() < 0.49 ? 0u : 1u;
  const std::vector<ChartMesh> charts = extract_charts(grid, face_chart, 2);
  ChartParametrization p = parametrize_charts(charts);
  const MeshStretch before = p.stretch[0];
  enlarge_chart(p, charts[0], 0, 3.0);
  EXPECT_NEAR(p.stretch[0].domain_area, 9.0 * before.domain_area, 1e-9 * p.stretch[0].domain_area);
  EXPECT_NEAR(p.stretch[0].l2, before.l2 / 3.0, 1e-9);
  double s = 0.0, d = 0.0, a = 0.0;
  for (const MeshStretch& c : p.stretch) s += c.l2 * c.l2 * c.surface_area, d += c.domain_area, a += c.surface_area;
  EXPECT_NEAR(p.total.domain_area, d, 1e-9 * d);
  EXPECT_NEAR(p.total.l2, std::sqrt(s / a), 1e-9);
  EXPECT_NEAR(p.total.efficiency, a * a / (d * s), 1e-9);
  EXPECT_LT(p.total.efficiency, 0.9) << "an enlarged chart is oversampled: the atlas's efficiency drops";
  EXPECT_THROW(enlarge_chart(p, charts[0], 2, 2.0), InvalidInput);
  EXPECT_THROW(enlarge_chart(p, charts[0], 0, 0.0), InvalidInput);
}

TEST(McgimChartParam, ChartWithoutAreaGetsAFiniteScale) {
  // Two components, one chart each; the second collapsed onto a segment (every face of zero area, as some of
  // a raw scan's charts are). Its stretch is undefined; the atlas's totals stay finite and it keeps a
  // parameter domain of the other chart's scale, so it can still be sampled.
  TriMesh mesh = make_grid(6, 6, 1.0);
  const TriMesh flat = make_grid(6, 6, 1.0);
  const auto offset = static_cast<std::uint32_t>(mesh.positions.size());
  for (const Vec3& q : flat.positions) mesh.positions.emplace_back(2.0 + q.x(), 0.0, 0.0);
  for (const Face& f : flat.faces) mesh.faces.push_back({f[0] + offset, f[1] + offset, f[2] + offset});
  std::vector<std::uint32_t> face_chart(mesh.faces.size(), 0);
  for (std::size_t f = flat.faces.size(); f < mesh.faces.size(); ++f) face_chart[f] = 1;
  const std::vector<ChartMesh> charts = extract_charts(mesh, face_chart, 2);
  const ChartParametrization p = parametrize_charts(charts);
  EXPECT_TRUE(std::isfinite(p.total.domain_area));
  EXPECT_TRUE(std::isfinite(p.total.l2));
  EXPECT_TRUE(std::isfinite(p.total.efficiency));
  EXPECT_GT(p.stretch[1].domain_area, 0.0);
  for (const Vec2& q : p.uv[1]) EXPECT_TRUE(q.allFinite());
  EXPECT_GT(p.stretch[0].efficiency, 0.99);
}

TEST(McgimRaster, ChartsComeOutAsManifoldDisksAtEveryOrientation) {
  // A thin curved strip: interior rasterization alone would break it into pieces.
  TriMesh strip = make_grid(40, 1, 1.0);
  for (Vec3& p : strip.positions) p = Vec3(std::cos(p.x() * 3.0) * 10.0, std::sin(p.x() * 3.0) * 10.0, p.y() * 0.3);
  const std::vector<ChartMesh> charts = one_chart(strip);
  const ChartParametrization p = parametrize_charts(charts);
  for (int o = 0; o < 16; ++o) {
    const ChartRaster r = rasterize_chart(charts[0], p.uv[0], o * 2.0 * 3.141592653589793 / 16, 1.3);
    ASSERT_GT(r.shape.width, 0u);
    EXPECT_TRUE(r.manifold);
    for (std::uint32_t y = 0; y < r.shape.height; ++y)
      for (std::uint32_t x = 0; x < r.shape.width; ++x)
        if (r.shape.at(x, y)) {
          EXPECT_TRUE(sample_is_manifold(r.shape.cells, r.shape.width, r.shape.height, x, y));
        }
    // One connected disk: the §3 reconstruction of the shape has one boundary loop (V - E + F = 1).
    MultiChartImage im = flat_image(r.shape.width, r.shape.height, r.shape.cells);
    const TriMesh t = reconstruct_multichart(im);
    const EdgeTopology topo = build_edge_topology(t);
    EXPECT_EQ(static_cast<long>(t.num_vertices()) - static_cast<long>(topo.num_edges()) + static_cast<long>(t.num_faces()), 1)
        << "orientation " << o;
    EXPECT_EQ(edge_counts(t).nonmanifold, 0u);
  }
}

/// Converts and checks the invariants every conversion must keep.
McgimResult convert_checked(const TriMesh& mesh, std::uint32_t charts, std::size_t samples) {
  const EmbreeDevice device;
  McgimOptions o;
  o.charts = charts;
  o.samples = samples;
  McgimResult r = convert_to_multichart(device, mesh, o);
  check_multichart_image(r.image, "result");
  EXPECT_LE(r.image.samples(), samples);
  EXPECT_LT(std::max(r.image.width, r.image.height), 4 * std::min(r.image.width, r.image.height));
  EXPECT_GT(r.stats.packing_efficiency, 0.3);
  EXPECT_GT(r.stats.stretch.efficiency, 0.6);
  return r;
}

void expect_watertight(const McgimResult& r, const TriMesh& input) {
  const TriMesh t = reconstruct_multichart(r.image);
  const EdgeCounts c = edge_counts(t);
  EXPECT_EQ(c.boundary, 0u);
  EXPECT_EQ(c.nonmanifold, 0u);
  EXPECT_EQ(c.inconsistent, 0u);
  // And close to the input.
  const EmbreeDevice device;
  HausdorffOptions h;
  h.samples = 20000;
  EXPECT_GT(symmetric_hausdorff(device, input, t, h).psnr, 40.0);
}

TEST(McgimConvert, ClosedMeshesOfGenusZeroToThreeReconstructWatertight) {
  expect_watertight(convert_checked(make_icosphere(1.0, 4), 8, 16384), make_icosphere(1.0, 4));
  const TriMesh torus = make_torus(1.0, 0.35, 48, 24);
  expect_watertight(convert_checked(torus, 12, 16384), torus);
  for (int genus : {2, 3}) {
    const TriMesh slab = make_slab_with_holes(genus, 2);
    SCOPED_TRACE(genus);
    expect_watertight(convert_checked(slab, 16, 16384), slab);
  }
}

TEST(McgimConvert, SeveralComponentsAndOneChartRequested) {
  TriMesh sphere = make_icosphere(0.5, 3);
  TriMesh torus = make_torus(1.0, 0.3, 32, 16);
  for (Vec3& p : sphere.positions) p.x() += 3.0;
  const TriMesh both = concatenate(sphere, torus);
  const McgimResult r = convert_checked(both, 1, 16384);
  EXPECT_GE(r.stats.charts, 3u);  // a sphere needs two disks, a torus more: seeds are added
  expect_watertight(r, both);
}

TEST(McgimConvert, AutoCountRule) {
  EXPECT_TRUE(auto_count_replaces(1.0, 0.98));
  EXPECT_FALSE(auto_count_replaces(1.0, 0.995));  // closer, but within the estimate's noise: fewer charts stay
  EXPECT_FALSE(auto_count_replaces(1.0, 1.2));
  EXPECT_TRUE(auto_count_replaces(std::numeric_limits<double>::infinity(), 5.0));
}

TEST(McgimConvert, AutoChartsKeepsTheCloserCountUnlessATie) {
  // --charts auto: every count is converted and measured; a later count wins only when it is closer by more
  // than 1 %. The result must be exactly the fixed-count conversion of the count the rule picks.
  const TriMesh torus = make_torus(1.0, 0.35, 48, 24);
  const EmbreeDevice device;
  McgimOptions o;
  o.samples = 8192;
  o.auto_charts = {6, 12};
  const McgimResult r = convert_to_multichart(device, torus, o);
  ASSERT_EQ(r.stats.auto_tried, (std::vector<std::uint32_t>{6, 12}));
  ASSERT_EQ(r.stats.auto_rms.size(), 2u);
  std::size_t pick = 0;
  for (std::size_t i = 1; i < 2; ++i)
    if (auto_count_replaces(r.stats.auto_rms[pick], r.stats.auto_rms[i])) pick = i;
  McgimOptions fixed = o;
  fixed.charts = o.auto_charts[pick];
  const McgimResult f = convert_to_multichart(device, torus, fixed);
  EXPECT_EQ(r.stats.charts, f.stats.charts);
  EXPECT_EQ(r.image.width, f.image.width);
  EXPECT_EQ(r.image.height, f.image.height);
  EXPECT_EQ(r.image.mask, f.image.mask);
  EXPECT_EQ(r.image.chart, f.image.chart);
  EXPECT_EQ(r.image.unified, f.image.unified);
  ASSERT_EQ(r.image.positions.size(), f.image.positions.size());
  EXPECT_EQ(std::memcmp(r.image.positions.data(), f.image.positions.data(), r.image.positions.size() * sizeof(float)), 0);
}

/// `count` small square disks (4 × 4 grids) side by side: one chart each whatever the count asked for.
TriMesh small_disks(int count) {
  TriMesh disks;
  for (int k = 0; k < count; ++k) {
    TriMesh g = make_grid(4, 4, 0.5);
    const auto base = static_cast<std::uint32_t>(disks.positions.size());
    for (const Vec3& p : g.positions) disks.positions.push_back(p + Vec3(1.5 * k, 0.3 * k, 0.1 * (k % 2)));
    for (const Face& f : g.faces) disks.faces.push_back({f[0] + base, f[1] + base, f[2] + base});
  }
  return disks;
}

/// --charts auto trying 2 and 4 charts within `samples`.
McgimOptions auto_counts_2_and_4(std::size_t samples) {
  McgimOptions o;
  o.samples = samples;
  o.auto_charts = {2, 4};
  return o;
}

TEST(McgimConvert, AutoChartsConvertsARepeatedChartificationOnce) {
  // Six small disks: each count asks for fewer charts than there are components, so both chartifications
  // are one chart per component. The second count is not converted again; its figure is the first's and
  // the result is the fixed-count conversion's.
  const TriMesh disks = small_disks(6);
  const EmbreeDevice device;
  const McgimOptions o = auto_counts_2_and_4(4096);
  const McgimResult r = convert_to_multichart(device, disks, o);
  ASSERT_EQ(r.stats.auto_tried, (std::vector<std::uint32_t>{2, 4}));
  ASSERT_EQ(r.stats.auto_rms.size(), 2u);
  EXPECT_EQ(r.stats.auto_rms[0], r.stats.auto_rms[1]);
  EXPECT_EQ(r.stats.auto_same_as, (std::vector<std::uint32_t>{0, 2}));  // 4 repeated 2's charts
  McgimOptions fixed = o;
  fixed.charts = 2;
  const McgimResult f = convert_to_multichart(device, disks, fixed);
  EXPECT_EQ(r.stats.charts, 6u);
  EXPECT_EQ(r.image.mask, f.image.mask);
  EXPECT_EQ(r.image.chart, f.image.chart);
  ASSERT_EQ(r.image.positions.size(), f.image.positions.size());
  EXPECT_EQ(std::memcmp(r.image.positions.data(), f.image.positions.data(), r.image.positions.size() * sizeof(float)), 0);
}

TEST(McgimConvert, AutoChartsDoesNotRetryARepeatedChartificationThatFailed) {
  // Forty small disks in 256 samples: every count gives one chart per component, which cannot be packed.
  // The second count's chartification is the first's; it is named in the error, not packed again.
  const TriMesh disks = small_disks(40);
  const EmbreeDevice device;
  const McgimOptions o = auto_counts_2_and_4(256);
  try {
    (void)convert_to_multichart(device, disks, o);
    FAIL() << "40 charts packed into 256 samples";
  } catch (const NumericalError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("2 charts: 40 charts cannot be packed"), std::string::npos) << what;
    EXPECT_NE(what.find("; 4 charts: the same charts as 2)"), std::string::npos) << what;
    EXPECT_EQ(what.find("pack_charts"), what.rfind("pack_charts")) << "packed twice: " << what;
  }
}

TEST(McgimConvert, ASliverStripStartsPackingWhereItFits) {
  // A 1 × 10⁻⁷ strip: the area-based scale makes it ~10⁵ samples long, 800 times the longest side of any
  // rectangle of 4,096 samples. The packer starts where it fits instead of rasterizing ~10¹⁰-cell shapes at
  // every step above (which ran out of memory after minutes).
  TriMesh strip;
  for (int i = 0; i <= 49; ++i) {
    strip.positions.emplace_back(i / 49.0, 0.0, 0.0);
    strip.positions.emplace_back(i / 49.0, 1e-7, 0.0);
  }
  for (std::uint32_t i = 0; i < 49; ++i) {
    strip.faces.push_back({2 * i, 2 * i + 2, 2 * i + 3});
    strip.faces.push_back({2 * i, 2 * i + 3, 2 * i + 1});
  }
  const EmbreeDevice device;
  McgimOptions o;
  o.charts = 4;
  o.samples = 4096;
  const McgimResult r = convert_to_multichart(device, strip, o);
  check_multichart_image(r.image, "strip");
  EXPECT_LE(r.image.samples(), 4096u);
  EXPECT_GT(r.stats.scale_steps, 600);  // the steps skipped still count from the area-based scale
}

TEST(McgimConvert, ChartsThatSampleToNoAreaAreRefusedSayingWhatHelps) {
  // One triangle 1 × 10⁻³: at 4,096 samples its apex falls between samples and the image's samples are
  // collinear, an image without area (the fidelity report then failed with "the surface has no area to sample
  // (largest face area 0, 251 faces)", which named neither the cause nor the cure).
  TriMesh sliver;
  sliver.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.5, 1e-3, 0)};
  sliver.faces = {{0, 1, 2}};
  const EmbreeDevice device;
  McgimOptions o;
  o.charts = 8;
  o.samples = 4096;
  try {
    (void)convert_to_multichart(device, sliver, o);
    FAIL() << "a sliver thinner than a sample gave an image";
  } catch (const NumericalError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("the image has no surface area: its chart is thinner than the sampling step of its"),
              std::string::npos) << what;
    EXPECT_NE(what.find("(--samples 4096); a larger --samples or fewer --charts helps"), std::string::npos) << what;
  }
}

TEST(McgimConvert, BadInputIsRefused) {
  const EmbreeDevice device;
  McgimOptions o;
  o.charts = 4;
  o.samples = 10;
  EXPECT_THROW((void)convert_to_multichart(device, make_icosphere(1.0, 2), o), InvalidInput);
  o.samples = 4096;
  EXPECT_THROW((void)convert_to_multichart(device, TriMesh{}, o), InvalidInput);
}

TEST(McgimConvert, AnEdgeOfThreeFacesIsCutIntoThreeSheets) {
  const EmbreeDevice device;
  McgimOptions o;
  o.charts = 3;
  o.samples = 1024;
  TriMesh fin;
  fin.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(0, 0, 1)};
  fin.faces = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  const McgimResult r = convert_to_multichart(device, fin, o);
  EXPECT_EQ(r.stats.cut_nonmanifold_edges, 1u);
  EXPECT_EQ(r.stats.charts, 3u);
  const TriMesh back = reconstruct_multichart(r.image);
  EXPECT_EQ(edge_counts(back).nonmanifold, 0u);
  EXPECT_EQ(edge_counts(back).inconsistent, 0u);
}

}  // namespace
}  // namespace gimforge
