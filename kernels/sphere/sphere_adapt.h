#pragma once
/// \file sphere_adapt.h
/// Adaptive sampling of a flat-octahedron spherical geometry image (adaptive geometry images §3 on the
/// spherical domain of Praun & Hoppe 2003): the image's square is the parameter square of the mesh cut
/// along the domain's seams (octa_disk.h), its sides fold about their midpoints, and the samples move as
/// those of a geometry image do (sample_adjust.h, sample_adaptively), the corners and side midpoints (the
/// seam points) held. Only the flattened octahedron is a square glued this way whose reconstruction
/// splits every cell along its shorter diagonal as the adjustment measures it; the octahedron and the
/// tetrahedron keep the domain's own diagonals and the cube has six faces.

#include <cstdint>
#include <span>
#include <vector>

#include "kernels/adaptive/roi_sampling.h"
#include "kernels/adaptive/sample_adjust.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/mesh.h"

namespace gimforge {

struct SphereAdaptResult {
  std::vector<Vec2> sample_uv;      ///< (2n+1)² parameter points, row-major as the image
  std::vector<Vec3> positions;      ///< the surface point of each
  std::vector<Vec3f> colors;        ///< interpolated from the mesh's colours (empty when it has none)
  AdaptiveSampling sampling;        ///< start grid and the figures of every round
  std::size_t disk_faces{0};        ///< faces of the cut disk (octa_disk.h)
  std::size_t disk_flipped{0};      ///< of them, turned over in the square
  RoiSummary roi;                   ///< with a ROI (`roi` given): its samples and figures
};

/// Adapts the samples of the flat-octahedron image at tessellation n of `mesh` (closed, genus 0,
/// `sphere` its parametrization, one unit vector per vertex). The start grid is evaluated on the cut disk,
/// so `adapt_max_before` is not exactly the uniform image's figure (octa_disk.h: the two parametrizations
/// differ inside triangles). With a region of interest (`roi`, its vertices those of `mesh`) the samples
/// move as roi_sampling.h says, from the uniform grid (the strips under AdaptStart::Strips); a disk face
/// belongs to the vertex form's ROI when the input face it lies in touches a flagged vertex. Throws
/// InvalidInput for bad sizes or an empty ROI, NumericalError when the cut fails (octa_disk.h), Cancelled
/// via options.progress.
[[nodiscard]] SphereAdaptResult adapt_flat_octahedron(const EmbreeDevice& device, const TriMesh& mesh,
                                                      std::span<const Vec3> sphere, std::uint32_t n, AdaptStart start,
                                                      AdaptOptions options, const RoiSource& roi = {});

}  // namespace gimforge
