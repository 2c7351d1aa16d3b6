// Relief-map construction (§3.3), quantization and geometry-based reconstruction (§3.5.1).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/procedural.h"
#include "kernels/relief/relief_map.h"

namespace gimforge {
namespace {

/// Axis-aligned cube [-h, h]³, each face split into s×s quads (two triangles each), outward orientation.
TriMesh make_cube(double h, int s) {
  TriMesh m;
  for (int axis = 0; axis < 3; ++axis) {
    for (int side = 0; side < 2; ++side) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      const auto base = static_cast<std::uint32_t>(m.positions.size());
      for (int j = 0; j <= s; ++j)
        for (int i = 0; i <= s; ++i) {
          Vec3 p;
          p[axis] = side ? h : -h;
          p[u] = -h + 2 * h * i / s;
          p[v] = -h + 2 * h * j / s;
          m.positions.push_back(p);
        }
      const auto at = [&](int i, int j) { return base + static_cast<std::uint32_t>(j * (s + 1) + i); };
      for (int j = 0; j < s; ++j)
        for (int i = 0; i < s; ++i) {
          // (u, v, axis) is right-handed: counter-clockwise in (u, v) faces +axis.
          if (side) {
            m.faces.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
            m.faces.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
          } else {
            m.faces.push_back({at(i, j), at(i + 1, j + 1), at(i + 1, j)});
            m.faces.push_back({at(i, j), at(i, j + 1), at(i + 1, j + 1)});
          }
        }
    }
  }
  return m;
}

double psnr_of(const TriMesh& original, const TriMesh& reconstruction) {
  HausdorffOptions o;
  o.samples = 100'000;
  return symmetric_hausdorff(EmbreeDevice(), original, reconstruction, o).psnr;
}

TEST(ReliefQuantization, RoundTripsWithinHalfAStep) {
  const double cell = 0.37;
  const double scale = distance_scale_for(cell);
  EXPECT_DOUBLE_EQ(scale * kMaxQuantizedDistance, kMaxProjectionLength * cell);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> d(0.0, kMaxProjectionLength * cell);
  std::uint16_t previous = 0;
  double previous_d = 0.0;
  for (int k = 0; k < 100000; ++k) {
    const double x = d(rng);
    const std::uint16_t q = quantize_distance(x, scale);
    ASSERT_NE(q, kEmptyTexel);
    ASSERT_LE(std::abs(dequantize_distance(q, scale) - x), 0.5 * scale * (1 + 1e-12)) << x;
    if (x >= previous_d) {
      EXPECT_GE(q, previous);  // monotone (compare with the previous draw when larger)
    }
    previous = q;
    previous_d = x;
  }
  EXPECT_EQ(quantize_distance(0.0, scale), 0);
  EXPECT_EQ(quantize_distance(kMaxProjectionLength * cell, scale), kMaxQuantizedDistance);
  EXPECT_EQ(quantize_distance(10.0 * cell, scale), kMaxQuantizedDistance);  // clamped, never the empty code
  EXPECT_EQ(quantize_distance(-1e-9, scale), 0);
}

// Four collinear points: nothing to sample. It was stored as a map of empty texels (exit 0) that render
// and reconstruct then refused.
TEST(ReliefMap, AMeshWithoutSurfaceAreaIsRefused) {
  TriMesh line;
  line.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3(3, 0, 0)};
  line.faces = {{0, 1, 2}, {1, 2, 3}};
  try {
    (void)build_relief_map(line, ReliefOptions{});
    ADD_FAILURE() << "no error";
  } catch (const InvalidInput& e) {
    EXPECT_STREQ(e.what(), "relief map: the mesh has no surface area");
  }
}

TEST(ReliefMap, SpherePointsLieOnTheSphere) {
  const double r = 1.3;
  const TriMesh sphere = make_icosphere(r, 5);
  ReliefOptions o;
  o.grid = 4;
  o.texture = 16;
  const ReliefMap map = build_relief_map(sphere, o);
  map.check();
  EXPECT_EQ(map.n, 4u);
  ASSERT_EQ(map.levels.size(), 1u);
  EXPECT_FALSE(map.cells.empty());
  EXPECT_EQ(map.distances.size(), map.num_layers() * 16 * 16);
  EXPECT_TRUE(map.colors.empty());
  // The icosphere's flat faces lie inside the sphere by up to r(1 − cos(edge / 2)).
  const double chord_sag = r * 0.0025;
  std::size_t filled = 0;
  for (std::size_t l = 0; l < map.num_layers(); ++l)
    for (std::uint32_t j = 0; j < 16; ++j)
      for (std::uint32_t i = 0; i < 16; ++i) {
        const std::size_t t = map.texel_index(l, i, j);
        if (map.distances[t] == kEmptyTexel) continue;
        ++filled;
        const Vec3 p = map.texel_surface_point(l, i, j);
        ASSERT_NEAR(p.norm(), r - chord_sag / 2, chord_sag / 2 + map.distance_scale + 1e-6) << "layer " << l;
        // The stored normal is the outward unit normal, up to the 8-bit quantization and the faceting.
        const Vec3 nrm(map.normals[3 * t] / 127.0, map.normals[3 * t + 1] / 127.0, map.normals[3 * t + 2] / 127.0);
        EXPECT_GT(nrm.normalized().dot(p.normalized()), 0.99);
        // The point lies in its cell.
        const Vec3 local = (p - map.cell_min(map.layer_cell[l])) / map.cell_size;
        EXPECT_GE(local.minCoeff(), -1e-6);
        EXPECT_LE(local.maxCoeff(), 1 + 1e-6);
      }
  EXPECT_GT(filled, map.num_layers() * 16 * 16 / 4);
}

TEST(ReliefMap, CubeReconstructsWithinTolerance) {
  const TriMesh cube = make_cube(1.0, 4);
  ReliefOptions o;
  o.grid = 1;  // one grey cell, case 0: perspective from the centre sees the whole cube
  o.texture = 32;
  const ReliefMap map = build_relief_map(cube, o);
  ASSERT_EQ(map.cells.size(), 1u);
  EXPECT_EQ(map.projections[0].base_case, ReliefCase::k0);
  EXPECT_EQ(map.num_layers(), 6u);
  EXPECT_EQ(map.levels[0].occluded, 0u);
  const TriMesh rec = reconstruct_relief(map);
  EXPECT_GT(rec.num_faces(), 6u * 31 * 31);
  EXPECT_GT(psnr_of(cube, rec), 80.0);
  // Every reconstructed vertex lies on the cube's surface (one coordinate at ±1).
  for (const Vec3& p : rec.positions) ASSERT_NEAR(p.cwiseAbs().maxCoeff(), 1.0, 1e-4);
  // Reconstructed faces are oriented like the input's (outwards).
  std::size_t outward = 0;
  for (const Face& f : rec.faces) {
    const Vec3 c = (rec.positions[f[0]] + rec.positions[f[1]] + rec.positions[f[2]]) / 3;
    const Vec3 n = (rec.positions[f[1]] - rec.positions[f[0]]).cross(rec.positions[f[2]] - rec.positions[f[0]]);
    outward += n.dot(c) > 0 ? 1u : 0u;
  }
  EXPECT_EQ(outward, rec.num_faces());
}

TEST(ReliefMap, SphereReconstructsWithinTolerance) {
  const TriMesh sphere = make_icosphere(1.0, 5);
  for (const std::uint32_t n : {1u, 4u, 8u}) {
    ReliefOptions o;
    o.grid = n;
    o.texture = 32;
    const ReliefMap map = build_relief_map(sphere, o);
    const TriMesh rec = reconstruct_relief(map);
    EXPECT_GT(psnr_of(sphere, rec), 60.0) << "grid " << n;
  }
}

TEST(ReliefMap, ThinSheetsKeepTheirRimCells) {
  // A flat square (and one with 10^-4 of noise) lies in one layer of cells, off their centres and axes of
  // projection. Centred, it lay on the planes between layers (even N) or in a layer's middle (odd N), which
  // hold the rim cells' centres and axes of projection: those cells saw it edge-on and lost it. At T = 32:
  // 13.8 / 13.8 / 19.1 / 31.9 dB at N = 1 / 2 / 3 / 8, now 48.6 / 48.6 / 54.0 / 67.3 dB.
  TriMesh flat = make_grid(24, 24, 1.0);
  TriMesh noisy = flat;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-1e-4, 1e-4);
  for (Vec3& p : noisy.positions) p.z() = jitter(rng);
  for (const TriMesh* sheet : {&flat, &noisy})
    for (const std::uint32_t n : {1u, 2u, 3u, 8u}) {
      ReliefOptions o;
      o.grid = n;
      o.texture = 32;
      const ReliefMap map = build_relief_map(*sheet, o);
      const TriMesh rec = reconstruct_relief(map);
      EXPECT_GT(psnr_of(*sheet, rec), 45.0) << (sheet == &flat ? "flat" : "noisy") << ", grid " << n;
      // Every cell holding the sheet lies in the one middle layer.
      for (const std::uint32_t c : map.cells) EXPECT_EQ(c / (n * n), n / 2) << "grid " << n;
    }
  // The placement follows the sheet (translation moves the cube with it) ...
  TriMesh far = flat;
  for (Vec3& p : far.positions) p += Vec3(4e5, 5e6, 250.0);
  ReliefOptions o;
  o.grid = 4;
  const ReliefMap near_map = build_relief_map(flat, o);
  const ReliefMap far_map = build_relief_map(far, o);
  EXPECT_NEAR(far_map.origin.z() - 250.0, near_map.origin.z(), 1e-9);
  EXPECT_EQ(far_map.cells.size(), near_map.cells.size());
  // ... and a mesh thicker than a quarter cell keeps the centred cube.
  const ReliefMap sphere = build_relief_map(make_icosphere(1.0, 2), o);
  EXPECT_NEAR(sphere.origin.z() + 2.0 * sphere.cell_size, 0.0, 1e-12);
}

TEST(ReliefMap, AutomaticGridDoublesWhileSamplesAreOccluded) {
  // One sphere seen from the centre of the single cell: no point is occluded, N = 1 suffices.
  const TriMesh sphere = make_icosphere(1.0, 4);
  ReliefOptions o;
  o.texture = 16;
  const ReliefMap one = build_relief_map(sphere, o);
  ASSERT_EQ(one.levels.size(), 1u);
  EXPECT_EQ(one.n, 1u);
  EXPECT_LT(one.levels[0].occlusion_ratio(), 0.001);
  // Two concentric spheres: from the centre the inner one hides the outer one (ratio 1/2 at N = 1).
  TriMesh shells = concatenate(make_icosphere(1.0, 4), make_icosphere(0.5, 4));
  o.max_grid = 16;
  o.occlusion_threshold = 0.05;
  const ReliefMap map = build_relief_map(shells, o);
  ASSERT_GE(map.levels.size(), 2u);
  EXPECT_NEAR(map.levels[0].occlusion_ratio(), 0.5, 0.05);
  for (std::size_t k = 1; k < map.levels.size(); ++k) {
    EXPECT_EQ(map.levels[k].n, 2 * map.levels[k - 1].n);
    EXPECT_GT(map.levels[k - 1].occlusion_ratio(), o.occlusion_threshold);
  }
  EXPECT_EQ(map.n, map.levels.back().n);
  EXPECT_TRUE(map.levels.back().occlusion_ratio() <= o.occlusion_threshold || map.n == o.max_grid);
}

TEST(ReliefMap, AutomaticGridDoublesWhileMostFacesAreSeenEdgeOn) {
  // A tilted square through the centre of its one cell: every projection ray runs in its plane, so it has
  // few samples and none occluded, and the paper's rule kept N = 1, whose map reconstructs to a blob.
  TriMesh square = make_grid(20, 20, 1.0);
  for (Vec3& p : square.positions) p.z() = 0.3 * p.x() + 0.2 * p.y();
  ReliefOptions o;
  o.texture = 16;
  const ReliefMap map = build_relief_map(square, o);
  ASSERT_GE(map.levels.size(), 2u);
  EXPECT_EQ(map.levels[0].n, 1u);
  EXPECT_EQ(map.levels[0].faces, square.num_faces());
  EXPECT_EQ(map.levels[0].edge_on, square.num_faces());
  EXPECT_LE(map.levels[0].occlusion_ratio(), o.occlusion_threshold);
  EXPECT_GT(map.n, 2u) << "at N = 2 the square passes through the cells' common vertex, their centre of projection";
  EXPECT_LE(map.levels.back().edge_on_ratio(), kEdgeOnRatioLimit);
  // A sphere sees almost none of its faces edge-on from the centre, and keeps N = 1.
  const ReliefMap sphere = build_relief_map(make_icosphere(1.0, 4), o);
  EXPECT_EQ(sphere.n, 1u);
  EXPECT_LT(sphere.levels[0].edge_on_ratio(), 0.01);
}

TEST(ReliefMap, ColoursAreSampledFromVertexColours) {
  TriMesh sphere = make_icosphere(1.0, 4);
  for (const Vec3& p : sphere.positions)
    sphere.colors.push_back(((p.array() + 1.0) / 2.0).matrix().cast<float>());
  ReliefOptions o;
  o.grid = 2;
  o.texture = 8;
  const ReliefMap map = build_relief_map(sphere, o);
  ASSERT_EQ(map.colors.size(), map.distances.size() * 3);
  for (std::size_t l = 0; l < map.num_layers(); ++l)
    for (std::uint32_t j = 0; j < 8; ++j)
      for (std::uint32_t i = 0; i < 8; ++i) {
        const std::size_t t = map.texel_index(l, i, j);
        if (map.distances[t] == kEmptyTexel) continue;
        const Vec3 expected = (map.texel_surface_point(l, i, j).array() + 1.0) / 2.0 * 255.0;
        for (int c = 0; c < 3; ++c) ASSERT_NEAR(map.colors[3 * t + static_cast<std::size_t>(c)], expected[c], 3.0);
      }
}

// ---- The sampler against a brute-force reference (§3.3.2) ------------------------------------------------

/// Closest distance between the segments p1q1 and p2q2 (Ericson, Real-Time Collision Detection, §5.1.9).
double segment_distance(const Vec3& p1, const Vec3& q1, const Vec3& p2, const Vec3& q2) {
  const Vec3 d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  double s = 0.0, t = 0.0;
  if (a == 0.0 && e == 0.0) return r.norm();
  if (a == 0.0) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e == 0.0) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2), denom = a * e - b * b;
      s = denom != 0.0 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0.0) {
        t = 0.0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1.0) {
        t = 1.0;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return ((p1 + s * d1) - (p2 + t * d2)).norm();
}

/// What the projection segment org + t·dir, t ∈ [0, tmax], meets, found by testing every triangle of the
/// mesh in world coordinates (plane intersection, then the signs of the three sub-triangle areas).
struct ReferenceTexel {
  bool hit{false};
  double t{0.0};                 ///< nearest hit
  std::uint32_t face{0};         ///< its triangle (the lowest index among equal t)
  double next_other{std::numeric_limits<double>::infinity()};  ///< nearest hit on any other triangle
  std::uint64_t occluded{0};     ///< hits farther than 1e-9 · cell from the nearest
  /// The segment passes within 1e-7 · cell of a triangle edge, or a hit lies within 1e-7 · cell of an end
  /// of the segment: the exact answer depends on the rounding.
  bool ambiguous{false};
};

ReferenceTexel reference_texel(const TriMesh& mesh, const Vec3& org, const Vec3& dir, double tmax, double cell) {
  const double eps = 1e-7 * cell;
  const Vec3 end = org + tmax * dir;
  const Vec3 lo = org.cwiseMin(end) - Vec3::Constant(eps), hi = org.cwiseMax(end) + Vec3::Constant(eps);
  ReferenceTexel r;
  std::vector<std::pair<double, std::uint32_t>> hits;
  for (std::uint32_t f = 0; f < mesh.faces.size(); ++f) {
    const Vec3& a = mesh.positions[mesh.faces[f][0]];
    const Vec3& b = mesh.positions[mesh.faces[f][1]];
    const Vec3& c = mesh.positions[mesh.faces[f][2]];
    const Vec3 n = (b - a).cross(c - a);
    if (n.squaredNorm() == 0.0) continue;
    if ((a.cwiseMin(b).cwiseMin(c).array() > hi.array()).any() || (a.cwiseMax(b).cwiseMax(c).array() < lo.array()).any())
      continue;
    if (segment_distance(org, end, a, b) < eps || segment_distance(org, end, b, c) < eps ||
        segment_distance(org, end, c, a) < eps)
      r.ambiguous = true;
    const double denom = n.dot(dir);
    if (denom == 0.0) continue;
    const double t = n.dot(a - org) / denom;
    if (t < -eps || t > tmax + eps) continue;
    const Vec3 p = org + t * dir;
    // Inside when the three sub-triangles are oriented like the triangle; a relative slack of 1e-12 keeps
    // segments through a shared edge from slipping between its two triangles.
    const double slack = -1e-12 * n.squaredNorm();
    if (n.dot((b - p).cross(c - p)) < slack || n.dot((c - p).cross(a - p)) < slack || n.dot((a - p).cross(b - p)) < slack)
      continue;
    if (t < eps || t > tmax - eps) r.ambiguous = true;
    if (t < 0.0 || t > tmax) continue;
    hits.emplace_back(t, f);
  }
  if (hits.empty()) return r;
  std::sort(hits.begin(), hits.end());
  r.hit = true;
  r.t = hits[0].first;
  r.face = hits[0].second;
  for (const auto& [t, f] : hits) {
    if (t - r.t > 1e-9 * cell) ++r.occluded;
    if (f != r.face) r.next_other = std::min(r.next_other, t);
  }
  return r;
}

/// Rotates a mesh about its centroid by a fixed random rotation (generic position: no texel segment
/// through the edges that symmetric meshes put in the planes of the grid).
TriMesh rotated(TriMesh m, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  const Eigen::Quaterniond q(g(rng), g(rng), g(rng), g(rng));
  const Eigen::Matrix3d rot = q.normalized().toRotationMatrix();
  for (Vec3& p : m.positions) p = rot * p;
  return m;
}

/// The box [lo, hi] (outward triangles).
TriMesh make_box(const Vec3& lo, const Vec3& hi) {
  TriMesh m = make_cube(0.5, 1);
  for (Vec3& p : m.positions) p = lo + (p.array() + 0.5).matrix().cwiseProduct(hi - lo);
  return m;
}

/// Thin features that give the cell configurations a sphere does not: at grid 4, a plate one cell layer
/// thick (cases 4a inside, 3a along its sides, 2a at its corners) and a rod one cell row thick (2b, and 1
/// at its ends); two small boxes at opposite corners fix the bounding cube to about [-1, 1]³. Tilted by a
/// small angle, so that no texel segment runs along an edge.
TriMesh thin_features() {
  TriMesh m = make_box(Vec3(-0.9, -0.9, 0.55), Vec3(0.9, 0.9, 0.65));
  m = concatenate(m, make_box(Vec3(-0.9, -0.35, -0.35), Vec3(0.9, -0.3, -0.3)));
  m = concatenate(m, make_box(Vec3(-1.0, -1.0, -1.0), Vec3(-0.95, -0.95, -0.95)));
  m = concatenate(m, make_box(Vec3(0.95, 0.95, 0.95), Vec3(1.0, 1.0, 1.0)));
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(0.02, Vec3(0.3, -0.5, 0.8).normalized()).toRotationMatrix();
  for (Vec3& p : m.positions) p = tilt * p;
  return m;
}

/// Random triangles of very different sizes in [-1, 1]³, plus a duplicated triangle and a degenerate one.
TriMesh triangle_soup(std::size_t count, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0), expo(-4.0, 0.0);
  TriMesh m;
  for (std::size_t k = 0; k < count; ++k) {
    const Vec3 centre(unit(rng), unit(rng), unit(rng));
    const double size = std::exp2(expo(rng));
    const auto base = static_cast<std::uint32_t>(m.positions.size());
    for (int v = 0; v < 3; ++v) {
      Vec3 p;
      do {
        p = centre + size * Vec3(unit(rng), unit(rng), unit(rng));
      } while (p.cwiseAbs().maxCoeff() > 1.0);
      m.positions.push_back(p);
    }
    m.faces.push_back({base, base + 1, base + 2});
  }
  m.faces.push_back(m.faces[3]);                                  // duplicated
  const auto base = static_cast<std::uint32_t>(m.positions.size());
  m.positions.push_back(Vec3(0.1, 0.2, 0.3));                     // degenerate (collinear)
  m.positions.push_back(Vec3(0.2, 0.4, 0.6));
  m.positions.push_back(Vec3(0.3, 0.6, 0.9));
  m.faces.push_back({base, base + 1, base + 2});
  return m;
}

struct ReferenceComparison {
  std::size_t texels{0};
  std::size_t filled{0};
  std::size_t ambiguous{0};
  std::size_t ambiguous_differing{0};  ///< ambiguous texels whose empty flag or distance differs
  std::size_t normals_compared{0};
  std::array<std::size_t, kNumReliefCases> filled_by_case{};  ///< compared non-empty texels per base case
};

/// Builds the map of `mesh` at grid n and texture T and compares every texel with the reference.
ReferenceComparison compare_with_reference(const TriMesh& mesh, std::uint32_t n, std::uint32_t T, const std::string& what) {
  SCOPED_TRACE(what + ", grid " + std::to_string(n) + ", texture " + std::to_string(T));
  ReliefOptions o;
  o.grid = n;
  o.texture = T;
  const ReliefMap map = build_relief_map(mesh, o);
  map.check();
  ReferenceComparison cmp;
  std::size_t failures = 0;
  std::uint64_t ref_samples = 0, ref_occluded = 0;
  for (std::size_t l = 0; l < map.num_layers(); ++l) {
    const std::size_t g = map.layer_cell[l];
    for (std::uint32_t j = 0; j < T; ++j) {
      for (std::uint32_t i = 0; i < T; ++i) {
        const Vec3 q = face_point(map.layer_face[l], map.texel_coord(i), map.texel_coord(j));
        const ProjectionRay pr = projection_ray(map.projections[g], q);
        const ReferenceTexel ref =
            reference_texel(mesh, map.to_world(g, q), -pr.direction, pr.length * map.cell_size, map.cell_size);
        const std::size_t t = map.texel_index(l, i, j);
        const std::uint16_t got = map.distances[t];
        ++cmp.texels;
        if (ref.hit) {
          ref_samples += 1 + ref.occluded;
          ref_occluded += ref.occluded;
        }
        const std::uint16_t want = ref.hit ? quantize_distance(ref.t, map.distance_scale) : kEmptyTexel;
        const bool agree = (got == kEmptyTexel) == (want == kEmptyTexel) && std::abs(int{got} - int{want}) <= 1;
        if (ref.ambiguous) {
          ++cmp.ambiguous;
          if (!agree) ++cmp.ambiguous_differing;
          continue;
        }
        if (!agree && failures++ < 10)
          ADD_FAILURE() << "layer " << l << " (cell " << map.cells[g] << ", face " << int{map.layer_face[l]}
                        << ", case " << relief_case_name(map.projections[g].base_case) << ") texel (" << i << ", " << j
                        << "): distance " << got << ", reference " << want;
        if (!ref.hit) continue;
        ++cmp.filled;
        ++cmp.filled_by_case[static_cast<std::size_t>(map.projections[g].base_case)];
        // The normal is the nearest triangle's, wherever that triangle is the only one that near.
        if (ref.next_other - ref.t > 2 * map.distance_scale) {
          ++cmp.normals_compared;
          const Face& f = mesh.faces[ref.face];
          const Vec3 nrm = (mesh.positions[f[1]] - mesh.positions[f[0]]).cross(mesh.positions[f[2]] - mesh.positions[f[0]]).normalized();
          for (int c = 0; c < 3; ++c) {
            const auto expected = static_cast<std::int8_t>(std::lround(nrm[c] * 127.0));
            if (map.normals[3 * t + static_cast<std::size_t>(c)] != expected && failures++ < 10)
              ADD_FAILURE() << "layer " << l << " texel (" << i << ", " << j << "): normal differs from face " << ref.face;
          }
        }
      }
    }
  }
  EXPECT_EQ(failures, 0u);
  // Hit counts: the reference counts exactly like the sampler; ambiguous texels may differ by a few hits.
  EXPECT_EQ(map.levels.size(), 1u);
  const auto slack = static_cast<std::int64_t>(4 * cmp.ambiguous);
  EXPECT_LE(std::abs(static_cast<std::int64_t>(map.levels[0].samples) - static_cast<std::int64_t>(ref_samples)), slack)
      << map.levels[0].samples << " samples, reference " << ref_samples;
  EXPECT_LE(std::abs(static_cast<std::int64_t>(map.levels[0].occluded) - static_cast<std::int64_t>(ref_occluded)), slack)
      << map.levels[0].occluded << " occluded, reference " << ref_occluded;
  return cmp;
}

/// Runs the comparison at grids 1, 2, 4 and two texture sizes; returns the totals.
ReferenceComparison compare_on_grids(const TriMesh& mesh, const std::string& what) {
  ReferenceComparison total;
  for (const std::uint32_t n : {1u, 2u, 4u}) {
    for (const std::uint32_t T : {8u, 13u}) {
      const ReferenceComparison c = compare_with_reference(mesh, n, T, what);
      total.texels += c.texels;
      total.filled += c.filled;
      total.ambiguous += c.ambiguous;
      total.ambiguous_differing += c.ambiguous_differing;
      total.normals_compared += c.normals_compared;
      for (std::size_t k = 0; k < total.filled_by_case.size(); ++k) total.filled_by_case[k] += c.filled_by_case[k];
    }
  }
  EXPECT_GT(total.filled, total.texels / 20) << what;
  EXPECT_GT(total.normals_compared, total.filled / 2) << what;
  std::printf("[ reference ] %-22s %7zu texels, %6zu filled, %4zu ambiguous (%zu of them differ)\n", what.c_str(),
              total.texels, total.filled, total.ambiguous, total.ambiguous_differing);
  return total;
}

TEST(ReliefSampling, MatchesBruteForceOnGenericMeshes) {
  const std::vector<std::pair<std::string, TriMesh>> meshes = {
      {"icosphere", rotated(make_icosphere(1.0, 3), 1)},
      {"torus", rotated(make_torus(1.0, 0.35, 32, 16), 2)},
      {"nested spheres", rotated(concatenate(make_icosphere(1.0, 2), make_icosphere(0.5, 2)), 3)},
      {"cube", rotated(make_cube(1.0, 2), 4)},
      {"triangle soup", triangle_soup(300, 5)},
      {"thin plate and rod", thin_features()},
  };
  std::array<std::size_t, kNumReliefCases> by_case{};
  for (const auto& [name, mesh] : meshes) {
    const ReferenceComparison c = compare_on_grids(mesh, name);
    EXPECT_LE(c.ambiguous, c.texels / 200) << name;  // a tiny fraction of the texels
    for (std::size_t k = 0; k < by_case.size(); ++k) by_case[k] += c.filled_by_case[k];
  }
  // All ten base cases, hence all four projection types, were compared.
  for (std::size_t k = 0; k < by_case.size(); ++k) {
    std::printf("[ reference ] case %-3s %zu filled texels compared\n",
                std::string(relief_case_name(static_cast<ReliefCase>(k))).c_str(), by_case[k]);
    EXPECT_GT(by_case[k], 0u) << "case " << relief_case_name(static_cast<ReliefCase>(k));
  }
}

TEST(ReliefSampling, CellsHoldingMoreTrianglesThanOneLoadMatchBruteForce) {
  // 81,920 faces in one cell (grid 1): the sampler loads a cell's triangles 65,536 at a time; the nearest
  // hit and its normal must not depend on which load a triangle came in.
  const TriMesh mesh = rotated(make_icosphere(1.0, 6), 1);
  ASSERT_GT(mesh.num_faces(), 65536u);
  const ReferenceComparison c = compare_with_reference(mesh, 1, 8, "81,920 faces in one cell");
  EXPECT_GT(c.filled, 0u);
  EXPECT_GT(c.normals_compared, c.filled / 2);
}

TEST(ReliefSampling, MatchesBruteForceOnAxisAlignedMeshes) {
  // Symmetric meshes in the grid's own axes: segments through the grid centre, the face centres or the
  // diagonals of the cube's quads run exactly along edges (ambiguous texels: more of them, but they
  // should still agree nearly everywhere).
  const std::vector<std::pair<std::string, TriMesh>> meshes = {
      {"axis-aligned icosphere", make_icosphere(1.0, 3)},
      {"axis-aligned torus", make_torus(1.0, 0.35, 32, 16)},
      {"axis-aligned cube", make_cube(1.0, 2)},
  };
  for (const auto& [name, mesh] : meshes) {
    const ReferenceComparison c = compare_on_grids(mesh, name);
    EXPECT_LE(c.ambiguous_differing, c.ambiguous / 50 + 2) << name;
  }
}

TEST(ReliefSampling, SegmentsEndingOnTheSurfaceMeetIt) {
  // One triangle through the centre of the bounding cube: at grid 1 every projection segment ends at the
  // centre of projection, on the triangle, so every texel samples that point (distance = segment length).
  // It is tilted (z = x / 2): a flat one in z = 0 would be thin, and thin meshes are placed off the centre.
  TriMesh m;
  m.positions = {Vec3(-1.0, -1.0, -0.5), Vec3(1.0, -1.0, 0.5), Vec3(0.0, 1.0, 0.0)};
  m.faces = {{0, 1, 2}};
  ReliefOptions o;
  o.grid = 1;
  o.texture = 8;  // no texel in the triangle's plane (those segments are coplanar with it)
  const ReliefMap map = build_relief_map(m, o);
  ASSERT_EQ(map.num_layers(), 6u);
  ASSERT_EQ(map.projections[0].base_case, ReliefCase::k0);
  EXPECT_EQ(map.levels[0].samples, 6u * 8 * 8);
  EXPECT_EQ(map.levels[0].occluded, 0u);
  for (std::size_t l = 0; l < 6; ++l)
    for (std::uint32_t j = 0; j < 8; ++j)
      for (std::uint32_t i = 0; i < 8; ++i) {
        const Vec3 q = face_point(map.layer_face[l], map.texel_coord(i), map.texel_coord(j));
        const ProjectionRay pr = projection_ray(map.projections[0], q);
        const std::size_t t = map.texel_index(l, i, j);
        ASSERT_EQ(map.distances[t], quantize_distance(pr.length * map.cell_size, map.distance_scale))
            << "layer " << l << " texel (" << i << ", " << j << ")";
        EXPECT_NEAR(map.normals[3 * t], -127.0 / std::sqrt(5.0), 1.0);  // (-1, 0, 2) / sqrt(5)
        EXPECT_EQ(map.normals[3 * t + 1], 0);
        EXPECT_NEAR(map.normals[3 * t + 2], 254.0 / std::sqrt(5.0), 1.0);
        EXPECT_LT(map.texel_surface_point(l, i, j).norm(), 1e-3);
      }
}

TEST(ReliefSampling, ResultDoesNotDependOnTheThreadCount) {
  TriMesh mesh = concatenate(make_torus(1.0, 0.35, 48, 24), triangle_soup(200, 9));
  for (const Vec3& p : mesh.positions) mesh.colors.push_back(((p.array() + 1.5) / 3.0).matrix().cast<float>());
  ReliefOptions o;
  o.texture = 16;
  o.max_grid = 8;
  o.occlusion_threshold = 0.0;  // all levels 1, 2, 4, 8
  const ReliefMap many = build_relief_map(mesh, o);
  ReliefMap one;
  {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = build_relief_map(mesh, o);
  }
  ASSERT_EQ(many.levels.size(), 4u);
  ASSERT_EQ(one.levels.size(), many.levels.size());
  for (std::size_t k = 0; k < many.levels.size(); ++k) {
    EXPECT_EQ(one.levels[k].samples, many.levels[k].samples);
    EXPECT_EQ(one.levels[k].occluded, many.levels[k].occluded);
  }
  EXPECT_EQ(one.distances, many.distances);
  EXPECT_EQ(one.normals, many.normals);
  EXPECT_EQ(one.colors, many.colors);
}

TEST(ReliefSampling, SharedEdgesAndDuplicatesAreNotOccluded) {
  // One cell seeing a closed cube from its centre: every segment meets the surface once, also where it
  // passes through an edge or a vertex shared by several triangles.
  TriMesh cube = make_cube(1.0, 3);
  ReliefOptions o;
  o.grid = 1;
  o.texture = 31;  // texel segments through the quads' diagonals and the cube's vertices
  ReliefMap map = build_relief_map(cube, o);
  EXPECT_EQ(map.levels[0].occluded, 0u);
  EXPECT_EQ(map.levels[0].samples, std::uint64_t{6} * 31 * 31);
  // Every face twice: still one sample per texel.
  const std::size_t faces = cube.faces.size();
  for (std::size_t f = 0; f < faces; ++f) cube.faces.push_back(cube.faces[f]);
  const ReliefMap twice = build_relief_map(cube, o);
  EXPECT_EQ(twice.levels[0].occluded, 0u);
  EXPECT_EQ(twice.distances, map.distances);
  EXPECT_EQ(twice.normals, map.normals);
  // A second, smaller cube inside (rotated: no segment through its edges): the outer cube stays the nearest
  // surface everywhere, the inner one adds one occluded sample per texel.
  const TriMesh nested = concatenate(make_cube(1.0, 3), rotated(make_cube(0.5, 1), 7));
  const ReliefMap both = build_relief_map(nested, o);
  const std::uint64_t texels = std::uint64_t{6} * 31 * 31;
  EXPECT_EQ(both.levels[0].occluded, texels);
  EXPECT_EQ(both.levels[0].samples, 2 * texels);
  EXPECT_EQ(both.distances, map.distances);
  EXPECT_EQ(both.normals, map.normals);
}

TEST(ReliefSampling, CancelsThroughProgress) {
  ReliefOptions o;
  o.grid = 4;
  o.texture = 8;
  bool sampling_seen = false;
  o.progress = [&](std::string_view stage, double) {
    if (stage != "relief sampling") return true;
    sampling_seen = true;
    return false;
  };
  EXPECT_THROW((void)build_relief_map(make_icosphere(1.0, 3), o), Cancelled);
  EXPECT_TRUE(sampling_seen);
}

TEST(ReliefMap, CheckRejectsInconsistentMaps) {
  ReliefOptions o;
  o.grid = 4;
  o.texture = 4;
  const ReliefMap good = build_relief_map(make_icosphere(1.0, 3), o);
  EXPECT_NO_THROW(good.check());
  auto bad = good;
  bad.layer_face[0] = static_cast<std::uint8_t>((bad.layer_face[0] + 1) % 6);
  EXPECT_THROW(bad.check(), InvalidInput);
  bad = good;
  bad.external_faces[0] ^= 1;
  EXPECT_THROW(bad.check(), InvalidInput);
  bad = good;
  bad.distances.pop_back();
  EXPECT_THROW(bad.check(), InvalidInput);
  bad = good;
  bad.cells[0] = 4 * 4 * 4;
  EXPECT_THROW(bad.check(), InvalidInput);
  bad = good;
  bad.cell_size = std::nan("");
  EXPECT_THROW(bad.check(), InvalidInput);
}

TEST(ReliefMap, RejectsBadOptions) {
  const TriMesh sphere = make_icosphere(1.0, 2);
  ReliefOptions o;
  o.texture = 1;
  EXPECT_THROW((void)build_relief_map(sphere, o), InvalidInput);
  o = {};
  o.grid = 2000;
  EXPECT_THROW((void)build_relief_map(sphere, o), InvalidInput);
  o = {};
  o.occlusion_threshold = -0.1;
  EXPECT_THROW((void)build_relief_map(sphere, o), InvalidInput);
  o = {};
  o.max_grid = 0;
  EXPECT_THROW((void)build_relief_map(sphere, o), InvalidInput);
  EXPECT_THROW((void)build_relief_map(TriMesh{}, ReliefOptions{}), InvalidInput);
}

}  // namespace
}  // namespace gimforge
