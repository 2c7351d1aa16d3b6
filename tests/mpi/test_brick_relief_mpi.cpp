// Relief conversion of a scan by bricks (jobs/brick_relief.h) for any number of ranks (ctest runs 2 and 4):
// the same map as one process bit for bit (cells, texels, levels), the same statistics and fidelity figures
// exactly, for a closed scan far from the origin (flood fill) and an open one with a zero-area face and an
// unreferenced far vertex (parity votes); a truncated file fails every rank without a hang; a PLY with
// colours is left to one process. EXPECT, not ASSERT: collectives stay matched.
#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "io/mesh_io.h"
#include "jobs/brick_relief.h"
#include "jobs/load_mesh.h"
#include "jobs/pipeline.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "mpi/agree.h"
#include "mpi/mpi_comm.h"
#include "tests/mpi/shared_folder.h"

using namespace gimforge;
namespace fs = std::filesystem;

namespace {

/// A wavy torus of 12,800 faces; open: a strip of faces removed, a zero-area face and an unreferenced far
/// vertex added.
TriMesh scan_mesh(bool open, const Vec3& offset) {
  TriMesh t = make_torus(1.0, 0.4, 160, 40);
  for (Vec3& p : t.positions) p += 0.04 * Vec3(std::sin(9 * p.y()), std::cos(7 * p.z()), std::sin(5 * p.x()));
  if (open) {
    t.faces.erase(t.faces.begin() + 2000, t.faces.begin() + 2600);
    t.positions.push_back(0.5 * (t.positions[0] + t.positions[1]));
    t.faces.push_back({0, 1, static_cast<std::uint32_t>(t.positions.size() - 1)});
    t.positions.push_back(Vec3(50.0, 50.0, 50.0));
  }
  for (Vec3& p : t.positions) p += offset;
  return t;
}

void expect_equal(const jobs::Conversion& bricks, const jobs::Conversion& one) {
  const ReliefMap& a = bricks.relief.value();
  const ReliefMap& b = one.relief.value();
  EXPECT_EQ(a.n, b.n);
  EXPECT_EQ(a.origin, b.origin);
  EXPECT_EQ(a.cell_size, b.cell_size);
  EXPECT_EQ(a.cells, b.cells);
  EXPECT_EQ(a.external_faces, b.external_faces);
  EXPECT_EQ(a.distances, b.distances);
  EXPECT_EQ(a.normals, b.normals);
  EXPECT_EQ(a.levels.size(), b.levels.size());
  for (std::size_t k = 0; k < std::min(a.levels.size(), b.levels.size()); ++k) {
    EXPECT_EQ(a.levels[k].samples, b.levels[k].samples) << "level " << k;
    EXPECT_EQ(a.levels[k].occluded, b.levels[k].occluded) << "level " << k;
    EXPECT_EQ(a.levels[k].faces, b.levels[k].faces) << "level " << k;
    EXPECT_EQ(a.levels[k].edge_on, b.levels[k].edge_on) << "level " << k;
  }
  EXPECT_EQ(a.inside_method, b.inside_method);
  EXPECT_EQ(bricks.origin, one.origin);
  for (const char* key : {"psnr", "hausdorff_rms", "hausdorff_max", "bbox_diagonal", "samples", "occluded_samples",
                          "grid_levels_tried", "storage_bytes", "reconstruction_faces", "reconstruction_vertices"}) {
    EXPECT_TRUE(bricks.numbers.contains(key)) << key;
    EXPECT_TRUE(one.numbers.contains(key)) << key;
    if (bricks.numbers.contains(key) && one.numbers.contains(key)) {
      EXPECT_EQ(bricks.numbers.at(key), one.numbers.at(key)) << key;
    }
  }
  EXPECT_EQ(bricks.fidelity.value().ab.vertex_samples, one.fidelity.value().ab.vertex_samples);
  EXPECT_EQ(bricks.fidelity.value().ba.max, one.fidelity.value().ba.max);
  EXPECT_EQ(bricks.input_faces, one.input_faces);
  EXPECT_GT(bricks.numbers.at("rank_peak_rss_mb"), 0.0);
}

/// A relief conversion of `scan` with the default options.
jobs::ConversionRequest relief_request(const std::string& scan) {
  jobs::ConversionRequest request;
  request.source = scan;
  request.method.method = jobs::Method::Relief;
  return request;
}

void convert_both_ways(const mpi::Comm& world, const std::string& scan, const jobs::ConversionRequest& request,
                       bool watertight) {
  const EmbreeDevice device;
  EXPECT_TRUE(jobs::converts_relief_in_bricks(world, scan, request) || world.size() == 1);
  const jobs::Conversion bricks = jobs::brick_relief(world, device, scan, request);
  if (world.rank() == 0) {
    const jobs::LoadedMesh m = jobs::load_mesh(scan, jobs::load_policy(jobs::Method::Relief, false));
    const jobs::Conversion one = jobs::convert_mesh(device, m.mesh, request);
    EXPECT_EQ(one.relief.value().watertight_inside_test, watertight);
    expect_equal(bricks, one);
  } else {
    EXPECT_FALSE(bricks.relief.has_value());
  }
  world.barrier();
}

}  // namespace

TEST(BrickRelief, ClosedScanFarFromTheOriginEqualsOneProcess) {
  const mpi::Comm world = mpi::mpi_world();
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-brelief");
  const std::string scan = dir + "/torus.ply";
  if (world.rank() == 0)
    io::write_ply(scan, scan_mesh(false, Vec3(612345.0, 4123456.0, 80.0)), {.binary = true, .double_precision = true});
  world.barrier();
  jobs::ConversionRequest request = relief_request(scan);
  request.method.texture = 16;  // automatic grid: several levels, each replayed
  request.fidelity.samples = 20000;
  convert_both_ways(world, scan, request, true);
}

TEST(BrickRelief, OpenScanVotesAsOneProcess) {
  const mpi::Comm world = mpi::mpi_world();
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-brelief");
  const std::string scan = dir + "/open.ply";
  if (world.rank() == 0) io::write_ply(scan, scan_mesh(true, Vec3::Zero()), {.binary = true});
  world.barrier();
  jobs::ConversionRequest request = relief_request(scan);
  request.method.grid = "8";
  request.method.texture = 12;
  request.fidelity.samples = 5000;
  convert_both_ways(world, scan, request, false);
}

TEST(BrickRelief, DuplicateFacesGoAsTheLoaderRemovesThem) {
  // Copies of faces (the same vertices, some rotated or mirrored) spread over the scan: the loader keeps the
  // first of each; by bricks, the owner of each copy finds it. With them kept the scan would not count as
  // watertight, and the metric would sample their area twice.
  const mpi::Comm world = mpi::mpi_world();
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-brelief");
  const std::string scan = dir + "/copies.ply";
  if (world.rank() == 0) {
    TriMesh t = scan_mesh(false, Vec3(1000.0, -2000.0, 30.0));
    const std::size_t faces = t.faces.size();
    for (std::size_t f = 7; f < faces; f += 97) {
      const Face a = t.faces[f];
      t.faces.push_back(f % 2 == 0 ? Face{a[1], a[2], a[0]} : Face{a[2], a[1], a[0]});
    }
    t.faces.insert(t.faces.begin() + 3, t.faces[5000]);  // a copy before its original
    io::write_ply(scan, t, {.binary = true});
  }
  world.barrier();
  jobs::ConversionRequest request = relief_request(scan);
  request.method.texture = 16;
  request.fidelity.samples = 20000;
  convert_both_ways(world, scan, request, true);
}

TEST(BrickRelief, TruncatedScanFailsEveryRank) {
  const mpi::Comm world = mpi::mpi_world();
  const EmbreeDevice device;
  const std::string scan = gimforge::test::truncated_scan(world, gimforge::test::shared_folder(world, "gimforge-brelief"));
  jobs::ConversionRequest request = relief_request(scan);
  gimforge::test::expect_fails_as_truncated(world, [&] { (void)jobs::brick_relief(world, device, scan, request); });
}

// A scan without area is refused as one process refuses it; it was stored as an empty map (exit 0) that no
// reader could use. Rank 0 names the cause, the others learn that a peer failed.
TEST(BrickRelief, AScanWithoutAreaIsRefusedAsByOneProcess) {
  const mpi::Comm world = mpi::mpi_world();
  const EmbreeDevice device;
  const std::string scan = gimforge::test::shared_folder(world, "gimforge-brelief") + "/line.ply";
  if (world.rank() == 0) {
    TriMesh line;
    line.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3(3, 0, 0)};
    line.faces = {{0, 1, 2}, {1, 2, 3}};
    io::write_ply(scan, line, {.binary = true});
  }
  world.barrier();
  jobs::ConversionRequest request = relief_request(scan);
  request.method.grid = "4";
  request.method.texture = 8;
  request.fidelity.enabled = false;
  try {
    (void)jobs::brick_relief(world, device, scan, request);
    ADD_FAILURE() << "no error";
  } catch (const mpi::PeerFailed&) {
    EXPECT_NE(world.rank(), 0);
  } catch (const Error& e) {
    EXPECT_EQ(world.rank(), 0);
    EXPECT_NE(std::string(e.what()).find("the mesh has no surface area"), std::string::npos) << e.what();
  }
}

TEST(BrickRelief, ScansWithColoursAreLeftToOneProcess) {
  const mpi::Comm world = mpi::mpi_world();
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-brelief");
  const std::string plain = dir + "/plain.ply", coloured = dir + "/coloured.ply";
  if (world.rank() == 0) {
    TriMesh t = make_torus(1.0, 0.4, 40, 20);
    io::write_ply(plain, t, {.binary = true});
    t.colors.assign(t.positions.size(), Vec3f(0.2f, 0.4f, 0.6f));
    io::write_ply(coloured, t, {.binary = true});
  }
  world.barrier();
  jobs::ConversionRequest request;
  request.method.method = jobs::Method::Relief;
  EXPECT_EQ(jobs::converts_relief_in_bricks(world, plain, request), world.size() > 1);
  EXPECT_FALSE(jobs::converts_relief_in_bricks(world, coloured, request));
  request.method.method = jobs::Method::Gim;
  EXPECT_FALSE(jobs::converts_relief_in_bricks(world, plain, request));
  world.barrier();
}
