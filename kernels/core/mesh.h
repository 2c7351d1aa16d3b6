#pragma once
/// \file mesh.h
/// The triangle mesh value type shared by every kernel, reader and writer.
/// A TriMesh is plain data (indexed face set); connectivity structures are built by the algorithms that
/// need them (see edge_topology.h), so the mesh itself stays a light container.
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace gimforge {

using Vec3 = Eigen::Vector3d;
using Vec3f = Eigen::Vector3f;
/// Vertex indices of one triangle, counter-clockwise seen from outside for consistently oriented meshes.
using Face = std::array<std::uint32_t, 3>;

/// True when a face repeats a vertex index (a topologically degenerate face: it has no area and no edges).
[[nodiscard]] inline bool has_repeated_index(const Face& f) { return f[0] == f[1] || f[1] == f[2] || f[0] == f[2]; }

/// Axis-aligned bounding box. An empty box has min > max.
struct BoundingBox {
  Vec3 min{Vec3::Constant(std::numeric_limits<double>::infinity())};
  Vec3 max{Vec3::Constant(-std::numeric_limits<double>::infinity())};

  [[nodiscard]] bool empty() const { return (min.array() > max.array()).any(); }
  /// Length of the diagonal; 0 for an empty box.
  [[nodiscard]] double diagonal() const { return empty() ? 0.0 : (max - min).norm(); }
  /// Centre of the box, in double; zero for an empty box.
  [[nodiscard]] Vec3 center() const { return empty() ? Vec3::Zero() : Vec3(0.5 * (min + max)); }
  void extend(const Vec3& p) {
    min = min.cwiseMin(p);
    max = max.cwiseMax(p);
  }
};

/// Indexed triangle mesh.
/// - `positions`: one entry per vertex.
/// - `faces`: triangles as vertex indices into `positions`.
/// - `colors`: optional per-vertex RGB in [0,1]; either empty or `positions.size()` entries.
/// - `normals`: optional per-vertex unit normals; either empty or `positions.size()` entries.
struct TriMesh {
  std::vector<Vec3> positions;
  std::vector<Face> faces;
  std::vector<Vec3f> colors;
  std::vector<Vec3f> normals;

  [[nodiscard]] std::size_t num_vertices() const { return positions.size(); }
  [[nodiscard]] std::size_t num_faces() const { return faces.size(); }
  [[nodiscard]] bool has_colors() const { return !colors.empty(); }
  [[nodiscard]] bool has_normals() const { return !normals.empty(); }
};

/// Non-owning view of a triangle mesh (positions + faces), so buffers from any source reach kernels
/// without copies. Valid only while the viewed storage lives.
struct MeshView {
  std::span<const Vec3> positions;
  std::span<const Face> faces;

  MeshView() = default;
  MeshView(std::span<const Vec3> p, std::span<const Face> f) : positions(p), faces(f) {}
  MeshView(const TriMesh& m) : positions(m.positions), faces(m.faces) {}  // NOLINT: implicit by design
};

/// Bounding box of the vertices referenced by at least one face (all vertices if `faces` is empty).
[[nodiscard]] BoundingBox bounding_box(MeshView mesh);

/// Area of triangle `f` of `mesh`. Precondition: indices in range.
[[nodiscard]] double triangle_area(MeshView mesh, std::size_t f);

/// Total surface area.
[[nodiscard]] double surface_area(MeshView mesh);

/// Adds `offset` to every position (in double): moves a mesh between frames (jobs/load_mesh.h, local frame).
void translate(TriMesh& mesh, const Vec3& offset);

}  // namespace gimforge
