// Benchmark: geometry-image conversion time per stage on one core.
//
//   bench_gim MESH [--subdivide K] [--size N]
//
// --subdivide K splits every triangle 1-to-4 at edge midpoints K times (the surface is unchanged, the face
// count grows 4^K), to reach a given mesh size from a real model. Runs with one TBB thread and prints the
// face count, time per stage, stretch efficiency and PSNR of the reconstruction against the input.
#include <chrono>
#include <cstdio>
#include <map>
#include <string>

#include <fmt/format.h>
#include <tbb/global_control.h>

#include "io/mesh_io.h"
#include "kernels/core/errors.h"
#include "kernels/gim/gim_convert.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/validate.h"

using namespace gimforge;

namespace {

TriMesh subdivide(const TriMesh& in) {
  TriMesh out;
  out.positions = in.positions;
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> mid;
  auto m = [&](std::uint32_t a, std::uint32_t b) {
    auto [it, inserted] = mid.try_emplace(std::minmax(a, b), static_cast<std::uint32_t>(out.positions.size()));
    if (inserted) out.positions.push_back(0.5 * (in.positions[a] + in.positions[b]));
    return it->second;
  };
  for (const Face& f : in.faces) {
    const std::uint32_t ab = m(f[0], f[1]), bc = m(f[1], f[2]), ca = m(f[2], f[0]);
    out.faces.push_back({f[0], ab, ca});
    out.faces.push_back({f[1], bc, ab});
    out.faces.push_back({f[2], ca, bc});
    out.faces.push_back({ab, bc, ca});
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fputs("usage: bench_gim MESH [--subdivide K] [--size N]\n", stderr);
    return 2;
  }
  int levels = 0;
  std::uint32_t size = 257;
  for (int i = 2; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    if (key == "--subdivide") levels = std::stoi(argv[i + 1]);
    else if (key == "--size") size = static_cast<std::uint32_t>(std::stoul(argv[i + 1]));
    else { fmt::print(stderr, "unknown option {}\n", key); return 2; }
  }
  try {
    TriMesh mesh = io::read_mesh(argv[1]);
    (void)repair_mesh(mesh);
    for (int k = 0; k < levels; ++k) mesh = subdivide(mesh);
    tbb::global_control one_core(tbb::global_control::max_allowed_parallelism, 1);
    const EmbreeDevice device("threads=1");
    GimOptions options;
    options.image = {size, 512, {}};
    const auto t0 = std::chrono::steady_clock::now();
    const GimResult r = convert_to_geometry_image(device, mesh, options);
    const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const TriMesh recon = reconstruct_geometry_image(r.image.positions, r.image.size, &r.image.sideband);
    const HausdorffResult h = symmetric_hausdorff(device, mesh, recon, {1'000'000});
    fmt::print("mesh               {} (subdivided {}x: {} faces)\n", argv[1], levels, mesh.num_faces());
    fmt::print("image              {0}x{0}, normal map 512x512, 1 thread\n", size);
    fmt::print("cut                {:.2f} s ({} cut-paths, {} augmentations)\n", r.stats.seconds_cut, r.stats.cut_paths,
               r.stats.augmentations);
    fmt::print("parametrize        {:.2f} s (all trials of the cut augmentation)\n", r.stats.seconds_parametrize);
    fmt::print("sample             {:.2f} s\n", r.stats.seconds_sample);
    fmt::print("total conversion   {:.2f} s\n", total);
    fmt::print("stretch efficiency {:.3f}\n", r.stats.stretch.efficiency);
    fmt::print("PSNR               {:.2f} dB\n", h.psnr);
  } catch (const Error& e) {
    fmt::print(stderr, "bench_gim: {}\n", e.what());
    return 1;
  }
  return 0;
}
