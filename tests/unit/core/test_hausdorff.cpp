#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>

#include <embree3/rtcore.h>

#include "kernels/core/closest_point.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/procedural.h"
#include "kernels/core/surface_sampling.h"

using namespace gimforge;

namespace {

/// Independent reference for point-triangle distance: project onto the plane, accept if inside (by
/// edge-side tests), otherwise the nearest of the three segments.
double reference_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  auto segment = [&](const Vec3& s, const Vec3& t) {
    const Vec3 d = t - s;
    const double len2 = d.squaredNorm();
    double x = len2 > 0 ? (p - s).dot(d) / len2 : 0.0;
    x = std::min(1.0, std::max(0.0, x));
    return (s + x * d - p).norm();
  };
  const Vec3 n = (b - a).cross(c - a);
  const double n2 = n.squaredNorm();
  if (n2 > 0) {
    const Vec3 q = p - n * ((p - a).dot(n) / n2);
    const bool inside = (b - a).cross(q - a).dot(n) >= 0 && (c - b).cross(q - b).dot(n) >= 0 &&
                        (a - c).cross(q - c).dot(n) >= 0;
    if (inside) return (q - p).norm();
  }
  return std::min({segment(a, b), segment(b, c), segment(c, a)});
}

double brute_force_distance(const Vec3& p, const TriMesh& m) {
  double best = std::numeric_limits<double>::infinity();
  for (const Face& f : m.faces)
    best = std::min(best, reference_distance(p, m.positions[f[0]], m.positions[f[1]], m.positions[f[2]]));
  return best;
}

TriMesh bumpy_sphere(int subdivisions, double amplitude) {
  TriMesh m = make_icosphere(1.0, subdivisions);
  for (Vec3& p : m.positions) p *= 1.0 + amplitude * std::sin(5 * p.x()) * std::cos(3 * p.y() + p.z());
  return m;
}

}  // namespace

TEST(ClosestPoint, MatchesIndependentReference) {
  const Vec3 a(0.1, -0.2, 0.3), b(1.2, 0.1, -0.4), c(-0.3, 0.9, 0.2);
  for (std::uint64_t i = 0; i < 20000; ++i) {
    const Vec3 p(4 * uniform01(1, 3 * i) - 2, 4 * uniform01(1, 3 * i + 1) - 2, 4 * uniform01(1, 3 * i + 2) - 2);
    const TrianglePoint tp = closest_point_on_triangle(p, a, b, c);
    ASSERT_NEAR((tp.point - p).norm(), reference_distance(p, a, b, c), 1e-12) << "point " << i;
    ASSERT_NEAR(tp.barycentric.sum(), 1.0, 1e-12);
    ASSERT_LT((tp.barycentric.x() * a + tp.barycentric.y() * b + tp.barycentric.z() * c - tp.point).norm(), 1e-12);
  }
}

TEST(ClosestPoint, DegenerateTriangles) {
  const Vec3 p(0.5, 1.0, 0.0);
  EXPECT_NEAR((closest_point_on_triangle(p, {0, 0, 0}, {1, 0, 0}, {2, 0, 0}).point - p).norm(), 1.0, 1e-15);
  EXPECT_NEAR((closest_point_on_triangle(p, {0, 0, 0}, {0, 0, 0}, {0, 0, 0}).point - p).norm(), std::sqrt(1.25),
              1e-15);
}

TEST(ClosestPoint, SliversKeepTheirDistanceInAnyFrame) {
  // Slivers as a stray vertex makes them (10^8 long, 0.1 wide; a needle and a flat one whose apex sits
  // in the middle of its long edge; each vertex order), rotated and moved to georeferenced coordinates. The answer must be
  // the canonical frame's (where the reference is exact to rounding) within the rounding of the rotated
  // vertices (~10^-8); the region tests' 2×2 determinants were off by 10 % on such triangles.
  const double kLong = 1e8, kWide = 0.1;
  const std::array<std::array<Vec3, 3>, 2> slivers{{{Vec3(kLong, 0, 0), Vec3(0, 0, 0), Vec3(0, kWide, 0)},
                                                   {Vec3(0.37 * kLong, kWide, 0), Vec3(0, 0, 0), Vec3(kLong, 0, 0)}}};
  const Eigen::Matrix3d rotation = Eigen::Quaterniond(0.8, -0.3, 0.4, 0.2).normalized().toRotationMatrix();
  const Vec3 offset(512345.25, 5.1e6, 231.5);
  auto frame = [&](const Vec3& v) -> Vec3 { return rotation * v + offset; };
  for (std::size_t s = 0; s < slivers.size(); ++s) {
    for (std::uint64_t i = 0; i < 6000; ++i) {
      const auto& v = slivers[s];  // each vertex order in turn: the small angle at a, b or c
      const Vec3 &a = v[i % 3], &b = v[(i + 1) % 3], &c = v[(i + 2) % 3];
      const double height = std::pow(10.0, -3.0 + 4.0 * uniform01(21, 3 * i));
      const Vec3 p(kLong * (1.2 * uniform01(22, i) - 0.1), kWide * (6 * uniform01(23, i) - 2.5),
                   i % 2 == 0 ? height : -height);
      const double expected = reference_distance(p, a, b, c);
      const TrianglePoint tp = closest_point_on_triangle(frame(p), frame(a), frame(b), frame(c));
      ASSERT_NEAR((tp.point - frame(p)).norm(), expected, 1e-7 + 1e-12 * expected)
          << "sliver " << s << " point " << i << " (" << p.transpose() << ")";
      ASSERT_NEAR(tp.barycentric.sum(), 1.0, 1e-9);
    }
  }
}

TEST(SurfaceSampling, DeterministicAndOnTheSurface) {
  const TriMesh m = make_torus(2.0, 0.5, 20, 10);
  const auto s1 = sample_surface(m, {5000, 42});
  const auto s2 = sample_surface(m, {5000, 42});
  const auto s3 = sample_surface(m, {5000, 43});
  ASSERT_EQ(s1.points.size(), 5000u);
  EXPECT_EQ(s1.points, s2.points);
  EXPECT_NE(s1.points, s3.points);
  for (std::size_t i = 0; i < s1.points.size(); ++i) {
    const Face& f = m.faces[s1.faces[i]];
    ASSERT_LT(reference_distance(s1.points[i], m.positions[f[0]], m.positions[f[1]], m.positions[f[2]]), 1e-12);
  }
}

TEST(SurfaceSampling, AreaWeighted) {
  // Two triangles, one with 3x the area of the other: samples split 1:3.
  TriMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 5}, {3, 0, 5}, {0, 1, 5}};
  m.faces = {{0, 1, 2}, {3, 4, 5}};
  const auto s = sample_surface(m, {40000, 7});
  const auto on_big = std::count(s.faces.begin(), s.faces.end(), 1u);
  EXPECT_EQ(on_big, 30000);  // stratified along the CDF: exact up to one sample
}

TEST(SurfaceSampling, RejectsZeroArea) {
  TriMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  m.faces = {{0, 1, 2}};
  EXPECT_THROW((void)sample_surface(m, {10, 1}), InvalidInput);
}

TEST(TriangleBvh, ClosestPointMatchesBruteForce) {
  const EmbreeDevice device;
  const TriMesh m = bumpy_sphere(3, 0.1);
  const TriangleBvh bvh(device, m);
  for (std::uint64_t i = 0; i < 2000; ++i) {
    const Vec3 p(3 * uniform01(9, 3 * i) - 1.5, 3 * uniform01(9, 3 * i + 1) - 1.5, 3 * uniform01(9, 3 * i + 2) - 1.5);
    const ClosestPoint cp = bvh.closest_point(p);
    ASSERT_TRUE(cp.found());
    const double ref = brute_force_distance(p, m);
    ASSERT_NEAR(cp.distance, ref, 1e-12 * std::max(1.0, ref)) << "point " << i;
    // An upper bound taken from an arbitrary face never changes the answer.
    const double bound = bvh.distance_to_face(p, static_cast<std::uint32_t>(i % m.num_faces()));
    ASSERT_EQ(bvh.closest_point(p, bound).distance, cp.distance);
  }
}

TEST(TriangleBvh, FarAwayPoints) {
  const EmbreeDevice device;
  const TriMesh m = make_icosphere(1.0, 2);
  const TriangleBvh bvh(device, m);
  const Vec3 p(1e4, -3e3, 2e3);
  EXPECT_NEAR(bvh.closest_point(p).distance, brute_force_distance(p, m), 1e-9);
}

TEST(TriangleBvh, StrayVerticesAndFarFramesKeepTheExactAnswer) {
  // A stray vertex 10^8 away (its faces are left out of the float BVH and measured on every query) and the
  // whole mesh 5·10^7 from its frame's origin (the BVH is built around its median vertex): the answers stay
  // the brute force's, from any point, through the stray faces too; the ray-casting scene keeps every face.
  const EmbreeDevice device;
  for (const Vec3& offset : {Vec3(0, 0, 0), Vec3(-5e7, 0, 0)}) {
    TriMesh m = bumpy_sphere(3, 0.1);  // 1280 faces
    m.positions[7].x() = 1e8;
    for (Vec3& p : m.positions) p += offset;
    const TriangleBvh bvh(device, m);
    for (std::uint64_t i = 0; i < 500; ++i) {
      Vec3 p(3 * uniform01(11, 3 * i) - 1.5, 3 * uniform01(11, 3 * i + 1) - 1.5, 3 * uniform01(11, 3 * i + 2) - 1.5);
      if (i % 5 == 0) p.x() += 5e7 * uniform01(12, i);  // beside the stray faces
      p += offset;
      const ClosestPoint cp = bvh.closest_point(p);
      ASSERT_TRUE(cp.found());
      // Against every face measured by the BVH's own exact routine: the float BVH's culling must not lose
      // the closest one (the routine's own accuracy on these 10^8 × 0.1 slivers is
      // ClosestPoint.SliversKeepTheirDistanceInAnyFrame's).
      double ref = std::numeric_limits<double>::infinity();
      for (std::uint32_t f = 0; f < m.faces.size(); ++f) ref = std::min(ref, bvh.distance_to_face(p, f));
      ASSERT_NEAR(cp.distance, ref, 1e-12 * std::max(1.0, ref)) << "point " << i;
      ASSERT_NEAR(bvh.distance_to_face(p, cp.face), cp.distance, 1e-12 * std::max(1.0, ref));
    }
    RTCScene scene = static_cast<RTCScene>(bvh.native_scene());
    ASSERT_NE(scene, nullptr);
    RTCBounds bounds;
    rtcGetSceneBounds(scene, &bounds);
    EXPECT_GT(double{bounds.upper_x}, 9e7 + offset.x());  // the stray vertex's faces are in it
    EXPECT_NEAR(double{bounds.lower_x}, offset.x() - 1.0, 8.0);  // in the mesh's own frame (float: ±4 at 5·10^7)
  }
}

TEST(TriangleBvh, RejectsEmptyMesh) {
  const EmbreeDevice device;
  TriMesh empty;
  EXPECT_THROW(TriangleBvh(device, empty), InvalidInput);
}

TEST(Hausdorff, MeshToItselfIsZero) {
  const EmbreeDevice device;
  const TriMesh m = bumpy_sphere(3, 0.05);
  const auto r = symmetric_hausdorff(device, m, m, {20000});
  EXPECT_LT(r.max, 1e-12);
  EXPECT_LT(r.rms, 1e-12);
  EXPECT_GT(r.psnr, 200.0);
}

TEST(Hausdorff, ConcentricIcospheres) {
  const EmbreeDevice device;
  const TriMesh a = make_icosphere(1.0, 5);
  const TriMesh b = make_icosphere(1.01, 5);
  const auto r = symmetric_hausdorff(device, a, b, {100000});
  EXPECT_NEAR(r.rms, 0.01, 0.02 * 0.01);
  EXPECT_NEAR(r.ab.mean, 0.01, 0.02 * 0.01);
  EXPECT_NEAR(r.ba.rms, 0.01, 0.02 * 0.01);
  EXPECT_NEAR(r.max, 0.01, 0.02 * 0.01);
  EXPECT_NEAR(r.psnr, 20 * std::log10(r.diag / r.rms), 1e-12);
  EXPECT_NEAR(r.diag, 2 * std::sqrt(3.0), 0.2);
}

TEST(Hausdorff, AgreesWithBruteForceReference) {
  const EmbreeDevice device;
  const TriMesh a = bumpy_sphere(2, 0.08);
  TriMesh b = make_torus(0.8, 0.35, 14, 9);
  HausdorffOptions opt;
  opt.samples = 3000;
  const auto r = symmetric_hausdorff(device, a, b, opt);

  auto reference = [&](const TriMesh& from, const TriMesh& to) {
    auto samples = sample_surface(from, {opt.samples, opt.seed});
    std::vector<double> d;
    for (const Vec3& p : samples.points) d.push_back(brute_force_distance(p, to));
    for (const Vec3& p : from.positions) d.push_back(brute_force_distance(p, to));
    return summarize_distances(d, samples.points.size());
  };
  const auto ab = reference(a, b);
  const auto ba = reference(b, a);
  auto rel = [](double x, double y) { return std::abs(x - y) / std::max(std::abs(y), 1e-300); };
  EXPECT_LT(rel(r.ab.max, ab.max), 1e-9);
  EXPECT_LT(rel(r.ab.mean, ab.mean), 1e-9);
  EXPECT_LT(rel(r.ab.rms, ab.rms), 1e-9);
  EXPECT_LT(rel(r.ba.max, ba.max), 1e-9);
  EXPECT_LT(rel(r.ba.mean, ba.mean), 1e-9);
  EXPECT_LT(rel(r.ba.rms, ba.rms), 1e-9);
  EXPECT_LT(rel(r.rms, std::sqrt((ab.rms * ab.rms + ba.rms * ba.rms) / 2)), 1e-9);
  EXPECT_EQ(r.ab.vertex_samples, a.num_vertices());
}

TEST(Hausdorff, DeterministicForFixedSamples) {
  const EmbreeDevice device;
  const TriMesh a = bumpy_sphere(3, 0.05);
  const TriMesh b = make_icosphere(1.0, 4);
  const auto r1 = symmetric_hausdorff(device, a, b, {30000});
  const auto r2 = symmetric_hausdorff(device, a, b, {30000});
  EXPECT_EQ(r1.rms, r2.rms);
  EXPECT_EQ(r1.max, r2.max);
  EXPECT_EQ(r1.ab.mean, r2.ab.mean);
}

TEST(Hausdorff, CancelThroughProgress) {
  const EmbreeDevice device;
  const TriMesh m = make_icosphere(1.0, 3);
  HausdorffOptions opt;
  opt.samples = 100000;
  opt.progress = [](std::string_view, double f) { return f < 0.5; };
  EXPECT_THROW((void)symmetric_hausdorff(device, m, m, opt), Cancelled);
}
