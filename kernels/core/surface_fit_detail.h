#pragma once
/// \file surface_fit_detail.h
/// Internal to kernels/: the two terms of the geometry-image optimization energy (surface_fit.h) with
/// their analytic gradients, exposed so that tests can check them against finite differences on a fixed
/// triangulation. Not part of the public API.
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "kernels/core/embree_device.h"
#include "kernels/core/mesh.h"

namespace gimforge::detail {

/// An edge ab shared by exactly two faces, with c the third vertex of the face that runs a -> b and d the
/// third vertex of the other face. The dihedral angle is measured between the normals of the triangles
/// (a, b, c) and (b, a, d), i.e. of the two faces oriented consistently across the edge, whatever the
/// orientation they were stored with: it is 0 where the two faces are coplanar and not folded.
struct DihedralEdge {
  std::uint32_t a, b, c, d;
};

/// The edges of a triangulation.
struct EdgeSet {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;  ///< every distinct edge (lower index first)
  std::vector<DihedralEdge> dihedral;                          ///< edges with exactly two faces
};

/// Edges of `faces` (sorted by vertex pair). Edges with one face (boundary) or more than two faces
/// (non-manifold) are not dihedral; nor are two faces over the same three vertices. Precondition: no face
/// repeats a vertex.
[[nodiscard]] EdgeSet build_edges(std::span<const Face> faces);

/// Smoothness term of §4.6 before weighting: Σ_e |θ_e|^p over `edges`, θ_e the signed dihedral angle in
/// radians (0 for flat). An edge whose length is zero or one of whose triangles is a sliver over it (height
/// below kMinRelativeHeight = 1 % of the edge length) is skipped: the angle is undefined at height 0 and its
/// gradient grows like 1/height near it. The zipper of multi-chart images leaves such slivers; with them in,
/// their few vertices' gradients dwarfed the rest and the descent stalled at its first step (cow at 32
/// charts: energy 2.795e-8 → 2.795e-8; without them 2.795e-8 → 9.7e-10, 77.7 → 84.7 dB). When `gradient` is non-empty (one
/// entry per position) adds `gradient_scale` · ∂/∂x of the sum into it, with the dihedral-angle gradient of
/// Bridson et al. 2003 ("Simulation of clothing with folds and wrinkles", §4.1). Precondition: exponent >= 1.
double dihedral_energy(std::span<const Vec3> positions, std::span<const DihedralEdge> edges, int exponent,
                       std::span<Vec3> gradient, double gradient_scale = 1.0);

/// Fit term of §4.6 (Hoppe et al. 1993): (1/N) Σ_i |r_i − c_i|² over the N `samples` r_i, c_i the exact
/// closest point of `remesh` (a BVH is built here). When `gradient` is non-empty (one entry per remesh
/// position) adds ∂/∂x_v = −(2/N) b_v (r_i − c_i) for the three vertices v of the face holding c_i, b_v
/// their barycentric coordinates (the projection held fixed, as in Hoppe 1993; by the envelope theorem
/// this is also the exact derivative wherever the closest point is unique). `hints` is empty or holds one
/// face index per sample: a face near the sample's answer, whose distance bounds the query (any value is
/// safe; out-of-range values are ignored); it is overwritten with the answer's face. Returns +∞ when some
/// sample finds no face. Throws InvalidInput (no faces), LibraryError (Embree).
double fit_energy(const EmbreeDevice& device, std::span<const Vec3> samples, MeshView remesh,
                  std::span<Vec3> gradient, std::span<std::uint32_t> hints = {});

}  // namespace gimforge::detail
