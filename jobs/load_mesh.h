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
  /// Appended to a refusal for require_manifold / require_oriented: what does take such a mesh.
  const char* refusal_hint{""};
  /// Whether the refusal also suggests the wrap that seals the mesh's holes (error_naming.h wrap_advice), where
  /// one does.
  bool suggest_wrap{false};
  /// false: the consumer takes any triangle soup (`metrics`): only fatal defects are checked and no
  /// duplicate faces sought (O(F) instead of O(F log F): loading a 10^7-face scan took 3× its metric).
  /// Degenerate faces and unreferenced vertices are still removed with `repair`. Needs no requirement.
  bool topology{true};
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
/// "PATH: <the defect's description>", and FormatError for a coordinate beyond ±1e18 (where squared
/// distances overflow single precision: Embree's BVH, float32 images). Positions keep the file's coordinates, in double. With policy.warn,
/// warns when they are stored as 32-bit floats so far from the origin that the file itself resolves them
/// coarsely (coarser than 1e-6 of the bounding-box diagonal: e.g. a 3 m scan at UTM northing 5·10^6).
[[nodiscard]] LoadedMesh load_mesh(const std::filesystem::path& path, const LoadPolicy& policy = {});

/// The local frame (docs/archive.md, "Local frame and origin"). Scans come in georeferenced coordinates
/// (UTM: x ≈ 4·10^5, y ≈ 5·10^6), where float32 images and Embree's float BVH keep a few bits of the
/// surface's detail; every kernel therefore runs on the mesh moved so that its origin is here, and what
/// the kernels make is stored relative to it, with the origin beside it (attribute `frame_origin`).
/// The origin of a mesh's local frame: the centre of the bounding box of all its positions, in double;
/// zero for a mesh without vertices or with a non-finite coordinate (the checks report those).
[[nodiscard]] Vec3 local_frame_origin(const TriMesh& mesh);
/// Moves `mesh` into the local frame at `origin` (positions − origin, in double).
void to_local_frame(TriMesh& mesh, const Vec3& origin);
/// Moves `mesh` from the local frame at `origin` back to the input's coordinates (positions + origin).
void to_input_frame(TriMesh& mesh, const Vec3& origin);

}  // namespace gimforge::jobs
