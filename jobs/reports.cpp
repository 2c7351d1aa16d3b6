#include "jobs/reports.h"

#include <cmath>

#include <fmt/format.h>

#include "io/mesh_io.h"
#include "io/printable.h"

namespace gimforge::jobs {
namespace {

nlohmann::json vec_json(const Vec3& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); }

nlohmann::json defects_json(const ValidationReport& report) {
  nlohmann::json list = nlohmann::json::array();
  for (const Defect& d : report.defects)
    list.push_back({{"kind", to_string(d.kind)}, {"severity", to_string(d.severity)}, {"count", d.count},
                    {"message", d.message}});
  return list;
}

nlohmann::json repairs_json(const RepairReport& r) {
  return {{"removed_degenerate_faces", r.removed_degenerate_faces},
          {"removed_duplicate_faces", r.removed_duplicate_faces},
          {"removed_unreferenced_vertices", r.removed_unreferenced_vertices}};
}

/// Genus as an integer when it is one (the usual case), else the computed value.
nlohmann::json genus_json(double g) {
  if (g == std::floor(g)) return static_cast<long long>(g);
  return g;
}

nlohmann::json one_sided_json(const OneSidedDistance& d) { return {{"max", d.max}, {"mean", d.mean}, {"rms", d.rms}}; }

}  // namespace

std::optional<double> float32_resolution(const TriMesh& mesh, bool float32_storage) {
  if (!float32_storage || !io::float32_exact(mesh)) return std::nullopt;  // not float32 data (or not finite)
  const double relative = io::float32_relative_spacing(mesh);
  if (relative <= io::kFloat32Tolerance) return std::nullopt;
  return relative * bounding_box(mesh).diagonal();
}

nlohmann::json info_json(const LoadedMesh& m, const TopologyReport& t) {
  const std::optional<double> resolution = float32_resolution(m.mesh, m.read.float32_coordinates);
  nlohmann::json genus = nlohmann::json::array();
  nlohmann::json comps = nlohmann::json::array();
  for (const ComponentTopology& c : t.components) {
    genus.push_back(genus_json(c.genus));
    comps.push_back({{"faces", c.faces}, {"vertices", c.vertices}, {"edges", c.edges},
                     {"boundary_edges", c.boundary_edges}, {"boundary_loops", c.boundary_loops},
                     {"euler_characteristic", c.euler_characteristic}, {"genus", genus_json(c.genus)},
                     {"closed", c.closed}, {"manifold", c.manifold}, {"orientable", c.orientable},
                     {"oriented", c.oriented}});
  }
  return {
      {"file", m.path.string()},
      {"format", io::format_name(m.read.format)},
      {"encoding", m.read.encoding},
      {"file_bytes", m.read.file_bytes},
      {"vertices", m.file_vertices},
      {"faces", m.file_faces},
      {"polygons", m.read.polygons},
      {"referenced_vertices", t.referenced_vertices},
      {"edges", t.edges},
      {"components", t.components.size()},
      {"boundary_edges", t.boundary_edges},
      {"boundary_loops", t.boundary_loops},
      {"euler_characteristic", t.euler_characteristic},
      {"genus", genus},
      {"closed", t.closed},
      {"manifold", t.manifold},
      {"orientable", t.orientable},
      {"oriented", t.oriented},
      {"nonmanifold_edges", t.nonmanifold_edges},
      {"nonmanifold_vertices", t.nonmanifold_vertices},
      {"inconsistent_edges", t.inconsistent_edges},
      {"bbox", {{"min", vec_json(t.bbox.min)}, {"max", vec_json(t.bbox.max)}}},
      {"bbox_diagonal", t.bbox.diagonal()},
      {"surface_area", t.surface_area},
      {"has_colors", m.mesh.has_colors()},
      {"has_normals", m.mesh.has_normals()},
      {"component_details", comps},
      {"defects", defects_json(m.validation)},
      {"repairs", repairs_json(m.repair)},
      {"float32_resolution", resolution ? nlohmann::json(*resolution) : nlohmann::json()},
  };
}

std::string info_text(const LoadedMesh& m, const TopologyReport& t) {
  auto yes = [](bool b) { return b ? "yes" : "no"; };
  std::string genus;
  const std::size_t shown = std::min<std::size_t>(t.components.size(), 12);
  for (std::size_t i = 0; i < shown; ++i) genus += fmt::format("{}{}", i ? " " : "", t.components[i].genus);
  if (t.components.size() > shown) genus += fmt::format(" ... ({} more)", t.components.size() - shown);
  std::string s;
  s += fmt::format("file             {} ({}, {}, {} bytes)\n", io::printable(m.path.string()), io::format_name(m.read.format),
                   m.read.encoding, m.read.file_bytes);
  s += fmt::format("vertices         {} ({} referenced)\n", m.file_vertices, t.referenced_vertices);
  s += fmt::format("faces            {} triangles", m.file_faces);
  if (m.read.triangulated) s += fmt::format(" ({} polygons, {} fan-triangulated)", m.read.polygons, m.read.triangulated);
  s += fmt::format("\nedges            {}\n", t.edges);
  s += fmt::format("components       {}\n", t.components.size());
  s += fmt::format("boundary loops   {} ({} boundary edges)\n", t.boundary_loops, t.boundary_edges);
  s += fmt::format("euler char.      {}\n", t.euler_characteristic);
  s += fmt::format("genus            {} (per component, largest first)\n", genus);
  s += fmt::format("closed           {}\n", yes(t.closed));
  s += fmt::format("manifold         {}", yes(t.manifold));
  if (!t.manifold)
    s += fmt::format(" ({} non-manifold edges, {} non-manifold vertices)", t.nonmanifold_edges, t.nonmanifold_vertices);
  s += fmt::format("\norientable       {}\noriented         {}", yes(t.orientable), yes(t.oriented));
  if (t.inconsistent_edges) s += fmt::format(" ({} inconsistent edges)", t.inconsistent_edges);
  s += fmt::format("\nbbox             [{:.10g}, {:.10g}, {:.10g}] - [{:.10g}, {:.10g}, {:.10g}]\n", t.bbox.min.x(),
                   t.bbox.min.y(), t.bbox.min.z(), t.bbox.max.x(), t.bbox.max.y(), t.bbox.max.z());
  s += fmt::format("bbox diagonal    {:.9g}\n", t.bbox.diagonal());
  s += fmt::format("surface area     {:.9g}\n", t.surface_area);
  for (const Defect& d : m.validation.defects) s += fmt::format("{:<16} {}\n", to_string(d.severity), d.message);
  return s;
}

nlohmann::json metrics_json(const HausdorffResult& r) {
  nlohmann::json j = {{"diag", r.diag}, {"ab", one_sided_json(r.ab)}, {"ba", one_sided_json(r.ba)},
                      {"max", r.max},   {"rms", r.rms}};
  j["psnr"] = std::isfinite(r.psnr) ? nlohmann::json(r.psnr) : nlohmann::json(nullptr);
  return j;
}

std::string metrics_text(const HausdorffResult& r, const std::string& a, const std::string& b) {
  std::string s;
  s += fmt::format("A = {}\nB = {}\n", io::printable(a), io::printable(b));
  s += fmt::format("diag (A's bounding box)  {:.9g}\n", r.diag);
  s += fmt::format("{:<10} {:>14} {:>14} {:>14}\n", "", "max", "mean", "rms");
  s += fmt::format("{:<10} {:>14.7e} {:>14.7e} {:>14.7e}\n", "A -> B", r.ab.max, r.ab.mean, r.ab.rms);
  s += fmt::format("{:<10} {:>14.7e} {:>14.7e} {:>14.7e}\n", "B -> A", r.ba.max, r.ba.mean, r.ba.rms);
  s += fmt::format("{:<10} {:>14.7e} {:>14} {:>14.7e}\n", "symmetric", r.max, "", r.rms);
  const std::size_t vertices = r.ab.vertex_samples + r.ba.vertex_samples;  // 0 with --no-vertices
  s += fmt::format("PSNR  {:.2f} dB   (20 log10(diag / rms); {} + {} area samples{})\n", r.psnr, r.ab.area_samples,
                   r.ba.area_samples, vertices > 0 ? fmt::format(", plus {} vertices", vertices) : "");
  return s;
}

nlohmann::json validation_json(const LoadedMesh& m) {
  return {{"file", m.path.string()},
          {"vertices", m.file_vertices},
          {"faces", m.file_faces},
          {"defects", defects_json(m.validation)},
          {"repairs", repairs_json(m.repair)}};
}

}  // namespace gimforge::jobs
