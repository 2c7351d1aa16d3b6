#pragma once
/// \file vertex_rings.h
/// Ordered one-rings (vertex umbrellas) of a manifold triangle mesh, shared by the parametrization kernels
/// (Floater weights, stretch optimization, progressive mesh).
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/mesh.h"

namespace gimforge {

/// Neighbours of every vertex in counter-clockwise order (seen with the faces' orientation), CSR layout.
/// - `ring(v)` = neighbours of v; for a closed ring, the face (v, ring[k], ring[k+1 mod d]) exists for all k;
///   for an open ring (a boundary vertex) only for k < d-1, and ring[0], ring[d-1] are its boundary
///   neighbours.
/// - `open[v]` = 1 for boundary vertices. Unreferenced vertices have an empty, closed ring.
struct VertexRings {
  std::vector<std::uint32_t> offsets;     ///< num_vertices + 1
  std::vector<std::uint32_t> neighbours;  ///< concatenated rings
  std::vector<char> open;                 ///< per vertex

  /// The ordered ring of vertex v.
  [[nodiscard]] std::span<const std::uint32_t> ring(std::size_t v) const {
    return {neighbours.data() + offsets[v], neighbours.data() + offsets[v + 1]};
  }
};

/// Builds the rings. Degenerate faces (repeated index) are ignored.
/// Preconditions: indices in range. Throws TopologyError when a vertex's faces do not form one
/// consistently oriented fan (non-manifold vertex or inconsistent orientation).
[[nodiscard]] VertexRings build_vertex_rings(MeshView mesh);

}  // namespace gimforge
