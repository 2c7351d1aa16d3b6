// Benchmark: ray casting of relief maps (Apaza & Andújar §3.5.2) against an Embree reference render of
// the original mesh.
//
//   bench_relief_raycast [MESH] [--grid N|auto] [--texture 64] [--size 512] [--views AZ,EL;AZ,EL;...]
//                        [--repeat R] [--threads 1,2] [--steps 12] [--refine 6] [--filter bilinear|nearest]
//                        [--up x|y|z] [--margin 1.05] [--cull on|off] [--simd on|off]
//                        [--traversal cells|walk] [--write-dir DIR]
//
// MESH defaults to ../shared/data/meshes/bunny_closed.ply. The relief map is built once (build_relief_map,
// not timed here: bench_relief times it). For every thread count and view: the best and median wall time
// of R renders of size × size pixels (one primary ray per pixel; the ray caster's tables are built once
// and not timed), rays per second of the best run, inside tests per ray, and the image comparison with
// the Embree reference render of the same view (PSNR of the shaded 8-bit images over all pixels,
// silhouette IoU, depth errors relative to the bounding-box diagonal, mean normal angle). The reference
// render's own time is printed too. --margin scales the bounding sphere that the orbit camera fits into
// the frame (OrbitView::margin): 1.05 shows the whole model, about 0.4 a close-up where most rays hit it.
// --cull off disables the empty-space bounds (RaycastOptions::cull_empty_space: the same image with more
// inside tests). --simd off marches the border cells one sample at a time even where the CPU has AVX2
// (RaycastOptions::vectorized: the same image and test count). --traversal walk makes every pixel's ray
// walk the grid instead of drawing the cells front to back (RaycastOptions::traversal: the same image and
// test count). --write-dir writes both shaded images of every view as PGM.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <tbb/global_control.h>

#include "io/mesh_io.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/relief/mesh_render.h"
#include "kernels/relief/relief_map.h"
#include "kernels/relief/relief_raycast.h"

using namespace gimforge;
using Clock = std::chrono::steady_clock;

namespace {

std::vector<int> parse_ints(const std::string& text) {
  std::vector<int> values;
  std::stringstream in(text);
  for (std::string item; std::getline(in, item, ',');) values.push_back(std::stoi(item));
  return values;
}

/// "AZ,EL;AZ,EL;..."
std::vector<OrbitView> parse_views(const std::string& text, int up, double margin) {
  std::vector<OrbitView> views;
  std::stringstream in(text);
  for (std::string item; std::getline(in, item, ';');) {
    const auto comma = item.find(',');
    if (comma == std::string::npos) throw InvalidInput("--views: expected AZ,EL;AZ,EL;...");
    OrbitView v;
    v.azimuth_deg = std::stod(item.substr(0, comma));
    v.elevation_deg = std::stod(item.substr(comma + 1));
    v.up_axis = up;
    v.margin = margin;
    views.push_back(v);
  }
  return views;
}

/// Writes the shaded image as a binary PGM (kept free of the PNG library, which lives in gimforge_h5).
void write_pgm(const std::string& path, const RenderImage& img) {
  std::ofstream out(path, std::ios::binary);
  out << "P5\n" << img.width << ' ' << img.height << "\n255\n";
  out.write(reinterpret_cast<const char*>(img.shaded.data()), static_cast<std::streamsize>(img.shaded.size()));
  if (!out) throw IoError(path + ": cannot write");
}

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

}  // namespace

int main(int argc, char** argv) {
  std::string mesh_path = "../shared/data/meshes/bunny_closed.ply";
  ReliefOptions build;
  build.grid = 16;
  build.texture = 64;
  RaycastOptions rc;
  std::uint32_t size = 512;
  std::string views_text = "30,20;120,10;210,30;300,-15";
  std::vector<int> thread_counts{1, 2};
  int repeat = 5;
  int up = 1;
  double margin = 1.05;
  std::string write_dir;
  int i = 1;
  if (argc > 1 && argv[1][0] != '-') mesh_path = argv[i++];
  for (; i < argc; i += 2) {
    const std::string key = argv[i];
    if (i + 1 >= argc) {
      fmt::print(stderr, "option {} needs a value\n", key);
      return 2;
    }
    const std::string value = argv[i + 1];
    if (key == "--grid") build.grid = value == "auto" ? 0u : static_cast<std::uint32_t>(std::stoul(value));
    else if (key == "--texture") build.texture = static_cast<std::uint32_t>(std::stoul(value));
    else if (key == "--size") size = static_cast<std::uint32_t>(std::stoul(value));
    else if (key == "--views") views_text = value;
    else if (key == "--repeat") repeat = std::max(1, std::stoi(value));
    else if (key == "--threads") thread_counts = parse_ints(value);
    else if (key == "--steps") rc.linear_steps = static_cast<std::uint32_t>(std::stoul(value));
    else if (key == "--refine") rc.binary_steps = static_cast<std::uint32_t>(std::stoul(value));
    else if (key == "--filter" && (value == "bilinear" || value == "nearest"))
      rc.filter = value == "bilinear" ? ReliefFilter::Bilinear : ReliefFilter::Nearest;
    else if (key == "--up" && (value == "x" || value == "y" || value == "z")) up = value[0] - 'x';
    else if (key == "--write-dir") write_dir = value;
    else if (key == "--margin") margin = std::stod(value);
    else if (key == "--cull" && (value == "on" || value == "off")) rc.cull_empty_space = value == "on";
    else if (key == "--simd" && (value == "on" || value == "off")) rc.vectorized = value == "on";
    else if (key == "--traversal" && (value == "cells" || value == "walk"))
      rc.traversal = value == "cells" ? RenderTraversal::CellOrder : RenderTraversal::Walk;
    else {
      fmt::print(stderr,
                 "usage: bench_relief_raycast [MESH] [--grid N|auto] [--texture 64] [--size 512] [--views AZ,EL;...]\n"
                 "       [--repeat R] [--threads 1,2] [--steps 12] [--refine 6] [--filter bilinear|nearest]\n"
                 "       [--up x|y|z] [--margin 1.05] [--cull on|off] [--simd on|off] [--traversal cells|walk]\n"
                 "       [--write-dir DIR]\n");
      return 2;
    }
  }
  try {
    const std::vector<OrbitView> views = parse_views(views_text, up, margin);
    const TriMesh mesh = io::read_mesh(mesh_path);
    const BoundingBox box = bounding_box(mesh);
    const double diagonal = box.diagonal();
    auto t0 = Clock::now();
    const ReliefMap map = build_relief_map(mesh, build);
    const double build_s = seconds_since(t0);
    fmt::print("mesh {}: {} vertices, {} faces, diagonal {:.4g}\n", mesh_path, mesh.num_vertices(), mesh.num_faces(),
               diagonal);
    fmt::print("relief map: n = {}, T = {}, {} grey cells, {} layers, {:.1f} KiB, built in {:.2f} s\n", map.n,
               map.texture, map.cells.size(), map.num_layers(), static_cast<double>(map.storage_bytes()) / 1024.0,
               build_s);
    fmt::print("ray casting: {} linear steps per cell, refinement as fine as {} halvings, {} filter, "
               "empty-space culling {}; {}x{} pixels\n\n",
               rc.linear_steps, rc.binary_steps, rc.filter == ReliefFilter::Bilinear ? "bilinear" : "nearest",
               rc.cull_empty_space ? "on" : "off", size, size);

    t0 = Clock::now();
    const ReliefRaycaster caster(map, rc);
    const double setup_s = seconds_since(t0);
    const EmbreeDevice device;
    const MeshRenderer reference(device, mesh, rc.ambient);
    fmt::print("ray caster set-up: {:.2f} ms; cells marched {}; {}\n\n", 1e3 * setup_s,
               caster.vectorized() ? "8 samples at a time (AVX2)" : "one sample at a time",
               rc.traversal == RenderTraversal::CellOrder ? "cells drawn front to back" : "every ray walks the grid");

    if (!write_dir.empty()) std::filesystem::create_directories(write_dir);
    fmt::print("| threads | view (az, el) | best ms | median ms | Mrays/s | tests/ray | hit px | ref ms | PSNR dB "
               "| IoU | depth mean/diag | depth p95/diag | normal ° |\n");
    fmt::print("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const int threads : thread_counts) {
      const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
      std::uint64_t total_rays = 0;
      double total_best = 0.0;
      double psnr_sum = 0.0, iou_sum = 0.0;
      for (const OrbitView& view : views) {
        const Camera camera = orbit_camera(box, view, size, size);
        std::vector<double> times;
        RenderImage img;
        for (int r = 0; r < repeat; ++r) {
          img = caster.render(camera);
          times.push_back(img.seconds);
        }
        std::sort(times.begin(), times.end());
        RenderImage ref = reference.render(camera);
        double ref_best = ref.seconds;
        for (int r = 1; r < std::min(repeat, 3); ++r) ref_best = std::min(ref_best, reference.render(camera).seconds);
        const RenderComparison cmp = compare_renders(img, ref);
        total_rays += img.rays;
        total_best += times.front();
        psnr_sum += cmp.psnr;
        iou_sum += cmp.iou;
        fmt::print("| {} | {:g}, {:g} | {:.1f} | {:.1f} | {:.2f} | {:.1f} | {} | {:.1f} | {:.2f} | {:.4f} | {:.2e} "
                   "| {:.2e} | {:.2f} |\n",
                   threads, view.azimuth_deg, view.elevation_deg, 1e3 * times.front(), 1e3 * times[times.size() / 2],
                   1e-6 * static_cast<double>(img.rays) / times.front(),
                   static_cast<double>(img.samples) / static_cast<double>(img.rays), img.hits, 1e3 * ref_best, cmp.psnr,
                   cmp.iou, cmp.depth_mean_abs / diagonal, cmp.depth_p95 / diagonal, cmp.normal_mean_deg);
        if (!write_dir.empty() && threads == thread_counts.front()) {
          const auto stem = fmt::format("{}/view_{:g}_{:g}", write_dir, view.azimuth_deg, view.elevation_deg);
          write_pgm(stem + "_relief.pgm", img);
          write_pgm(stem + "_reference.pgm", ref);
        }
      }
      fmt::print("| {} | all views | {:.1f} (sum) | | **{:.2f}** | | | | {:.2f} (mean) | {:.4f} (mean) | | | |\n",
                 threads,
                 1e3 * total_best, 1e-6 * static_cast<double>(total_rays) / total_best,
                 psnr_sum / static_cast<double>(views.size()), iou_sum / static_cast<double>(views.size()));
    }
  } catch (const std::exception& e) {
    fmt::print(stderr, "bench_relief_raycast: {}\n", e.what());
    return 1;
  }
  return 0;
}
