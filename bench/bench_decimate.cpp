// Benchmark: quadric decimation of a mesh to a proxy (kernels/scan/decimate.h), whole or in bricks, and the
// proxy's fidelity (symmetric RMS Hausdorff PSNR against the mesh, 1M samples per direction).
//
//   bench_decimate MESH --faces F [--bricks B] [--threads T] [--no-metric]
#include <chrono>
#include <vector>
#include <cstdio>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <tbb/global_control.h>

#include "io/mesh_io.h"
#include "jobs/scan_bricks.h"
#include "kernels/scan/bricks.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/validate.h"
#include "kernels/scan/decimate.h"

using namespace gimforge;
using Clock = std::chrono::steady_clock;

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fputs("usage: bench_decimate MESH --faces F [--bricks B] [--threads T] [--no-metric]\n", stderr);
    return 2;
  }
  DecimateOptions options;
  int threads = 0;
  std::size_t bricks = 1;
  bool metric = true;
  for (int i = 2; i < argc; ++i) {
    const std::string key = argv[i];
    if (key == "--no-metric") {
      metric = false;
      continue;
    }
    if (i + 1 >= argc) { fmt::print(stderr, "{} needs a value\n", key); return 2; }
    if (key == "--faces") options.target_faces = std::stoull(argv[++i]);
    else if (key == "--bricks") bricks = std::stoull(argv[++i]);
    else if (key == "--threads") threads = std::stoi(argv[++i]);
    else { fmt::print(stderr, "unknown option {}\n", key); return 2; }
  }
  std::unique_ptr<tbb::global_control> limit;
  if (threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
  try {
    TriMesh mesh = io::read_mesh(argv[1]);
    (void)repair_mesh(mesh);
    // Bricks as the proxy path cuts them: k-d splits of the vertex histogram, a face in its first vertex's.
    std::vector<std::uint8_t> brick_of_face;
    if (bricks > 1) {
      CentroidHistogram histogram = jobs::brick_histogram(bounding_box(mesh));
      for (const Vec3& p : mesh.positions) histogram.add(p);
      const BrickPartition partition = partition_bricks(histogram, bricks);
      for (const Face& f : mesh.faces) brick_of_face.push_back(static_cast<std::uint8_t>(partition.brick_of(mesh.positions[f[0]])));
      options.brick_of_face = brick_of_face;
    }
    const auto t0 = Clock::now();
    const DecimateResult r = decimate_quadric(mesh, options);
    const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    fmt::print("{}: {} faces -> {} faces ({} bricks, {} rejected) in {:.2f} s\n", argv[1], mesh.num_faces(),
               r.mesh.num_faces(), bricks, r.rejected_faces, seconds);
    if (metric) {
      const EmbreeDevice device;
      const HausdorffResult h = symmetric_hausdorff(device, mesh, r.mesh, {});
      fmt::print("proxy PSNR {:.3f} dB (rms {:.4g}, max {:.4g})\n", h.psnr, h.rms, h.max);
    }
  } catch (const Error& e) {
    fmt::print(stderr, "bench_decimate: {}\n", e.what());
    return 1;
  }
  return 0;
}
