#pragma once
/// \file chart_smooth.h
/// Smoothing of chart boundaries after chartification (ours; the paper does not describe a step like it).
/// The Dijkstra growth of §4.1 leaves ragged boundaries: one-face teeth and sharp, narrow corners where two
/// growth fronts met. Flattened, each becomes a spike of the chart's outline. Spikes cost twice: the
/// packer of §4.3 cannot nest spiky outlines (a spike's tip holds the chart away from its neighbours, and the
/// cells beside it are lost), and the sampling of §4.4 renders a spike as a thin peninsula whose two sides
/// the zipper of §4.5 must fold together. Both rules below move faces from one chart to a neighbour only
/// where that shortens the boundary between them and keeps both charts topological disks; every move
/// strictly shortens the total boundary length, so the passes end.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "kernels/core/mesh.h"

namespace gimforge {

struct BoundarySmoothing {
  std::size_t teeth{0};      ///< faces moved by the tooth rule
  std::size_t fan_faces{0};  ///< faces moved by the fan rule
  int passes{0};             ///< passes over the mesh (the last one moved nothing, unless the bound was hit)
};

/// Smooths the boundaries of the charts `face_chart` (one chart id per face of `mesh`, every chart a
/// topological disk) in place, by two rules applied in passes until nothing moves:
/// - tooth: a face whose two edges border one other chart B and whose third edge its own chart A (an "ear"
///   one face wide) moves to B when its tip vertex is in no other face of A;
/// - fan: at a vertex v inside the mesh where exactly two charts A and B meet, the fan of A's faces around v
///   moves to B when its rim (the edges opposite v) is shorter than A's two boundary edges at v — a convex
///   corner of A — provided the fan is one fan and its rim vertices other than its two ends are interior
///   vertices of A (A is not pinched, and B, which does not hold them, gains the fan along its two edges at
///   v, so it stays a disk). A thin peninsula erodes from its tip this way; a straight boundary stays.
/// Charts keep their ids; none becomes empty. The mesh must be edge-manifold.
BoundarySmoothing smooth_chart_boundaries(const TriMesh& mesh, std::vector<std::uint32_t>& face_chart);

}  // namespace gimforge
