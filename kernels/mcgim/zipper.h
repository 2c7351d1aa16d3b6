#pragma once
/// \file zipper.h
/// Geometry-image zippering (Sander et al. 2003, §4.5): seals the cracks between charts that meet on the
/// surface.
///  - Cut-nodes: mesh vertices where a chart's boundary changes neighbour (chart corners: more than two
///    charts, or a chart boundary meeting a mesh boundary); a closed boundary between two charts gets three
///    cut-nodes of its own. Every chart maps each of its cut-nodes to a distinct sample of its discrete
///    boundary loop, subject to keeping the cut-nodes' cyclic order (dynamic programming), the closest to
///    where the chart's placed parametrization puts the cut-node (the paper takes the closest in 3D, which
///    can pick a sample across a thin feature); those samples get the cut-node's position and are unified.
///  - Snap: every sample of a discrete cut-path moves to the closest point of its continuous cut-path (a
///    polyline of mesh edges); samples along a mesh boundary snap to it too.
///  - Unify: the two discrete cut-paths of each cut-path are traversed in lock-step from one cut-node
///    sample to the other; each step advances one path (the new sample joins the current cluster and takes
///    its position) or both (a new cluster at the first path's sample), whichever moves a sample least.
/// The result reconstructs (mcgim_image.h) to a watertight mesh for a closed input.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/edge_topology.h"
#include "kernels/core/mesh.h"
#include "kernels/mcgim/chart_param.h"

namespace gimforge {

struct ZipperStats {
  std::size_t cut_nodes{0};        ///< mesh vertices that are cut-nodes
  std::size_t cut_paths{0};        ///< cut-paths between two charts (unified)
  std::size_t boundary_paths{0};   ///< chart boundary stretches along a mesh boundary (snapped only)
  std::size_t snapped_samples{0};
  std::size_t unified_samples{0};  ///< samples in a cluster of two or more
};

/// The charts' boundary loops on the mesh and their cut-nodes (as described above).
struct ChartLoops {
  std::vector<std::vector<std::uint32_t>> loop;   ///< per chart: its boundary loop's mesh vertices
  std::vector<std::vector<std::uint32_t>> label;  ///< per loop edge: the chart across it (0xffffffff: mesh boundary)
  std::vector<std::vector<std::uint32_t>> edge;   ///< per loop edge: its index in the edge topology
  std::vector<char> is_cut;                       ///< per mesh vertex: 1 for a cut-node
  std::vector<std::size_t> cut_nodes;             ///< per chart: cut-nodes on its loop
};
[[nodiscard]] ChartLoops chart_loops(MeshView mesh, const EdgeTopology& topo, const std::vector<std::uint32_t>& face_chart,
                                     const std::vector<ChartMesh>& charts);

/// Zippers an assembled image in place. `positions` (width·height, row-major, row 0 at the bottom), `mask`
/// and `chart` (chart of each defined sample, 0xffffffff elsewhere) describe the placed charts; `charts` and
/// `loops` (chart_loops) the chartification of `mesh` they came from. Fills `unified` (width·height: representative
/// sample per defined sample, 0xffffffff elsewhere) and moves samples as described above.
/// Throws NumericalError naming the chart when its discrete shape is not a disk (more than one boundary
/// loop, a pinched boundary) or has fewer boundary samples than cut-nodes: a larger sample budget helps.
/// `vertex_image[c][v]` is local vertex v of chart c in image coordinates (column, row: where the placed
/// parametrization puts it): cut-node samples are chosen nearest to it there, which keeps them on the right
/// side of thin features where 3D distance could not tell.
ZipperStats zipper_charts(MeshView mesh, const ChartLoops& loops, const std::vector<ChartMesh>& charts,
                          const std::vector<std::vector<Vec2>>& vertex_image, std::uint32_t width,
                          std::uint32_t height, std::vector<Vec3>& positions, std::span<const std::uint8_t> mask,
                          std::span<const std::uint32_t> chart, std::vector<std::uint32_t>& unified);

}  // namespace gimforge
