#pragma once
/// \file stretch_optimizer.h
/// Hierarchical L2 geometric-stretch minimization (Sander, Gortler, Snyder, Hoppe 2002, "Signal-
/// specialized parametrization"; ../shared/notes/parametrization.md): simplify the free (interior) vertices
/// to a progressive mesh, optimize the base, then apply vertex splits coarse to fine, placing each new
/// vertex in the kernel of its 1-ring and optimizing its neighbourhood by line searches that never flip a
/// triangle, with periodic priority-queue sweeps. Shared by geometry images (square domain) and other
/// planar-domain methods.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"
#include "kernels/param/stretch.h"

namespace gimforge {

struct StretchOptimizerOptions {
  std::size_t base_vertices{64};   ///< free vertices left in the base mesh of the progressive mesh
  double refine_factor{1.5};       ///< sweep all vertices each time the vertex count grows by this factor
  int final_sweeps{4};             ///< full sweeps at the finest level
  double tolerance{1e-4};          ///< a vertex is re-queued when its neighbourhood energy changed by more
  std::uint64_t seed{1};           ///< line-search directions are random but reproducible
  /// Free boundary (multi-chart charts, Sander et al. 2003 §4.2): no vertex need be fixed, and the energy is
  /// the scale-invariant product (Σ L2²(T) A'(T)) · (Σ parameter area) — minimizing it maximizes the stretch
  /// efficiency, where Σ L2² A' alone would grow the domain without bound. Boundary vertices then move
  /// under the no-flip rule of their open ring (the half-planes of their ring's edges: their own kernel).
  bool free_boundary{false};
  ProgressCallback progress{};     ///< stages "simplify", "refine", "sweep"
};

struct StretchOptimizerResult {
  std::vector<Vec2> uv;            ///< one per vertex; fixed vertices unchanged
  MeshStretch initial;             ///< of the input parametrization
  MeshStretch final;
  std::size_t vertex_splits{0};
  std::size_t base_free_vertices{0};
  double seconds_simplify{0.0};
  double seconds_optimize{0.0};
};

/// Minimizes the L2 stretch of a disk-like mesh's parametrization.
/// - `uv`: one per vertex; for `fixed` vertices the constraint positions; for the others a valid
///   embedding (e.g. Floater's) that the optimizer may use where it needs a fallback.
/// - `fixed[v] != 0` marks vertices that must not move (the boundary).
/// Guarantees: no triangle is flipped in the result if none was flipped in the input; the result's L2
/// stretch (free_boundary: its stretch efficiency) is never worse than the input's (the input is returned
/// when the optimization could not beat it).
/// Free vertices on the mesh boundary are never collapsed, and move only under the no-flip rule.
/// Cost: O(V log V) simplification plus O(V) line searches per sweep (≈3 s for 60K faces on one core).
/// Throws InvalidInput (size mismatch, flipped input), Cancelled.
[[nodiscard]] StretchOptimizerResult optimize_stretch(MeshView mesh, std::span<const Vec2> uv,
                                                      std::span<const char> fixed,
                                                      const StretchOptimizerOptions& options = {});

}  // namespace gimforge
