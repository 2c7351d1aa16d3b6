#include "jobs/load_mesh.h"

#include <fmt/format.h>
#include <fmt/std.h>
#include <spdlog/spdlog.h>

#include "kernels/core/errors.h"

namespace gimforge::jobs {
namespace {

void enforce(const LoadedMesh& m, const LoadPolicy& policy) {
  const std::string name = m.path.string();
  if (const Defect* d = m.validation.first(Severity::Fatal)) throw InvalidInput(fmt::format("{}: {}", name, d->message));
  for (const Defect& d : m.validation.defects) {
    const bool refused = (policy.require_manifold &&
                          (d.kind == DefectKind::NonManifoldEdge || d.kind == DefectKind::NonManifoldVertex)) ||
                         (policy.require_oriented && d.kind == DefectKind::InconsistentOrientation);
    if (refused) throw TopologyError(fmt::format("{}: {}", name, d.message));
  }
}

void log_findings(const LoadedMesh& m) {
  const std::string name = m.path.string();
  const RepairReport& r = m.repair;
  if (r.removed_degenerate_faces)
    spdlog::warn("{}: repaired: removed {} degenerate face(s) (repeated vertex index)", name, r.removed_degenerate_faces);
  if (r.removed_duplicate_faces)
    spdlog::warn("{}: repaired: removed {} duplicate face(s)", name, r.removed_duplicate_faces);
  if (r.removed_unreferenced_vertices)
    spdlog::warn("{}: repaired: removed {} unreferenced vertex(es)", name, r.removed_unreferenced_vertices);
  for (const Defect& d : m.validation.defects) {
    if (d.severity == Severity::Topological) spdlog::warn("{}: {}", name, d.message);
    if (d.severity == Severity::Info) spdlog::info("{}: {}", name, d.message);
  }
}

}  // namespace

LoadedMesh load_mesh(const std::filesystem::path& path, const LoadPolicy& policy) {
  LoadedMesh m;
  m.path = path;
  m.mesh = io::read_mesh(path, &m.read);
  m.file_vertices = m.mesh.num_vertices();
  m.file_faces = m.mesh.num_faces();
  m.validation = validate_mesh(m.mesh);
  enforce(m, policy);
  if (policy.repair) m.repair = repair_mesh(m.mesh);
  if (policy.warn) log_findings(m);
  spdlog::debug("{}: read {} vertices, {} triangles ({} {})", path.string(), m.file_vertices, m.file_faces,
                io::format_name(m.read.format), m.read.encoding);
  return m;
}

}  // namespace gimforge::jobs
