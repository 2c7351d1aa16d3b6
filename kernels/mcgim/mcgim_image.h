#pragma once
/// \file mcgim_image.h
/// The multi-chart geometry image (Sander et al. 2003, §3): a W × H grid of 3D samples, some of them
/// undefined (outside every chart), and its reconstruction rules: for each 2×2 quad of samples, fewer than
/// three defined give no face, exactly three give one triangle, four give two triangles split along the
/// shorter diagonal (in 3D). Zippered samples (zipper.h) are unified: every defined sample names the
/// representative sample of its cluster, and the reconstruction makes one vertex per cluster, so charts
/// that meet on the surface share their boundary vertices (a watertight mesh for a closed input).
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "kernels/core/mesh.h"

namespace gimforge {

inline constexpr std::uint32_t kNoChart = 0xffffffffu;
inline constexpr std::uint32_t kNoSample = 0xffffffffu;

struct MultiChartImage {
  std::uint32_t width{0};
  std::uint32_t height{0};
  /// height × width × 3, row-major (row y, column x; row 0 is the bottom row of the packing), float32; NaN
  /// where undefined.
  std::vector<float> positions;
  std::vector<std::uint8_t> mask;      ///< height × width: 1 where the sample is defined
  std::vector<std::uint32_t> chart;    ///< height × width: the chart of a defined sample, kNoChart elsewhere
  /// height × width: the representative sample (y·width + x) of each defined sample's unified cluster —
  /// itself when the sample is not unified with another; kNoSample where undefined. A representative is
  /// its own representative, and every sample of a cluster has the representative's position.
  std::vector<std::uint32_t> unified;
  /// Optional: the split of every pinned quad (pinned_quads), one bit each in the quads' row-major order,
  /// least significant bit first, padding bits 0: 1 splits along (x + 1, y)–(x, y + 1), 0 along
  /// (x, y)–(x + 1, y + 1). Empty: the shorter diagonal everywhere. A lossily coded image carries the
  /// encoder's splits (zipper_diagonal_bits): whether the faces of a pinned quad cancel or meet other faces
  /// depends on its diagonal, so a split re-chosen from decoded positions could change the reconstruction's
  /// topology (a pinched-off closed piece, a flap). Every other quad may flip freely: either split
  /// triangulates the same four distinct vertices, over a diagonal edge no other face has.
  std::vector<std::uint8_t> zipper_diagonals;

  [[nodiscard]] std::size_t samples() const { return std::size_t{width} * height; }
  [[nodiscard]] std::size_t defined_samples() const;
  /// Distinct clusters among the defined samples: the vertices of the reconstruction before unused ones go.
  [[nodiscard]] std::size_t unique_vertices() const;
};

/// The quads (x, y)–(x + 1, y + 1), index y·(width − 1) + x, whose split can change the reconstruction's
/// topology, from the mask and the zipper alone: four defined samples that are not four distinct clusters,
/// or a diagonal whose two clusters are also corners together of another quad (of three or four defined
/// samples). 1 for those, 0 elsewhere; empty for an image narrower or lower than 2.
[[nodiscard]] std::vector<std::uint8_t> pinned_quads(const MultiChartImage& image);
/// The split the reconstruction makes of every pinned quad now (the stored bits where there are, else the
/// shorter diagonal of the positions), packed as `zipper_diagonals`; empty when no quad is pinned.
[[nodiscard]] std::vector<std::uint8_t> zipper_diagonal_bits(const MultiChartImage& image);

/// Checks an image read from elsewhere: sizes agree (positions 3·W·H, the others W·H), defined samples are
/// finite and undefined ones NaN, every defined sample names a defined representative that is its own
/// representative and holds the same position, undefined samples name kNoSample and no chart, and
/// `zipper_diagonals`, when given, holds one bit per pinned quad. Throws FormatError "<where>: <what is wrong>".
void check_multichart_image(const MultiChartImage& image, std::string_view where);

/// The checks of check_multichart_image that do not look at the positions (sizes, mask values, charts,
/// clusters): what a reader must know before it decodes positions with them. Throws FormatError.
void check_multichart_structure(const MultiChartImage& image, std::string_view where);

/// The reconstruction of §3 (see the file comment; pinned quads split as `zipper_diagonals` says when it is
/// given): one vertex per cluster that some face uses (in the
/// order of the representatives' sample indices), faces counter-clockwise in (column, row) order; faces
/// whose corners fall into fewer than three clusters (zipper degenerates) are dropped, and so are zipper
/// folds (two faces over the same three clusters facing each other: both go; same-facing copies: one stays);
/// a cluster whose faces form several fans (a zipper pinch) becomes one vertex per fan. `vertex_sample`
/// then names the same representative for each copy. `vertex_sample`, when
/// given, receives the representative sample of every vertex.
[[nodiscard]] TriMesh reconstruct_multichart(const MultiChartImage& image,
                                             std::vector<std::uint32_t>* vertex_sample = nullptr);

/// Splits every non-manifold vertex (fans of faces touching only at it) into one vertex per fan.
/// `source_vertex`, when given, receives for every output vertex the input vertex it copies.
[[nodiscard]] TriMesh split_nonmanifold_vertices(const TriMesh& mesh, std::vector<std::uint32_t>* source_vertex = nullptr);

/// The faces of the reconstruction over the clusters' representatives, for `positions` given per
/// representative in `vertex_sample` order (the triangulator of the geometry-image optimization:
/// diagonals re-chosen from the moved positions). `vertex_of_sample` maps a representative sample to its
/// vertex (kNoSample for the others).
[[nodiscard]] std::vector<Face> triangulate_multichart(const MultiChartImage& image,
                                                       std::span<const std::uint32_t> vertex_of_sample,
                                                       std::span<const Vec3> positions);

/// Per-sample normals for rendering (§3): the normalized cross product of central differences, an undefined
/// neighbour replaced by the sample itself; height × width × 3 float32, NaN where undefined or degenerate.
[[nodiscard]] std::vector<float> multichart_normals(const MultiChartImage& image);

}  // namespace gimforge
