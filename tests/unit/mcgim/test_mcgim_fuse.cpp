// Fusing a decoded multi-chart geometry image (kernels/mcgim/mcgim_fuse.h): fusing makes every zipper cluster
// one value, error diffusion lowers the step it leaves next to the chart boundaries, and a JPEG 2000 code of a
// closed surface's image reconstructs watertight once fused.
#include <algorithm>
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "kernels/codec/geometry_codec.h"
#include "kernels/core/edge_topology.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/mcgim/mcgim_convert.h"
#include "kernels/mcgim/mcgim_fuse.h"

namespace gimforge {
namespace {

MultiChartImage torus_image() {
  const EmbreeDevice device;
  McgimOptions o;
  o.charts = 12;
  o.samples = 16384;
  return convert_to_multichart(device, make_torus(1.0, 0.35, 48, 24), o).image;
}

Vec3 at(const MultiChartImage& im, std::size_t s) { return {im.positions[3 * s], im.positions[3 * s + 1], im.positions[3 * s + 2]}; }

/// The image with a smooth "codec" error that depends on where a sample lies in the image, so the members of a
/// zipper cluster (in different charts, far apart) get different errors.
MultiChartImage decoded_copy(const MultiChartImage& im) {
  MultiChartImage d = im;
  for (std::size_t s = 0; s < im.samples(); ++s) {
    if (!im.mask[s]) continue;
    const double u = static_cast<double>(s % im.width) / im.width, v = static_cast<double>(s / im.width) / im.height;
    for (std::size_t c = 0; c < 3; ++c)
      d.positions[3 * s + c] += static_cast<float>(0.01 * std::sin(9 * u + 7 * v + static_cast<double>(c)));
  }
  return d;
}

std::size_t cluster_size(const MultiChartImage& im, std::size_t s) {
  std::size_t n = 0;
  for (std::size_t t = 0; t < im.samples(); ++t) n += im.mask[t] && im.unified[t] == im.unified[s];
  return n;
}

bool clusters_equal(const MultiChartImage& im) {
  for (std::size_t s = 0; s < im.samples(); ++s)
    if (im.mask[s] && at(im, s) != at(im, im.unified[s])) return false;
  return true;
}

/// RMS, over pairs of 4-neighbours of one chart of which exactly one is clustered, of the error of their step.
double step_error(const MultiChartImage& a, const MultiChartImage& o, const std::vector<bool>& clustered) {
  double sum = 0.0;
  std::size_t count = 0;
  for (std::size_t s = 0; s < a.samples(); ++s) {
    if (!a.mask[s]) continue;
    for (const std::size_t t : {s + 1, s + a.width}) {
      if (t >= a.samples() || (t == s + 1 && t % a.width == 0) || !a.mask[t] || a.chart[t] != a.chart[s]) continue;
      if (clustered[s] == clustered[t]) continue;
      sum += ((at(a, s) - at(a, t)) - (at(o, s) - at(o, t))).squaredNorm();
      ++count;
    }
  }
  return std::sqrt(sum / static_cast<double>(count));
}

double rms(const MultiChartImage& a, const MultiChartImage& o) {
  double sum = 0.0;
  std::size_t count = 0;
  for (std::size_t s = 0; s < a.samples(); ++s)
    if (a.mask[s]) sum += (at(a, s) - at(o, s)).squaredNorm(), ++count;
  return std::sqrt(sum / static_cast<double>(count));
}

std::size_t open_or_nonmanifold_edges(const TriMesh& mesh) {
  const EdgeTopology topo = build_edge_topology(mesh);
  std::size_t bad = 0;
  for (std::size_t e = 0; e < topo.num_edges(); ++e) bad += topo.valence(e) != 2;
  return bad;
}

}  // namespace

TEST(McgimFuse, MakesClustersEqualAndDiffusionLowersTheStepItLeaves) {
  const MultiChartImage original = torus_image();
  MultiChartImage fused = decoded_copy(original);
  ASSERT_FALSE(clusters_equal(fused));
  std::vector<bool> clustered(original.samples());
  for (std::size_t s = 0; s < original.samples(); ++s) clustered[s] = original.mask[s] && cluster_size(original, s) > 1;
  std::vector<Vec3> displacement;
  const ZipperFuseStats stats = fuse_zipper(fused, displacement);
  EXPECT_TRUE(clusters_equal(fused));
  EXPECT_NO_THROW(check_multichart_image(fused, "fused"));
  EXPECT_GT(stats.clusters, 50u);
  EXPECT_GT(stats.max_displacement, 1e-3);
  for (std::size_t s = 0; s < original.samples(); ++s)
    if (!clustered[s]) {
      EXPECT_EQ(displacement[s], Vec3::Zero()) << s;  // only clusters move
    }
  MultiChartImage diffused = fused;
  diffuse_zipper_fusing(diffused, displacement);
  EXPECT_TRUE(clusters_equal(diffused));  // clustered samples keep their fused values
  for (std::size_t s = 0; s < original.samples(); ++s)
    if (!original.mask[s]) {
      EXPECT_TRUE(std::isnan(diffused.positions[3 * s])) << s;  // undefined stay undefined
    }
  const double before = step_error(fused, original, clustered), after = step_error(diffused, original, clustered);
  EXPECT_LT(after, 0.6 * before) << "step error " << before << " -> " << after;
  EXPECT_LT(rms(diffused, original), rms(fused, original));
}

TEST(McgimFuse, ACodedClosedSurfaceReconstructsWatertightOnceFused) {
  const MultiChartImage original = torus_image();
  ASSERT_EQ(open_or_nonmanifold_edges(reconstruct_multichart(original)), 0u);
  // As compress codes it: the positions minus each chart's quadric.
  std::uint32_t charts = 0;
  for (std::size_t s = 0; s < original.samples(); ++s)
    if (original.mask[s]) charts = std::max(charts, original.chart[s] + 1);
  const std::vector<float> planes = chart_planes(original, charts);
  std::vector<float> residual = original.positions;
  apply_chart_planes(residual, original, planes, -1);
  CodingTarget target;
  target.bytes = 12000;
  const CodedGeometry coded = encode_geometry(to_points(residual), original.width, original.height, original.mask,
                                              GeometryCodec::J2k, LatticeExtension::Mirror, target);
  MultiChartImage decoded = original;
  decoded.positions = to_floats(coded.decoded);
  for (std::size_t s = 0; s < decoded.samples(); ++s)
    if (!decoded.mask[s]) decoded.positions[3 * s] = decoded.positions[3 * s + 1] = decoded.positions[3 * s + 2] = std::numeric_limits<float>::quiet_NaN();
  apply_chart_planes(decoded.positions, decoded, planes, +1);
  EXPECT_FALSE(clusters_equal(decoded));  // the coder splits the zipper ...
  EXPECT_THROW(check_multichart_image(decoded, "decoded"), FormatError);
  std::vector<Vec3> displacement;
  (void)fuse_zipper(decoded, displacement);
  diffuse_zipper_fusing(decoded, displacement);
  check_multichart_image(decoded, "fused");  // ... fusing closes it
  EXPECT_EQ(open_or_nonmanifold_edges(reconstruct_multichart(decoded)), 0u);
  EXPECT_LT(rms(decoded, original), 0.002);
}

TEST(McgimFuse, RefusesArraysThatDisagree) {
  MultiChartImage ok = torus_image();
  MultiChartImage im = ok;
  im.unified.pop_back();
  std::vector<Vec3> displacement;
  EXPECT_THROW((void)fuse_zipper(im, displacement), InvalidInput);
  displacement.assign(3, Vec3::Zero());
  EXPECT_THROW(diffuse_zipper_fusing(ok, displacement), InvalidInput);
}

}  // namespace gimforge

namespace gimforge {

TEST(McgimChartPlanes, AQuadraticChartLeavesNoResidualAndTheMapsUndoEachOther) {
  // Two charts side by side, one sample apart, with unrelated quadratic positions: the residual vanishes.
  MultiChartImage im;
  im.width = 21;
  im.height = 8;
  const std::size_t n = im.samples();
  im.positions.assign(3 * n, std::numeric_limits<float>::quiet_NaN());
  im.mask.assign(n, 0);
  im.chart.assign(n, kNoChart);
  im.unified.assign(n, kNoSample);
  for (std::uint32_t y = 0; y < im.height; ++y)
    for (std::uint32_t x = 0; x < im.width; ++x) {
      if (x == 10) continue;  // the gutter
      const std::size_t s = std::size_t{y} * im.width + x;
      const double u = x, v = y;
      const std::uint32_t c = x < 10 ? 0 : 1;
      const Vec3 p = c == 0 ? Vec3(0.1 * u, 0.2 * v + 0.01 * u * u, 5.0 + 0.003 * u * v)
                            : Vec3(-40.0 + 0.05 * v * v, 3.0 - 0.1 * u, 0.02 * u - 0.01 * v);
      for (std::size_t k = 0; k < 3; ++k) im.positions[3 * s + k] = static_cast<float>(p[static_cast<Eigen::Index>(k)]);
      im.mask[s] = 1;
      im.chart[s] = c;
      im.unified[s] = static_cast<std::uint32_t>(s);
    }
  const std::vector<float> planes = chart_planes(im, 2);
  ASSERT_EQ(planes.size(), 2 * kPlaneFloats);
  std::vector<float> residual = im.positions;
  apply_chart_planes(residual, im, planes, -1);
  double largest = 0.0;
  for (std::size_t s = 0; s < n; ++s)
    if (im.mask[s])
      for (std::size_t k = 0; k < 3; ++k) largest = std::max(largest, std::abs(double{residual[3 * s + k]}));
  EXPECT_LT(largest, 1e-4);  // float32 positions up to 40: a few ulps
  apply_chart_planes(residual, im, planes, +1);
  for (std::size_t s = 0; s < n; ++s) {
    if (!im.mask[s]) {
      EXPECT_TRUE(std::isnan(residual[3 * s]));
      continue;
    }
    for (std::size_t k = 0; k < 3; ++k) EXPECT_NEAR(residual[3 * s + k], im.positions[3 * s + k], 1e-5);
  }
  EXPECT_THROW(apply_chart_planes(residual, im, std::vector<float>(kPlaneFloats), +1), InvalidInput);  // chart 1 has none
}

}  // namespace gimforge
