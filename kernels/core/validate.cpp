#include "kernels/core/validate.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <unordered_map>

#include <fmt/format.h>

#include "kernels/core/edge_topology.h"
#include "kernels/core/errors.h"

namespace gimforge {
namespace {

Severity severity_of(DefectKind kind) {
  switch (kind) {
    case DefectKind::IndexOutOfRange:
    case DefectKind::NonFiniteCoordinate:
    case DefectKind::NoFaces: return Severity::Fatal;
    case DefectKind::DegenerateFace:
    case DefectKind::DuplicateFace:
    case DefectKind::UnreferencedVertex: return Severity::Repairable;
    case DefectKind::NonManifoldEdge:
    case DefectKind::NonManifoldVertex:
    case DefectKind::InconsistentOrientation: return Severity::Topological;
    case DefectKind::ZeroAreaFace:
    case DefectKind::DuplicatePosition: return Severity::Info;
  }
  return Severity::Info;
}

void add(ValidationReport& report, DefectKind kind, std::size_t count, std::string message) {
  if (count > 0) report.defects.push_back({kind, severity_of(kind), count, std::move(message)});
}

const char* plural(std::size_t n, const char* one, const char* many) { return n == 1 ? one : many; }

/// A position's bits, −0 as +0: vertices with equal keys are at the same point.
std::array<std::uint64_t, 3> position_key(const Vec3& p) {
  std::array<std::uint64_t, 3> key{};
  for (int i = 0; i < 3; ++i) {
    const double x = p[i] == 0.0 ? 0.0 : p[i];
    std::memcpy(&key[static_cast<std::size_t>(i)], &x, sizeof x);
  }
  return key;
}

struct PositionHash {
  std::size_t operator()(const std::array<std::uint64_t, 3>& k) const {
    return std::hash<std::uint64_t>()(k[0] * 0x9e3779b97f4a7c15ull ^ k[1] * 0xc2b2ae3d27d4eb4full ^ k[2]);
  }
};
using PositionMap = std::unordered_map<std::array<std::uint64_t, 3>, std::uint32_t, PositionHash>;

/// Throws InvalidInput "<what>: face F references vertex V, but the mesh has N vertices".
void require_indices_in_range(const TriMesh& mesh, const char* what) {
  for (std::size_t f = 0; f < mesh.faces.size(); ++f)
    for (std::uint32_t v : mesh.faces[f])
      if (v >= mesh.positions.size())
        throw InvalidInput(fmt::format("{}: face {} references vertex {}, but the mesh has {} vertices", what, f, v,
                                       mesh.positions.size()));
}

/// Sorted vertex triple: the identity of a face regardless of orientation and rotation.
std::array<std::uint32_t, 3> sorted_face(const Face& f) {
  std::array<std::uint32_t, 3> s = f;
  std::sort(s.begin(), s.end());
  return s;
}

/// Indices of faces that repeat an earlier face (same vertex set), in increasing order.
std::vector<std::uint32_t> duplicate_faces(MeshView mesh) {
  std::vector<std::uint32_t> order(mesh.faces.size());
  for (std::uint32_t f = 0; f < order.size(); ++f) order[f] = f;
  std::vector<std::array<std::uint32_t, 3>> keys(mesh.faces.size());
  for (std::size_t f = 0; f < keys.size(); ++f) keys[f] = sorted_face(mesh.faces[f]);
  std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return keys[a] < keys[b]; });
  std::vector<std::uint32_t> dups;
  for (std::size_t i = 1; i < order.size(); ++i)
    if (keys[order[i]] == keys[order[i - 1]] && !has_repeated_index(mesh.faces[order[i]])) dups.push_back(order[i]);
  std::sort(dups.begin(), dups.end());
  return dups;
}

void check_indices_and_coordinates(MeshView mesh, ValidationReport& report) {
  std::size_t bad_refs = 0;
  std::string first_bad;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    for (std::uint32_t v : mesh.faces[f]) {
      if (v >= mesh.positions.size()) {
        if (bad_refs++ == 0)
          first_bad = fmt::format("face {} references vertex {}, but the mesh has {} vertices", f, v,
                                  mesh.positions.size());
      }
    }
  }
  add(report, DefectKind::IndexOutOfRange, bad_refs,
      fmt::format("{} face {} out of range (first: {})", bad_refs,
                  plural(bad_refs, "index is", "indices are"), first_bad));
  std::size_t non_finite = 0;
  std::size_t first_nf = 0;
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    if (!mesh.positions[v].allFinite() && non_finite++ == 0) first_nf = v;
  }
  if (non_finite > 0) {
    const Vec3& p = mesh.positions[first_nf];
    add(report, DefectKind::NonFiniteCoordinate, non_finite,
        fmt::format("{} {} a non-finite coordinate (first: vertex {} = ({}, {}, {}))", non_finite,
                    plural(non_finite, "vertex has", "vertices have"), first_nf, p.x(), p.y(), p.z()));
  }
  add(report, DefectKind::NoFaces, mesh.faces.empty() ? 1 : 0, "mesh has no faces");
}

void check_faces_and_vertices(MeshView mesh, const ValidateOptions& options, ValidationReport& report) {
  std::size_t degenerate = 0, zero_area = 0;
  std::size_t first_degenerate = 0, first_zero = 0;
  std::vector<char> referenced(mesh.positions.size(), 0);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const Face& t = mesh.faces[f];
    for (std::uint32_t v : t) referenced[v] = 1;
    if (has_repeated_index(t)) {
      if (degenerate++ == 0) first_degenerate = f;
      continue;
    }
    const Vec3& a = mesh.positions[t[0]];
    const Vec3& b = mesh.positions[t[1]];
    const Vec3& c = mesh.positions[t[2]];
    const double longest2 = std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
    if ((b - a).cross(c - a).norm() <= options.zero_area_tolerance * longest2 && zero_area++ == 0) first_zero = f;
  }
  add(report, DefectKind::DegenerateFace, degenerate,
      fmt::format("{} {} a repeated vertex index (first: face {})", degenerate,
                  plural(degenerate, "face has", "faces have"), first_degenerate));
  const auto dups = duplicate_faces(mesh);
  add(report, DefectKind::DuplicateFace, dups.size(),
      fmt::format("{} duplicate {} (first: face {})", dups.size(), plural(dups.size(), "face", "faces"),
                  dups.empty() ? 0 : dups.front()));
  const auto unreferenced = static_cast<std::size_t>(std::count(referenced.begin(), referenced.end(), 0));
  const auto first_unref = static_cast<std::size_t>(std::find(referenced.begin(), referenced.end(), 0) - referenced.begin());
  add(report, DefectKind::UnreferencedVertex, unreferenced,
      fmt::format("{} unreferenced {} (first: vertex {})", unreferenced, plural(unreferenced, "vertex", "vertices"),
                  first_unref));
  add(report, DefectKind::ZeroAreaFace, zero_area,
      fmt::format("{} zero-area {} with distinct vertices (first: face {}); kept", zero_area,
                  plural(zero_area, "face", "faces"), first_zero));

  // Referenced vertices sharing an exact position with an earlier referenced vertex.
  PositionMap seen;
  seen.reserve(mesh.positions.size());
  std::size_t dup_pos = 0;
  std::string first_dup;
  for (std::uint32_t v = 0; v < mesh.positions.size(); ++v) {
    if (!referenced[v]) continue;
    auto [it, inserted] = seen.emplace(position_key(mesh.positions[v]), v);
    if (!inserted && dup_pos++ == 0) first_dup = fmt::format("vertices {} and {}", it->second, v);
  }
  add(report, DefectKind::DuplicatePosition, dup_pos,
      fmt::format("{} {} the position of another vertex (first: {}); kept", dup_pos,
                  plural(dup_pos, "vertex repeats", "vertices repeat"), first_dup));
}

/// Non-manifold and orientation checks on the faces that survive repair (duplicates removed), so that a
/// repairable duplicate face is not also reported as a non-manifold edge.
void check_topology(MeshView input, ValidationReport& report) {
  const auto dups = duplicate_faces(input);
  std::vector<Face> kept;
  MeshView mesh = input;
  if (!dups.empty()) {
    kept.reserve(input.faces.size() - dups.size());
    std::size_t next_dup = 0;
    for (std::size_t f = 0; f < input.faces.size(); ++f) {
      if (next_dup < dups.size() && dups[next_dup] == f) {
        ++next_dup;
        continue;
      }
      kept.push_back(input.faces[f]);
    }
    mesh = MeshView(input.positions, kept);
  }
  const EdgeTopology topo = build_edge_topology(mesh);
  const ManifoldCheck check = check_manifold(mesh, topo);
  if (!check.nonmanifold_edges.empty()) {
    const auto e = check.nonmanifold_edges.front();
    add(report, DefectKind::NonManifoldEdge, check.nonmanifold_edges.size(),
        fmt::format("{} non-manifold {} shared by more than two faces (first: vertices {}-{}, {} faces)",
                    check.nonmanifold_edges.size(), plural(check.nonmanifold_edges.size(), "edge", "edges"),
                    topo.edges[e][0], topo.edges[e][1], topo.valence(e)));
  }
  if (!check.nonmanifold_vertices.empty()) {
    const auto v = check.nonmanifold_vertices.front();
    add(report, DefectKind::NonManifoldVertex, check.nonmanifold_vertices.size(),
        fmt::format("{} non-manifold {} where separate fans of faces meet (first: vertex {}, {} fans)",
                    check.nonmanifold_vertices.size(), plural(check.nonmanifold_vertices.size(), "vertex", "vertices"),
                    v, check.vertex_fans[v]));
  }
  if (!check.inconsistent_edges.empty()) {
    const auto e = check.inconsistent_edges.front();
    add(report, DefectKind::InconsistentOrientation, check.inconsistent_edges.size(),
        fmt::format("inconsistent orientation: {} {} traversed in the same direction by both faces (first: "
                    "vertices {}-{})",
                    check.inconsistent_edges.size(), plural(check.inconsistent_edges.size(), "edge is", "edges are"),
                    topo.edges[e][0], topo.edges[e][1]));
  }
}

}  // namespace

std::size_t ValidationReport::count(DefectKind kind) const {
  for (const Defect& d : defects)
    if (d.kind == kind) return d.count;
  return 0;
}

bool ValidationReport::has(Severity severity) const { return first(severity) != nullptr; }

const Defect* ValidationReport::first(Severity severity) const {
  for (const Defect& d : defects)
    if (d.severity == severity) return &d;
  return nullptr;
}

ValidationReport validate_mesh(MeshView mesh, const ValidateOptions& options) {
  ValidationReport report;
  check_indices_and_coordinates(mesh, report);
  if (report.count(DefectKind::IndexOutOfRange) > 0) {
    report.topology_skipped = true;  // every later check indexes positions
    return report;
  }
  if (options.complete) {
    check_faces_and_vertices(mesh, options, report);
    check_topology(mesh, report);
  } else {
    report.topology_skipped = true;
  }
  std::stable_sort(report.defects.begin(), report.defects.end(),
                   [](const Defect& a, const Defect& b) { return a.kind < b.kind; });
  return report;
}

std::size_t weld_positions(TriMesh& mesh) {
  require_indices_in_range(mesh, "weld_positions");
  PositionMap first;
  first.reserve(mesh.positions.size());
  std::vector<std::uint32_t> to(mesh.positions.size());
  std::vector<std::uint8_t> seen(mesh.positions.size(), 0);
  std::size_t welded = 0;
  for (Face& f : mesh.faces)
    for (std::uint32_t& v : f) {
      if (!seen[v]) {
        seen[v] = 1;
        const auto [it, inserted] = first.emplace(position_key(mesh.positions[v]), v);
        to[v] = it->second;
        welded += inserted ? 0 : 1;
      }
      v = to[v];
    }
  return welded;
}

RepairReport repair_mesh(TriMesh& mesh, bool duplicates) {
  require_indices_in_range(mesh, "repair_mesh");
  RepairReport report;
  // Degenerate and duplicate faces.
  std::vector<char> drop(mesh.faces.size(), 0);
  if (duplicates)
    for (std::uint32_t f : duplicate_faces(mesh)) drop[f] = 1;
  std::size_t kept = 0;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    if (has_repeated_index(mesh.faces[f])) {
      ++report.removed_degenerate_faces;
    } else if (drop[f]) {
      ++report.removed_duplicate_faces;
    } else {
      mesh.faces[kept++] = mesh.faces[f];
    }
  }
  mesh.faces.resize(kept);
  // Unreferenced vertices.
  std::vector<std::uint32_t> remap(mesh.positions.size(), kInvalidIndex);
  for (const Face& t : mesh.faces)
    for (std::uint32_t v : t) remap[v] = 0;
  std::uint32_t next = 0;
  for (std::size_t v = 0; v < remap.size(); ++v) {
    if (remap[v] == kInvalidIndex) continue;
    remap[v] = next;
    mesh.positions[next] = mesh.positions[v];
    if (mesh.has_colors()) mesh.colors[next] = mesh.colors[v];
    if (mesh.has_normals()) mesh.normals[next] = mesh.normals[v];
    ++next;
  }
  report.removed_unreferenced_vertices = mesh.positions.size() - next;
  mesh.positions.resize(next);
  if (mesh.has_colors()) mesh.colors.resize(next);
  if (mesh.has_normals()) mesh.normals.resize(next);
  for (Face& t : mesh.faces)
    for (std::uint32_t& v : t) v = remap[v];
  return report;
}

const char* to_string(DefectKind kind) {
  switch (kind) {
    case DefectKind::IndexOutOfRange: return "index_out_of_range";
    case DefectKind::NonFiniteCoordinate: return "non_finite_coordinate";
    case DefectKind::NoFaces: return "no_faces";
    case DefectKind::DegenerateFace: return "degenerate_face";
    case DefectKind::DuplicateFace: return "duplicate_face";
    case DefectKind::UnreferencedVertex: return "unreferenced_vertex";
    case DefectKind::NonManifoldEdge: return "non_manifold_edge";
    case DefectKind::NonManifoldVertex: return "non_manifold_vertex";
    case DefectKind::InconsistentOrientation: return "inconsistent_orientation";
    case DefectKind::ZeroAreaFace: return "zero_area_face";
    case DefectKind::DuplicatePosition: return "duplicate_position";
  }
  return "unknown";
}

const char* to_string(Severity severity) {
  switch (severity) {
    case Severity::Fatal: return "fatal";
    case Severity::Repairable: return "repairable";
    case Severity::Topological: return "topological";
    case Severity::Info: return "info";
  }
  return "unknown";
}

}  // namespace gimforge
