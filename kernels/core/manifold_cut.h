#pragma once
/// \file manifold_cut.h
/// Cutting any triangle mesh into an edge-manifold, consistently oriented one over the same surface: edges
/// with more than two faces, and edges across which the faces cannot agree on an orientation (a Möbius
/// strip's seam), become boundaries; faces are reoriented to agree with their neighbours; vertices where
/// several fans of faces meet become one vertex per fan; faces around an edge of more than two are paired
/// into sheets first (sheet_pairs). Positions are not moved and no face is added or removed, so the surface
/// (and any distance to it) is the input's; only its connectivity is cut.
#include <cstddef>
#include <cstdint>
#include <array>
#include <functional>
#include <span>
#include <vector>

#include "kernels/core/edge_topology.h"
#include "kernels/core/mesh.h"

namespace gimforge {

/// Splits vertices by fans: the corners of two faces that share a two-sided edge e are joined at both of
/// its vertices when `join(e)` holds (e indexes `topo`, the edge table of `mesh`); every class of joined
/// corners at a vertex becomes a vertex of its own (in order of first use by the faces). Works whatever the
/// faces' orientations. `source_vertex`, when given, receives the input vertex of every output vertex.
/// `sheets` joins more: face pairs {f0, f1, e} across an edge e of more than two faces (sheet_pairs).
[[nodiscard]] TriMesh split_vertices_by_fans(const TriMesh& mesh, const EdgeTopology& topo,
                                             const std::function<bool(std::size_t)>& join,
                                             std::vector<std::uint32_t>* source_vertex = nullptr,
                                             std::span<const std::array<std::uint32_t, 3>> sheets = {});

/// The faces around an edge of more than two faces, paired into sheets {f0, f1, e}: sorted by their angle
/// around the edge, a face is paired with its neighbour when the wedge between them lies behind both (the
/// inside of a closed piece, for outward faces: two solids touching along an edge stay two closed solids),
/// then the rest with an unpaired neighbour of the opposite direction along the edge. Faces without area
/// across the edge (a third corner on the edge's line) are never paired.
[[nodiscard]] std::vector<std::array<std::uint32_t, 3>> sheet_pairs(const TriMesh& mesh, const EdgeTopology& topo);

struct ManifoldCut {
  TriMesh mesh;                              ///< the cut mesh: the input's faces, in order, some reversed
  std::vector<std::uint32_t> source_vertex;  ///< for every vertex of `mesh`, the input vertex it copies
  std::size_t nonmanifold_edges{0};          ///< edges of more than two faces, made boundaries
  std::size_t orientation_cuts{0};           ///< two-face edges whose faces could not agree, made boundaries
  std::size_t flipped_faces{0};              ///< faces reversed to agree with their neighbours
  std::size_t split_vertices{0};             ///< vertices added: output vertices minus the input's used ones
  [[nodiscard]] bool changed() const { return nonmanifold_edges + orientation_cuts + flipped_faces + split_vertices > 0; }
};

/// Cuts `mesh` (faces without a repeated vertex: the loader removes those) as the file comment says.
/// Orientation: a piece (faces connected over two-face edges) whose faces agree is left alone (an inward
/// closed shell may be a cavity). Of one that does not, faces are reversed to agree with a breadth-first
/// walk, and the piece then points where its stored vertex normals do, else (a closed piece, each edge of
/// its faces used twice by them) encloses a positive volume, else keeps the way most of its faces were. Edges of more
/// than two faces keep the sheets sheet_pairs finds (the first cut; what it leaves is cut apart). A mesh that is already an
/// oriented 2-manifold comes back unchanged (the same vertices and faces). Throws InvalidInput for a
/// degenerate face.
[[nodiscard]] ManifoldCut cut_to_manifold(const TriMesh& mesh);

}  // namespace gimforge
