#pragma once
/// \file relief_map_detail.h
/// Internal to kernels/: the sampling step of build_relief_map (relief_sampling.cpp), called from
/// relief_map.cpp.
#include <cstdint>

#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"
#include "kernels/relief/relief_cells.h"
#include "kernels/relief/relief_map.h"

namespace gimforge::detail {

/// Samples every layer of `map` (§3.3.2): sizes and fills distances, normals and, when the mesh has
/// vertex colours, colours. Per grey cell g, only the triangles grid.grey_triangles[g] are considered:
/// each is clipped to the cell, its projection onto each domain face bounds a rectangle of texels, and
/// the projection segment of every texel in it is intersected exactly (double precision) with the
/// triangle; the nearest hit is kept. Hits within 1e-9 · cell_size of the nearest one on the same segment
/// (the same surface point reached through a shared edge or vertex, duplicated faces) are not occluded;
/// every other hit is. Multi-threaded over grey cells (TBB); the result does not depend on the number of
/// threads. Preconditions: the cell table of `map` (cells, projections, layers, texture, cell_size)
/// was built from `grid` and `mesh`; colours, if any, one per vertex. Throws Cancelled through `progress`
/// (stage "relief sampling").
[[nodiscard]] ReliefSampleCounts sample_relief_layers(ReliefMap& map, const TriMesh& mesh, const CellGrid& grid,
                                                      const ProgressCallback& progress);

}  // namespace gimforge::detail
