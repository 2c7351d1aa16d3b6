#pragma once
/// \file square_boundary.h
/// Boundary parametrization of a cut mesh onto the unit square (Gu, Gortler, Hoppe 2002, §3.1):
/// cut-nodes on grid points of the coarsest intended level, cut-paths allotted boundary length in
/// proportion to their 3D length (an integer number of grid units, mates identical, the rounding residual
/// redistributed symmetrically), edges spanning a square corner split (and their mates), triangles with all
/// three vertices on one side split — generalized to every interior edge whose two ends lie on one side
/// (such a chord would flatten the region it cuts off) — and the layout rotated so that no valence-1
/// cut-node sits on a corner.
#include <cstdint>
#include <vector>

#include "kernels/gim/cut.h"
#include "kernels/param/stretch.h"

namespace gimforge {

/// One cut-path of ρ': loop positions [first, first + edges] (indices into SquareBoundary::boundary, modulo
/// its size), its mate (or -1 for a path of original mesh boundary), and its place on the square perimeter
/// in grid units: it runs from perimeter unit `start_unit` to `start_unit + units` (counter-clockwise,
/// modulo 4·units_per_side).
struct CutPath {
  std::uint32_t first{0};
  std::uint32_t edges{0};
  std::int32_t mate{-1};
  double length{0.0};      ///< 3D length
  std::uint32_t start_unit{0};
  std::uint32_t units{0};
};

/// The cut mesh with its boundary on the unit square. `disk`, `original_vertex` and `boundary` extend
/// the CutMesh with the vertices inserted by the splits (their original_vertex is kInvalidIndex).
/// `boundary_uv[i]` is the square position of `boundary[i]`; `perimeter[i]` its perimeter coordinate in
/// grid units (monotone along the loop, in [0, 4·units_per_side)).
struct SquareBoundary {
  TriMesh disk;
  std::vector<std::uint32_t> original_vertex;
  std::vector<std::uint32_t> boundary;
  std::vector<Vec2> boundary_uv;
  std::vector<double> perimeter;
  std::vector<CutPath> paths;
  std::uint32_t units_per_side{64};
  std::size_t corner_splits{0};
  std::size_t side_splits{0};  ///< interior edges split because both ends lay on one side
};

struct SquareBoundaryOptions {
  /// Grid units per side of the coarsest level whose grid points carry the cut-nodes: 64 for 65×65,
  /// so every level (2^k·64 + 1)² down to 65×65 samples the cut-nodes exactly.
  std::uint32_t units_per_side{64};
};

/// Lays out the boundary of `cut` on the unit square. Throws TopologyError when the cut has more
/// cut-paths than the perimeter has grid units.
[[nodiscard]] SquareBoundary map_boundary_to_square(const CutMesh& cut, const SquareBoundaryOptions& options = {});

/// Point of the square perimeter at perimeter coordinate `c` (grid units, counter-clockwise from (0,0):
/// bottom side, right side, top side, left side).
[[nodiscard]] Vec2 perimeter_point(double c, std::uint32_t units_per_side);

}  // namespace gimforge
