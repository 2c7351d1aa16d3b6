#pragma once
/// \file topology.h
/// Topological summary of a triangle mesh: connected components, boundary loops, Euler characteristic,
/// genus per component, closed / manifold / orientable flags, bounding box.
#include <cstddef>
#include <vector>

#include "kernels/core/mesh.h"

namespace gimforge {

/// Topology of one connected component (faces connected through shared vertices).
struct ComponentTopology {
  std::size_t faces{0};
  std::size_t vertices{0};        ///< referenced vertices
  std::size_t edges{0};
  std::size_t boundary_edges{0};  ///< edges with exactly one incident face
  std::size_t boundary_loops{0};
  long long euler_characteristic{0};  ///< V - E + F
  /// (2 - chi - boundary_loops) / 2. An integer for orientable 2-manifolds; for non-manifold or
  /// non-orientable components it is reported as computed (possibly fractional) and is not a genus.
  double genus{0.0};
  bool closed{false};      ///< no boundary edges
  bool manifold{false};    ///< no non-manifold edges or vertices
  bool orientable{false};  ///< faces can be oriented consistently (checked over its two-sided edges)
  bool oriented{false};    ///< faces are oriented consistently as given
};

/// Topology of the whole mesh. Components are sorted by face count, largest first.
struct TopologyReport {
  std::size_t vertices{0};             ///< all vertices, referenced or not
  std::size_t referenced_vertices{0};
  std::size_t faces{0};                ///< faces that are not degenerate (no repeated index)
  std::size_t edges{0};
  std::size_t boundary_edges{0};
  std::size_t boundary_loops{0};
  std::size_t nonmanifold_edges{0};
  std::size_t nonmanifold_vertices{0};
  std::size_t inconsistent_edges{0};
  long long euler_characteristic{0};
  std::vector<ComponentTopology> components;
  bool closed{false};
  bool manifold{false};
  bool orientable{false};
  bool oriented{false};
  BoundingBox bbox;
  double surface_area{0.0};
};

/// Computes the TopologyReport. Precondition: indices in range (validate_mesh first); degenerate faces are
/// ignored. Boundary loops are the connected components of the graph of boundary edges: in a 2-manifold
/// every boundary vertex has two boundary edges and these are exactly the boundary curves; at a
/// non-manifold vertex, loops that touch count as one. Cost: O(F log F).
[[nodiscard]] TopologyReport analyze_topology(MeshView mesh);

/// The width of the mesh's widest hole: over its boundary loops (as analyze_topology counts them), the
/// largest extent of a loop's vertices along their second principal axis — a round hole's diameter, a slit's
/// width, the rim of an open sheet its size. Independent of translation and rotation; 0 for a closed mesh.
/// What a closing that seals holes narrower than some width can do with the mesh (a wrap, scan/wrap.h).
/// Precondition: indices in range. Cost: O(F log F).
[[nodiscard]] double widest_hole(MeshView mesh);

}  // namespace gimforge
