// bench_ply_read FILE [--repeat N]: reads a mesh file N times (default 5) with gimforge::io::read_mesh and
// prints the best and median wall time and throughput (file bytes / seconds, MB = 10^6 bytes).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/format.h>

#include "io/mesh_io.h"

namespace {

struct Args {
  std::string file;
  int repeat{5};
};

bool parse_args(int argc, char** argv, Args& args) {
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (a == "--repeat" && i + 1 < argc) {
      args.repeat = std::stoi(argv[++i]);
    } else if (args.file.empty() && !a.starts_with("--")) {
      args.file = std::string(a);
    } else {
      return false;
    }
  }
  return !args.file.empty() && args.repeat > 0;
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  try {
    if (!parse_args(argc, argv, args)) {
      fmt::print(stderr, "usage: bench_ply_read FILE [--repeat N]\n");
      return 2;
    }
    std::vector<double> seconds;
    gimforge::io::ReadInfo info;
    gimforge::TriMesh mesh;
    for (int r = 0; r < args.repeat; ++r) {
      const auto t0 = std::chrono::steady_clock::now();
      mesh = gimforge::io::read_mesh(args.file, &info);
      const auto t1 = std::chrono::steady_clock::now();
      seconds.push_back(std::chrono::duration<double>(t1 - t0).count());
    }
    std::sort(seconds.begin(), seconds.end());
    const double best = seconds.front();
    const double median = seconds[seconds.size() / 2];
    const double mb = static_cast<double>(info.file_bytes) / 1e6;
    fmt::print("file: {} ({} bytes, {} {})\n", args.file, info.file_bytes, gimforge::io::format_name(info.format),
               info.encoding);
    fmt::print("V: {} F: {}\n", mesh.num_vertices(), mesh.num_faces());
    fmt::print("repeat: {}\n", args.repeat);
    fmt::print("best: {:.4f} s ({:.1f} MB/s)\n", best, mb / best);
    fmt::print("median: {:.4f} s ({:.1f} MB/s)\n", median, mb / median);
    return 0;
  } catch (const std::exception& e) {
    fmt::print(stderr, "bench_ply_read: error: {}\n", e.what());
    return 1;
  }
}
