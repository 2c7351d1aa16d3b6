#pragma once
/// \file floater.h
/// Floater's shape-preserving parametrization (Floater 1997): fixed boundary positions, interior vertices
/// as convex combinations of their neighbours with weights from a local geodesic polar map. Bijective for a
/// convex boundary (Tutte–Floater). Mean-value weights (Floater 2003) are offered as the alternative.
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/param/stretch.h"

namespace gimforge {

struct FloaterOptions {
  enum class Weights { ShapePreserving, MeanValue, Uniform };
  Weights weights{Weights::ShapePreserving};
};

/// Parametrizes a mesh with the given vertices fixed at `fixed_uv` (typically the boundary loop on a convex
/// polygon). Every other vertex is solved from u_i = Σ_j λ_ij u_j (sparse linear solve).
/// Preconditions: `mesh` is a connected manifold; fixed_vertices.size() == fixed_uv.size() >= 3.
/// Throws InvalidInput on bad arguments, NumericalError if the solve fails.
/// Returns one uv per vertex of `mesh` (unreferenced vertices get (0,0)).
[[nodiscard]] std::vector<Vec2> floater_parametrization(MeshView mesh, std::span<const std::uint32_t> fixed_vertices,
                                                        std::span<const Vec2> fixed_uv,
                                                        const FloaterOptions& options = {});

/// Places an ordered boundary loop on the unit circle, spaced by 3D edge length (Gu et al. §3.2).
[[nodiscard]] std::vector<Vec2> circle_boundary(MeshView mesh, std::span<const std::uint32_t> loop);

}  // namespace gimforge
