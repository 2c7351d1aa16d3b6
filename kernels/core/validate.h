#pragma once
/// \file validate.h
/// Mesh validation and repair: what is wrong with a mesh, how bad it is, and the repairs that are safe.
///
/// Severity policy (docs/cli.md repeats it for users):
/// - Fatal: out-of-range indices, non-finite coordinates, no faces. Nothing downstream can use the mesh.
/// - Repairable (repair_mesh fixes them, the CLI warns): faces with a repeated vertex index (degenerate),
///   exact duplicate faces (same three vertices in any order), unreferenced vertices.
/// - Topological (reported; the algorithms that need a 2-manifold refuse the mesh, others accept it):
///   non-manifold edges and vertices, inconsistent orientation.
/// - Informational: zero-area faces with three distinct vertices (kept: removing them would open holes),
///   vertices at identical positions (kept: welding changes the topology the file states).
#include <cstddef>
#include <string>
#include <vector>

#include "kernels/core/mesh.h"

namespace gimforge {

enum class DefectKind {
  IndexOutOfRange,
  NonFiniteCoordinate,
  NoFaces,
  DegenerateFace,
  DuplicateFace,
  UnreferencedVertex,
  NonManifoldEdge,
  NonManifoldVertex,
  InconsistentOrientation,
  ZeroAreaFace,
  DuplicatePosition,
};

enum class Severity { Fatal, Repairable, Topological, Info };

/// One kind of defect found in a mesh: how many, and a description of the first occurrence.
struct Defect {
  DefectKind kind;
  Severity severity;
  std::size_t count;
  std::string message;  ///< one line, e.g. "2 edges are shared by more than two faces (first: vertices 3-4, 3 faces)"
};

/// Result of validate_mesh. `defects` lists only kinds that occur, in DefectKind order.
struct ValidationReport {
  std::vector<Defect> defects;
  /// True when the topological checks were skipped because a fatal defect made them meaningless.
  bool topology_skipped{false};

  [[nodiscard]] std::size_t count(DefectKind kind) const;
  [[nodiscard]] bool has(Severity severity) const;
  /// The first defect of that severity, or nullptr.
  [[nodiscard]] const Defect* first(Severity severity) const;
  [[nodiscard]] bool clean() const { return defects.empty(); }
};

/// Options for validate_mesh.
struct ValidateOptions {
  /// A face counts as zero-area when twice its area is below this fraction of its longest edge squared.
  double zero_area_tolerance{1e-12};
  /// false: only the fatal checks (indices, coordinates, no faces), O(F + V): for consumers of any triangle
  /// soup (the fidelity metric) on meshes of 10^7–10^8 faces, where the sorts behind the other checks
  /// cost more than the work itself.
  bool complete{true};
};

/// Checks a mesh for every DefectKind. Never throws on bad data (that is what it reports).
/// Cost: O(F log F).
[[nodiscard]] ValidationReport validate_mesh(MeshView mesh, const ValidateOptions& options = {});

/// What repair_mesh changed.
struct RepairReport {
  std::size_t removed_degenerate_faces{0};
  std::size_t removed_duplicate_faces{0};
  std::size_t removed_unreferenced_vertices{0};
  [[nodiscard]] bool changed() const {
    return removed_degenerate_faces + removed_duplicate_faces + removed_unreferenced_vertices > 0;
  }
};

/// Removes degenerate faces, exact duplicate faces (keeping the first; not with `duplicates` false, which
/// avoids their O(F log F) sort) and unreferenced vertices (reindexing faces, colors and normals). Keeps the
/// order of everything it keeps. Precondition: indices in range (throws InvalidInput otherwise).
RepairReport repair_mesh(TriMesh& mesh, bool duplicates = true);

/// Welds every vertex the faces use to the one at the same position they use first (bit for bit; −0 as +0): a
/// triangle soup, or a mesh split along attribute seams, becomes one surface. Faces are re-indexed; faces
/// and vertices made redundant stay (repair_mesh removes them). Returns how many vertices were welded to
/// another. Not part of repair_mesh, which keeps the topology the file states: an explicit request
/// (`convert-format --weld`). Precondition: indices in range (throws InvalidInput otherwise).
std::size_t weld_positions(TriMesh& mesh);

[[nodiscard]] const char* to_string(DefectKind kind);
[[nodiscard]] const char* to_string(Severity severity);

}  // namespace gimforge
