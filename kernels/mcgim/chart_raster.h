#pragma once
/// \file chart_raster.h
/// Geometry-image sampling of one chart (Sander et al. 2003, §4.4): the chart's parametrization rotated and
/// scaled onto the integer sample lattice, then
///  1. interior rasterization: every lattice point inside a parameter triangle (closed) gets the
///     barycentric interpolation of the triangle's 3D corners;
///  2. boundary rasterization: every still undefined cell of the 1-sample-wide band along a boundary edge
///     (the cells whose square the edge crosses: a 4-connected band) gets the closest point of the nearest
///     such edge, so thin "peninsulas" stay connected; defined samples are never overwritten;
///  3. non-manifold dilation: while some sample's reconstruction (the rules of §3, mcgim_image.h) is not a
///     single fan around it, a minimal number of its undefined neighbours become defined with its position;
///     4-adjacent samples that no triangle joins get a third, and enclosed undefined samples (a hole, which a
///     disk cannot have) are filled, so the discrete chart is one disk.
/// The same function gives the packer its shapes (pack.h) and the sampling its samples, so what is packed is
/// exactly what is sampled.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/mcgim/chart_param.h"
#include "kernels/mcgim/pack.h"

namespace gimforge {

struct ChartRaster {
  ChartShape shape;               ///< tight mask, row 0 at the bottom
  std::vector<Vec3> positions;    ///< per cell of the shape (width · height), meaningful where defined
  std::vector<Vec2> vertex_cells; ///< every chart vertex in the shape's cell coordinates (cell (i, j) at (i, j))
  std::size_t interior{0};        ///< samples from interior rasterization
  std::size_t boundary{0};        ///< added by boundary rasterization
  std::size_t dilated{0};         ///< added by non-manifold dilation
  bool manifold{true};            ///< false when dilation gave up (a bound on its passes was reached)
};

/// Rasterizes `chart` with parametrization `uv` (one per local vertex) rotated by `angle` radians about the
/// uv centroid and scaled by `scale` samples per parameter unit. Deterministic: the same arguments give the
/// same shape. Precondition: uv.size() == chart.mesh.num_vertices() (InvalidInput otherwise).
[[nodiscard]] ChartRaster rasterize_chart(const ChartMesh& chart, std::span<const Vec2> uv, double angle,
                                          double scale);

/// True when the reconstruction (§3 rules) around defined cell (x, y) of `mask` (width × height, 1 defined)
/// is one fan: its link among the 8 neighbours is non-empty and connected. Cells outside are undefined.
[[nodiscard]] bool sample_is_manifold(std::span<const std::uint8_t> mask, std::uint32_t width, std::uint32_t height,
                                      std::int64_t x, std::int64_t y);

}  // namespace gimforge
