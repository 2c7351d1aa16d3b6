// Spatial bricks of equal triangle count (kernels/scan/bricks.h): balance, coverage, the k-d tree's
// agreement with the boxes, coarse histograms, errors.
#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <vector>

#include "kernels/core/errors.h"
#include "kernels/core/hash.h"
#include "kernels/scan/bricks.h"
#include "kernels/scan/synth.h"

namespace gimforge {
namespace {

double uniform(std::uint64_t i, std::uint64_t k) { return static_cast<double>(splitmix64(i * 3 + k) >> 11) * 0x1p-53; }

BoundingBox unit_box(double x = 1.0, double y = 1.0, double z = 1.0) {
  BoundingBox b;
  b.extend(Vec3::Zero());
  b.extend(Vec3(x, y, z));
  return b;
}

TEST(Bricks, UniformPointsGiveBalancedCompactBricks) {
  CentroidHistogram h(unit_box(4.0, 1.0, 1.0), {64, 16, 16});
  std::vector<Vec3> points;
  for (std::uint64_t i = 0; i < 200'000; ++i) points.emplace_back(4.0 * uniform(i, 0), uniform(i, 1), uniform(i, 2));
  for (const Vec3& p : points) h.add(p);
  for (const std::size_t n : {1u, 2u, 3u, 4u, 7u, 16u}) {
    const BrickPartition b = partition_bricks(h, n);
    ASSERT_EQ(b.size(), n);
    std::vector<std::uint64_t> owned(n, 0);
    for (const Vec3& p : points) ++owned[b.brick_of(p)];
    for (std::size_t i = 0; i < n; ++i) {
      EXPECT_EQ(owned[i], b.count[i]) << n << " bricks, brick " << i;  // the tree agrees with the counts
      EXPECT_NEAR(static_cast<double>(owned[i]), 200'000.0 / static_cast<double>(n), 0.06 * 200'000.0 / static_cast<double>(n))
          << n << " bricks, brick " << i;
      const BoundingBox box = b.bounds(i);
      for (const Vec3& p : points) {
        if (b.brick_of(p) == i) {
          EXPECT_TRUE((p.array() >= box.min.array() - 1e-12).all() && (p.array() <= box.max.array() + 1e-12).all());
        }
      }
    }
    if (n == 2) {  // the long axis is cut first
      EXPECT_NEAR(b.bounds(0).max.x(), 2.0, 0.1);
      EXPECT_EQ(b.bounds(0).max.y(), 1.0);
    }
  }
}

TEST(Bricks, ClusteredFacesOfATerrainBalanceByCount) {
  // Faces of a terrain whose right half is 9× denser: equal counts, so the left bricks are wider.
  TerrainOptions o;
  o.nx = 60;
  o.ny = 60;
  o.holes = 0;
  const TerrainScan scan(o);
  TriMesh m;
  for (std::uint32_t y = 0; y <= o.ny; ++y) scan.vertex_row(y, m.positions);
  for (std::uint32_t y = 0; y < o.ny; ++y) scan.face_row(y, m.faces);
  BoundingBox box;
  for (const Vec3& p : m.positions) box.extend(p);
  CentroidHistogram h(box, {60, 60, 1});
  h.add_face_centroids(m.positions, m.faces);
  std::vector<Vec3> centroids;
  for (const Face& f : m.faces) {
    const Vec3 c = (m.positions[f[0]] + m.positions[f[1]] + m.positions[f[2]]) / 3.0;
    const int copies = c.x() > 30.0 ? 9 : 1;
    for (int i = 0; i < copies; ++i) centroids.push_back(c);
    if (copies > 1) h.add(c, 8);
  }
  EXPECT_EQ(h.total(), centroids.size());
  const BrickPartition b = partition_bricks(h, 4);
  std::vector<std::uint64_t> owned(4, 0);
  for (const Vec3& c : centroids) ++owned[b.brick_of(c)];
  const double quarter = static_cast<double>(centroids.size()) / 4.0;
  for (const std::uint64_t n : owned) EXPECT_NEAR(static_cast<double>(n), quarter, 0.05 * quarter);
}

TEST(Bricks, TooCoarseHistogramLeavesEmptyBricksAndClampsOutsiders) {
  CentroidHistogram h(unit_box(), {2, 1, 1});
  h.add(Vec3(0.25, 0.5, 0.5), 10);
  h.add(Vec3(0.75, 0.5, 0.5), 10);
  h.add(Vec3(-5.0, 9.0, 0.5));  // outside: clamped into cell (0, 0, 0)
  h.add(Vec3(std::numeric_limits<double>::quiet_NaN(), 0.5, 0.5));
  EXPECT_EQ(h.total(), 22u);
  const BrickPartition b = partition_bricks(h, 4);
  ASSERT_EQ(b.size(), 4u);
  std::uint64_t sum = 0, empty = 0;
  for (std::size_t i = 0; i < 4; ++i) {
    sum += b.count[i];
    empty += b.count[i] == 0 ? 1u : 0u;
  }
  EXPECT_EQ(sum, 22u);
  EXPECT_EQ(empty, 2u);  // two cells cannot make four bricks
  EXPECT_EQ(b.count[b.brick_of(Vec3(-5.0, 9.0, 0.5))], 12u);
  EXPECT_EQ(b.count[b.brick_of(Vec3(5.0, 0.0, 0.0))], 10u);
}

TEST(Bricks, RefusesBadInput) {
  EXPECT_THROW(CentroidHistogram(BoundingBox{}, {4, 4, 4}), InvalidInput);
  EXPECT_THROW(CentroidHistogram(unit_box(), {0, 4, 4}), InvalidInput);
  EXPECT_THROW(CentroidHistogram(unit_box(), {1024, 1024, 1024}), InvalidInput);
  const CentroidHistogram h(unit_box(), {4, 4, 4});
  EXPECT_THROW((void)partition_bricks(h, 0), InvalidInput);
  // A flat box (zero extent on an axis) is fine: every point goes to cell 0 along it.
  BoundingBox flat = unit_box(1.0, 1.0, 0.0);
  CentroidHistogram f(flat, {4, 4, 4});
  f.add(Vec3(0.5, 0.5, 0.0));
  EXPECT_EQ(f.cell_of(Vec3(0.5, 0.5, 0.0))[2], 0u);
  EXPECT_EQ(partition_bricks(f, 2).size(), 2u);
}

}  // namespace
}  // namespace gimforge
