// The flat-octahedron square as a cut disk for adaptive sampling (kernels/sphere/octa_disk.h).
#include <gtest/gtest.h>

#include <map>

#include "kernels/adaptive/sample_adjust.h"
#include "kernels/core/surface_sampling.h"
#include "kernels/core/procedural.h"
#include "kernels/core/topology.h"
#include "kernels/sphere/domain_map.h"
#include "kernels/sphere/octa_disk.h"
#include "kernels/sphere/sphere_convert.h"
#include "kernels/core/errors.h"
#include "kernels/sphere/sphere_resample.h"
#include "kernels/sphere/spherical_domain.h"

using namespace gimforge;

namespace {

/// An icosphere's own sphere map, the mesh deformed by a linear map.
struct Ellipsoid {
  TriMesh mesh;
  std::vector<Vec3> sphere;
  explicit Ellipsoid(int subdivisions) {
    mesh = make_icosphere(1.0, subdivisions);
    const Eigen::Matrix3d a = (Eigen::Matrix3d() << 2.0, 0.3, 0.0, 0.0, 1.0, 0.0, 0.1, 0.0, 0.5).finished();
    for (Vec3& p : mesh.positions) {
      sphere.push_back(p.normalized());
      p = a * p + Vec3(5e5, -3e5, 200.0);  // far from the origin: the cut works on sphere points only
    }
  }
};

void expect_disk(const Ellipsoid& e, const OctaDisk& d) {
  const TopologyReport t = analyze_topology(d.disk);
  EXPECT_EQ(t.euler_characteristic, 1);
  EXPECT_EQ(t.boundary_loops, 1u);
  EXPECT_EQ(t.nonmanifold_edges, 0u);
  EXPECT_EQ(t.nonmanifold_vertices, 0u);
  EXPECT_EQ(t.inconsistent_edges, 0u);
  EXPECT_EQ(d.flipped, 0u);  // slivers turned by the straight layout near a side midpoint are untangled
  EXPECT_EQ(d.flipped_area, 0.0);
  ASSERT_EQ(d.face_origin.size(), d.disk.faces.size());
  // The same surface, face for face; the square covered once.
  EXPECT_NEAR(surface_area(d.disk), surface_area(e.mesh), 1e-9 * surface_area(e.mesh));
  double uv_area = 0.0;
  for (std::size_t f = 0; f < d.disk.faces.size(); ++f) {
    const Face& g = d.disk.faces[f];
    const Vec2 a = d.uv[g[1]] - d.uv[g[0]], b = d.uv[g[2]] - d.uv[g[0]];
    uv_area += 0.5 * (a.x() * b.y() - a.y() * b.x());
    const Face& o = e.mesh.faces[d.face_origin[f]];
    const Vec3 n = (e.mesh.positions[o[1]] - e.mesh.positions[o[0]]).cross(e.mesh.positions[o[2]] - e.mesh.positions[o[0]]).normalized();
    for (const std::uint32_t v : g) ASSERT_NEAR(n.dot(d.disk.positions[v] - e.mesh.positions[o[0]]), 0.0, 1e-8);
  }
  EXPECT_NEAR(uv_area, 1.0, 1e-12);
  // Boundary vertices lie on the sides, and each one's mate (the side folded about its midpoint) holds the
  // same surface point.
  std::map<std::pair<double, double>, Vec3> at;
  for (std::size_t v = 0; v < d.uv.size(); ++v) {
    const Vec2& q = d.uv[v];
    ASSERT_TRUE(q.x() >= 0.0 && q.x() <= 1.0 && q.y() >= 0.0 && q.y() <= 1.0);
    at[{q.x(), q.y()}] = d.disk.positions[v];
  }
  const std::vector<std::uint32_t> boundary = [&] {
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> edges;
    for (const Face& f : d.disk.faces)
      for (std::size_t k = 0; k < 3; ++k) ++edges[{std::min(f[k], f[(k + 1) % 3]), std::max(f[k], f[(k + 1) % 3])}];
    std::vector<std::uint32_t> out;
    for (const auto& [e2, count] : edges)
      if (count == 1) out.push_back(e2.first), out.push_back(e2.second);
    return out;
  }();
  ASSERT_FALSE(boundary.empty());
  for (const std::uint32_t v : boundary) {
    const Vec2& q = d.uv[v];
    const bool side_x = q.x() == 0.0 || q.x() == 1.0, side_y = q.y() == 0.0 || q.y() == 1.0;
    ASSERT_TRUE(side_x || side_y) << q.transpose();
    const Vec2 mate = side_x ? Vec2(q.x(), 1.0 - q.y()) : Vec2(1.0 - q.x(), q.y());
    const auto it = at.find({mate.x(), mate.y()});
    ASSERT_NE(it, at.end()) << "no mate for " << q.transpose();
    EXPECT_EQ(it->second, d.disk.positions[v]);
  }
}

}  // namespace

TEST(OctaDisk, EllipsoidIsCutIntoTheSquare) {
  const EmbreeDevice device;
  const Ellipsoid e(3);
  const OctaDisk d = cut_flat_octahedron(device, e.mesh, e.sphere);
  expect_disk(e, d);
  // The disk's parametrization follows the domain map: on the image lattice the surface points agree
  // with the image's own resampling (I → D → S → M) up to a part of an edge (the disk is linear in D, the
  // image on the sphere, and this mesh's edges are 0.2 rad long; a vertex within a fifth of an edge of a
  // seam point becomes that point).
  const std::uint32_t n = 16;
  const DomainImage image(SphericalDomain::FlatOctahedron, n);
  const std::vector<Vec3> directions = sample_domain_map(builtin_domain_map(SphericalDomain::FlatOctahedron), image);
  const std::vector<Vec3> exact = resample_spherical_map(device, e.mesh, e.sphere, directions);
  const ParametrizedSurface surface(device, d.disk, d.uv);
  const Face& f0 = e.mesh.faces[0];
  const double edge = (e.mesh.positions[f0[1]] - e.mesh.positions[f0[0]]).norm();
  double worst = 0.0;
  for (std::size_t k = 0; k < exact.size(); ++k) {
    const SampleIndex s = image.sample_at(k);
    const Vec2 uv(static_cast<double>(s.i) / (image.width() - 1), static_cast<double>(s.j) / (image.height() - 1));
    worst = std::max(worst, (surface.at(uv).position - exact[k]).norm());
  }
  EXPECT_LT(worst, 0.25 * edge);
}

TEST(OctaDisk, CoarseMeshIsRefinedFirst) {
  const EmbreeDevice device;
  const Ellipsoid e(0);  // 20 faces, each a fifth of a hemisphere
  const OctaDisk d = cut_flat_octahedron(device, e.mesh, e.sphere, 0.2);
  expect_disk(e, d);
  EXPECT_GE(d.disk.faces.size(), 1024u);
}

TEST(OctaDisk, AnyRotationOfTheSphereMapCuts) {
  // The seam points fall anywhere among the triangles: inside, near edges, near vertices.
  const EmbreeDevice device;
  for (std::uint64_t seed = 1; seed <= 12; ++seed) {
    Ellipsoid e(3);
    const Eigen::Quaterniond q = Eigen::Quaterniond(uniform01(seed, 0) - 0.5, uniform01(seed, 1) - 0.5,
                                                    uniform01(seed, 2) - 0.5, uniform01(seed, 3) - 0.5)
                                     .normalized();
    for (Vec3& s : e.sphere) s = (q * s).normalized();
    SCOPED_TRACE(seed);
    expect_disk(e, cut_flat_octahedron(device, e.mesh, e.sphere));
  }
}

TEST(OctaDisk, CoarseSpheresUnderRandomRotations) {
  // A second review found coarse maps (20 to 320 faces) whose cut turned faces over or stepped backwards
  // along a side, and passed its check: coarse meshes are now subdivided first, and the check walks the
  // boundary in order and compares mates.
  const EmbreeDevice device;
  for (int subdivisions = 0; subdivisions <= 2; ++subdivisions)
    for (std::uint64_t seed = 1; seed <= 20; ++seed) {
      Ellipsoid e(subdivisions);
      const Eigen::Quaterniond q = Eigen::Quaterniond(uniform01(seed, 7) - 0.5, uniform01(seed, 8) - 0.5,
                                                      uniform01(seed, 9) - 0.5, uniform01(seed, 10) - 0.5)
                                       .normalized();
      for (Vec3& x : e.sphere) x = (q * x).normalized();
      SCOPED_TRACE(::testing::Message() << "subdivisions " << subdivisions << " seed " << seed);
      expect_disk(e, cut_flat_octahedron(device, e.mesh, e.sphere));  // no turned face, mates equal
    }
}

TEST(OctaDisk, VertexAtASeamPointBecomesIt) {
  // A vertex a hair's breadth from an equator vertex (a review found the cut then was not a disk, or threw).
  const EmbreeDevice device;
  const DomainSphereMap& map = builtin_domain_map(SphericalDomain::FlatOctahedron);
  const DomainImage image(SphericalDomain::FlatOctahedron, map.n);
  const Vec3 cone = map.sphere[image.linear_index({0, image.width() - 1, image.n()})];
  for (const double offset : {0.0, 1e-12, 1e-9, 1e-6, 1e-4}) {
    Ellipsoid e(3);
    // Rotate the map so that vertex 5 lies `offset` from the cone point.
    const Eigen::Quaterniond to_cone = Eigen::Quaterniond::FromTwoVectors(e.sphere[5], cone);
    for (Vec3& s : e.sphere) s = (to_cone * s).normalized();
    const Vec3 off = (cone.cross(Vec3(0.3, 0.5, 0.8))).normalized();
    e.sphere[5] = (cone + offset * off).normalized();
    SCOPED_TRACE(offset);
    expect_disk(e, cut_flat_octahedron(device, e.mesh, e.sphere));
  }
}

TEST(OctaDisk, TetrahedronMapWithLargeTriangles) {
  // Four vertices: every seam point inside a triangle spanning a quarter of the sphere.
  const EmbreeDevice device;
  Ellipsoid e(0);
  e.mesh.positions = {Vec3(1, 1, 1), Vec3(1, -1, -1), Vec3(-1, 1, -1), Vec3(-1, -1, 1)};
  e.mesh.faces = {{0, 1, 2}, {0, 3, 1}, {0, 2, 3}, {1, 3, 2}};
  e.sphere.clear();
  for (const Vec3& p : e.mesh.positions) e.sphere.push_back(p.normalized());
  expect_disk(e, cut_flat_octahedron(device, e.mesh, e.sphere));
}

TEST(OctaDisk, GlueFoldsEverySideAboutItsMidpoint) {
  const PerimeterGlue glue = flat_octahedron_glue([](const Vec2& p) { return Vec3(p.x(), p.y(), 0.0); });
  EXPECT_DOUBLE_EQ(glue.mate(0.25), 0.75);
  EXPECT_DOUBLE_EQ(glue.mate(1.1), 1.9);
  EXPECT_DOUBLE_EQ(glue.mate(3.75), 3.25);
  for (const double c : {0.0, 0.5, 1.0, 2.5, 3.0, 3.5}) EXPECT_TRUE(glue.node(c)) << c;
  EXPECT_FALSE(glue.node(0.3));
  // Both mates ask for the same point.
  EXPECT_EQ(glue.position(2.2), glue.position(2.8));
  EXPECT_EQ(glue.position(0.1), Vec3(0.1, 0.0, 0.0));
}

TEST(OctaDisk, MismatchedSphereIsRefused) {
  const EmbreeDevice device;
  const Ellipsoid e(1);
  std::vector<Vec3> short_sphere(e.sphere.begin(), e.sphere.end() - 1);
  EXPECT_THROW((void)cut_flat_octahedron(device, e.mesh, short_sphere), InvalidInput);
}

namespace {

/// A bumpy closed genus-0 surface over the icosphere (its own sphere map): a sharp ridge that the uniform
/// samples cut across.
struct Bumpy {
  TriMesh mesh = make_icosphere(1.0, 3);
  std::vector<Vec3> sphere;
  Bumpy() {
    for (Vec3& p : mesh.positions) {
      const Vec3 u = p.normalized();
      sphere.push_back(u);
      p = u * (1.0 + 0.25 * std::max(0.0, 1.0 - 8.0 * std::abs(u.x() - 0.3))) + Vec3(4e5, 0.0, -7e3);
    }
  }
};

}  // namespace

namespace {

/// Adaptive sampling of the flat-octahedron image at tessellation n, at most `rounds` rounds.
SphereOptions adaptive_flat_octahedron(std::uint32_t n, std::uint32_t rounds) {
  SphereOptions o;
  o.domain = SphericalDomain::FlatOctahedron;
  o.n = n;
  o.adaptive = true;
  o.adapt.rounds = rounds;
  return o;
}

/// Side samples of a flat-octahedron image sit at the mirror of their mate, on the surface at the same
/// point, and the reconstruction is closed.
void expect_glued(const SphereResult& r) {
  const std::uint32_t w = 2 * r.image.n + 1;
  ASSERT_EQ(r.image.sample_uv.size(), 2u * w * w);
  const auto uv = [&](std::uint32_t i, std::uint32_t j) {
    const std::size_t k = std::size_t{j} * w + i;
    return Vec2(r.image.sample_uv[2 * k], r.image.sample_uv[2 * k + 1]);
  };
  const auto pos = [&](std::uint32_t i, std::uint32_t j) {
    const std::size_t k = 3 * (std::size_t{j} * w + i);
    return Vec3f(r.image.positions[k], r.image.positions[k + 1], r.image.positions[k + 2]);
  };
  for (std::uint32_t i = 0; i < w; ++i) {
    EXPECT_NEAR(uv(i, 0).x(), 1.0 - uv(w - 1 - i, 0).x(), 1e-6) << i;
    EXPECT_NEAR(uv(i, w - 1).x(), 1.0 - uv(w - 1 - i, w - 1).x(), 1e-6) << i;
    EXPECT_NEAR(uv(0, i).y(), 1.0 - uv(0, w - 1 - i).y(), 1e-6) << i;
    EXPECT_NEAR(uv(w - 1, i).y(), 1.0 - uv(w - 1, w - 1 - i).y(), 1e-6) << i;
    EXPECT_EQ(pos(i, 0), pos(w - 1 - i, 0));
    EXPECT_EQ(pos(0, i), pos(0, w - 1 - i));
    EXPECT_EQ(pos(i, w - 1), pos(w - 1 - i, w - 1));
    EXPECT_EQ(pos(w - 1, i), pos(w - 1, w - 1 - i));
  }
  const TopologyReport t = analyze_topology(reconstruct_spherical_geometry(r.image));
  EXPECT_TRUE(t.closed);
  EXPECT_EQ(t.nonmanifold_edges, 0u);
}

}  // namespace

TEST(SphereAdapt, FlatOctahedronSamplesMoveAndStayGlued) {
  const EmbreeDevice device;
  const Bumpy b;
  SphereOptions o;
  o.domain = SphericalDomain::FlatOctahedron;
  o.n = 6;
  const SphereResult uniform = convert_with_sphere_map(device, b.mesh, b.sphere, o);
  EXPECT_TRUE(uniform.image.sample_uv.empty());
  o.adaptive = true;
  o.adapt.rounds = 2;
  const SphereResult r = convert_with_sphere_map(device, b.mesh, b.sphere, o);
  const std::uint32_t w = 2 * o.n + 1;
  ASSERT_EQ(r.image.sample_uv.size(), 2u * w * w);
  ASSERT_GE(r.stats.adapt_history.size(), 2u);
  const AdaptRound &first = r.stats.adapt_history.front(), &last = r.stats.adapt_history.back();
  EXPECT_LT(std::max(last.max_d1, last.max_d2), std::max(first.max_d1, first.max_d2));
  std::uint64_t moves = 0;
  for (const AdaptRound& round : r.stats.adapt_history) moves += round.moves;
  EXPECT_GT(moves, 0u);
  // Seam points held, sides folded: mates mirrored in the square and equal on the surface; the
  // reconstruction closed and manifold.
  const auto uv = [&](std::uint32_t i, std::uint32_t j) {
    const std::size_t k = std::size_t{j} * w + i;
    return Vec2(r.image.sample_uv[2 * k], r.image.sample_uv[2 * k + 1]);
  };
  EXPECT_EQ(uv(0, 0), Vec2(0, 0));
  EXPECT_EQ(uv(o.n, 0), Vec2(0.5, 0));
  EXPECT_EQ(uv(w - 1, o.n), Vec2(1, 0.5));
  for (std::uint32_t i = 0; i < w; ++i) EXPECT_EQ(uv(i, 0).y(), 0.0);
  expect_glued(r);
  EXPECT_EQ(analyze_topology(reconstruct_spherical_geometry(r.image)).euler_characteristic, 2);
}

TEST(SphereAdapt, RefusedWhereNotBuilt) {
  const EmbreeDevice device;
  const Bumpy b;
  SphereOptions o;
  o.n = 4;
  o.adaptive = true;
  o.domain = SphericalDomain::Octahedron;
  EXPECT_THROW((void)convert_with_sphere_map(device, b.mesh, b.sphere, o), InvalidInput);
  // A mesh with a hole: its samples there are undefined.
  TriMesh open = b.mesh;
  open.faces.pop_back();
  o.domain = SphericalDomain::FlatOctahedron;
  try {
    (void)convert_to_spherical_image(device, open, o);
    FAIL() << "no error";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("closed mesh"), std::string::npos) << e.what();
  }
}

TEST(SphereAdapt, StripsStartKeepsTheSidesFolded) {
  const EmbreeDevice device;
  const Bumpy b;
  SphereOptions o = adaptive_flat_octahedron(6, 1);
  o.adapt_start = AdaptStart::Strips;
  const SphereResult r = convert_with_sphere_map(device, b.mesh, b.sphere, o);
  EXPECT_TRUE(r.stats.adapt_started_from_strips);
  expect_glued(r);
}

TEST(SphereAdapt, RegionOfInterestGetsSamplesAndItsErrorFalls) {
  const EmbreeDevice device;
  const Bumpy b;
  SphereOptions o = adaptive_flat_octahedron(8, 4);
  o.roi.kind = RoiSource::Kind::Vertices;
  // The ridge: the faces touching a vertex within 0.12 of it.
  for (const Vec3& u : b.sphere) o.roi.vertices.push_back(std::abs(u.x() - 0.3) < 0.12 ? 1 : 0);
  const SphereResult r = convert_with_sphere_map(device, b.mesh, b.sphere, o);
  const std::uint32_t w = 2 * o.n + 1;
  const RoiSummary& roi = r.stats.roi;
  ASSERT_EQ(roi.inside.size(), std::size_t{w} * w);
  EXPECT_GT(roi.samples_start, 0u);
  EXPECT_GT(roi.samples_enhanced, roi.samples_start + roi.samples_start / 2);
  std::uint64_t flagged = 0;
  const Vec3 centre(4e5, 0.0, -7e3);
  for (std::size_t k = 0; k < roi.inside.size(); ++k) {
    if (!roi.inside[k]) continue;
    ++flagged;
    const Vec3 p(r.image.positions[3 * k], r.image.positions[3 * k + 1], r.image.positions[3 * k + 2]);
    EXPECT_NEAR((p - centre).normalized().x(), 0.3, 0.3) << k;  // on the ridge's faces (they reach a little further)
  }
  EXPECT_EQ(flagged, roi.samples_final);
  // Mated side samples (one surface point) and the four corners (the pole) are in the ROI together.
  const auto in = [&](std::uint32_t i, std::uint32_t j) { return roi.inside[std::size_t{j} * w + i]; };
  for (std::uint32_t i = 0; i < w; ++i) {
    EXPECT_EQ(in(i, 0), in(w - 1 - i, 0)) << i;
    EXPECT_EQ(in(i, w - 1), in(w - 1 - i, w - 1)) << i;
    EXPECT_EQ(in(0, i), in(0, w - 1 - i)) << i;
    EXPECT_EQ(in(w - 1, i), in(w - 1, w - 1 - i)) << i;
  }
  EXPECT_EQ(in(0, 0), in(w - 1, w - 1));
  // The objective, the ROI's D2, never rises, and ends below the start grid's.
  ASSERT_GE(r.stats.adapt_history.size(), 2u);
  for (std::size_t k = 1; k < r.stats.adapt_history.size(); ++k)
    EXPECT_LE(r.stats.adapt_history[k].roi.max_d2, r.stats.adapt_history[k - 1].roi.max_d2);
  EXPECT_LT(r.stats.adapt_history.back().roi.max_d2, roi.roi_start.max_d2);
  expect_glued(r);
  // Auto: a window of the square; a ROI without adaptive sampling, or with flags for other vertices, is refused.
  SphereOptions automatic = o;
  automatic.roi.kind = RoiSource::Kind::Auto;
  automatic.adapt.rounds = 1;
  const SphereResult a = convert_with_sphere_map(device, b.mesh, b.sphere, automatic);
  EXPECT_GT(a.stats.roi.samples_enhanced, a.stats.roi.samples_start);
  expect_glued(a);
  SphereOptions uniform = o;
  uniform.adaptive = false;
  EXPECT_THROW((void)convert_with_sphere_map(device, b.mesh, b.sphere, uniform), InvalidInput);
  SphereOptions short_flags = o;
  short_flags.roi.vertices.resize(5);
  EXPECT_THROW((void)convert_with_sphere_map(device, b.mesh, b.sphere, short_flags), InvalidInput);
}
