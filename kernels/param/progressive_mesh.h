#pragma once
/// \file progressive_mesh.h
/// A progressive mesh of half-edge collapses (Hoppe 1996) that keeps a set of locked vertices, for the
/// hierarchical parametrization methods (Sander et al. 2002, planar domain; Praun & Hoppe 2003, sphere).
/// Domain-agnostic: simplification is ordered by Garland–Heckbert quadrics of the 3D surface and checked for
/// topological validity; a caller-supplied filter adds domain conditions (e.g. "no parameter triangle flips").
/// Collapses are recorded and undone in reverse order as vertex splits.
#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string_view>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"

namespace gimforge {

/// One half-edge collapse `vertex` -> `target`, as recorded for its vertex split.
/// - `removed_faces`: faces that contained both vertices (deleted by the collapse).
/// - `moved_corners`: corners 3*face + i that referred to `vertex` and were re-pointed to `target`.
struct VertexSplitRecord {
  std::uint32_t vertex{0};
  std::uint32_t target{0};
  std::vector<std::uint32_t> removed_faces;
  std::vector<std::uint32_t> moved_corners;
};

/// Mutable mesh state plus the stack of recorded collapses. Face indices are those of the input mesh; a face
/// is alive when it exists in the current level.
class ProgressiveMesh {
 public:
  /// Domain test of a candidate collapse (vertex -> target) on the current state; return false to forbid it.
  using CollapseFilter = std::function<bool(const ProgressiveMesh&, std::uint32_t vertex, std::uint32_t target)>;

  /// Starts at the full mesh. `locked[v] != 0` marks vertices never removed (may be empty: none locked).
  /// Preconditions: manifold, consistently oriented, indices in range; throws InvalidInput on size mismatch.
  ProgressiveMesh(MeshView mesh, std::span<const char> locked);

  /// Collapses unlocked interior vertices, cheapest quadric error first, until `target_free` unlocked vertices
  /// remain or no valid collapse is left. Reports progress as `stage`. Returns the number of collapses done.
  std::size_t simplify(std::size_t target_free, const CollapseFilter& filter = {},
                       const ProgressCallback& progress = {}, std::string_view stage = "simplify");

  /// True when `vertex` -> `target` is topologically valid now: vertex unlocked, alive and interior, target
  /// adjacent, link condition holds, more than 4 vertices remain.
  [[nodiscard]] bool can_collapse(std::uint32_t vertex, std::uint32_t target) const;

  /// Applies a collapse (precondition: can_collapse) and pushes its record.
  void collapse(std::uint32_t vertex, std::uint32_t target);

  /// Number of recorded collapses not yet undone.
  [[nodiscard]] std::size_t pending_splits() const { return records_.size(); }
  /// The record the next split() will undo. Precondition: pending_splits() > 0.
  [[nodiscard]] const VertexSplitRecord& next_split() const { return records_.back(); }
  /// Undoes the most recent collapse; returns the re-inserted vertex.
  std::uint32_t split();

  /// Current faces (input indexing; dead faces keep stale corners). Check face_alive().
  [[nodiscard]] std::span<const Face> faces() const { return faces_; }
  [[nodiscard]] bool face_alive(std::size_t f) const { return face_alive_[f] != 0; }
  [[nodiscard]] bool vertex_alive(std::size_t v) const { return vertex_alive_[v] != 0; }
  [[nodiscard]] bool locked(std::size_t v) const { return locked_[v] != 0; }
  /// Alive faces incident to v (any order).
  [[nodiscard]] std::span<const std::uint32_t> vertex_faces(std::size_t v) const { return vertex_faces_[v]; }
  /// Distinct neighbours of v in the current level, appended to `out` after clearing it.
  void neighbours(std::uint32_t v, std::vector<std::uint32_t>& out) const;
  /// True when v has an edge with a single incident face in the current level.
  [[nodiscard]] bool on_boundary(std::uint32_t v) const;
  [[nodiscard]] std::size_t alive_vertices() const { return alive_vertices_; }
  [[nodiscard]] std::size_t alive_free_vertices() const { return alive_free_; }
  /// The current level as a face list (alive faces only), indexing the input vertices.
  [[nodiscard]] std::vector<Face> alive_faces() const;
  [[nodiscard]] MeshView input() const { return mesh_; }

 private:
  using Quadric = std::array<double, 10>;
  [[nodiscard]] double collapse_cost(std::uint32_t vertex, std::uint32_t target) const;
  void init_quadrics();
  void detach_face(std::uint32_t f, std::uint32_t except);
  static void erase_value(std::vector<std::uint32_t>& list, std::uint32_t value);

  MeshView mesh_;
  std::vector<Face> faces_;
  std::vector<char> face_alive_;
  std::vector<char> vertex_alive_;
  std::vector<char> locked_;
  std::vector<std::vector<std::uint32_t>> vertex_faces_;
  std::vector<Quadric> quadrics_;
  std::vector<VertexSplitRecord> records_;
  std::size_t alive_vertices_{0};
  std::size_t alive_free_{0};
};

}  // namespace gimforge
