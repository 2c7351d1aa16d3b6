#pragma once
/// \file geometry_image.h
/// Geometry images (Gu, Gortler, Hoppe 2002): regular resampling of a parametrized disk into an n×n image
/// of [x, y, z], the topological sideband (§3.3) that records how the image boundary is glued, and the
/// reconstruction to a triangle mesh (§4: 2×2 quads split along the shorter diagonal; boundary fused from
/// the sideband; level of detail by sub-sampling).
///
/// Image layout: row-major (H = n, W = n, 3); pixel (row j, column i) is the surface point at parameter
/// (s, t) = (i/(n−1), j/(n−1)), or, for adaptive sampling (kernels/adaptive), at the parameter point the
/// image's `sample_uv` records for it.
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "kernels/core/embree_device.h"
#include "kernels/core/mesh.h"
#include "kernels/gim/square_boundary.h"

namespace gimforge {

/// The topological sideband: the cut-paths around the square in order, each with its label and its place
/// on the perimeter in grid units of the coarsest level (`units_per_side` units per side). Mates carry
/// labels +k and −k (k ≥ 1); a path of the original mesh boundary carries label 0 (no mate).
struct Sideband {
  struct Path {
    std::int32_t label{0};
    std::uint32_t start_unit{0};
    std::uint32_t units{0};
  };
  /// The most units per side a sideband may have (so that 4 · units_per_side and the unit sums fit).
  static constexpr std::uint32_t kMaxUnitsPerSide = std::uint32_t{1} << 20;

  std::uint32_t units_per_side{64};
  std::vector<Path> paths;

  /// Builds the sideband of a square boundary layout.
  [[nodiscard]] static Sideband from_boundary(const SquareBoundary& boundary);
  /// Throws InvalidInput unless units_per_side is in [1, kMaxUnitsPerSide], the paths tile the perimeter
  /// (each inside it, each starting where the previous one ends) and every label ±k appears exactly once
  /// with equal lengths. Safe on any values (sidebands are read from archives).
  void check() const;
};

/// Equivalence classes of the boundary grid points of an n×n image: `representative[j*n + i]` is the
/// pixel that (i, j) is glued to (itself for interior pixels and unglued boundary pixels).
/// Precondition: (n − 1) is a multiple of units_per_side (the cut-nodes lie on grid points).
[[nodiscard]] std::vector<std::uint32_t> boundary_classes(const Sideband& sideband, std::uint32_t n);

/// The point of the square's perimeter that perimeter coordinate c is glued to by the sideband, both in
/// sides (0..4 counter-clockwise from (0, 0), as perimeter_point), or NaN where c lies on a path of the
/// original boundary (label 0).
[[nodiscard]] double glued_perimeter_coordinate(const Sideband& sideband, double c);

/// True where perimeter coordinate c (sides) is a cut-node: the start of a path of the sideband.
[[nodiscard]] bool is_cut_node(const Sideband& sideband, double c);

/// The surface point at perimeter coordinate c (sides) of the square boundary's polyline (the point the
/// geometry image's boundary samples take). Keeps a copy of what it needs.
[[nodiscard]] std::function<Vec3(double)> boundary_curve(const SquareBoundary& boundary);

struct GeometryImageOptions {
  std::uint32_t size{257};         ///< n; (n − 1) must be a multiple of units_per_side
  std::uint32_t normal_size{512};  ///< resolution of the normal map; 0 for none
  /// Where the n·n samples lie in the parameter square (row-major); empty for the uniform grid
  /// (i/(n−1), j/(n−1)). A boundary sample takes the boundary polyline at its perimeter coordinate, a
  /// glued one its canonical partner's value (sample_uv must glue mates to mirrored points).
  std::vector<Vec2> sample_uv;
};

struct GeometryImage {
  std::uint32_t size{0};
  std::vector<float> positions;  ///< n·n·3
  std::uint32_t normal_size{0};
  std::vector<float> normals;    ///< m·m·3 unit normals (empty if normal_size == 0)
  std::uint32_t color_size{0};
  std::vector<float> colors;     ///< n·n·3 in [0,1], sampled at the geometry resolution when the mesh has colours
  std::vector<float> sample_uv;  ///< n·n·2 parameter points of the samples (adaptive sampling); empty: uniform
  Sideband sideband;
};

/// Samples the parametrized disk `boundary.disk` with parameter coordinates `uv` (one per disk vertex,
/// boundary vertices at `boundary.boundary_uv`) on the regular grid. Interior grid points are located in
/// the parameter domain with Embree point queries on the flat parameter triangles; boundary grid points
/// are evaluated along the boundary polyline, and every grid point of a cut-path's mate copies the value of
/// its partner, so glued samples are bit-identical. Normals are the interpolated area-weighted vertex
/// normals of the original surface. Throws InvalidInput for a bad size.
[[nodiscard]] GeometryImage sample_geometry_image(const EmbreeDevice& device, const SquareBoundary& boundary,
                                                  std::span<const Vec2> uv, const GeometryImageOptions& options);

/// Sizes of the levels of detail of an n×n image that keep the cut-nodes on grid points: n, (n−1)/2 + 1,
/// ... down to units_per_side + 1.
[[nodiscard]] std::vector<std::uint32_t> lod_sizes(std::uint32_t n, std::uint32_t units_per_side);

/// Reconstructs a mesh from an n×n geometry image at level `level` (sub-sampling by 2^level): every 2×2
/// quad becomes two triangles split along the shorter 3D diagonal; with a sideband the image boundary is
/// fused (glued grid points become one vertex at their average), so a closed input gives a closed mesh.
/// Triangles that collapse under fusing are dropped; where the fused boundary folds around a cut tip, a
/// quad whose shorter diagonal would repeat its neighbour's triangle takes the other diagonal.
/// Throws InvalidInput for a bad level or size.
[[nodiscard]] TriMesh reconstruct_geometry_image(std::span<const float> positions, std::uint32_t n,
                                                 const Sideband* sideband, std::uint32_t level = 0);

}  // namespace gimforge
