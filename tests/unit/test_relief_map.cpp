// Relief-map construction (§3.3), quantization and geometry-based reconstruction (§3.5.1).
#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "kernels/embree_device.h"
#include "kernels/errors.h"
#include "kernels/hausdorff.h"
#include "kernels/procedural.h"
#include "kernels/relief_map.h"

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
