// relief_fidelity against the exact reference: symmetric_hausdorff against reconstruct_relief(map).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "io/mesh_io.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/procedural.h"
#include "kernels/relief/relief_fidelity.h"
#include "kernels/relief/relief_map.h"

namespace gimforge {
namespace {

struct Case {
  std::string name;
  TriMesh mesh;
  std::uint32_t grid;     // 0 = automatic
  std::uint32_t texture;
};

std::vector<Case> cases() {
  const std::filesystem::path data(GIMFORGE_TEST_DATA_DIR);
  std::vector<Case> c;
  c.push_back({"icosphere N=1", make_icosphere(1.0, 3), 1, 16});
  c.push_back({"icosphere N=4", make_icosphere(1.0, 3), 4, 16});
  c.push_back({"torus N=6", make_torus(1.0, 0.3, 48, 16), 6, 12});
  c.push_back({"slab with holes N=5", make_slab_with_holes(2, 2), 5, 10});
  c.push_back({"grid (open) N=3", make_grid(12, 9, 1.0), 3, 16});
  c.push_back({"kitten auto", io::read_mesh(data / "kitten.ply"), 0, 16});
  c.push_back({"fist N=8", io::read_mesh(data / "fist.ply"), 8, 8});
  c.push_back({"cathead N=2", io::read_mesh(data / "cathead.ply"), 2, 32});
  return c;
}

void expect_relative(double got, double want, double tolerance, const std::string& what) {
  EXPECT_LE(std::abs(got - want), tolerance * std::max(std::abs(want), 1e-300))
      << what << ": got " << got << ", reference " << want;
}

TEST(ReliefFidelity, AgreesWithTheReconstructionReference) {
  const EmbreeDevice device;
  HausdorffOptions o;
  o.samples = 20'000;
  for (const Case& c : cases()) {
    SCOPED_TRACE(c.name);
    ReliefOptions ro;
    ro.grid = c.grid;
    ro.texture = c.texture;
    const ReliefMap map = build_relief_map(c.mesh, ro);
    const TriMesh recon = reconstruct_relief(map);
    const HausdorffResult ref = symmetric_hausdorff(device, c.mesh, recon, o);
    const ReliefFidelity got = relief_fidelity(device, c.mesh, map, o);
    const HausdorffResult& h = got.hausdorff;
    EXPECT_EQ(got.reconstruction_vertices, recon.num_vertices());
    EXPECT_EQ(got.reconstruction_faces, recon.num_faces());
    // Every vertex is a face's corner (reconstruct wrote the texels no face used, which readers then removed).
    std::vector<char> used(recon.num_vertices(), 0);
    for (const Face& f : recon.faces)
      for (const std::uint32_t v : f) used[v] = 1;
    EXPECT_EQ(std::count(used.begin(), used.end(), 0), 0);
    EXPECT_EQ(h.diag, ref.diag);
    // Original -> reconstruction: the same samples, exact distances to the same triangles (the minimum
    // over them does not depend on the search): equal up to rounding.
    EXPECT_EQ(h.ab.area_samples, ref.ab.area_samples);
    EXPECT_EQ(h.ab.vertex_samples, ref.ab.vertex_samples);
    expect_relative(h.ab.rms, ref.ab.rms, 1e-12, "rms A->B");
    expect_relative(h.ab.mean, ref.ab.mean, 1e-12, "mean A->B");
    expect_relative(h.ab.max, ref.ab.max, 1e-12, "max A->B");
    // Reconstruction -> original: sample_surface's samples, but the cumulative area is summed per layer
    // (its rounding may move a sample onto a neighbouring triangle).
    EXPECT_EQ(h.ba.area_samples, ref.ba.area_samples);
    EXPECT_EQ(h.ba.vertex_samples, ref.ba.vertex_samples);
    expect_relative(h.ba.rms, ref.ba.rms, 1e-6, "rms B->A");
    expect_relative(h.ba.mean, ref.ba.mean, 1e-6, "mean B->A");
    expect_relative(h.ba.max, ref.ba.max, 1e-6, "max B->A");
    expect_relative(h.rms, ref.rms, 1e-6, "symmetric rms");
    EXPECT_NEAR(h.psnr, ref.psnr, 1e-4);
  }
}

TEST(ReliefFidelity, ReconstructionVerticesLieWithinHalfAQuantizationStep) {
  // The bound that lets relief_fidelity skip measuring the reconstruction's vertices.
  const EmbreeDevice device;
  for (const Case& c : cases()) {
    SCOPED_TRACE(c.name);
    ReliefOptions ro;
    ro.grid = c.grid;
    ro.texture = c.texture;
    const ReliefMap map = build_relief_map(c.mesh, ro);
    const TriMesh recon = reconstruct_relief(map);
    const TriangleBvh bvh(device, c.mesh);
    const std::vector<double> d = distances_to_surface(recon.positions, bvh);
    const double worst = *std::max_element(d.begin(), d.end());
    EXPECT_LE(worst, 0.5 * map.distance_scale * (1.0 + 1e-6)) << "cell size " << map.cell_size;
  }
}

TEST(ReliefFidelity, AgreesWhenTheVerticesMustBeMeasured) {
  // A cube's reconstruction lies on the cube's faces except along the edges; the default max-edge rule
  // keeps the edge quads, so the maximum comes from the area samples; a max_edge_texels below one texel
  // spacing keeps only the flat quads, whose points are all within the vertex bound: the vertices are
  // measured then.
  const EmbreeDevice device;
  const TriMesh cube = io::read_mesh(std::filesystem::path(GIMFORGE_TEST_DATA_DIR) / "cube.off");
  ReliefOptions ro;
  ro.grid = 2;
  ro.texture = 9;
  const ReliefMap map = build_relief_map(cube, ro);
  HausdorffOptions o;
  o.samples = 20'000;
  for (double max_edge : {8.0, 1.5}) {
    SCOPED_TRACE(max_edge);
    const TriMesh recon = reconstruct_relief(map, max_edge);
    const HausdorffResult ref = symmetric_hausdorff(device, cube, recon, o);
    const HausdorffResult h = relief_fidelity(device, cube, map, o, max_edge).hausdorff;
    expect_relative(h.ab.rms, ref.ab.rms, 1e-12, "rms A->B");
    expect_relative(h.ba.rms, ref.ba.rms, 1e-6, "rms B->A");
    expect_relative(h.ba.max, ref.ba.max, 1e-6, "max B->A");
    expect_relative(h.max, ref.max, 1e-6, "max");
  }
}

TEST(ReliefFidelity, SharedMeshAgreesWithTheReference) {
  const std::filesystem::path mesh = std::filesystem::path(GIMFORGE_SHARED_MESHES_DIR) / "bunny_closed.ply";
  if (!std::filesystem::exists(mesh)) GTEST_SKIP() << mesh << " is absent";
  const EmbreeDevice device;
  const TriMesh m = io::read_mesh(mesh);
  ReliefOptions ro;
  ro.grid = 16;
  ro.texture = 32;
  const ReliefMap map = build_relief_map(m, ro);
  HausdorffOptions o;
  o.samples = 100'000;
  const HausdorffResult ref = symmetric_hausdorff(device, m, reconstruct_relief(map), o);
  const HausdorffResult h = relief_fidelity(device, m, map, o).hausdorff;
  expect_relative(h.ab.rms, ref.ab.rms, 1e-12, "rms A->B");
  expect_relative(h.ba.rms, ref.ba.rms, 1e-6, "rms B->A");
  expect_relative(h.max, ref.max, 1e-6, "max");
  EXPECT_NEAR(h.psnr, ref.psnr, 1e-4);
}

TEST(ReliefFidelity, DoesNotDependOnTheThreadCount) {
  const EmbreeDevice device;
  const TriMesh mesh = io::read_mesh(std::filesystem::path(GIMFORGE_TEST_DATA_DIR) / "kitten.ply");
  ReliefOptions ro;
  ro.grid = 4;
  ro.texture = 16;
  const ReliefMap map = build_relief_map(mesh, ro);
  HausdorffOptions o;
  o.samples = 30'000;
  const HausdorffResult many = relief_fidelity(device, mesh, map, o).hausdorff;
  HausdorffResult one;
  {
    tbb::global_control single(tbb::global_control::max_allowed_parallelism, 1);
    one = relief_fidelity(device, mesh, map, o).hausdorff;
  }
  EXPECT_EQ(one.ab.rms, many.ab.rms);
  EXPECT_EQ(one.ab.max, many.ab.max);
  EXPECT_EQ(one.ba.rms, many.ba.rms);
  EXPECT_EQ(one.ba.max, many.ba.max);
  EXPECT_EQ(one.psnr, many.psnr);
}

TEST(ReliefFidelity, RejectsBadInput) {
  const EmbreeDevice device;
  const TriMesh sphere = make_icosphere(1.0, 2);
  ReliefOptions ro;
  ro.grid = 2;
  ro.texture = 8;
  const ReliefMap map = build_relief_map(sphere, ro);
  HausdorffOptions o;
  o.samples = 0;
  EXPECT_THROW((void)relief_fidelity(device, sphere, map, o), InvalidInput);
  o.samples = 100;
  EXPECT_THROW((void)relief_fidelity(device, TriMesh{}, map, o), InvalidInput);
  // No quad survives a maximum edge of 0 texels: nothing to measure.
  EXPECT_THROW((void)relief_fidelity(device, sphere, map, o, 0.0), InvalidInput);
}

}  // namespace
}  // namespace gimforge
