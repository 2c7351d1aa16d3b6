// Resampling a spherically parametrized mesh: Embree rays from the centre locate sphere points.
#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/sphere/sphere_convert.h"
#include "kernels/sphere/sphere_map.h"
#include "kernels/sphere/sphere_resample.h"
#include "kernels/sphere/spherical_domain.h"
#include "kernels/core/surface_sampling.h"
#include "kernels/core/topology.h"

using namespace gimforge;

namespace {

std::vector<Vec3> random_directions(std::size_t n, std::uint64_t seed) {
  std::vector<Vec3> d;
  while (d.size() < n) {
    const std::uint64_t k = 3 * d.size();
    const Vec3 v(2 * uniform01(seed, k) - 1, 2 * uniform01(seed, k + 1) - 1, 2 * uniform01(seed, k + 2) - 1);
    if (v.norm() > 0.1) d.push_back(v.normalized());
    else d.push_back(Vec3(0, 0, 1));
  }
  return d;
}

/// An icosphere and its own sphere map, with the mesh deformed by a linear map A: for every direction the
/// resampled point must be A applied to the ray's hit on the icosphere's planar triangles.
struct Ellipsoid {
  TriMesh sphere_mesh = make_icosphere(1.0, 3);
  Eigen::Matrix3d A = (Eigen::Matrix3d() << 2.0, 0.3, 0.0, 0.0, 1.0, 0.0, 0.1, 0.0, 0.5).finished();
  std::vector<Vec3> sphere;
  TriMesh mesh;
  Ellipsoid() {
    for (const Vec3& p : sphere_mesh.positions) sphere.push_back(p.normalized());
    mesh = sphere_mesh;
    for (Vec3& p : mesh.positions) p = A * p;
  }
};

}  // namespace

TEST(SphereResample, LinearlyDeformedSphere) {
  const EmbreeDevice device;
  const Ellipsoid e;
  const SphericalLocator locator(device, e.mesh, e.sphere);
  for (const Vec3& d : random_directions(2000, 5)) {
    const SphericalLocator::Location loc = locator.locate(d);
    ASSERT_NEAR(loc.barycentric.sum(), 1.0, 1e-12);
    ASSERT_GE(loc.barycentric.minCoeff(), 0.0);
    const Face& f = e.sphere_mesh.faces[loc.face];
    const Vec3 hit = loc.barycentric.x() * e.sphere[f[0]] + loc.barycentric.y() * e.sphere[f[1]] +
                     loc.barycentric.z() * e.sphere[f[2]];
    ASSERT_LT((hit.normalized() - d).norm(), 1e-12) << "the hit lies on the ray from the centre";
    ASSERT_LT((locator.position(d) - e.A * hit).norm(), 1e-12);
  }
}

TEST(SphereResample, VertexDirectionsReturnTheVertices) {
  const EmbreeDevice device;
  const Ellipsoid e;
  const std::vector<Vec3> out = resample_spherical_map(device, e.mesh, e.sphere, e.sphere);
  for (std::size_t v = 0; v < out.size(); ++v) ASSERT_LT((out[v] - e.mesh.positions[v]).norm(), 1e-9) << v;
}

TEST(SphereResample, OctahedralImageOfAnEllipsoidReconstructsClosed) {
  const EmbreeDevice device;
  const Ellipsoid e;
  const DomainImage image(SphericalDomain::Octahedron, 16);
  std::vector<Vec3> directions = domain_positions(image, DomainEmbedding::Sphere);
  const std::vector<Vec3> samples = resample_spherical_map(device, e.mesh, e.sphere, directions);
  const TriMesh r = reconstruct_spherical_image(image, samples);
  const TopologyReport t = analyze_topology(r);
  EXPECT_TRUE(t.closed);
  EXPECT_TRUE(t.manifold);
  EXPECT_EQ(t.euler_characteristic, 2);
}

TEST(SphereResample, RejectsBadInput) {
  const EmbreeDevice device;
  const TriMesh m = make_icosphere(1.0, 1);
  std::vector<Vec3> sphere(m.positions.size(), Vec3(0, 0, 2));
  EXPECT_THROW(SphericalLocator(device, m, sphere), InvalidInput);
  sphere.pop_back();
  EXPECT_THROW(SphericalLocator(device, m, sphere), InvalidInput);
}

// §4.6 optimization of a spherical image: samples of one domain point move together (the image stays
// closed), undefined samples stay undefined, and the fit to a finer surface improves.
TEST(SphereResample, OptimizationKeepsTheImageClosedAndFitsBetter) {
  const EmbreeDevice device;
  const Ellipsoid e;
  TriMesh fine = make_icosphere(1.0, 5);
  for (Vec3& p : fine.positions) p = e.A * p.normalized();
  for (const SphericalDomain domain : {SphericalDomain::Octahedron, SphericalDomain::Cube}) {
    SphericalImage image;
    image.domain = domain;
    image.n = 6;
    const DomainImage layout = image.layout();
    const std::vector<Vec3> samples =
        resample_spherical_map(device, e.mesh, e.sphere, domain_positions(layout, DomainEmbedding::Sphere));
    for (const Vec3& p : samples)
      for (int c = 0; c < 3; ++c) image.positions.push_back(static_cast<float>(p[c]));
    image.mask.assign(layout.num_samples(), 1);
    // One undefined domain point (every sample of it), as a hole leaves.
    const std::vector<std::uint32_t> ids = layout.vertex_ids();
    for (std::size_t k = 0; k < ids.size(); ++k)
      if (ids[k] == ids[layout.num_samples() / 2]) {
        image.mask[k] = 0;
        for (int c = 0; c < 3; ++c) image.positions[3 * k + static_cast<std::size_t>(c)] = std::nanf("");
      }
    SurfaceFitOptions options;
    options.iterations = 15;
    options.smoothness = 1e-5;
    const SurfaceFitResult fit = optimize_spherical_image(device, fine, image, options);
    EXPECT_LT(fit.energy_after, 0.9 * fit.energy_before) << to_string(domain);
    std::vector<int> first(layout.num_domain_points(), -1);
    for (std::size_t k = 0; k < ids.size(); ++k) {
      if (!image.mask[k]) {
        EXPECT_TRUE(std::isnan(image.positions[3 * k]));
        continue;
      }
      if (first[ids[k]] < 0) first[ids[k]] = static_cast<int>(k);
      for (std::size_t c = 0; c < 3; ++c)
        ASSERT_EQ(image.positions[3 * k + c], image.positions[3 * static_cast<std::size_t>(first[ids[k]]) + c]) << k;
    }
    const TriMesh r = reconstruct_spherical_geometry(image);
    const TopologyReport t = analyze_topology(r);
    EXPECT_FALSE(t.closed) << "the undefined point leaves a hole";
    EXPECT_TRUE(t.manifold) << to_string(domain);
  }
}

namespace {

// A hole narrower than the sample spacing holds no sample: the image closes it over, and the statistics say
// so (a new user's cow: 4 holes filled, 3 boundary loops in the reconstruction). A wide hole keeps samples.
TEST(SphereHoles, HolesThatHoldNoSampleAreCounted) {
  const EmbreeDevice device;
  const TriMesh ball = make_icosphere(1.0, 4);  // 5,120 faces
  const auto convert = [&](const std::vector<std::size_t>& removed) {
    TriMesh open = ball;
    open.faces.clear();
    for (std::size_t f = 0; f < ball.faces.size(); ++f)
      if (std::find(removed.begin(), removed.end(), f) == removed.end()) open.faces.push_back(ball.faces[f]);
    std::vector<Vec3> sphere;  // the filled mesh's vertices on the unit sphere: a valid map of a round ball
    for (const Vec3& p : fill_holes(open).mesh.positions) sphere.push_back(p.normalized());
    SphereOptions o;
    o.n = 4;  // 9 x 9 samples
    return convert_with_sphere_map(device, open, sphere, o).stats;
  };
  std::vector<std::size_t> cap;  // every face above z = 0.7: a hole wider than the sample spacing
  for (std::size_t f = 0; f < ball.faces.size(); ++f)
    if (ball.positions[ball.faces[f][0]].z() > 0.7 && ball.positions[ball.faces[f][1]].z() > 0.7 &&
        ball.positions[ball.faces[f][2]].z() > 0.7)
      cap.push_back(f);
  std::size_t tiny = 0;  // one face far from the cap, well below the cap's z
  while (ball.positions[ball.faces[tiny][0]].z() > -0.5) ++tiny;
  std::vector<std::size_t> both = cap;
  both.push_back(tiny);
  const SphereStats wide = convert(cap);
  EXPECT_EQ(wide.holes_filled, 1u);
  EXPECT_GT(wide.masked_samples, 0u);
  EXPECT_EQ(wide.holes_without_samples, 0u);
  const SphereStats two = convert(both);
  EXPECT_EQ(two.holes_filled, 2u);
  EXPECT_EQ(two.holes_without_samples, 1u);
}

}  // namespace
