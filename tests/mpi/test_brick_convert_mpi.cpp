// Image conversion of a scan by bricks (jobs/brick_convert.h) for any number of ranks >= 2 (ctest runs 2
// and 4): the same proxy as one process (bit for bit: its PSNR and size), the same image up to samples whose
// ray runs through an edge shared by two ranks' faces (a float ulp), the same fidelity to 1e-9, far from the
// origin too; a truncated file fails every rank without a hang. EXPECT, not ASSERT: collectives stay matched.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "io/atomic_file.h"
#include "io/mesh_io.h"
#include "io/ply_ranges.h"
#include "jobs/brick_convert.h"
#include "jobs/load_mesh.h"
#include "jobs/pipeline.h"
#include "jobs/scan_bricks.h"
#include "kernels/core/validate.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "mpi/agree.h"
#include "mpi/mpi_comm.h"
#include "tests/mpi/shared_folder.h"

using namespace gimforge;
namespace fs = std::filesystem;

namespace {

/// A 65×65 geometry image of `scan` through a 1,500-face proxy decimated in 5 bricks (seams between bricks,
/// and ranks holding several bricks), 20,000 metric samples.
jobs::ConversionRequest gim_request(const std::string& scan) {
  jobs::ConversionRequest request;
  request.source = scan;
  request.method.method = jobs::Method::Gim;
  request.method.size = 65;
  request.method.normal_size = 64;
  request.method.proxy_faces = "1500";
  request.fidelity.samples = 20000;
  request.method.proxy_bricks = 5;
  return request;
}

/// The wavy 25,600-face torus far from the origin (UTM-like), written by rank 0 as `dir`/torus.ply.
std::string write_torus_scan(const mpi::Comm& world, const std::string& dir) {
  const std::string scan = dir + "/torus.ply";
  if (world.rank() == 0) {
    TriMesh t = make_torus(1.0, 0.4, 160, 80);
    for (Vec3& p : t.positions) p += Vec3(612345.0, 4123456.0, 80.0) + 0.01 * Vec3(std::sin(9 * p.x()), 0, 0);
    io::write_ply(scan, t, {.binary = true, .double_precision = true});
  }
  world.barrier();
  return scan;
}

}  // namespace

TEST(BrickConvert, EqualsOneProcess) {
  const mpi::Comm world = mpi::mpi_world();
  const EmbreeDevice device;
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-bconvert");
  const std::string scan = write_torus_scan(world, dir);
  const jobs::ConversionRequest request = gim_request(scan);
  EXPECT_TRUE(jobs::converts_in_bricks(world, scan, request));
  if (world.rank() == 0) {  // what a run killed during its fidelity left: a process of this host that is gone
    std::string leftover = io::temporary_path(dir + "/.gimforge-torus.reconstruction.ply").string();
    leftover.replace(leftover.rfind('.', leftover.size() - 5) + 1, std::string::npos, "999999999.tmp");
    std::ofstream(leftover) << "ply";
  }
  const std::optional<jobs::Conversion> result = jobs::brick_convert(world, device, scan, request, dir);
  EXPECT_TRUE(result.has_value());
  const jobs::Conversion bricks = result.value_or(jobs::Conversion{});
  if (world.rank() == 0 && result) {
    const jobs::LoadedMesh m = jobs::load_mesh(scan, jobs::load_policy(jobs::Method::Gim, false));
    const jobs::Conversion one = jobs::convert_mesh(device, m.mesh, request);
    EXPECT_EQ(bricks.numbers.at("proxy_bricks"), 5.0);
    EXPECT_EQ(bricks.numbers.at("proxy_faces"), one.numbers.at("proxy_faces"));
    EXPECT_EQ(bricks.numbers.at("proxy_psnr"), one.numbers.at("proxy_psnr"));  // the same proxy
    EXPECT_EQ(bricks.origin, one.origin);
    EXPECT_NEAR(bricks.numbers.at("psnr"), one.numbers.at("psnr"), 1e-9 * one.numbers.at("psnr"));
    const std::vector<float>& a = bricks.gim.value().image.positions;
    const std::vector<float>& b = one.gim.value().image.positions;
    EXPECT_EQ(a.size(), b.size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i)
      if (a[i] != b[i]) {
        ++differ;
        EXPECT_NEAR(a[i], b[i], 1e-5) << i;
      }
    EXPECT_LE(differ, a.size() / 100);
    EXPECT_GT(bricks.numbers.at("psnr"), bricks.numbers.at("proxy_psnr"));
  }
  // No temporary file is left beside the output, and the killed run's is gone.
  if (world.rank() == 0) {
    for (const auto& entry : fs::directory_iterator(dir)) {
      EXPECT_EQ(entry.path().filename().string().rfind(".gimforge-", 0), std::string::npos) << entry.path();
    }
  }
  world.barrier();
}

TEST(BrickConvert, AWrapOfTheProxyEqualsOneProcess) {
  // Two pieces (gim alone refuses them): the ranks' proxy is wrapped on every rank alike (--wrap 64), the
  // same wrap and proxy as one process, the same image up to ulps.
  const mpi::Comm world = mpi::mpi_world();
  const EmbreeDevice device;
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-bwrap");
  const std::string scan = dir + "/pieces.ply";
  if (world.rank() == 0) {
    TriMesh ball = make_icosphere(0.3, 3);
    for (Vec3& p : ball.positions) p += Vec3(2.2, 0.0, 0.0);
    TriMesh t = concatenate(make_torus(1.0, 0.4, 160, 80), ball);  // 25,600 + 1,280 faces
    for (Vec3& p : t.positions) p += Vec3(612345.0, 4123456.0, 80.0);
    io::write_ply(scan, t, {.binary = true, .double_precision = true});
  }
  world.barrier();
  jobs::ConversionRequest request = gim_request(scan);
  request.method.wrap = "64";
  const std::optional<jobs::Conversion> result = jobs::brick_convert(world, device, scan, request, dir);
  EXPECT_TRUE(result.has_value());
  const jobs::Conversion bricks = result.value_or(jobs::Conversion{});
  if (world.rank() == 0 && result) {
    const jobs::LoadedMesh m = jobs::load_mesh(scan, jobs::load_policy(request.method, false));
    const jobs::Conversion one = jobs::convert_mesh(device, m.mesh, request);
    for (const char* key : {"wrap_faces", "wrap_dropped_components", "proxy_faces"})
      EXPECT_EQ(bricks.numbers.at(key), one.numbers.at(key)) << key;
    // The wrap's vertices are new points: through the ranks' temporary file in the input's frame they round.
    for (const char* key : {"proxy_psnr", "psnr"})
      EXPECT_NEAR(bricks.numbers.at(key), one.numbers.at(key), 1e-9 * one.numbers.at(key)) << key;
    EXPECT_EQ(one.numbers.at("wrap_dropped_components"), 1.0);  // the ball
    const std::vector<float>& a = bricks.gim.value().image.positions;
    const std::vector<float>& b = one.gim.value().image.positions;
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i], b[i], 1e-5) << i;
  }
  world.barrier();
}

TEST(BrickConvert, AFitAfterTheTransferEqualsOneProcess) {
  // --optimize: the image is fitted to the full surface after the transfer; the ranks draw the fit's area
  // samples on their slices of the scan (brick_samples), the same samples one process draws on the whole.
  const mpi::Comm world = mpi::mpi_world();
  const EmbreeDevice device;
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-bfit");
  const std::string scan = write_torus_scan(world, dir);
  jobs::ConversionRequest request = gim_request(scan);
  request.method.optimize = true;
  const std::optional<jobs::Conversion> result = jobs::brick_convert(world, device, scan, request, dir);
  EXPECT_TRUE(result.has_value());
  const jobs::Conversion bricks = result.value_or(jobs::Conversion{});
  if (world.rank() == 0 && result) {
    const jobs::LoadedMesh m = jobs::load_mesh(scan, jobs::load_policy(jobs::Method::Gim, false));
    const jobs::Conversion one = jobs::convert_mesh(device, m.mesh, request);
    // The transfer differs by float ulps where a ray meets a seam between ranks; the fit carries them.
    for (const char* key : {"fit_energy_before", "fit_energy_after", "psnr"})
      EXPECT_NEAR(bricks.numbers.at(key), one.numbers.at(key), 1e-6 * one.numbers.at(key)) << key;
    const std::vector<float>& a = bricks.gim.value().image.positions;
    const std::vector<float>& b = one.gim.value().image.positions;
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i], b[i], 1e-5) << i;
    EXPECT_GT(bricks.numbers.at("psnr"), bricks.numbers.at("proxy_psnr") + 10.0);
  }
  world.barrier();
}

TEST(BrickConvert, DuplicateFacesGoAsTheLoaderRemovesThem) {
  // Copies of faces (rotated or mirrored) across the scan: one process's loader drops them before the proxy
  // and the fidelity; by bricks the owner of each copy finds it, and the proxy, the face count and the
  // fidelity come out as one process's.
  const mpi::Comm world = mpi::mpi_world();
  const EmbreeDevice device;
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-bconvert");
  const std::string scan = dir + "/copies.ply";
  if (world.rank() == 0) {
    TriMesh t = make_torus(1.0, 0.4, 160, 80);
    for (Vec3& p : t.positions) p += 0.01 * Vec3(std::sin(9 * p.x()), 0, 0);
    const std::size_t faces = t.faces.size();
    for (std::size_t f = 11; f < faces; f += 61) {
      const Face a = t.faces[f];
      t.faces.push_back(f % 2 == 0 ? Face{a[2], a[0], a[1]} : Face{a[0], a[2], a[1]});
    }
    io::write_ply(scan, t, {.binary = true});
  }
  world.barrier();
  const jobs::ConversionRequest request = gim_request(scan);
  const std::optional<jobs::Conversion> result = jobs::brick_convert(world, device, scan, request, dir);
  EXPECT_TRUE(result.has_value());
  if (world.rank() == 0 && result) {
    const jobs::LoadedMesh m = jobs::load_mesh(scan, jobs::load_policy(jobs::Method::Gim, false));
    const jobs::Conversion one = jobs::convert_mesh(device, m.mesh, request);
    EXPECT_EQ(result->input_faces, one.input_faces);
    EXPECT_EQ(result->numbers.at("proxy_faces"), one.numbers.at("proxy_faces"));
    EXPECT_EQ(result->numbers.at("proxy_psnr"), one.numbers.at("proxy_psnr"));
    EXPECT_NEAR(result->numbers.at("psnr"), one.numbers.at("psnr"), 1e-9 * one.numbers.at("psnr"));
  }
  world.barrier();
}

TEST(BrickConvert, TruncatedScanFailsEveryRank) {
  const mpi::Comm world = mpi::mpi_world();
  const EmbreeDevice device;
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-bconvert");
  const std::string scan = gimforge::test::truncated_scan(world, dir);
  jobs::ConversionRequest request;
  request.source = scan;
  request.method.proxy_faces = "1500";
  gimforge::test::expect_fails_as_truncated(world, [&] { (void)jobs::brick_convert(world, device, scan, request, dir); });
}

TEST(BrickConvert, AMeshTheLoaderRefusesIsRefusedOrCutAsByOneProcess) {
  // The torus with eight fins on its edges (non-manifold edges and vertices), three faces turned over
  // (orientation conflicts) and a duplicate face (removed, not counted): the ranks count what the loader's
  // validation counts, whatever the rank count; gim refuses it as the loader does, and mcgim, which cuts it
  // to a 2-manifold before its proxy, declines so that rank 0 converts it whole as one process does.
  const mpi::Comm world = mpi::mpi_world();
  const EmbreeDevice device;
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-bconvert");
  const std::string scan = dir + "/defects.ply";
  if (world.rank() == 0) {
    TriMesh t = make_torus(1.0, 0.4, 160, 80);
    for (std::size_t f = 1000; f < 25600; f += 3500) {
      const Face face = t.faces[f];
      const Vec3 apex = (t.positions[face[0]] + t.positions[face[1]]) / 2.0 + Vec3(0.0, 0.0, 0.05);
      t.positions.push_back(apex);
      t.faces.push_back({face[0], face[1], static_cast<std::uint32_t>(t.positions.size() - 1)});
    }
    for (const std::size_t f : {3000u, 11000u, 19000u}) std::swap(t.faces[f][1], t.faces[f][2]);
    t.faces.push_back(t.faces[5]);
    io::write_ply(scan, t, {.binary = true, .double_precision = true});
  }
  world.barrier();
  jobs::ConversionRequest request = gim_request(scan);
  const std::optional<io::PlyTriangleFile> file = io::PlyTriangleFile::open(scan);
  ASSERT_TRUE(file.has_value());
  jobs::ScannedMesh scanned = jobs::scan_mesh(world, *file);
  const Vec3 origin = scanned.box.center();
  jobs::BrickMesh brick = jobs::read_brick(world, scanned, origin, {0.0, jobs::scan_longest_edge(world, scanned, origin), true});
  EXPECT_TRUE(jobs::drop_duplicate_faces(world, scanned, brick));
  const jobs::BrickTopology topology = jobs::brick_topology(world, brick);
  if (world.rank() == 0) {
    const ValidationReport v = validate_mesh(io::read_mesh(scan));
    EXPECT_EQ(topology.nonmanifold_edges, v.count(DefectKind::NonManifoldEdge));
    EXPECT_EQ(topology.nonmanifold_vertices, v.count(DefectKind::NonManifoldVertex));
    EXPECT_EQ(topology.inconsistent_edges, v.count(DefectKind::InconsistentOrientation));
    EXPECT_EQ(topology.nonmanifold_edges, 8u);
    EXPECT_EQ(topology.inconsistent_edges, 9u);
  }
  bool refused = false;
  try {
    (void)jobs::brick_convert(world, device, scan, request, dir);
  } catch (const TopologyError& e) {
    refused = world.rank() == 0 && std::string(e.what()).find("8 non-manifold edges") != std::string::npos;
  } catch (const mpi::PeerFailed&) {
    refused = world.rank() != 0;
  }
  EXPECT_TRUE(refused);
  request.method.method = jobs::Method::Mcgim;
  request.method.samples = 4096;
  request.method.charts = "8";
  EXPECT_FALSE(jobs::brick_convert(world, device, scan, request, dir).has_value());
  world.barrier();
}

TEST(BrickConvert, ErrorsOfTheWrapAreNamedAsByOneProcess) {
  // A flat sheet encloses nothing to wrap: "FILE: its wrap (--wrap 64): no closed surface ...", as one process
  // words it (the ranks' message had neither the file nor the wrap).
  const mpi::Comm world = mpi::mpi_world();
  const EmbreeDevice device;
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-bconvert");
  const std::string scan = dir + "/sheet.ply";
  if (world.rank() == 0) {
    TriMesh sheet;
    for (std::uint32_t j = 0; j < 60; ++j)
      for (std::uint32_t i = 0; i < 60; ++i) sheet.positions.emplace_back(i / 59.0, j / 59.0, 0.0);
    for (std::uint32_t j = 0; j + 1 < 60; ++j)
      for (std::uint32_t i = 0; i + 1 < 60; ++i) {
        const std::uint32_t a = j * 60 + i;
        sheet.faces.push_back({a, a + 1, a + 61});
        sheet.faces.push_back({a, a + 61, a + 60});
      }
    io::write_ply(scan, sheet, {.binary = true, .double_precision = true});
  }
  world.barrier();
  jobs::ConversionRequest request = gim_request(scan);
  request.method.wrap = "64";
  std::string message;
  try {
    (void)jobs::brick_convert(world, device, scan, request, dir);
  } catch (const mpi::PeerFailed&) {
    message = "peer";
  } catch (const Error& e) {
    message = e.what();
  }
  if (world.rank() == 0)
    EXPECT_EQ(message.rfind(scan + ": its wrap (--wrap 64): no closed surface", 0), 0u) << message;
  else
    EXPECT_EQ(message, "peer");
  world.barrier();
}

TEST(BrickConvert, DeclinesWhenOnlyDegenerateFacesCalledForAProxy) {
  // 25,600 faces and 600 degenerate ones: the file's count calls for a 25,800-face proxy, the scan without
  // them (what one process loads) does not. Every rank declines, and the caller converts it whole.
  const mpi::Comm world = mpi::mpi_world();
  const EmbreeDevice device;
  const std::string dir = gimforge::test::shared_folder(world, "gimforge-bconvert");
  const std::string scan = dir + "/dirty.ply";
  if (world.rank() == 0) {
    TriMesh t = make_torus(1.0, 0.4, 160, 80);
    for (std::uint32_t i = 0; i < 600; ++i) t.faces.push_back({i, i, i + 1});
    io::write_ply(scan, t);
  }
  world.barrier();
  jobs::ConversionRequest request;
  request.source = scan;
  request.method.proxy_faces = "25800";
  EXPECT_TRUE(jobs::converts_in_bricks(world, scan, request));
  EXPECT_FALSE(jobs::brick_convert(world, device, scan, request, dir).has_value());
  world.barrier();
}
