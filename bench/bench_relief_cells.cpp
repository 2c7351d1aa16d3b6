// Benchmark: cell classification for relief mapping (Apaza & Andújar §3.1) on a mesh, on 1 and 2 threads.
//
//   bench_relief_cells MESH [--n 16,32,64] [--threads 1,2] [--repeat R] [--inside auto|parity]
//
// For every grid size and thread count: the best and median wall time of R runs of classify_cells
// (grey cells with their face lists, regions, inside test, external faces; the mesh read is not timed),
// and the classification itself: grey / black / white cells, border and interior grey cells, regions,
// the inside test used and its ambiguous cells. Also times the watertightness check alone.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <tbb/global_control.h>

#include "io/mesh_io.h"
#include "kernels/core/errors.h"
#include "kernels/relief/relief_cells.h"

using namespace gimforge;
using Clock = std::chrono::steady_clock;

namespace {

std::vector<int> parse_list(const std::string& text) {
  std::vector<int> values;
  std::stringstream in(text);
  for (std::string item; std::getline(in, item, ',');) values.push_back(std::stoi(item));
  return values;
}

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fputs("usage: bench_relief_cells MESH [--n 16,32,64] [--threads 1,2] [--repeat R] [--inside auto|parity]\n",
               stderr);
    return 2;
  }
  std::vector<int> sizes{16, 32, 64}, thread_counts{1, 2};
  int repeat = 5;
  InsideTest inside = InsideTest::Automatic;
  for (int i = 2; i + 1 < argc; i += 2) {
    const std::string key = argv[i], value = argv[i + 1];
    if (key == "--n") sizes = parse_list(value);
    else if (key == "--threads") thread_counts = parse_list(value);
    else if (key == "--repeat") repeat = std::max(1, std::stoi(value));
    else if (key == "--inside" && (value == "auto" || value == "parity"))
      inside = value == "auto" ? InsideTest::Automatic : InsideTest::ParityVotes;
    else { fmt::print(stderr, "unknown option {} {}\n", key, value); return 2; }
  }
  try {
    const TriMesh mesh = io::read_mesh(argv[1]);
    fmt::print("mesh {}: {} vertices, {} faces\n", argv[1], mesh.num_vertices(), mesh.num_faces());
    {
      const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
      const auto t0 = Clock::now();
      const bool closed = is_closed_edge_manifold(mesh);
      fmt::print("watertightness check: {:.1f} ms (1 thread) -> {}\n\n", 1e3 * seconds_since(t0),
                 closed ? "closed, edge-manifold" : "not watertight");
    }
    fmt::print("| n | threads | best | median | grey (BG / IG) | black | white | regions | inside test | ambiguous |\n");
    fmt::print("|---|---|---|---|---|---|---|---|---|---|\n");
    for (const int n : sizes) {
      for (const int threads : thread_counts) {
        const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
        CellGridOptions o;
        o.n = static_cast<std::uint32_t>(n);
        o.inside_test = inside;
        std::vector<double> times;
        CellGrid grid;
        for (int r = 0; r < repeat; ++r) {
          const auto t0 = Clock::now();
          grid = classify_cells(mesh, o);
          times.push_back(seconds_since(t0));
        }
        std::sort(times.begin(), times.end());
        const auto bg = static_cast<std::size_t>(std::count(grid.border.begin(), grid.border.end(), 1));
        fmt::print("| {} | {} | {:.1f} ms | {:.1f} ms | {} ({} / {}) | {} | {} | {} | {} | {} |\n", n, threads,
                   1e3 * times.front(), 1e3 * times[times.size() / 2], grid.grey_cells.size(), bg,
                   grid.grey_cells.size() - bg, grid.count(CellClass::Black), grid.count(CellClass::White), grid.regions,
                   grid.watertight_inside_test ? "flood fill" : "parity votes", grid.ambiguous_cells);
      }
    }
    CellGridOptions o;
    o.inside_test = inside;
    fmt::print("\ninside method: {}\n", classify_cells(mesh, o).inside_method);
  } catch (const Error& e) {
    fmt::print(stderr, "bench_relief_cells: error: {}\n", e.what());
    return 1;
  }
  return 0;
}
