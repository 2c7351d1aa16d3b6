#include "jobs/load_mesh.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <fmt/std.h>
#include <spdlog/spdlog.h>

#include "io/ply_ranges.h"
#include "io/printable.h"
#include "jobs/error_naming.h"
#include "jobs/reports.h"
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
    if (!refused) continue;
    throw TopologyError(fmt::format("{}: {}{}{}", name, d.message, policy.refusal_hint,
                                    policy.suggest_wrap ? wrap_clause(&m.mesh) : std::string{}));
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
  if (!m.read.dropped_normals.empty())
    spdlog::warn("{}: {}: the file's vertex normals are dropped (gimforge computes the normals it uses)", name,
                 m.read.dropped_normals);
  for (const Defect& d : m.validation.defects) {
    if (d.severity == Severity::Topological) spdlog::warn("{}: {}", name, d.message);
    if (d.severity == Severity::Info)
      spdlog::info("{}: {}{}", name, d.message,
                   d.kind == DefectKind::DuplicatePosition ? " (an unwelded mesh: `gimforge convert-format --weld` welds them)" : "");
  }
}

/// Warns when the file stores float32 coordinates and the largest is so large that float32 resolves it
/// coarser than 1e-6 of the bounding-box diagonal: the file has lost the detail before gimforge reads it.
void warn_far_float32(const LoadedMesh& m) {
  const std::optional<double> resolution = float32_resolution(m.mesh, m.read.float32_coordinates);
  if (!resolution) return;
  double largest = 0.0;
  for (const Vec3& v : m.mesh.positions) largest = std::max(largest, v.cwiseAbs().maxCoeff());
  spdlog::warn("{}: every coordinate is a 32-bit float, the largest {:.4g}: the file resolves them to {:.3g} "
               "only ({:.2g} of the bounding-box diagonal); store them as double",
               m.path.string(), largest, *resolution, *resolution / bounding_box(m.mesh).diagonal());
}

}  // namespace

Vec3 local_frame_origin(const TriMesh& mesh) {
  BoundingBox box;
  for (const Vec3& v : mesh.positions) box.extend(v);
  const Vec3 c = box.center();
  return c.allFinite() ? c : Vec3::Zero();
}

void to_local_frame(TriMesh& mesh, const Vec3& origin) { translate(mesh, -origin); }

void to_input_frame(TriMesh& mesh, const Vec3& origin) { translate(mesh, origin); }

LoadedMesh load_mesh(const std::filesystem::path& path, const LoadPolicy& policy) {
  LoadedMesh m;
  m.path = path;
  m.mesh = io::read_mesh(path, &m.read);
  m.file_vertices = m.mesh.num_vertices();
  m.file_faces = m.mesh.num_faces();
  // io::kMaxCoordinate: beyond it every measure of the mesh would be inf or NaN (the brick readers refuse it too).
  for (std::size_t i = 0; i < m.mesh.positions.size(); ++i)
    if (const double far = m.mesh.positions[i].cwiseAbs().maxCoeff(); far > io::kMaxCoordinate)
      throw io::far_coordinate_error(io::printable(path.string()), i, far);
  {  // io::kMinDiagonal, over the vertices the faces use (the brick scan measures the same)
    BoundingBox used;
    for (const Face& f : m.mesh.faces)
      for (const std::uint32_t v : f)
        if (v < m.mesh.positions.size()) used.extend(m.mesh.positions[v]);
    if (used.empty()) {
      // no faces: validate_mesh says so
    } else if (auto small = io::small_extent_error(io::printable(path.string()), (used.max - used.min).stableNorm())) {
      throw *small;
    }
  }
  ValidateOptions vo;
  vo.complete = policy.topology || policy.require_manifold || policy.require_oriented;
  m.validation = validate_mesh(m.mesh, vo);
  enforce(m, policy);
  if (policy.repair) m.repair = repair_mesh(m.mesh, vo.complete);
  if (policy.warn) {
    log_findings(m);
    warn_far_float32(m);
  }
  spdlog::debug("{}: read {} vertices, {} triangles ({} {})", path.string(), m.file_vertices, m.file_faces,
                io::format_name(m.read.format), m.read.encoding);
  return m;
}

}  // namespace gimforge::jobs
