// Benchmark: exact closest-point queries per second per core against a mesh, for samples on a nearby
// surface (the case of a remesh compared with its original).
//
//   bench_point_query MESH [--samples N] [--offset F] [--threads T]
//
// The query points are area-weighted samples of MESH displaced along their face normal by F times the
// bounding-box diagonal (alternating sign), i.e. points on a surface near the original. Prints the BVH
// build time, queries per second on T threads, and per core.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <fmt/format.h>
#include <tbb/global_control.h>

#include "io/mesh_io.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/surface_sampling.h"
#include "kernels/core/validate.h"

using namespace gimforge;
using Clock = std::chrono::steady_clock;

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fputs("usage: bench_point_query MESH [--samples N] [--offset F] [--threads T]\n", stderr);
    return 2;
  }
  std::size_t samples = 2'000'000;
  double offset = 1e-3;
  int threads = 1;
  for (int i = 2; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    if (key == "--samples") samples = std::stoull(argv[i + 1]);
    else if (key == "--offset") offset = std::stod(argv[i + 1]);
    else if (key == "--threads") threads = std::stoi(argv[i + 1]);
    else { fmt::print(stderr, "unknown option {}\n", key); return 2; }
  }
  try {
    TriMesh mesh = io::read_mesh(argv[1]);
    (void)repair_mesh(mesh);
    const double diag = bounding_box(mesh).diagonal();
    const SurfaceSamples s = sample_surface(mesh, {samples, 12345});
    std::vector<Vec3> points(s.points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Face& f = mesh.faces[s.faces[i]];
      Vec3 n = (mesh.positions[f[1]] - mesh.positions[f[0]]).cross(mesh.positions[f[2]] - mesh.positions[f[0]]);
      n.normalize();
      points[i] = s.points[i] + ((i % 2) ? 1.0 : -1.0) * offset * diag * n;
    }
    tbb::global_control control(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
    const EmbreeDevice device;
    const auto t0 = Clock::now();
    const TriangleBvh bvh(device, mesh);
    const auto t1 = Clock::now();
    const std::vector<double> d = distances_to_surface(points, bvh);
    const auto t2 = Clock::now();
    const double build = std::chrono::duration<double>(t1 - t0).count();
    const double query = std::chrono::duration<double>(t2 - t1).count();
    const OneSidedDistance stats = summarize_distances(d, d.size());
    fmt::print("mesh            {} ({} faces)\n", argv[1], mesh.num_faces());
    fmt::print("queries         {} points at {:.1e} x diag from the surface\n", points.size(), offset);
    fmt::print("threads         {}\n", threads);
    fmt::print("bvh build       {:.3f} s\n", build);
    fmt::print("query time      {:.3f} s\n", query);
    fmt::print("queries/s       {:.0f}\n", static_cast<double>(points.size()) / query);
    fmt::print("queries/s/core  {:.0f}\n", static_cast<double>(points.size()) / query / threads);
    fmt::print("check: mean distance / diag = {:.3e} (expected about {:.1e})\n", stats.mean / diag, offset);
  } catch (const Error& e) {
    fmt::print(stderr, "bench_point_query: {}\n", e.what());
    return 1;
  }
  return 0;
}
