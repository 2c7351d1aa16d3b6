#pragma once
/// \file strip_sampling.h
/// Vertex-density-equalized sampling of the square parameter domain (adaptive geometry images, §3.1):
/// start from ⌊n/2⌋ strips per axis, split the strip holding the most parametrized vertices in half until
/// there are n − 1; the n lines bounding the strips of each axis cross at the n × n sample positions.
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/param/stretch.h"

namespace gimforge {

/// The n strip lines of each axis, increasing, from 0 to 1.
struct StripLines {
  std::vector<double> x;
  std::vector<double> y;
};

/// Equalizes vertex counts per strip along each axis (§3.1 steps 1–5). A strip holds the points with
/// coordinate in [left, right); ties go to the lowest strip. Along each axis only the points strictly
/// inside (0, 1) count (boundary vertices on the sides x = 0, 1 would otherwise pull every x-strip there),
/// and no strip is split below 1/16 of the uniform spacing (vertices sharing one coordinate would draw
/// strips of zero width; the next fullest strip is split instead). Throws InvalidInput for n < 3.
[[nodiscard]] StripLines equalized_strips(std::span<const Vec2> points, std::uint32_t n);

/// The n × n sample positions (row-major) of a geometry image that follows the strip lines inside and the
/// uniform grid on its boundary: the sideband glues boundary pixels by index, so the samples of mated
/// cut-paths must stay mirror images of each other and the cut-nodes on grid points (geometry_image.h).
/// Between the two, over a band of (n − 1)/8 samples from each side, x blends from i/(n−1) to the strip
/// line by a smoothstep of the row's distance from the bottom and top sides (y likewise by the column's):
/// each row stays increasing in x and each column in y, and the boundary samples lie exactly on the
/// uniform perimeter grid. (The paper's tensor grid, with a uniform boundary, would join the boundary
/// samples to interior ones far away: long slivers across the surface.) Where very uneven strips next to a
/// side would shear a quad of the band into a non-convex one, the strips' pull is halved until every quad
/// is sound (grid_quad.h; down to the uniform grid).
[[nodiscard]] std::vector<Vec2> strip_sample_grid(const StripLines& lines);

}  // namespace gimforge
