#pragma once
/// \file lscm.h
/// Least-squares conformal maps (Lévy, Petitjean, Ray, Maillot 2002): a free-boundary parametrization of a
/// disk-like mesh minimizing Σ_T A_T |∇v − rot(∇u)|², with two boundary vertices pinned (the farthest-apart
/// pair of the boundary loop, found approximately). Multi-chart geometry images use it as the start of
/// their free-boundary stretch optimization: unlike a circle boundary it keeps elongated charts elongated.
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/param/stretch.h"

namespace gimforge {

/// LSCM of `mesh` (connected, consistently oriented, a disk) with boundary loop `boundary` (≥ 2 vertices).
/// Returns one uv per vertex, counter-clockwise triangles positive. The map may still fold (flipped
/// triangles) on badly shaped meshes: callers check (mesh_stretch(...).flipped). Throws InvalidInput for
/// bad arguments, NumericalError when the solve fails.
[[nodiscard]] std::vector<Vec2> lscm_parametrization(MeshView mesh, std::span<const std::uint32_t> boundary);

}  // namespace gimforge
