// Benchmark: spherical geometry-image conversion (Praun & Hoppe 2003) time per stage on one core.
//
//   bench_sphere MESH [--domain octa|tetra|cube|flat-octa] [--n N] [optimizer options]
//
// Optimizer options (SphereMapOptions): --refine-factor F, --sweep-budget B, --final-sweeps K, --tolerance T,
// --chord C (optimize_max_chord), --epsilon E. Runs with one TBB thread and one Embree thread, and prints
// the face count, the time per stage, the stretch efficiencies and the PSNR of the reconstruction against
// the input (1M samples per direction, as `gimforge convert`).
#include <chrono>
#include <cstdio>
#include <string>

#include <fmt/format.h>
#include <tbb/global_control.h>

#include "io/mesh_io.h"
#include "kernels/errors.h"
#include "kernels/hausdorff.h"
#include "kernels/sphere_convert.h"
#include "kernels/validate.h"

using namespace gimforge;

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fputs("usage: bench_sphere MESH [--domain D] [--n N] [--refine-factor F] [--sweep-budget B] ...\n", stderr);
    return 2;
  }
  try {
    SphereOptions o;
    for (int i = 2; i + 1 < argc; i += 2) {
      const std::string key = argv[i], value = argv[i + 1];
      if (key == "--domain") o.domain = parse_spherical_domain(value);
      else if (key == "--n") o.n = static_cast<std::uint32_t>(std::stoul(value));
      else if (key == "--final-sweeps") o.map.final_sweeps = std::stoi(value);
      else if (key == "--tolerance") o.map.tolerance = std::stod(value);
      else if (key == "--refine-factor") o.map.refine_factor = std::stod(value);
      else if (key == "--sweep-budget") o.map.sweep_budget = std::stod(value);
      else if (key == "--min-quality") o.map.simplify_min_quality = std::stod(value);
      else if (key == "--chord") o.map.optimize_max_chord = std::stod(value);
      else if (key == "--epsilon") o.map.stretch.epsilon = std::stod(value);
      else { fmt::print(stderr, "unknown option {}\n", key); return 2; }
    }
    TriMesh mesh = io::read_mesh(argv[1]);
    (void)repair_mesh(mesh);
    tbb::global_control one_core(tbb::global_control::max_allowed_parallelism, 1);
    const EmbreeDevice device("threads=1");
    const auto t0 = std::chrono::steady_clock::now();
    const SphereResult r = convert_to_spherical_image(device, mesh, o);
    const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const TriMesh recon = reconstruct_spherical_geometry(r.image);
    const HausdorffResult h = symmetric_hausdorff(device, mesh, recon, {1'000'000});
    const SphereStats& s = r.stats;
    fmt::print("mesh               {} ({} faces, {} holes filled)\n", argv[1], mesh.num_faces(), s.holes_filled);
    fmt::print("image              {}, n = {} ({} samples, {} masked), 1 thread\n", to_string(o.domain), o.n,
               r.image.mask.size(), s.masked_samples);
    fmt::print("simplify           {:.2f} s\n", s.seconds_simplify);
    fmt::print("optimize           {:.2f} s ({} vertex splits)\n", s.seconds_optimize, s.vertex_splits);
    fmt::print("sample             {:.2f} s\n", s.seconds_sample);
    fmt::print("total conversion   {:.2f} s\n", total);
    fmt::print("efficiency         S->M {:.4f}, D->S {:.4f}, D->M {:.4f}\n", s.map_stretch.efficiency,
               s.domain_efficiency, s.efficiency_domain_to_mesh);
    fmt::print("PSNR               {:.2f} dB\n", h.psnr);
  } catch (const Error& e) {
    fmt::print(stderr, "bench_sphere: {}\n", e.what());
    return 1;
  }
  return 0;
}
