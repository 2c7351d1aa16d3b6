// Region-of-interest enhancement of adaptive geometry images (kernels/adaptive/roi.h, §4): the masks from
// pictures, vertices and the normal image, the enhancement of the ROI's samples, and the ROI mode of the
// sample adjustment.
#include <gtest/gtest.h>

#include <cmath>

#include "kernels/adaptive/roi.h"
#include "kernels/adaptive/sample_adjust.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/core/topology.h"
#include "kernels/gim/gim_convert.h"

using namespace gimforge;

namespace {

double cross2(const Vec2& o, const Vec2& a, const Vec2& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

/// A mask of the box [lo, hi] of the square.
RoiMask box_mask(const Vec2& lo, const Vec2& hi, std::uint32_t size) {
  RoiMask m{size, std::vector<std::uint8_t>(std::size_t{size} * size, 0)};
  for (std::uint32_t j = 0; j < size; ++j)
    for (std::uint32_t i = 0; i < size; ++i) {
      const Vec2 p((i + 0.5) / size, (j + 0.5) / size);
      m.inside[std::size_t{j} * size + i] = (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all();
    }
  return m;
}

/// A flat unit square meshed as a grid with a bump of height 0.2 around (0.75, 0.25): its parameter points
/// are its x, y.
struct Bumped {
  TriMesh mesh = make_grid(48, 48, 1.0);
  std::vector<Vec2> uv;
  Bumped() {
    for (Vec3& p : mesh.positions) {
      uv.emplace_back(p.x(), p.y());
      p.z() = 0.2 * std::exp(-150.0 * (std::pow(p.x() - 0.75, 2) + std::pow(p.y() - 0.25, 2)));
    }
  }
};

}  // namespace

TEST(RoiMask, PictureRowZeroIsTheTopOfTheSquare) {
  // A 3 × 2 picture: the top row's right pixel only.
  const std::vector<std::uint8_t> picture{0, 0, 1, 0, 0, 0};
  const RoiMask m = roi_from_picture(3, 2, picture, 64);
  EXPECT_TRUE(m.contains(Vec2(1.0, 1.0)));
  EXPECT_TRUE(m.contains(Vec2(0.9, 0.9)));
  EXPECT_FALSE(m.contains(Vec2(1.0, 0.0)));  // bottom right
  EXPECT_FALSE(m.contains(Vec2(0.0, 1.0)));  // top left
  EXPECT_FALSE(m.contains(Vec2(0.5, 0.9)));  // the middle pixel's half
  EXPECT_THROW((void)roi_from_picture(1, 2, std::vector<std::uint8_t>{1, 1}, 64), InvalidInput);
  EXPECT_THROW((void)roi_from_picture(2, 2, std::vector<std::uint8_t>{1}, 64), InvalidInput);
}

TEST(RoiMask, VerticesSelectTheFacesAroundThem) {
  const Bumped b;
  // The vertices within 0.1 of (0.25, 0.75).
  std::vector<std::uint8_t> flags(b.uv.size(), 0);
  for (std::size_t v = 0; v < b.uv.size(); ++v) flags[v] = (b.uv[v] - Vec2(0.25, 0.75)).norm() < 0.1;
  const RoiMask m = roi_from_vertices(b.mesh, b.uv, flags, 256);
  EXPECT_TRUE(m.contains(Vec2(0.25, 0.75)));
  EXPECT_TRUE(m.contains(Vec2(0.25 + 0.095, 0.75)));  // the faces around the outermost selected vertices
  EXPECT_FALSE(m.contains(Vec2(0.25 + 0.15, 0.75)));
  EXPECT_FALSE(m.contains(Vec2(0.75, 0.25)));
  EXPECT_NEAR(static_cast<double>(m.area_cells()) / (256.0 * 256.0), M_PI * 0.11 * 0.11, 0.01);
  EXPECT_THROW((void)roi_from_vertices(b.mesh, b.uv, std::vector<std::uint8_t>(3, 1), 256), InvalidInput);
}

TEST(RoiMask, AutoFindsTheDetailOfTheNormalImage) {
  const EmbreeDevice device;
  const Bumped b;
  const ParametrizedSurface surface(device, b.mesh, b.uv);
  const RoiMask m = roi_auto(surface, b.mesh, 65, 0.05, 512);
  EXPECT_TRUE(m.contains(Vec2(0.75, 0.25)));
  EXPECT_FALSE(m.contains(Vec2(0.25, 0.75)));
  EXPECT_NEAR(static_cast<double>(m.area_cells()) / (512.0 * 512.0), 0.05, 0.02);
  EXPECT_THROW((void)roi_auto(surface, b.mesh, 65, 1.0, 512), InvalidInput);
}

TEST(RoiEnhance, TheRoiGetsItsSamplesWithoutFoldingTheGrid) {
  const std::uint32_t n = 33;
  const std::vector<Vec2> start = uniform_grid(n);
  const RoiMask roi = box_mask(Vec2(0.3, 0.5), Vec2(0.55, 0.8), 512);
  std::vector<Vec2> vertices = uniform_grid(101);  // evenly parametrized vertices
  for (double gain : {2.0, 4.0}) {
    const RoiEnhanceResult r = enhance_roi(vertices, n, start, roi, {gain, 200});
    EXPECT_EQ(r.samples_before, samples_in(roi, start));
    EXPECT_GE(r.samples_after, r.target) << "gain " << gain;
    EXPECT_EQ(r.target, static_cast<std::uint64_t>(std::ceil(gain * static_cast<double>(r.samples_before))));
    EXPECT_EQ(r.samples_after, samples_in(roi, r.sample_uv));
    // The boundary stays; every quad stays strictly convex.
    for (std::uint32_t j = 0; j < n; ++j)
      for (std::uint32_t i = 0; i < n; ++i)
        if (i == 0 || j == 0 || i == n - 1 || j == n - 1) {
          EXPECT_EQ(r.sample_uv[j * n + i], start[j * n + i]);
        }
    for (std::uint32_t j = 0; j + 1 < n; ++j)
      for (std::uint32_t i = 0; i + 1 < n; ++i) {
        const std::array<Vec2, 4> q{r.sample_uv[j * n + i], r.sample_uv[j * n + i + 1], r.sample_uv[(j + 1) * n + i + 1],
                                    r.sample_uv[(j + 1) * n + i]};
        // Strictly convex also in float32, as readers of sample_uv check it.
        std::array<Vec2, 4> f;
        for (std::size_t k = 0; k < 4; ++k) f[k] = Vec2(static_cast<float>(q[k].x()), static_cast<float>(q[k].y()));
        for (std::size_t e = 0; e < 4; ++e) ASSERT_GT(cross2(f[e], f[(e + 1) % 4], f[(e + 2) % 4]), 0.0);
      }
  }
  // Gain 1: the start grid already holds its target.
  const RoiEnhanceResult same = enhance_roi(vertices, n, start, roi, {1.0, 200});
  EXPECT_EQ(same.sample_uv, start);
  EXPECT_EQ(same.iterations, 0u);
}

TEST(RoiEnhance, RefusesAnEmptyRoiAndBadGains) {
  const std::uint32_t n = 9;
  const std::vector<Vec2> start = uniform_grid(n);
  const RoiMask empty{64, std::vector<std::uint8_t>(64 * 64, 0)};
  EXPECT_THROW((void)enhance_roi(start, n, start, empty), InvalidInput);
  const RoiMask roi = box_mask(Vec2(0.2, 0.2), Vec2(0.6, 0.6), 64);
  EXPECT_THROW((void)enhance_roi(start, n, start, roi, {0.5, 10}), InvalidInput);
  EXPECT_THROW((void)enhance_roi(start, n, std::vector<Vec2>(5), roi), InvalidInput);
}

TEST(RoiAdjust, TheRoisDirectedDistanceNeverGrowsAndHalves) {
  const EmbreeDevice device;
  const Bumped b;
  const std::uint32_t n = 17;
  const ParametrizedSurface surface(device, b.mesh, b.uv);
  const RoiMask roi = box_mask(Vec2(0.6, 0.1), Vec2(0.9, 0.4), 512);  // the bump
  std::vector<Vec2> uv = uniform_grid(n);
  const auto positions = [&](const std::vector<Vec2>& grid) {
    std::vector<Vec3> p;
    for (const Vec2& q : grid) p.push_back(surface.at(q).position);
    return p;
  };
  LocalHausdorff before(device, b.mesh, b.uv, n, uv, positions(uv));
  before.verify(0.0);
  const auto [roi_before, outside_before] = region_figures(before, b.uv, roi);
  RoiEnhanceResult enhanced = enhance_roi(b.uv, n, uv, roi, {4.0, 200});
  AdaptOptions options;
  options.rounds = 8;
  options.roi = &roi;
  const AdaptResult r = adjust_samples(device, b.mesh, b.uv, n, enhanced.sample_uv, positions(enhanced.sample_uv), options);
  ASSERT_GE(r.history.size(), 2u);
  for (std::size_t k = 1; k < r.history.size(); ++k) EXPECT_LE(r.history[k].roi.max_d2, r.history[k - 1].roi.max_d2);
  // More samples on the bump, then the moves: its error at most half of the uniform grid's.
  EXPECT_LE(r.history.back().roi.max_d2, 0.5 * roi_before.max_d2);
  EXPECT_GT(outside_before.max_d2, 0.0);
}

TEST(RoiMask, GluedFlagsAreSetByClass) {
  std::vector<std::uint8_t> flags{0, 1, 0, 0, 0};
  glue_flags(flags, std::vector<std::uint32_t>{0, 3, 2, 3, 0});  // {0, 4}, {1, 3}, {2}
  EXPECT_EQ(flags, (std::vector<std::uint8_t>{0, 1, 0, 1, 0}));
  EXPECT_THROW(glue_flags(flags, std::vector<std::uint32_t>{0, 1}), InvalidInput);
  EXPECT_THROW(glue_flags(flags, std::vector<std::uint32_t>{0, 1, 2, 3, 5}), InvalidInput);
}

TEST(RoiGim, TheConversionRecordsTheRoiAndStaysWatertight) {
  const EmbreeDevice device;
  const TriMesh mesh = make_icosphere(1.0, 3);
  GimOptions opt;
  opt.image = {65, 0, {}};
  opt.max_augmentations = 2;
  opt.sampling = GimSampling::Adaptive;
  opt.adapt.rounds = 2;
  opt.roi.kind = RoiSource::Kind::Vertices;
  opt.roi.vertices.assign(mesh.num_vertices(), 0);
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) opt.roi.vertices[v] = mesh.positions[v].z() > 0.8;
  const GimResult r = convert_to_geometry_image(device, mesh, opt);
  ASSERT_EQ(r.stats.roi.inside.size(), 65u * 65u);
  // (4× is out of reach here: the cap meets the square's sides, whose samples stay.)
  EXPECT_GE(r.stats.roi.samples_enhanced, 2 * r.stats.roi.samples_start);
  EXPECT_GT(r.stats.roi.samples_start, 0u);
  std::uint64_t flagged = 0, on_sides = 0;
  for (std::size_t s = 0; s < r.stats.roi.inside.size(); ++s) {
    flagged += r.stats.roi.inside[s];
    if (s % 65 == 0 || s % 65 == 64 || s / 65 == 0 || s / 65 == 64) on_sides += r.stats.roi.inside[s];
    // Samples in the ROI lie on the cap z > 0.8 (faces touching it reach a little lower).
    if (r.stats.roi.inside[s]) {
      EXPECT_GT(r.image.positions[3 * s + 2], 0.6f);
    }
  }
  EXPECT_EQ(flagged, r.stats.roi.samples_final);
  EXPECT_GT(on_sides, 0u);  // the cap meets the sides: see the gain above
  // Glued boundary samples (cut-path mates, a cut-node's copies: one surface point) are in the ROI together.
  const std::vector<std::uint32_t> rep = boundary_classes(r.image.sideband, 65);
  std::size_t disagree = 0;
  for (std::size_t s = 0; s < rep.size(); ++s) disagree += r.stats.roi.inside[s] != r.stats.roi.inside[rep[s]];
  EXPECT_EQ(disagree, 0u);
  // A region across the cut: its mask cells on the two sides of a cut-path differed at 5 of 127 glued samples.
  GimOptions across = opt;
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) across.roi.vertices[v] = mesh.positions[v].x() > -0.2;
  const GimResult a = convert_to_geometry_image(device, mesh, across);
  const std::vector<std::uint32_t> rep_a = boundary_classes(a.image.sideband, 65);
  std::size_t disagree_a = 0, glued = 0, flagged_a = 0;
  for (std::size_t s = 0; s < rep_a.size(); ++s) {
    disagree_a += a.stats.roi.inside[s] != a.stats.roi.inside[rep_a[s]];
    glued += rep_a[s] != s;
    flagged_a += a.stats.roi.inside[s];
  }
  EXPECT_GT(glued, 0u);
  EXPECT_EQ(disagree_a, 0u);
  EXPECT_EQ(flagged_a, a.stats.roi.samples_final);
  const TopologyReport t = analyze_topology(reconstruct_geometry_image(r.image.positions, r.image.size, &r.image.sideband));
  EXPECT_EQ(t.boundary_edges, 0u);
  EXPECT_EQ(t.nonmanifold_edges, 0u);
  // A ROI needs adaptive sampling; vertex flags must be one per vertex.
  GimOptions uniform = opt;
  uniform.sampling = GimSampling::Uniform;
  EXPECT_THROW((void)convert_to_geometry_image(device, mesh, uniform), InvalidInput);
  GimOptions short_flags = opt;
  short_flags.roi.vertices.resize(3);
  EXPECT_THROW((void)convert_to_geometry_image(device, mesh, short_flags), InvalidInput);
}
