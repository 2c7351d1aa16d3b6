// `gimforge convert --method sphere`: the summary of a spherical geometry image (Praun & Hoppe 2003) and
// --sphere-map (the conversion itself is jobs::convert_mesh).
#include <filesystem>

#include <fmt/format.h>

#include "io/sphere_archive.h"
#include "io/printable.h"
#include "jobs/cli/convert_common.h"
#include "kernels/core/errors.h"

namespace gimforge::cli {
namespace {

/// "257x257 samples" or "6 faces of 33x33 samples".
std::string image_size(const DomainImage& layout) {
  const std::string face = fmt::format("{}x{}", layout.width(), layout.height());
  return layout.faces() == 1 ? face + " samples" : fmt::format("{} faces of {} samples", layout.faces(), face);
}

}  // namespace

void print_sphere_summary(const ConvertSummary& s) {
  const SphereResult& result = s.conversion.sphere.value();
  const SphereStats& st = result.stats;
  const DomainImage layout = result.image.layout();
  fmt::print("{} -> {}:/spherical/{}\n", io::printable(s.options.mesh), io::printable(s.options.output), io::printable(s.name));
  fmt::print("  spherical image  {}, n = {}: {}\n", to_string(layout.domain()), layout.n(), image_size(layout));
  if (st.holes_filled == 0)
    fmt::print("  holes            none\n");
  else
    fmt::print("  holes            {} filled ({} faces); {} of {} samples undefined (NaN, mask 0){}\n", st.holes_filled,
               st.hole_faces, st.masked_samples, layout.num_samples(),
               st.holes_without_samples > 0
                   ? fmt::format("; {} hole(s) narrower than the sample spacing hold no sample and are closed over",
                                 st.holes_without_samples)
                   : std::string());
  if (s.options.sphere_map.empty())
    fmt::print("  parametrization  {} base vertices + {} vertex splits, {} flipped spherical triangles\n",
               st.base_vertices, st.vertex_splits, st.map_stretch.flipped);
  else
    fmt::print("  parametrization  the sphere map stored in {} (not re-optimized), {} flipped spherical triangles\n",
               s.options.sphere_map, st.map_stretch.flipped);
  fmt::print("  stretch eff.     S->M {:.4f}, D->S {:.4f}, D->M {:.4f}\n", st.map_stretch.efficiency,
             st.domain_efficiency, st.efficiency_domain_to_mesh);
  const auto& n = s.conversion.numbers;
  std::string fit_time;
  if (n.contains("fit_energy_before")) {
    fmt::print("  optimization     energy {:.4g} -> {:.4g} in {:.2f} s (sec. 4.6 fit)\n", n.at("fit_energy_before"),
               n.at("fit_energy_after"), n.at("seconds_fit"));
    fit_time = fmt::format(", fit {:.2f} s", n.at("seconds_fit"));
  }
  print_adaptive(s.conversion);
  print_fidelity(s.conversion);
  print_times(s, fmt::format("simplify {:.2f} s, optimize {:.2f} s, sample {:.2f} s{}", st.seconds_simplify,
                             st.seconds_optimize, st.seconds_sample, fit_time));
}

nlohmann::json sphere_json_fields(const ConvertSummary& s) {
  const DomainImage layout = s.conversion.sphere.value().image.layout();
  return {{"domain", std::string(to_string(layout.domain()))}, {"n", layout.n()},
          {"faces", layout.faces()},          {"width", layout.width()},
          {"height", layout.height()},        {"input_faces", s.conversion.input_faces},
          {"input_vertices", s.conversion.input_vertices}};
}

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

}  // namespace gimforge::cli
