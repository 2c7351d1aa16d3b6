// Benchmark: relief-map construction (Apaza & Andújar §3.3) and the fidelity of its geometry-based
// reconstruction (§3.5.1), one line per mesh.
//
//   bench_relief MESH... [--grid N|auto] [--max-grid 32] [--texture 64] [--threshold 0.05]
//                        [--samples 1000000] [--repeat R] [--threads T] [--max-edge 8] [--diag D] [--verbose]
//
// Per mesh: faces, the grid N chosen (and the occlusion ratio of every level tried), grey cells, domain
// faces, storage bytes, the best wall time of R constructions (classification + sampling; the mesh read
// is not timed) with its split, and the symmetric RMS Hausdorff PSNR of the reconstruction against the
// input (--samples area samples per direction; 0 skips it). Threads: all cores unless --threads.
// --verbose adds both one-sided distances; --diag D counts, per base case, the input vertices farther than
// D from the reconstruction (where the representation loses surface); --max-edge sets reconstruct_relief's
// discontinuity limit in texel spacings.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <tbb/global_control.h>

#include "io/mesh_io.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "kernels/relief/relief_map.h"

using namespace gimforge;
using Clock = std::chrono::steady_clock;

int main(int argc, char** argv) {
  std::vector<std::string> meshes;
  ReliefOptions options;
  std::size_t samples = 1'000'000;
  int repeat = 1;
  int threads = 0;
  double max_edge_texels = 8.0;  // reconstruct_relief's discontinuity limit
  double diag_threshold = 0.0;   // > 0: per base case, the input vertices farther than this from the reconstruction
  bool verbose = false;          // both one-sided RMS and max distances
  for (int i = 1; i < argc; ++i) {
    const std::string key = argv[i];
    const bool has_value = i + 1 < argc;
    if (key == "--grid" && has_value) {
      const std::string v = argv[++i];
      options.grid = v == "auto" ? 0 : static_cast<std::uint32_t>(std::stoul(v));
    } else if (key == "--max-grid" && has_value) options.max_grid = static_cast<std::uint32_t>(std::stoul(argv[++i]));
    else if (key == "--texture" && has_value) options.texture = static_cast<std::uint32_t>(std::stoul(argv[++i]));
    else if (key == "--threshold" && has_value) options.occlusion_threshold = std::stod(argv[++i]);
    else if (key == "--samples" && has_value) samples = std::stoul(argv[++i]);
    else if (key == "--repeat" && has_value) repeat = std::max(1, std::stoi(argv[++i]));
    else if (key == "--threads" && has_value) threads = std::stoi(argv[++i]);
    else if (key == "--max-edge" && has_value) max_edge_texels = std::stod(argv[++i]);
    else if (key == "--diag" && has_value) diag_threshold = std::stod(argv[++i]);
    else if (key == "--verbose") verbose = true;
    else if (key.rfind("--", 0) == 0) {
      fmt::print(stderr, "unknown option {}\n", key);
      return 2;
    } else meshes.push_back(key);
  }
  if (meshes.empty()) {
    std::fputs("usage: bench_relief MESH... [--grid N|auto] [--max-grid 32] [--texture 64] [--threshold 0.05] "
               "[--samples 1000000] [--repeat R] [--threads T]\n",
               stderr);
    return 2;
  }
  std::unique_ptr<tbb::global_control> limit;
  if (threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
  fmt::print("{:<18} {:>8} {:>4} {:>6} {:>7} {:>11} {:>8} {:>7} {:>8} {:>8}  {}\n", "mesh", "faces", "N", "grey",
             "domain", "bytes", "best s", "cells s", "sample s", "PSNR dB", "levels (N: occlusion ratio)");
  int failures = 0;
  for (const std::string& path : meshes) {
    try {
      const TriMesh mesh = io::read_mesh(path);
      ReliefMap map;
      double best = 1e300, best_cells = 0.0, best_sampling = 0.0;  // the split of the best run
      for (int r = 0; r < repeat; ++r) {
        const auto t0 = Clock::now();
        map = build_relief_map(mesh, options);
        const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
        if (seconds < best) {
          best = seconds;
          best_cells = map.seconds_cells;
          best_sampling = map.seconds_sampling;
        }
      }
      double psnr = 0.0;
      if (samples > 0) {
        const TriMesh rec = reconstruct_relief(map, max_edge_texels);
        HausdorffOptions ho;
        ho.samples = samples;
        const HausdorffResult h = symmetric_hausdorff(EmbreeDevice(), mesh, rec, ho);
        psnr = h.psnr;
        if (diag_threshold > 0.0) {  // where the reconstruction misses the input: cases of the cells
          const EmbreeDevice dev;
          const TriangleBvh bvh(dev, rec);
          const double thr = diag_threshold;
          std::vector<int> hist(kNumReliefCases, 0), all(kNumReliefCases, 0);
          for (const Vec3& p : mesh.positions) {
            const Vec3 rel = (p - map.origin) / map.cell_size;
            const auto clampi = [&](double x) { return static_cast<std::uint32_t>(std::clamp(x, 0.0, map.n - 1.0)); };
            const std::size_t lin = (static_cast<std::size_t>(clampi(rel.z())) * map.n + clampi(rel.y())) * map.n + clampi(rel.x());
            const auto it = std::lower_bound(map.cells.begin(), map.cells.end(), lin);
            if (it == map.cells.end() || *it != lin) continue;
            const int c = static_cast<int>(map.projections[static_cast<std::size_t>(it - map.cells.begin())].base_case);
            ++all[static_cast<std::size_t>(c)];
            if (bvh.closest_point(p).distance > thr) ++hist[static_cast<std::size_t>(c)];
          }
          for (int c = 0; c < kNumReliefCases; ++c)
            fmt::print("  case {:>2}: {} of {} vertices farther than {}\n", relief_case_name(static_cast<ReliefCase>(c)),
                       hist[static_cast<std::size_t>(c)], all[static_cast<std::size_t>(c)], thr);
        }
        if (verbose)
          fmt::print("  rms a->b {:.3g} b->a {:.3g} max a->b {:.3g} b->a {:.3g} (diag {:.4g}); reconstruction {} faces\n",
                     h.ab.rms, h.ba.rms, h.ab.max, h.ba.max, h.diag, rec.num_faces());
      }
      std::string levels;
      for (const ReliefGridLevel& l : map.levels) levels += fmt::format("{}: {:.4f}  ", l.n, l.occlusion_ratio());
      std::string name = path.substr(path.find_last_of('/') + 1);
      fmt::print("{:<18} {:>8} {:>4} {:>6} {:>7} {:>11} {:>8.3f} {:>7.3f} {:>8.3f} {:>8.2f}  {}{}\n", name,
                 mesh.num_faces(), map.n, map.cells.size(), map.num_layers(), map.storage_bytes(), best,
                 best_cells, best_sampling, psnr, levels,
                 map.watertight_inside_test ? "" : "(parity inside test)");
      std::fflush(stdout);
    } catch (const Error& e) {
      fmt::print(stderr, "{}: {}\n", path, e.what());
      ++failures;
    }
  }
  return failures == 0 ? 0 : 1;
}
