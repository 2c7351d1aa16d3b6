#pragma once
/// \file roi.h
/// Region-of-interest (ROI) enhancement of adaptive geometry images (§4): a region of the parameter
/// square gets more of the n × n samples, moved there by ROI-weighted 1-ring averages, before the
/// Hausdorff-driven adjustment of §3.3 minimizes the directed distance from the ROI's reconstruction to the
/// original (sample_adjust.h, AdaptOptions::roi).
///
/// The ROI lives in the parameter square as a raster (RoiMask). It comes from the surface — the faces
/// touching a chosen vertex, rasterized through the parametrization (roi_from_vertices) — from a picture
/// over the square (roi_from_picture: a mask painted on the normal image, as the paper selects it), or
/// automatically from the normal image (roi_auto: the window of the square where the normals vary most).
///
/// Enhancement (enhance_roi), after the paper: the square outside the ROI is split into four regions (left,
/// right, below, above the ROI's bounding box: a point belongs to the side whose box edge it lies beyond by
/// the larger fraction of the box's half-size). Each non-ROI region r has n_ideal = (n_c / |V|) n² samples
/// by its share n_c of the parametrized vertices; their surplus (samples − n_ideal) sorted from high to low
/// gives weights 1, 2, 3, 4 (the region with most samples to spare gives them most readily) and the ROI
/// weighs more than all of them (8 at first). Every interior sample p0 moves to
///   p_new = Σ w_i ‖p0 − p_i‖ p_i / Σ w_i ‖p0 − p_i‖
/// over its 1-ring p_i (the eight grid neighbours: the paper's six of a triangulated grid, whichever
/// diagonal each quad takes), w_i the weight of the region p_i lies in, so samples drift towards the heavier
/// side. gimforge moves all samples to the fixed point of these averages at once: each iteration freezes
/// the coefficients w_i ‖p0 − p_i‖, solves the linear system of all interior samples (sparse LU) and steps
/// half of the way there (less after a step longer than the one before: the frozen coefficients overshoot),
/// the step halved until no quad folds (every quad sound, grid_quad.h: convex with a margin, also in float32,
/// no side shorter than 1/16 of the uniform spacing). (Gauss–Seidel sweeps of single moves spread a change of density by a sample per sweep: the
/// depleted band piled up next to the ROI, 10× its error there.) The weights are the regions' blurred over a
/// uniform spacing, so a sample crossing a region's edge does not jump, and the weights' ROI is the ROI
/// grown by two uniform spacings, so the density changes outside the ROI and its border triangles are as
/// fine as its middle. When the grid has settled (no step of a hundredth of a spacing) or the ROI gained in
/// 10 iterations less than a hundredth of what it lacked at the start, and it holds fewer than `gain` times
/// its samples of the start grid, the ROI weight doubles (at most 12 times). Boundary samples stay (the sideband glues them
/// by index).
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/param/stretch.h"

namespace gimforge {

class ParametrizedSurface;

/// A region of the parameter square: size × size cells over [0, 1]², row-major, row 0 at v = 0.
struct RoiMask {
  std::uint32_t size{0};
  std::vector<std::uint8_t> inside;
  /// Whether the cell holding `uv` (clamped into the square) is in the region.
  [[nodiscard]] bool contains(const Vec2& uv) const;
  /// Cells in the region.
  [[nodiscard]] std::size_t area_cells() const;
};

/// Cells per side of the masks gimforge builds for an n × n image: max(1024, 2(n − 1)).
[[nodiscard]] std::uint32_t roi_raster_size(std::uint32_t n);

/// The faces of `disk` flagged in `face_in` (one flag per face), rasterized through their parameter
/// triangles `uv` (the cells whose centre a face covers, and the cells holding its corners and centroid: a
/// face smaller than a cell still counts). Throws InvalidInput for mismatched sizes or raster 0.
[[nodiscard]] RoiMask roi_from_faces(MeshView disk, std::span<const Vec2> uv, std::span<const std::uint8_t> face_in,
                                     std::uint32_t raster);

/// roi_from_faces of the faces with at least one vertex flagged in `vertex_in` (one flag per disk vertex).
[[nodiscard]] RoiMask roi_from_vertices(MeshView disk, std::span<const Vec2> uv, std::span<const std::uint8_t> vertex_in,
                                        std::uint32_t raster);

/// A picture over the parameter square (width × height flags, row-major, row 0 the top: v = 1, as the
/// pictures of `preview`), its pixel centres on the grid points: pixel (x, y) at
/// (x / (width − 1), 1 − y / (height − 1)); each cell takes the nearest pixel. Throws InvalidInput for a
/// picture smaller than 2 × 2 or mismatched sizes.
[[nodiscard]] RoiMask roi_from_picture(std::uint32_t width, std::uint32_t height, std::span<const std::uint8_t> inside,
                                       std::uint32_t raster);

/// The ROI on the normal image, chosen automatically: the axis-aligned window of about `fraction` of the
/// square (k × k grid points, k = round(√fraction · (n − 1)) + 1) over which the normals of the n × n
/// uniform samples vary most (the sum over its points of Σ (1 − N·N') over their four neighbours N'), as a
/// user would pick the part of the normal image with most detail. Throws InvalidInput for a fraction
/// outside (0, 1) or n < 3.
[[nodiscard]] RoiMask roi_auto(const ParametrizedSurface& surface, MeshView disk, std::uint32_t n, double fraction,
                               std::uint32_t raster);

struct RoiEnhanceOptions {
  double gain{4.0};                ///< target: the ROI holds gain × its samples of the start grid (>= 1)
  std::uint32_t max_iterations{200};  ///< at most this many fixed-point iterations
};

struct RoiEnhanceResult {
  std::vector<Vec2> sample_uv;           ///< n·n parameter points
  std::uint64_t samples_before{0};       ///< samples in the ROI on the start grid
  std::uint64_t samples_after{0};        ///< ... after enhancement
  std::uint64_t target{0};               ///< what enhancement aimed at: ceil(gain × max(1, samples_before)),
                                         ///< at most the (n − 2)² interior samples
  std::array<double, 4> region_weights{};  ///< left, right, below, above
  double roi_weight{0.0};                ///< the ROI's weight when the sweeps stopped
  std::uint32_t iterations{0};          ///< fixed-point iterations
};

/// Moves the samples of an n × n grid (row-major, `sample_uv`) into `roi` as described above; `disk_uv`
/// holds the parametrized vertices (their count per region sets the weights). Throws InvalidInput for
/// n < 3, mismatched sizes, gain < 1 or an empty ROI.
[[nodiscard]] RoiEnhanceResult enhance_roi(std::span<const Vec2> disk_uv, std::uint32_t n, std::vector<Vec2> sample_uv,
                                           const RoiMask& roi, const RoiEnhanceOptions& options = {});

/// Samples of `sample_uv` in the ROI.
[[nodiscard]] std::uint64_t samples_in(const RoiMask& roi, std::span<const Vec2> sample_uv);

/// Flags made equal over glued samples (one surface point at several places of the square: a geometry
/// image's cut-path mates and cut-node copies, a flat-octahedron image's mirrored side samples):
/// `representative[k]` names the class of flag k (itself when unglued); a class with a set member is set
/// whole. Throws InvalidInput for mismatched sizes or a representative out of range.
void glue_flags(std::span<std::uint8_t> flags, std::span<const std::uint32_t> representative);

}  // namespace gimforge
