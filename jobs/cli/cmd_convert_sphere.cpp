// `gimforge convert --method sphere`: spherical geometry images (Praun & Hoppe 2003).
#include <chrono>
#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "io/sphere_archive.h"
#include "jobs/cli/commands.h"
#include "jobs/cli/convert_common.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/gim_store.h"
#include "jobs/progress.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "kernels/sphere/sphere_convert.h"

namespace gimforge::cli {
namespace {

using Clock = std::chrono::steady_clock;

nlohmann::json parameters(const ConvertOptions& o) {
  return {{"method", o.method}, {"domain", o.domain}, {"n", o.n}, {"metric_samples", o.metric_samples}};
}

/// The kernel's options from the command's; throws InvalidInput for a domain or n out of range (the CLI
/// checks both already; this guards other callers).
SphereOptions sphere_options(const ConvertOptions& o) {
  SphereOptions s;
  try {
    s.domain = parse_spherical_domain(o.domain);
  } catch (const InvalidInput&) {
    throw InvalidInput(fmt::format("unknown spherical domain '{}' (choose octa, tetra, cube or flat-octa)", o.domain));
  }
  if (o.n < 1 || o.n > kMaxSphereN)
    throw InvalidInput(fmt::format("tessellation number n = {} is out of range [1, {}]", o.n, kMaxSphereN));
  s.n = o.n;
  return s;
}

io::SphereRecord make_record(const ConvertOptions& o, const SphereStats& s, const HausdorffResult& h,
                             double seconds_metric, double seconds) {
  io::SphereRecord r;
  r.source = o.mesh;
  r.numbers = {{"map_efficiency", s.map_stretch.efficiency},
               {"map_l2_stretch", s.map_stretch.l2},
               {"flipped_triangles", static_cast<double>(s.map_stretch.flipped)},
               {"domain_efficiency", s.domain_efficiency},
               {"efficiency_domain_to_mesh", s.efficiency_domain_to_mesh},
               {"holes_filled", static_cast<double>(s.holes_filled)},
               {"hole_faces", static_cast<double>(s.hole_faces)},
               {"masked_samples", static_cast<double>(s.masked_samples)},
               {"base_vertices", static_cast<double>(s.base_vertices)},
               {"vertex_splits", static_cast<double>(s.vertex_splits)},
               {"seconds_simplify", s.seconds_simplify},
               {"seconds_optimize", s.seconds_optimize},
               {"seconds_sample", s.seconds_sample},
               {"seconds_metric", seconds_metric},
               {"seconds_total", seconds}};
  add_fidelity(r, h);
  return r;
}

/// "257x257 samples" or "6 faces of 33x33 samples".
std::string image_size(const DomainImage& layout) {
  const std::string face = fmt::format("{}x{}", layout.width(), layout.height());
  return layout.faces() == 1 ? face + " samples" : fmt::format("{} faces of {} samples", layout.faces(), face);
}

void print_summary(const ConvertOptions& o, const std::string& name, const SphereResult& result,
                   const HausdorffResult& h, double seconds_metric, double seconds) {
  const SphereStats& s = result.stats;
  const DomainImage layout = result.image.layout();
  fmt::print("{} -> {}:/spherical/{}\n", o.mesh, o.output, name);
  fmt::print("  spherical image  {}, n = {}: {}\n", to_string(layout.domain()), layout.n(), image_size(layout));
  if (s.holes_filled == 0)
    fmt::print("  holes            none\n");
  else
    fmt::print("  holes            {} filled ({} faces); {} of {} samples undefined (NaN, mask 0)\n", s.holes_filled,
               s.hole_faces, s.masked_samples, layout.num_samples());
  if (o.sphere_map.empty())
    fmt::print("  parametrization  {} base vertices + {} vertex splits, {} flipped spherical triangles\n",
               s.base_vertices, s.vertex_splits, s.map_stretch.flipped);
  else
    fmt::print("  parametrization  the sphere map stored in {} (not re-optimized), {} flipped spherical triangles\n",
               o.sphere_map, s.map_stretch.flipped);
  fmt::print("  stretch eff.     S->M {:.4f}, D->S {:.4f}, D->M {:.4f}\n", s.map_stretch.efficiency,
             s.domain_efficiency, s.efficiency_domain_to_mesh);
  print_fidelity(h);
  fmt::print("  time             simplify {:.2f} s, optimize {:.2f} s, sample {:.2f} s, metric {:.2f} s, "
             "total {:.2f} s\n",
             s.seconds_simplify, s.seconds_optimize, s.seconds_sample, seconds_metric, seconds);
}

/// The sphere map of --sphere-map ARCHIVE[:NAME] (NAME defaults to the mesh file's stem), checked against
/// the mesh it is applied to.
std::vector<Vec3> stored_sphere_map(const ConvertOptions& o, const TriMesh& mesh) {
  std::string archive = o.sphere_map, name = std::filesystem::path(o.mesh).stem().string();
  if (const auto colon = archive.rfind(':'); colon != std::string::npos && !std::filesystem::exists(archive)) {
    name = archive.substr(colon + 1);
    archive.resize(colon);
  }
  const io::SphereParametrization p = io::read_sphere_parametrization(io::Archive::open(archive), name);
  if (p.input_vertices != mesh.num_vertices() || p.input_faces != mesh.num_faces())
    throw InvalidInput(fmt::format("{}: the sphere map of '{}' was made for a mesh with {} vertices and {} faces; {} "
                                   "has {} and {}",
                                   archive, name, p.input_vertices, p.input_faces, o.mesh, mesh.num_vertices(),
                                   mesh.num_faces()));
  return p.sphere;
}

}  // namespace

int run_convert_sphere(const ConvertOptions& options) {
  const auto start = Clock::now();
  SphereOptions sopt = sphere_options(options);
  // Holes are allowed: the kernel fills them and masks the samples that land in them.
  const auto [m, name] = prepare_conversion(options, jobs::ImageKind::Spherical);
  const EmbreeDevice device;
  jobs::TerminalProgress progress("convert", options.progress);
  sopt.progress = progress.callback();
  const SphereResult result = with_mesh_path(options.mesh, [&] {
    if (options.sphere_map.empty()) return convert_to_spherical_image(device, m.mesh, sopt);
    return convert_with_sphere_map(device, m.mesh, stored_sphere_map(options, m.mesh), sopt);
  });
  // Fidelity of the level-0 reconstruction against the input (the papers' PSNR); holes stay open in both.
  const auto metric_start = Clock::now();
  const TriMesh recon = reconstruct_spherical_geometry(result.image);
  const HausdorffResult h = measure_fidelity(device, m.mesh, recon, options, progress);
  progress.finish();
  const double seconds_metric = seconds_since(metric_start);
  const double seconds = seconds_since(start);

  const io::SphereRecord record = make_record(options, result.stats, h, seconds_metric, seconds);
  const io::SphereParametrization parametrization{result.sphere, m.mesh.num_vertices(), m.mesh.num_faces()};
  jobs::add_to_archive(options.output, options.command_line, parameters(options).dump(), [&](io::Archive& archive) {
    io::write_spherical_image(archive, name, result.image, parametrization, record);
  });

  if (options.json) {
    const DomainImage layout = result.image.layout();
    print_json_summary(options, name,
                       {{"method", "sphere"}, {"domain", std::string(to_string(layout.domain()))}, {"n", layout.n()},
                        {"faces", layout.faces()}, {"width", layout.width()}, {"height", layout.height()},
                        {"input_faces", m.mesh.num_faces()}, {"input_vertices", m.mesh.num_vertices()}},
                       record);
  } else {
    print_summary(options, name, result, h, seconds_metric, seconds);
  }
  return kExitOk;
}

}  // namespace gimforge::cli
