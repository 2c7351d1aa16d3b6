// The fidelity metric by bricks (jobs/brick_metrics.h) for any number of ranks >= 2 (ctest runs 2 and 4):
// equal bit for bit to one process loading both files whole (`metrics`' load: degenerate faces and
// unreferenced vertices dropped, A's local frame), with georeferenced coordinates, with samples that no
// brick can certify (forwarded to every rank), and a truncated file failing every rank without a hang.
// Collectives stay matched on all ranks even when an expectation fails (EXPECT, not ASSERT).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <string>

#include "io/mesh_io.h"
#include "jobs/brick_metrics.h"
#include "jobs/load_mesh.h"
#include "jobs/scan_bricks.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "mpi/agree.h"
#include "mpi/mpi_comm.h"
#include "tests/mpi/shared_folder.h"
#include "tests/mpi/expect_metrics.h"

using namespace gimforge;
using gimforge::test::expect_same;
namespace fs = std::filesystem;

namespace {

HausdorffResult one_process(const EmbreeDevice& device, const std::string& a, const std::string& b,
                            const HausdorffOptions& o) {
  const jobs::LoadPolicy policy{.repair = true, .warn = false, .topology = false};
  jobs::LoadedMesh ma = jobs::load_mesh(a, policy), mb = jobs::load_mesh(b, policy);
  const Vec3 origin = jobs::local_frame_origin(ma.mesh);
  jobs::to_local_frame(ma.mesh, origin);
  jobs::to_local_frame(mb.mesh, origin);
  return symmetric_hausdorff(device, ma.mesh, mb.mesh, o);
}

/// Runs `work` on every rank, which must fail together: rank 0 with an Error saying `says`, the others with
/// mpi::PeerFailed (they print nothing).
void expect_said_once(const mpi::Comm& world, const std::function<void()>& work, const std::string& says) {
  std::string own;
  bool peer = false;
  try {
    work();
  } catch (const mpi::PeerFailed&) {
    peer = true;
  } catch (const Error& e) {
    own = e.what();
  }
  EXPECT_EQ(peer, world.rank() != 0);
  if (world.rank() == 0) {
    EXPECT_NE(own.find(says), std::string::npos) << own;
  }
}

}  // namespace

TEST(BrickMetrics, EqualsOneProcessBitForBit) {
  const mpi::Comm world = mpi::mpi_world();
  const EmbreeDevice device;
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-bricks");
  const Vec3 utm(512345.0, 4123456.0, 250.0);
  TriMesh a = make_icosphere(1.0, 4);
  // A degenerate face and an unreferenced far vertex: `metrics` drops both, so must the bricks.
  a.positions.push_back(Vec3(40.0, 0.0, 0.0));
  a.faces.push_back({0, 0, 1});
  TriMesh b = make_torus(1.0, 0.4, 60, 30);
  TriMesh far = make_icosphere(1.0, 3);  // 0.4 diagonals away: no brick certifies any answer
  for (Vec3& p : far.positions) p += Vec3(0.7, 0.0, 0.0);
  for (TriMesh* m : {&a, &b, &far})
    for (Vec3& p : m->positions) p += utm;
  if (world.rank() == 0) {
    io::PlyWriteOptions doubles;
    doubles.double_precision = true;
    io::write_mesh(dir + "/a.ply", a, doubles);
    io::write_mesh(dir + "/b.ply", b, doubles);
    io::write_mesh(dir + "/far.ply", far);  // float coordinates: what both readers see
  }
  world.barrier();
  EXPECT_TRUE(jobs::readable_in_bricks(dir + "/a.ply", dir + "/b.ply"));
  for (const std::string other : {"b.ply", "far.ply"}) {
    for (const std::size_t samples : {20'000u, 3u}) {  // 3 samples: most ranks draw none
      SCOPED_TRACE(other + " " + std::to_string(samples));
      HausdorffOptions o;
      o.samples = samples;
      const HausdorffResult want = one_process(device, dir + "/a.ply", dir + "/" + other, o);
      expect_same(jobs::brick_hausdorff(world, device, dir + "/a.ply", dir + "/" + other, o), want);
    }
  }
  world.barrier();
  if (world.rank() == 0) fs::remove_all(dir);
}

TEST(BrickMetrics, ATruncatedFileFailsEveryRank) {
  const mpi::Comm world = mpi::mpi_world();
  const EmbreeDevice device;
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-bricks");
  if (world.rank() == 0) {
    io::write_mesh(dir + "/a.ply", make_icosphere(1.0, 3));
    fs::copy_file(dir + "/a.ply", dir + "/cut.ply");
    fs::resize_file(dir + "/cut.ply", fs::file_size(dir + "/a.ply") - 7);
  }
  world.barrier();
  // A face count whose byte size wraps around 2^64 to exactly the file's size is refused, not read.
  if (world.rank() == 0) {
    std::ofstream(dir + "/wrap.ply", std::ios::binary)
        << "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
           "property float z\nelement face 1418980313362273202\nproperty list uchar int vertex_indices\nend_header\n"
        << std::string(10, '\0');  // 13 · 1418980313362273202 = 2^64 + 10
  }
  world.barrier();
  try {
    (void)io::PlyTriangleFile::open(dir + "/wrap.ply");
    ADD_FAILURE() << "wrap.ply opened";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("truncated binary PLY"), std::string::npos) << e.what();
  }
  expect_said_once(world, [&] { mpi::run_agreed(world, [&] { (void)jobs::readable_in_bricks(dir + "/a.ply", dir + "/cut.ply"); }); },
                   "cut.ply: truncated binary PLY");
  world.barrier();
  if (world.rank() == 0) fs::remove_all(dir);
}

TEST(BrickRead, AMeshTooSmallToMeasureIsRefusedOnceAsLoadingDoes) {
  // io::kMinDiagonal: 1e-30 across, the brick scan refuses it with loading's words, on rank 0 only.
  const mpi::Comm world = mpi::mpi_world();
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-bricks");
  TriMesh m = make_torus(1.0, 0.4, 12, 8);
  for (Vec3& p : m.positions) p *= 1e-30;
  if (world.rank() == 0) io::write_ply(dir + "/tiny.ply", m, {.binary = true, .double_precision = true});
  world.barrier();
  const auto file = io::PlyTriangleFile::open(dir + "/tiny.ply");
  ASSERT_TRUE(file.has_value());
  expect_said_once(world, [&] { (void)jobs::scan_mesh(world, *file); }, "tiny.ply: the mesh is only");
  world.barrier();
  if (world.rank() == 0) fs::remove_all(dir);
}

TEST(BrickRead, EveryFaceHasOneOwnerAndTheGhostsCoverTheMargin) {
  const mpi::Comm world = mpi::mpi_world();
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-bricks");
  TriMesh m = make_torus(1.0, 0.4, 60, 30);
  m.faces.push_back({5, 5, 6});  // degenerate: nobody's
  if (world.rank() == 0) io::write_mesh(dir + "/t.ply", m);
  world.barrier();
  const TriMesh file_mesh = io::read_mesh(dir + "/t.ply");  // the float coordinates the bricks see
  const auto file = io::PlyTriangleFile::open(dir + "/t.ply");
  ASSERT_TRUE(file.has_value());
  const jobs::ScannedMesh scan = jobs::scan_mesh(world, *file);
  EXPECT_EQ(scan.faces, m.faces.size() - 1);
  const Vec3 origin = scan.box.center();
  const jobs::BrickMesh brick = jobs::read_brick(world, scan, origin, {0.05, 0.0, true});
  ASSERT_EQ(brick.face_ids.size(), brick.mesh.faces.size());
  ASSERT_EQ(brick.owned.size(), brick.mesh.faces.size());
  // Owners, summed over the ranks: every face exactly once, the degenerate one never.
  std::vector<std::uint64_t> owners(m.faces.size(), 0);
  for (std::size_t f = 0; f < brick.face_ids.size(); ++f) owners[brick.face_ids[f]] += brick.owned[f];
  owners = world.allreduce(std::move(owners), mpi::ReduceOp::kSum);
  for (std::size_t f = 0; f + 1 < owners.size(); ++f) EXPECT_EQ(owners[f], 1u) << "face " << f;
  EXPECT_EQ(owners.back(), 0u);
  // Held faces: exactly the owned ones and those with a vertex within the margin of the brick, with the
  // file's positions in the local frame.
  const BoundingBox near{brick.bounds.min - Vec3::Constant(brick.margin), brick.bounds.max + Vec3::Constant(brick.margin)};
  const std::set<std::uint64_t> held(brick.face_ids.begin(), brick.face_ids.end());
  std::size_t expected = 0;
  for (std::size_t f = 0; f + 1 < file_mesh.faces.size(); ++f) {
    const Face& t = file_mesh.faces[f];
    bool close = brick.partition.brick_of(file_mesh.positions[t[0]] - origin) == static_cast<std::size_t>(world.rank());
    for (const std::uint32_t v : t) {
      const Vec3 q = file_mesh.positions[v] - origin;
      close = close || ((q.array() >= near.min.array()).all() && (q.array() <= near.max.array()).all());
    }
    expected += close ? 1 : 0;
    EXPECT_EQ(held.count(f), close ? 1u : 0u) << "face " << f;
  }
  EXPECT_EQ(held.size(), expected);
  for (std::size_t f = 0; f < brick.mesh.faces.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t v = file_mesh.faces[brick.face_ids[f]][static_cast<std::size_t>(k)];
      EXPECT_EQ(brick.mesh.positions[brick.mesh.faces[f][static_cast<std::size_t>(k)]], file_mesh.positions[v] - origin);
    }
  // A brick per rank, and none holds everything when there are several.
  EXPECT_EQ(brick.partition.size(), static_cast<std::size_t>(world.size()));
  EXPECT_LT(held.size(), m.faces.size() - 1);
  world.barrier();
  if (world.rank() == 0) fs::remove_all(dir);
}
