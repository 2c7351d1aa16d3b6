#pragma once
/// \file sphere_map.h
/// Stretch-minimizing spherical parametrization φ: S → M of a closed genus-0 mesh (Praun & Hoppe 2003, §3):
/// the mesh is simplified to a tetrahedron as a progressive mesh (quadric order, collapses that create
/// poorly shaped triangles deferred), the base tetrahedron is mapped to the sphere, and the vertex splits
/// are applied coarse to fine. Each new vertex is placed inside the kernel of its 1-ring spherical polygon;
/// vertices are then optimized one at a time by great-circle line searches (gradient and random directions,
/// Brent's parabolic minimization) restricted to the kernel, minimizing the spherical stretch energy with
/// the inverse-stretch regularizer (spherical_stretch.h). Whenever the vertex count has grown by a factor,
/// all vertices are swept in the order of a priority queue keyed by the change in their neighbourhood.
/// Every step keeps the map an embedding; it is verified after every stage in debug builds and at the end
/// always.
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"
#include "kernels/sphere/spherical_stretch.h"

namespace gimforge {

struct SphereMapOptions {
  SphericalStretchOptions stretch{};  ///< ε = 1e-4, p = 6, and the integration threshold of the reported stretch
  /// Integration threshold (longest chord of a piece) while optimizing: coarse levels have huge spherical
  /// triangles, and a coarser quadrature there costs far less for the same placement; fine levels are
  /// below either threshold.
  double optimize_max_chord{0.3};
  double simplify_min_quality{0.4};   ///< first simplification pass: no collapse creates a worse-shaped triangle
  double refine_factor{1.15};         ///< sweep all vertices each time the vertex count grows by this factor
  double tolerance{1e-3};             ///< a sweep stops re-queueing when the relative change is below this
  double sweep_budget{6.0};           ///< a sweep optimizes at most this many times the number of vertices
  int final_sweeps{2};                ///< priority sweeps at the finest level
  double hole_weight{1e-6};           ///< energy factor of faces marked as holes (§5)
  std::uint64_t seed{1};              ///< line-search directions are random but reproducible
  ProgressCallback progress{};        ///< stages "simplify", "refine", "sweep"
};

struct SphereMapResult {
  std::vector<Vec3> sphere;           ///< one unit vector per vertex
  SphericalStretch stretch;           ///< of the final map (over all faces, unweighted)
  std::size_t vertex_splits{0};
  std::size_t flipped{0};             ///< spherical triangles with non-positive orientation (always 0)
  double seconds_simplify{0.0};
  double seconds_optimize{0.0};
};

/// Parametrizes a closed, connected, manifold, consistently oriented genus-0 mesh onto the unit sphere.
/// `hole_faces` (empty, or one flag per face) marks faces whose energy is scaled by options.hole_weight.
/// Throws TopologyError when the mesh is not such a surface, InvalidInput for bad sizes or options,
/// NumericalError if the map could not be kept an embedding in floating point, Cancelled via progress.
[[nodiscard]] SphereMapResult spherical_parametrization(MeshView mesh, std::span<const char> hole_faces = {},
                                                        const SphereMapOptions& options = {});

/// Number of spherical triangles of `mesh` under `sphere` with s0·(s1×s2) ≤ 0 (flipped or degenerate).
[[nodiscard]] std::size_t count_flipped_spherical(MeshView mesh, std::span<const Vec3> sphere);

/// Closes every boundary loop of `mesh` with a fan around a new centre vertex (at the loop's centroid);
/// the new faces are flagged in `hole_face` (one entry per output face). The input's vertices and faces
/// keep their indices; new vertices and faces are appended in the order of the loops found.
struct FilledMesh {
  TriMesh mesh;
  std::vector<char> hole_face;
  std::size_t holes{0};
};
[[nodiscard]] FilledMesh fill_holes(const TriMesh& mesh);

}  // namespace gimforge
