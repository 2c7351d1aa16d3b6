#pragma once
/// \file gim_fuse.h
/// Fusing the cut of a lossily decoded geometry image (Gu, Gortler, Hoppe 2002 §5, "Compression and
/// Decompression"): a wavelet coder reconstructs cut-path mates differently, which opens cracks along the
/// cut (the paper's Fig. 1d). The topological sideband says which boundary grid points are one point of the
/// surface: pairs along a cut-path, k points at a cut-node of valence k. Fusing replaces every such class by
/// its average; error diffusion then spreads each fused point's displacement into the interior, so that
/// the averaging leaves no step next to the cut (Fig. 1e).
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/gim/geometry_image.h"

namespace gimforge {

struct FuseStats {
  std::size_t classes{0};        ///< boundary classes of more than one grid point
  double max_displacement{0.0};  ///< the largest move of a boundary grid point
  double rms_displacement{0.0};  ///< over the boundary grid points of those classes
};

/// Averages every class of glued boundary grid points of the n×n image (n·n·3 floats, row-major) in place;
/// the values of a class become bit-identical. `displacement` receives the move of every pixel (zero for
/// interior pixels and unglued boundary pixels). `trusted` (n·n flags, or empty): pixels decoded better than
/// the rest (the window of a ROI-first code); a class with a trusted member takes the mean of its trusted
/// members only. Throws InvalidInput for a size mismatch or an n whose n − 1 is not a multiple of the
/// sideband's units_per_side.
FuseStats fuse_cut(std::span<float> positions, std::uint32_t n, const Sideband& sideband,
                   std::vector<Vec3>& displacement, std::span<const std::uint8_t> trusted = {});

/// Error diffusion: adds to every interior pixel within `band` pixels of a side the displacements of the
/// boundary pixels facing it on its row and column, weighted (1 − d/band)² by its distance d, and divided
/// by the sum of the weights where that exceeds 1 (near the corners, where two sides reach). Boundary
/// pixels keep their fused values, so glued pixels stay identical. `band` 0 chooses max(2, (n − 1)/16).
void diffuse_fusing(std::span<float> positions, std::uint32_t n, std::span<const Vec3> displacement,
                    std::uint32_t band = 0);

}  // namespace gimforge
