// Moving a proxy's samples onto the full surface (kernels/scan/surface_transfer.h): points end on the
// surface, along the proxy normal where that crossing is near, at the closest point otherwise; equal points
// stay equal; undefined (NaN) points stay undefined.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/scan/surface_transfer.h"

namespace gimforge {
namespace {

TEST(SurfaceTransfer, CoarseSphereSamplesLandOnTheFineSphereAlongTheNormal) {
  const EmbreeDevice device;
  const TriMesh proxy = make_icosphere(1.0, 1);  // 80 faces: chords far inside the sphere
  const TriMesh fine = make_icosphere(1.0, 5);   // 20480 faces
  std::vector<Vec3> points;
  for (const Face& f : proxy.faces)  // face centres and a point near every corner
    for (const Vec3& w : {Vec3(Vec3(1, 1, 1) / 3.0), Vec3(0.8, 0.1, 0.1)})
      points.push_back(w.x() * proxy.positions[f[0]] + w.y() * proxy.positions[f[1]] + w.z() * proxy.positions[f[2]]);
  points.push_back(points[5]);  // an equal pair
  points.push_back(Vec3::Constant(std::numeric_limits<double>::quiet_NaN()));
  const TransferResult r = transfer_to_surface(device, proxy, fine, points);
  ASSERT_EQ(r.positions.size(), points.size());
  const TriangleBvh fine_bvh(device, fine);
  double before = 0.0;
  for (std::size_t i = 0; i + 1 < points.size(); ++i) {
    EXPECT_LT(fine_bvh.closest_point(r.positions[i]).distance, 1e-12) << i;
    before = std::max(before, fine_bvh.closest_point(points[i]).distance);
    // Along the (nearly radial) normal: the direction from the centre barely changes.
    EXPECT_GT(r.positions[i].normalized().dot(points[i].normalized()), 0.999) << i;
    EXPECT_NEAR(r.normals[i].norm(), 1.0, 1e-12);
    EXPECT_GT(r.normals[i].dot(r.positions[i].normalized()), 0.99);
  }
  EXPECT_GT(before, 0.05);  // the proxy really was far from the surface
  EXPECT_EQ(r.positions[points.size() - 2], r.positions[5]);
  EXPECT_TRUE(std::isnan(r.positions.back().x()));
  EXPECT_TRUE(std::isnan(r.normals.back().x()));
  EXPECT_EQ(r.faces.back(), kNoFace);
  EXPECT_EQ(r.stats.points, points.size() - 1);
  EXPECT_EQ(r.stats.along_normal, points.size() - 1);
  EXPECT_EQ(r.stats.closest, 0u);
  EXPECT_GT(r.stats.max_move, 0.05);
}

TEST(SurfaceTransfer, ASteepSurfaceFarAlongTheNormalTakesTheClosestPoint) {
  const EmbreeDevice device;
  const TriMesh proxy = make_grid(4, 4);  // z = 0, normal +z
  // The surface: the plane z = 0.1 + 3·(x − 0.5) (about 72° steep): along z it is three times farther than
  // its closest point, so the ray crossing (beyond 2× the closest distance) is not taken.
  TriMesh steep = make_grid(8, 8);
  for (Vec3& p : steep.positions) p.z() = 0.1 + 3.0 * (p.x() - 0.5);
  const std::vector<Vec3> points{Vec3(0.5, 0.5, 0.0), Vec3(0.4, 0.6, 0.0)};
  const TransferResult r = transfer_to_surface(device, proxy, steep, points);
  EXPECT_EQ(r.stats.closest, 2u);
  EXPECT_EQ(r.stats.along_normal, 0u);
  const TriangleBvh bvh(device, steep);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const ClosestPoint cp = bvh.closest_point(points[i]);
    EXPECT_NEAR((r.positions[i] - cp.point).norm(), 0.0, 1e-12);
  }
  // With a larger ray factor the crossing along the normal is taken: straight up.
  TransferOptions wide;
  wide.ray_factor = 4.0;
  const TransferResult w = transfer_to_surface(device, proxy, steep, points, wide);
  EXPECT_EQ(w.stats.along_normal, 2u);
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_NEAR(w.positions[i].x(), points[i].x(), 1e-9);
    EXPECT_NEAR(w.positions[i].y(), points[i].y(), 1e-9);
    EXPECT_NEAR(w.positions[i].z(), 0.1 + 3.0 * (points[i].x() - 0.5), 1e-9);
  }
}

TEST(SurfaceTransfer, RefusesEmptyMeshesAndASmallRayFactor) {
  const EmbreeDevice device;
  const TriMesh sphere = make_icosphere(1.0, 1);
  const std::vector<Vec3> points{Vec3(1, 0, 0)};
  EXPECT_THROW((void)transfer_to_surface(device, TriMesh{}, sphere, points), InvalidInput);
  EXPECT_THROW((void)transfer_to_surface(device, sphere, TriMesh{}, points), InvalidInput);
  TransferOptions o;
  o.ray_factor = 0.5;
  EXPECT_THROW((void)transfer_to_surface(device, sphere, sphere, points, o), InvalidInput);
}

}  // namespace
}  // namespace gimforge
