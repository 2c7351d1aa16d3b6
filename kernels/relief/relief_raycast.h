#pragma once
/// \file relief_raycast.h
/// Ray casting of relief maps on cubic cell complexes (Apaza & Andújar, §3.5.2) on the CPU. The camera,
/// the shading and the image types are in render_camera.h; the Embree reference renderer of the original
/// mesh and the comparison of two renders in mesh_render.h.
///
/// **The ray caster.** A viewing ray is clipped to the bounding cube of the map and walks the grid cells
/// it crosses in order (3D DDA, Amanatides & Woo); cells that are not grey (and grey cells whose maps hold
/// no surface sample) are skipped through a lookup table built once per ReliefRaycaster (a dense n³
/// table for n <= 160, an open-addressing hash of the grey cells above). Inside a grey cell the ray is
/// sampled with a *linear search*: a segment of length s inside the cell gets
/// max(ceil(linear_steps / 2), ceil(s / cell_size · linear_steps)) equally spaced samples, the last one at
/// the cell exit (at least half the steps even for a short segment, so that rays grazing an edge or a
/// corner of the object still find it). Border cells whose segment cannot reach the cell's smallest stored
/// distance (a bound of the projected distance along the segment, per projection type) are skipped, and
/// so are the samples that cannot reach the smallest stored distance of any face they may project onto
/// (the projected distance is at most the height above the face times a per-face constant, and the
/// heights are linear along the segment) and those projected nearer to their face than its smallest
/// stored distance. These bounds are conservative: RaycastOptions::cull_empty_space = false renders the
/// same image with more inside tests.
/// Every sample P is projected with the cell's projection
/// (relief_projection.h) onto a domain face: P' at face coordinates (u, v), and the projected distance
/// |P − P'|. P is *inside* when that distance is at least the stored distance at (u, v) (the surface lies
/// between P and the face); an empty texel (kEmptyTexel: no surface on that projection segment) is
/// outside. The crossing between the first inside sample and the previous sample (or the cell entry
/// point) is then *refined* by binary_steps halvings (binary search); the hit is the middle of the last
/// interval. Where the CPU has AVX2 (RaycastOptions::vectorized), the linear samples of a cell are tested
/// 8 at a time per ray, and renders refine the crossings of a cell 8 at a time, one ray per lane; every
/// lane performs the scalar operations in the same order, so that both paths give the same image. At the hit, the stored normals of the 2×2 texels around (u, v) are
/// interpolated bilinearly (empty texels left out, weights renormalized) and normalized.
///
/// *Interior grey cells* (case 6) project onto internal faces, which may lie inside or outside the
/// object, so "beyond the stored surface" does not mean inside there. Such a cell projects from its
/// centre C; a sample between the face and the stored surface lies on the other side of the surface than
/// C, any other sample on C's side. Whether C is inside is decided once per ray caster, by votes of the
/// texels of the cell's faces whose side is known from the neighbouring cell (black: inside; a border
/// cell or a decided interior cell: its own test) — with one surface crossing on a segment, an empty
/// texel puts C on the side of the face point, a sample on the other side. The rare interior cells left
/// undecided use any change of side along the ray as the crossing.
///
/// *Walls.* Where the surface runs along the projection rays (a depth discontinuity of the map, e.g.
/// the side of a step seen through a parallel projection), the texels hold another surface and the hit
/// is found where the stored distance jumps; the stored normal there belongs to the other surface. Such
/// hits are flagged (RayHit::discontinuity), and render() replaces their normal by the normal of the
/// rendered surface from the world positions of the neighbouring pixels (RaycastOptions::wall_normals).
///
/// Stored distances are read with ReliefFilter::Bilinear (the default): bilinear interpolation of the 2×2
/// texels around (u, v) (texel (i, j) samples (i / (T − 1), j / (T − 1)), so x = u · (T − 1)); where one of
/// the 2×2 texels is empty, the nearest texel alone decides (outside when it is empty), so interpolation
/// never crosses an empty texel. ReliefFilter::Nearest always uses the nearest texel.
///
/// **Renders** draw the cells as the paper's GPU renderer does (it rasterizes the front faces of the grey
/// cells and marches each fragment's ray inside its cell): RenderTraversal::CellOrder bins the cells
/// with samples into 16 × 16-pixel screen tiles by the bounds of their projections, in the order of the
/// grid (Manhattan) distance of their coordinates from the eye's cell, which grows by one with every cell a
/// ray from the eye enters, so that along every ray the cells come in the order the walk meets them. Each
/// tile marches, per cell, the pixels of the cell's rectangle that have no hit yet, over the segment of
/// their ray in the cell computed exactly as the walk computes it: the same cells, segments, hits and
/// inside-test counts as walking every pixel's ray (RenderTraversal::Walk), without the walk through empty
/// cells, with the texels of a cell read by neighbouring rays together, and with the rays of a cell sharing
/// vector work (with AVX2: 4 pixels' segments clipped and bounded at once, the linear searches of 4 rays in
/// lockstep, two of them interleaved, the refinements of 8 crossings in one vector).
///
/// The inner loop runs in single precision in unit-cell coordinates relative to the cell being walked
/// (no allocation, no virtual calls, the projection type dispatched once per cell); the ray set-up, the
/// cell segments and the DDA are in double precision. Renders are multi-threaded (TBB, screen tiles or
/// tiles of rows); results do not depend on the number of threads.
#include <cstdint>
#include <memory>

#include "kernels/core/mesh.h"
#include "kernels/relief/relief_map.h"
#include "kernels/relief/render_camera.h"

namespace gimforge {

/// The bounding box of the surface points stored in a relief map (texel_surface_point of every non-empty
/// texel): what orbit_camera frames when only the map is at hand (within a texel of the mesh's box).
/// An empty box when no texel holds a sample.
[[nodiscard]] BoundingBox relief_surface_bounds(const ReliefMap& map);

/// How stored distances are read between texels (see the file comment).
enum class ReliefFilter : std::uint8_t { Nearest, Bilinear };

/// How ReliefRaycaster::render() finds the grey cells that each pixel's ray crosses (see the file comment).
enum class RenderTraversal : std::uint8_t {
  /// The paper's order (§3.5.2 draws the front faces of the grey cells): the cells are binned into screen
  /// tiles by their projected bounds and visited front to back; each pixel marches the cells its ray
  /// crosses until the first hit.
  CellOrder,
  /// Every pixel's ray walks the grid as trace() does.
  Walk,
};

/// Options of the relief ray caster.
struct RaycastOptions {
  /// Linear-search samples per cell side length of ray (at least half of them in every cell), 1..1024.
  std::uint32_t linear_steps{12};
  /// Refinement of the first inside sample: halvings of its interval (binary search), 0..32.
  std::uint32_t binary_steps{6};
  ReliefFilter filter{ReliefFilter::Bilinear};
  double ambient{0.15};            ///< shade_grey's ambient term, 0..1
  /// render(): replace the stored normal of wall hits (RayHit::discontinuity) by the normal of the
  /// rendered surface, from the positions of the neighbouring pixels (see the file comment).
  bool wall_normals{true};
  /// Skip the inside tests of samples that the smallest stored distance of their cell and face proves to
  /// be outside (whole segments through a cell, their ends, single samples before any stored surface).
  /// The bounds are conservative: the image is the same either way, only the inside-test count differs.
  bool cull_empty_space{true};
  /// Test the samples of a cell 8 at a time with AVX2 where the CPU has it (chosen at run time). The lanes
  /// perform the scalar operations in the same order: the image and the test count are the same either
  /// way (ReliefRaycaster::vectorized() tells which path runs).
  bool vectorized{true};
  /// How render() finds the cells of a pixel's ray. Both give the same image and test count; CellOrder
  /// falls back to Walk for a camera whose axes are degenerate or whose eye is absurdly far (> 2^40 cells).
  RenderTraversal traversal{RenderTraversal::CellOrder};
};

/// The relief-map ray caster: per-map tables (cell lookup, per-cell projection data in single precision,
/// layer offsets) built once, then any number of rays and renders, concurrently. The map must outlive it
/// and stay unchanged.
class ReliefRaycaster {
 public:
  /// Builds the tables. Throws InvalidInput for options out of range or a map that fails
  /// ReliefMap::check() (checked here because the caster indexes the maps without bounds checks).
  explicit ReliefRaycaster(const ReliefMap& map, const RaycastOptions& options = {});
  ~ReliefRaycaster();
  ReliefRaycaster(ReliefRaycaster&&) noexcept;
  ReliefRaycaster& operator=(ReliefRaycaster&&) noexcept;
  ReliefRaycaster(const ReliefRaycaster&) = delete;
  ReliefRaycaster& operator=(const ReliefRaycaster&) = delete;

  /// Traces one ray; `direction` need not be unit (it is normalized), t is a world distance.
  [[nodiscard]] RayHit trace(const Vec3& origin, const Vec3& direction) const;
  /// Renders the view of `camera` (multi-threaded; RaycastOptions::traversal chooses how, not what).
  [[nodiscard]] RenderImage render(const Camera& camera) const;
  [[nodiscard]] const RaycastOptions& options() const;
  /// Whether the cells are marched with AVX2 (RaycastOptions::vectorized and a CPU that has it).
  [[nodiscard]] bool vectorized() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// ReliefRaycaster(map, options).render(camera).
[[nodiscard]] RenderImage raycast_relief(const ReliefMap& map, const Camera& camera,
                                         const RaycastOptions& options = {});

}  // namespace gimforge
