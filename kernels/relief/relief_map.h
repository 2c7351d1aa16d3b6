#pragma once
/// \file relief_map.h
/// Relief maps on cubic cell complexes (Apaza & Andújar): construction (§3.3: grey cells, sampling of
/// distance / normal / colour maps, choice of the grid size), the representation (§3.4) and the
/// geometry-based reconstruction (§3.5.1). Cell classification is relief_cells.h, the projections
/// relief_projection.h, ray casting relief_raycast.h.
///
/// **Texels.** Every domain face carries a T×T texture. Texel (i, j) samples the face point at face
/// coordinates (u, v) = (i / (T − 1), j / (T − 1)): the texels include the face's edges and corners, so
/// the domain faces of one cell share their border samples and the 2×2 texel quads of reconstruction
/// cover each face completely (as geometry images sample their boundary).
///
/// **Sampling (§3.3.2).** For the texel's face point P', the projection ray (relief_projection.h,
/// projection_ray) runs from P' back into the cell to the centre / axis / plane / opposite face; every
/// point of the cell projecting onto P' lies on that segment, [0, length]. The nearest surface point on the
/// segment (smallest distance |P − P'|) is stored, as the paper's depth test keeps the closest fragment.
/// As on the paper's GPU, each grey cell "renders" only its own triangles (CellGrid::grey_triangles) onto
/// each of its domain faces: a triangle is clipped to the cell, the projection of the clipped polygon
/// onto the face bounds a rectangle of texels, and the segment of every texel in the rectangle is
/// intersected exactly (double precision) with the triangle. The distance is quantized to 16 bits,
/// d ≈ q · scale with scale = √3 · cell_size / 65534 (q = 65535 = kEmptyTexel: the segment meets no
/// surface); the unit normal of the hit triangle (as the mesh orients it: counter-clockwise faces seen
/// from their front) is stored as three signed 8-bit components, and the colour (vertex colours
/// interpolated at the hit) as RGB8 when the mesh has colours. Every further hit on the same segment is an
/// *occluded sample* (a surface point that maps to an already covered texel); hits within 1e-9 · cell_size
/// of the nearest one (the same point reached through a shared edge or vertex, duplicated faces) are not.
/// A texel with a hit counts 1 + its occluded hits as samples.
///
/// **Grid size (§3.3.3).** With ReliefOptions::grid == 0 the construction starts at N = 1 and doubles N
/// while the ratio occluded samples / all samples exceeds occlusion_threshold, up to max_grid.
#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"
#include "kernels/relief/relief_cells.h"
#include "kernels/relief/relief_projection.h"

namespace gimforge {

/// Quantized distance of a texel whose projection segment meets no surface.
inline constexpr std::uint16_t kEmptyTexel = 0xffff;
/// Largest quantized distance of a surface sample.
inline constexpr std::uint16_t kMaxQuantizedDistance = 0xfffe;

/// Quantization step of the distances of cells of size `cell_size`: √3 · cell_size / 65534, so that the
/// longest projection segment maps to kMaxQuantizedDistance.
[[nodiscard]] inline double distance_scale_for(double cell_size) {
  return kMaxProjectionLength * cell_size / static_cast<double>(kMaxQuantizedDistance);
}
/// round(d / scale) clamped to [0, kMaxQuantizedDistance]; d must be finite and >= 0, scale > 0.
[[nodiscard]] std::uint16_t quantize_distance(double d, double scale);
/// q · scale. Precondition: q != kEmptyTexel.
[[nodiscard]] inline double dequantize_distance(std::uint16_t q, double scale) { return q * scale; }

/// Options of build_relief_map.
struct ReliefOptions {
  std::uint32_t grid{0};              ///< N cells per axis, 1..1024; 0 = choose automatically (§3.3.3)
  std::uint32_t max_grid{32};         ///< N_max of the automatic choice (a power of two is reached by doubling)
  double occlusion_threshold{0.01};   ///< automatic choice: stop doubling once occluded / all samples <= this
  std::uint32_t texture{64};          ///< T: texels per side of every domain-face texture, 2..1024
  double padding{1e-3};               ///< relative enlargement of the bounding cube (CellGridOptions)
  InsideTest inside_test{InsideTest::Automatic};
  /// The memory the caller can give the maps (0: no bound): a level whose texels need more (about 4 bytes
  /// each while they are sampled) is refused with InvalidInput once its cells are known, before sampling.
  std::uint64_t max_map_bytes{0};
  ProgressCallback progress{};        ///< stages "relief cells", "relief sampling"
};

/// One level tried by the automatic grid choice.
struct ReliefGridLevel {
  std::uint32_t n{0};
  std::size_t grey_cells{0};
  std::size_t domain_faces{0};
  std::uint64_t samples{0};           ///< surface points found on all projection segments (hits)
  std::uint64_t occluded{0};          ///< hits behind the nearest one on their segment
  std::uint64_t faces{0};             ///< faces of positive area whose centroid lies in a grey cell
  std::uint64_t edge_on{0};           ///< of those, the ones their cell's projection sees edge-on (EdgeOnCounts)
  [[nodiscard]] double occlusion_ratio() const {
    return samples == 0 ? 0.0 : static_cast<double>(occluded) / static_cast<double>(samples);
  }
  [[nodiscard]] double edge_on_ratio() const {
    return faces == 0 ? 0.0 : static_cast<double>(edge_on) / static_cast<double>(faces);
  }
};

/// Beyond this share of the faces seen edge-on, the automatic grid choice doubles N whatever the occlusion:
/// such a surface is nearly invisible to its projections (a flat mesh through the centre of its one cell,
/// a thin needle along the projection rays), has few samples and hence no occlusion, and its map
/// collapsed (14 dB).
inline constexpr double kEdgeOnRatioLimit = 0.5;
/// A face is seen edge-on when |cos| of the angle between its normal and the projection direction at its
/// centroid is below this (within 5.7° of edge-on).
inline constexpr double kEdgeOnCosine = 0.1;

/// The representation (§3.4): the grey-cell table, one layer per domain face, and the per-texel maps.
struct ReliefMap {
  std::uint32_t n{0};                 ///< grid cells per axis
  Vec3 origin{Vec3::Zero()};          ///< minimum corner of the bounding cube
  double cell_size{0.0};
  std::uint32_t texture{0};           ///< T
  double distance_scale{0.0};         ///< world units per quantization step

  /// Grey cells, in increasing linear index (k·n + j)·n + i.
  std::vector<std::uint32_t> cells;
  std::vector<std::uint8_t> external_faces;    ///< per grey cell, CellFace bits (0: interior grey)
  std::vector<CellProjection> projections;     ///< per grey cell, cell_projection(external_faces[g])
  /// Per grey cell plus one: the layers of cell g are first_layer[g] .. first_layer[g + 1] − 1, one per
  /// domain face in increasing face index.
  std::vector<std::uint32_t> first_layer;
  std::vector<std::uint8_t> layer_face;        ///< per layer: face index 0..5 (CellFace bit index)
  std::vector<std::uint32_t> layer_cell;       ///< per layer: its grey cell g

  /// layers × T × T quantized distances; texel (i, j) of layer l at (l·T + j)·T + i (i along u).
  std::vector<std::uint16_t> distances;
  /// layers × T × T × 3 unit normals as snorm8 (component = value / 127); zero at empty texels.
  std::vector<std::int8_t> normals;
  /// layers × T × T × 3 RGB8 colours when the mesh has vertex colours, else empty.
  std::vector<std::uint8_t> colors;

  // Construction report.
  std::vector<ReliefGridLevel> levels;         ///< every grid tried (one when the grid was given)
  std::string inside_method;                   ///< CellGrid::inside_method of the chosen grid
  bool watertight_inside_test{true};
  std::size_t white_cells{0};
  std::size_t black_cells{0};
  double seconds_cells{0.0};                   ///< classification, all levels
  double seconds_sampling{0.0};                ///< sampling, all levels

  [[nodiscard]] std::size_t num_layers() const { return layer_face.size(); }
  [[nodiscard]] std::size_t texels_per_layer() const { return static_cast<std::size_t>(texture) * texture; }
  /// Storage of the representation in bytes: distances (2 per texel), normals (3), colours (3 if any),
  /// and the cell table (4 + 1 bytes per grey cell).
  [[nodiscard]] std::size_t storage_bytes() const;
  /// Minimum corner of grey cell g in world coordinates.
  [[nodiscard]] Vec3 cell_min(std::size_t g) const;
  /// World position of a unit-cell point of grey cell g.
  [[nodiscard]] Vec3 to_world(std::size_t g, const Vec3& local) const { return cell_min(g) + cell_size * local; }
  /// Face coordinate of texel index i (0..T−1): i / (T − 1).
  [[nodiscard]] double texel_coord(std::uint32_t i) const { return static_cast<double>(i) / (texture - 1); }
  /// Linear index of texel (i, j) of layer l in `distances` (times 3 for normals and colours).
  [[nodiscard]] std::size_t texel_index(std::size_t l, std::uint32_t i, std::uint32_t j) const {
    return (l * texture + j) * texture + i;
  }
  /// The surface point stored at texel (i, j) of layer l, in world coordinates. Precondition: not empty.
  [[nodiscard]] Vec3 texel_surface_point(std::size_t l, std::uint32_t i, std::uint32_t j) const;
  /// Throws InvalidInput naming the first inconsistency (array sizes, indices, layer order, projections
  /// that do not match external_faces, non-finite geometry) — for maps read from files.
  void check() const;
};

/// Checks the options build_relief_map takes (the same messages), without a mesh.
void check_relief_options(const ReliefOptions& options);

/// The automatic grid choice (§3.3.3): the grid to try after `level`, or 0 when `level` is the one to keep
/// (a given grid, N_max reached, or the occlusion ratio at or below the threshold and at most
/// kEdgeOnRatioLimit of the faces seen edge-on).
[[nodiscard]] std::uint32_t next_relief_grid(const ReliefOptions& options, const ReliefGridLevel& level);

/// Sets the cell table of `map` (n, origin, cell size, texture, grey cells, projections, layers, the
/// white / black counts and the inside method) from a classified grid; the texel arrays are left alone.
/// Throws InvalidInput when the layers would exceed 2³¹ texels.
void set_relief_layout(ReliefMap& map, const CellGrid& grid, std::uint32_t texture);

/// ReliefGridLevel::faces / edge_on of a map's layout for the faces of `part` (all of a mesh, or the faces
/// one process owns: the counts of disjoint parts add up). Deterministic (integer counts).
struct EdgeOnCounts {
  std::uint64_t faces{0};
  std::uint64_t edge_on{0};
};
[[nodiscard]] EdgeOnCounts count_edge_on_faces(const ReliefMap& layout, MeshView part);

/// Hit counts of one sampling pass (ReliefGridLevel::samples / occluded).
struct ReliefSampleCounts {
  std::uint64_t samples{0};   ///< per non-empty texel: 1 (its nearest surface point) + its occluded hits
  std::uint64_t occluded{0};  ///< hits farther than the nearest one on their segment
};

/// Relief maps of a mesh whose faces are split into parts held by different processes (jobs/brick_relief.h),
/// made equal to build_relief_map's: each part reports every surface point its faces put on a projection
/// segment (sample_relief_hits); the hits of all parts, sorted by texel and then by face, replay the
/// sampler's depth test in the order one process meets them (resolve_relief_hits).
struct ReliefHit {
  std::uint64_t texel{0};              ///< layer · T² + texel index within the layer
  std::uint64_t face{0};               ///< the face's index in the whole mesh
  double tau{0.0};                     ///< segment parameter of the hit
  double length{0.0};                  ///< length of the segment as this hit's test computed it
  std::array<std::int8_t, 3> normal{};  ///< the face's unit normal as snorm8
  std::array<std::uint8_t, 5> unused{};  ///< zero: the hits travel between processes as bytes
};
static_assert(sizeof(ReliefHit) == 40, "ReliefHit has no padding: every byte sent is initialized");

/// Every hit of the faces of `part` (face f is face face_ids[f] of the whole mesh) on the segments of the
/// layers of `layout` (set_relief_layout of `grid`, the part's finish_cell_grid), in an order that depends
/// only on the inputs (not on the threads): sort them by texel and face to resolve them. Throws
/// InvalidInput when the sizes disagree.
[[nodiscard]] std::vector<ReliefHit> sample_relief_hits(const ReliefMap& layout, MeshView part, const CellGrid& grid,
                                                        std::span<const std::uint64_t> face_ids);

/// Fills the distances and normals of `map` (sized from its layout; no colours) from the hits of every part,
/// sorted by texel and then by face, and returns the counts: bit for bit what build_relief_map samples for
/// the whole mesh. Throws InvalidInput for hits out of range or out of order.
[[nodiscard]] ReliefSampleCounts resolve_relief_hits(ReliefMap& map, std::span<const ReliefHit> hits);

/// Builds the relief map of `mesh` (§3.3). Multi-threaded (TBB). Throws InvalidInput for the inputs
/// classify_cells rejects, texture outside 2..1024, grid > 1024, max_grid outside 1..1024, a negative or
/// non-finite occlusion_threshold, or a layer count whose maps would exceed 2³¹ texels; LibraryError when
/// OpenVDB fails; Cancelled through options.progress. The maps do not depend on the number of threads.
[[nodiscard]] ReliefMap build_relief_map(const TriMesh& mesh, const ReliefOptions& options = {});

/// Geometry-based reconstruction (§3.5.1): every texel with a surface sample becomes a vertex (the
/// stored point texel_surface_point), every 2×2 texel quad whose four texels are non-empty two triangles
/// (split along the shorter diagonal), oriented so that their normals agree with the stored normals.
/// Quads whose diagonal is longer than `max_edge_texels` texel spacings (a depth discontinuity between
/// separate surface parts) are dropped. Vertex normals are the stored normals. Texels no kept triangle uses
/// are left out: every vertex is a corner of a face.
[[nodiscard]] TriMesh reconstruct_relief(const ReliefMap& map, double max_edge_texels = 8.0);

}  // namespace gimforge
