#pragma once
/// \file wrap.h
/// A closed, one-piece stand-in for a surface that a single-chart image cannot take (issue #17 item 4: the
/// raw dragon scan has 151 components, 407 holes and 46 handles in its largest piece): the surface is
/// voxelized, closed morphologically (holes and tunnels narrower than about 2·closing voxels seal), its
/// inside filled from the outside by a flood fill, and the boundary of that solid is extracted by OpenVDB
/// (topologyToLevelSet, volumeToMesh) as a closed 2-manifold; only the largest piece is kept. The result
/// is a *proxy*: an image method parametrizes it, and its samples then move onto the real surface
/// (surface_transfer.h). It lies within about a voxel of the surface where the surface is closed and
/// spans its holes elsewhere.
#include <array>
#include <cstddef>
#include <cstdint>

#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"

namespace gimforge {

struct WrapOptions {
  std::uint32_t resolution{512};  ///< voxels along the bounding box's longest side (16 … 2048)
  std::uint32_t closing{1};       ///< morphological closing radius in voxels (0 … 16)
  /// Largest share of the input's area that may lie outside the kept piece's solid (separate objects, or a
  /// part the outside got into and broke into crumbs): beyond it the wrap is refused. Surfaces sealed inside
  /// the kept piece (a hollow part's inner wall) do not count.
  double max_area_left_out{0.25};
  ProgressCallback progress{};    ///< stage "wrap"
};

struct WrapResult {
  TriMesh mesh;                          ///< the closed surface, counter-clockwise seen from outside
  double voxel{0.0};                     ///< voxel edge length
  std::array<std::uint32_t, 3> dims{};   ///< voxel grid dimensions
  std::size_t dropped_components{0};     ///< pieces of the extracted surface other than the largest
  std::size_t dropped_faces{0};          ///< their faces
  double area_left_out{0.0};             ///< share of the input's area farther than kNearVoxels from the kept piece
  /// ... of which outside the kept piece's solid (measured only when area_left_out exceeds
  /// max_area_left_out; 0 otherwise)
  double area_outside{0.0};
};

/// How far (voxels, in each axis) an input point may lie from the kept piece and count as represented by it.
inline constexpr int kNearVoxels = 3;

/// Wraps `mesh` (any triangles: several components, holes, non-manifold edges). Throws InvalidInput for
/// options out of range, a mesh without extent or a grid over 2^30 voxels; NumericalError when nothing closed
/// comes out (a surface thinner than about two voxels everywhere), when the outside got in through a hole
/// wider than the closing (the largest piece holds less than half of the wrap) or when more than
/// `max_area_left_out` of the input's area lies outside the kept piece's solid (a scan of separate objects keeps
/// one of them: the cow beside a fist kept the fist, 10 dB); LibraryError when OpenVDB fails; Cancelled via
/// progress.
[[nodiscard]] WrapResult wrap_surface(MeshView mesh, const WrapOptions& options = {});

}  // namespace gimforge
