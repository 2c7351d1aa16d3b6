// A multi-chart image moved onto the full surface (jobs/proxy.h apply_transfers) keeps the splits its pinned
// quads had at its zippered positions (zipper_diagonals), so the move cannot change its topology.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include "jobs/pipeline.h"
#include "jobs/proxy.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/hash.h"
#include "kernels/core/procedural.h"
#include "kernels/core/surface_sampling.h"
#include "kernels/core/topology.h"
#include "kernels/mcgim/mcgim_convert.h"
#include "kernels/mcgim/mcgim_image.h"

namespace gimforge::jobs {
namespace {

TEST(ProxyFit, AMovedMultiChartImageKeepsTheSplitsOfItsZipperedPositions) {
  // The transfer moves every sample onto the full surface. Where a quad's split decides the topology
  // (pinned_quads: zipper clusters), choosing it again from the moved positions could open a boundary loop
  // or pinch off a closed piece; the moved image keeps the zippered positions' splits and stays closed.
  const EmbreeDevice device;
  McgimOptions o;
  o.samples = 4096;
  o.charts = 8;
  Conversion c;
  c.method = Method::Mcgim;
  c.mcgim = convert_to_multichart(device, make_torus(1.0, 0.4, 48, 24), o);
  const std::vector<std::uint8_t> zippered = zipper_diagonal_bits(c.mcgim->image);
  ASSERT_FALSE(zippered.empty());  // the zipper pins quads
  // A move of a third of a sample spacing in a random direction per point (equal points move alike).
  const double spacing = std::sqrt(surface_area(make_torus(1.0, 0.4, 48, 24)) / 4096.0);
  std::vector<TransferResult> moved;
  for (const std::vector<Vec3>& points : transfer_point_sets(c)) {
    TransferResult r;
    for (const Vec3& p : points) {
      const std::uint64_t h = splitmix64(std::hash<double>{}(p.x()) ^ std::hash<double>{}(p.y() + 2.0 * p.z()));
      const Vec3 d(uniform01(h, 0) - 0.5, uniform01(h, 1) - 0.5, uniform01(h, 2) - 0.5);
      r.positions.push_back(p.allFinite() ? Vec3(p + 0.66 * spacing * d) : p);
      r.normals.push_back(Vec3::UnitZ());
    }
    moved.push_back(std::move(r));
  }
  apply_transfers(c, moved, nullptr);
  EXPECT_EQ(c.mcgim->image.zipper_diagonals, zippered);
  // Its normals are central differences of the moved positions (docs/archive.md), not the transfer's (+z here).
  const std::vector<float> expected = multichart_normals(c.mcgim->image);
  ASSERT_EQ(c.mcgim->normals.size(), expected.size());
  std::size_t differ = 0;
  for (std::size_t i = 0; i < expected.size(); ++i)
    if (!(c.mcgim->normals[i] == expected[i] || (std::isnan(c.mcgim->normals[i]) && std::isnan(expected[i])))) ++differ;
  EXPECT_EQ(differ, 0u);
  const TopologyReport t = analyze_topology(reconstruct_multichart(c.mcgim->image));
  EXPECT_EQ(t.boundary_edges, 0u);
  EXPECT_EQ(t.nonmanifold_edges, 0u);
  EXPECT_EQ(t.components.size(), 1u);
}

// A geometry image's normal map is sampled at the uniform grid of its parameter square; through a proxy its
// grid points are found on the proxy's image first and then moved onto the full surface (transfer_point_sets).
// An adaptively sampled image's pixels lie at their own parameter points (sample_uv), so the grid points are
// interpolated there: read as if the pixels were uniform, they landed up to several sample spacings away and
// the normal map turned by up to 40° against the same image sampled uniformly (here: median 0.19, largest
// 3.0 spacings; now 0.008 and 0.6).
TEST(ProxyNormals, AnAdaptiveImagesNormalGridPointsAreWhereAUniformImagesAre) {
  TriMesh torus = make_torus(1.0, 0.4, 64, 32);
  for (Vec3& p : torus.positions) p.x() += 0.02 * std::sin(9.0 * p.x());
  const EmbreeDevice device;
  ConversionRequest r;
  r.method.method = Method::Gim;
  r.method.size = 65;
  r.method.normal_size = 64;
  r.method.proxy_faces = "off";
  r.fidelity.enabled = false;
  r.command_line = "test_proxy_splits";
  const Conversion uniform = convert_mesh(device, torus, r);
  r.method.sampling = "adaptive";
  r.method.adapt_start = "strips";
  r.method.adapt_rounds = 2;
  const Conversion adaptive = convert_mesh(device, torus, r);
  ASSERT_FALSE(adaptive.gim->image.sample_uv.empty());
  const std::vector<Vec3> a = transfer_point_sets(uniform).at(1), b = transfer_point_sets(adaptive).at(1);
  ASSERT_EQ(a.size(), b.size());
  const double spacing = std::sqrt(surface_area(torus) / (64.0 * 64.0));
  std::vector<double> d;
  for (std::size_t i = 0; i < a.size(); ++i) d.push_back((a[i] - b[i]).norm() / spacing);
  std::sort(d.begin(), d.end());
  EXPECT_LT(d[d.size() / 2], 0.05) << "median, in normal-map spacings";
  EXPECT_LT(d[d.size() * 99 / 100], 0.3) << "99th percentile";
  EXPECT_LT(d.back(), 1.0) << "largest";
}

}  // namespace
}  // namespace gimforge::jobs
