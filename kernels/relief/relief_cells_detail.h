#pragma once
/// \file relief_cells_detail.h
/// Internal to kernels/: the OpenVDB inside test of classify_cells (relief_cells.cpp, the only translation
/// unit that includes OpenVDB), called from relief_cells_grid.cpp.
#include <array>
#include <cstdint>
#include <span>
#include <vector>


namespace gimforge::detail {

/// Inside (1) / outside (0) of the non-grey cells `queries` (cell coordinates), decided by OpenVDB's
/// exterior flood fill (tools::traceExteriorBoundaries, the sign step of tools::meshToVolume) on the
/// voxelization given by the grey cells: voxel = cell, the grey cells (linear indices, grid of n³) form the
/// boundary layer, and a cell is outside when the fill reaches it from beyond the grid without crossing
/// that layer. Throws LibraryError if OpenVDB fails.
[[nodiscard]] std::vector<std::uint8_t> exterior_flood_fill(std::span<const std::uint32_t> grey_cells, std::uint32_t n,
                                                            std::span<const std::array<std::uint32_t, 3>> queries);

}  // namespace gimforge::detail
