// Benchmark: spherical geometry-image conversion (Praun & Hoppe 2003) time per stage on one core.
//
//   bench_sphere MESH [--domain octa|tetra|cube|flat-octa|all] [--n N] [optimizer options]
//
// --domain all parametrizes once and resamples the same sphere map into every domain (n as given for the
// octahedron; tetra, cube and flat-octa use the paper's Table 3 sizes for about equal sample counts:
// n·181/128, n·104/128 and n). Each reconstruction is checked closed and manifold (holes aside).
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
#include "kernels/sphere/domain_map.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/topology.h"
#include "kernels/sphere/sphere_convert.h"
#include "kernels/core/validate.h"

using namespace gimforge;

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fputs("usage: bench_sphere MESH [--domain D] [--n N] [--refine-factor F] [--sweep-budget B] ...\n", stderr);
    return 2;
  }
  try {
    SphereOptions o;
    bool all = false;
    for (int i = 2; i + 1 < argc; i += 2) {
      const std::string key = argv[i], value = argv[i + 1];
      if (key == "--domain" && value == "all") all = true;
      else if (key == "--domain") o.domain = parse_spherical_domain(value);
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
    const SphereStats& s = r.stats;
    fmt::print("mesh               {} ({} faces, {} holes filled)\n", argv[1], mesh.num_faces(), s.holes_filled);
    fmt::print("simplify           {:.2f} s\n", s.seconds_simplify);
    fmt::print("optimize           {:.2f} s ({} vertex splits)\n", s.seconds_optimize, s.vertex_splits);
    fmt::print("sample             {:.2f} s\n", s.seconds_sample);
    fmt::print("total conversion   {:.2f} s ({}, n = {}, 1 thread)\n", total, to_string(o.domain), o.n);
    fmt::print("S->M efficiency    {:.4f}\n", s.map_stretch.efficiency);
    const auto report = [&](const SphericalImage& image) {
      const TriMesh recon = reconstruct_spherical_geometry(image);
      const TopologyReport t = analyze_topology(recon);
      const HausdorffResult h = symmetric_hausdorff(device, mesh, recon, {1'000'000});
      std::size_t masked = 0;
      for (std::uint8_t m : image.mask) masked += m ? 0 : 1;
      const DomainImage layout = image.layout();
      std::vector<Vec3> p(image.positions.size() / 3);
      for (std::size_t k = 0; k < p.size(); ++k)
        p[k] = Vec3(image.positions[3 * k], image.positions[3 * k + 1], image.positions[3 * k + 2]);
      fmt::print("{:<10} n = {:<4} samples {:>6} masked {:>5}  D->S {:.4f}  D->M {:.4f}  PSNR {:.2f} dB  "
                 "recon: {} boundary loops, {}manifold\n",
                 to_string(image.domain), image.n, image.mask.size(), masked,
                 domain_map_stretch(builtin_domain_map(image.domain)).efficiency,
                 domain_to_surface_efficiency(layout, p), h.psnr, t.boundary_loops, t.manifold ? "" : "NOT ");
    };
    report(r.image);
    if (all)
      for (SphericalDomain d : kSphericalDomains) {
        if (d == o.domain) continue;
        const std::uint32_t n = d == SphericalDomain::Tetrahedron ? (o.n * 181 + 64) / 128
                                : d == SphericalDomain::Cube      ? (o.n * 104 + 64) / 128
                                                                  : o.n;
        report(resample_spherical_image(device, mesh, r.sphere, d, n));
      }
  } catch (const Error& e) {
    fmt::print(stderr, "bench_sphere: {}\n", e.what());
    return 1;
  }
  return 0;
}
