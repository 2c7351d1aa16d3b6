#pragma once
/// \file load_mesh.h
/// The pipeline every command uses to get a mesh: read, validate, refuse fatal defects, repair the
/// repairable ones with a warning, and enforce what the consumer needs (e.g. a 2-manifold).
#include <filesystem>

#include "io/mesh_io.h"
#include "kernels/core/mesh.h"
#include "kernels/core/validate.h"

namespace gimforge::jobs {

/// What the consumer of the mesh requires.
struct LoadPolicy {
  bool repair{true};             ///< remove degenerate/duplicate faces and unreferenced vertices
  bool require_manifold{false};  ///< refuse non-manifold edges/vertices
  bool require_oriented{false};  ///< refuse inconsistently oriented faces
  bool warn{true};               ///< log repairs and topological defects as warnings
};

/// A mesh as loaded, with what was found and changed.
struct LoadedMesh {
  std::filesystem::path path;
  TriMesh mesh;              ///< repaired (if policy.repair)
  io::ReadInfo read;         ///< format facts of the file
  std::size_t file_vertices{0};
  std::size_t file_faces{0};  ///< triangles after fan triangulation, before repair
  ValidationReport validation;  ///< of the mesh as read
  RepairReport repair;
};

/// Loads `path` under `policy`. Throws IoError/FormatError from the reader, and InvalidInput (for fatal
/// defects) or TopologyError (for a requirement the mesh does not meet) whose message is
/// "PATH: <the defect's description>".
[[nodiscard]] LoadedMesh load_mesh(const std::filesystem::path& path, const LoadPolicy& policy = {});

}  // namespace gimforge::jobs
