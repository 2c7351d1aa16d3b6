#pragma once
/// \file raycast_impl.h
/// Internal to kernels/relief/: the state of a ReliefRaycaster (its per-map tables), shared by
/// raycast_tables.cpp (which builds them) and relief_raycast.cpp (which traces and renders with them).
/// Also the ray-level primitives of the march: a ray's segment in a cell (double precision) and the texels
/// read at a hit. Generic code only: raycast_avx2.cpp (compiled with -mavx2) must not include this header,
/// whose lookups have inline member functions with external linkage.
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "kernels/relief/raycast_march.h"
#include "kernels/relief/relief_map.h"
#include "kernels/relief/relief_raycast.h"

namespace gimforge {
namespace detail {

/// Linear cell index → grey cell index (−1: skip the cell), as a dense table.
struct DenseLookup {
  const std::int32_t* table;
  [[nodiscard]] std::int32_t find(std::uint32_t linear) const { return table[linear]; }
};

/// The same as an open-addressing hash (linear probing, load <= 1/2) of the grey cells.
struct HashLookup {
  static constexpr std::uint32_t kEmptyKey = 0xffffffffu;
  const std::uint32_t* keys;
  const std::int32_t* values;
  std::uint32_t mask;
  int shift;
  [[nodiscard]] std::uint32_t slot(std::uint32_t key) const { return (key * 0x9E3779B1u) >> shift; }
  [[nodiscard]] std::int32_t find(std::uint32_t linear) const {
    for (std::uint32_t s = slot(linear);; s = (s + 1) & mask) {
      const std::uint32_t k = keys[s];
      if (k == linear) return values[s];
      if (k == kEmptyKey) return -1;
    }
  }
};

/// A ray in grid coordinates (cell units, origin at the minimum corner of the bounding cube): the point
/// og + t · dg at world distance t along the unit direction `dir` from `org`. The ray crosses the plane
/// x_a = i at t = (i − og_a) · inv_a: the walk and the cell-order render compute every crossing with this
/// expression, so that both give a cell the same segment. An axis with dg_a = 0 keeps the one cell index
/// fixed_a (−1 where the ray runs outside the cube on that axis).
struct GridRay {
  Vec3 org, dir;
  double og[3], dg[3], inv[3];
  std::int64_t fixed[3];
};

/// The rays of the pixels of a screen tile (index (y − by) · kTile + x − bx), with their directions in grid
/// units and reciprocals also by axis (for 4 lanes at a time).
struct TileRays {
  std::array<GridRay, kTile * kTile> ray;
  alignas(32) double dg[3][kTile * kTile];
  alignas(32) double inv[3][kTile * kTile];
  std::array<std::uint8_t, kTile * kTile> zero_component;  ///< the direction has a zero component
};

/// What a hit at (u, v) of the layer at `base` reads, from one read of the 2×2 texels around (u, v): the
/// stored distance (unit cell) as the bilinear filter reads it (+inf where the deciding texel is empty),
/// for the wall test, and the stored normal, interpolated bilinearly over the non-empty texels of the 2×2
/// (the quantized normals need no scaling before the normalization); with no weight on them, any
/// non-empty texel of the 2×2, else the nearest non-empty texel within two texels; zero if none.
struct HitTexels {
  float stored;
  Vec3 normal;
};

// The ray-level primitives of relief_raycast.cpp, with internal linkage as those of raycast_march.h.
namespace {

/// The segment [t0, t1] (t0 >= 0) of ray r in the cell with coordinates idx, from lo[a] = idx[a] − og[a]
/// and hi[a] = idx[a] + 1 − og[a]; true when it has positive length.
[[gnu::always_inline]] inline bool cell_segment(const GridRay& r, const std::int64_t idx[3], const double lo[3],
                                                 const double hi[3], double& t0, double& t1) {
  double first = 0.0, last = kInf;
  for (int a = 0; a < 3; ++a) {
    if (r.dg[a] == 0.0) {
      if (idx[a] != r.fixed[a]) return false;
      continue;
    }
    const double p = lo[a] * r.inv[a], q = hi[a] * r.inv[a];
    first = std::max(first, std::min(p, q));
    last = std::min(last, std::max(p, q));
  }
  t0 = first;
  t1 = last;
  return last > first;
}

inline HitTexels read_hit_texels(const Texels& tx, std::uint32_t base, float u, float v) {
  const float x = u * tx.tm1, y = v * tx.tm1;
  const std::int32_t i0 = std::min(static_cast<std::int32_t>(x), tx.T - 2);
  const std::int32_t j0 = std::min(static_cast<std::int32_t>(y), tx.T - 2);
  const float fx = x - static_cast<float>(i0), fy = y - static_cast<float>(j0);
  const std::uint32_t first = base + static_cast<std::uint32_t>(j0 * tx.T + i0);
  const auto T = static_cast<std::uint32_t>(tx.T);
  const std::uint32_t texel[4] = {first, first + 1, first + T, first + T + 1};
  const std::uint32_t q[4] = {tx.dist[texel[0]], tx.dist[texel[1]], tx.dist[texel[2]], tx.dist[texel[3]]};
  HitTexels out{kInfF, Vec3::Zero()};
  if (std::max(std::max(q[0], q[1]), std::max(q[2], q[3])) == kEmptyTexel) {
    const std::uint32_t nearest = q[(fy < 0.5f ? 0 : 2) + (fx < 0.5f ? 0 : 1)];
    if (nearest != kEmptyTexel) out.stored = static_cast<float>(nearest) / tx.inv_scale;
  } else {
    const float lo = static_cast<float>(q[0]) + fx * (static_cast<float>(q[1]) - static_cast<float>(q[0]));
    const float hi = static_cast<float>(q[2]) + fx * (static_cast<float>(q[3]) - static_cast<float>(q[2]));
    out.stored = (lo + fy * (hi - lo)) / tx.inv_scale;
  }
  auto normal_at = [&](std::size_t t) {
    const std::int8_t* n = tx.normals + 3 * t;
    return Vec3(n[0], n[1], n[2]);
  };
  const double wx = static_cast<double>(x) - i0, wy = static_cast<double>(y) - j0;
  Vec3 sum = Vec3::Zero();
  double wsum = 0.0;
  for (int k = 0; k < 4; ++k) {
    if (q[k] == kEmptyTexel) continue;
    const double w = ((k & 1) ? wx : 1.0 - wx) * ((k & 2) ? wy : 1.0 - wy);
    sum += w * normal_at(texel[k]);
    wsum += w;
  }
  if (wsum > 0.0 && sum.squaredNorm() > 0.0) {
    out.normal = sum.normalized();
    return out;
  }
  for (int k = 0; k < 4; ++k) {  // zero weights only: any non-empty texel of the 2×2
    if (q[k] == kEmptyTexel) continue;
    out.normal = normal_at(texel[k]).normalized();
    return out;
  }
  double best = kInf;
  for (std::int32_t j = std::max(j0 - 2, 0); j <= std::min(j0 + 3, tx.T - 1); ++j)
    for (std::int32_t i = std::max(i0 - 2, 0); i <= std::min(i0 + 3, tx.T - 1); ++i) {
      const std::size_t t = base + static_cast<std::size_t>(j * tx.T + i);
      if (tx.dist[t] == kEmptyTexel) continue;
      const double di = static_cast<double>(i) - static_cast<double>(x);
      const double dj = static_cast<double>(j) - static_cast<double>(y);
      const double d2 = di * di + dj * dj;
      if (d2 < best) {
        best = d2;
        out.normal = normal_at(t);
      }
    }
  if (out.normal.squaredNorm() > 0.0) out.normal.normalize();
  return out;
}

}  // namespace
}  // namespace detail

struct ReliefRaycaster::Impl {
  using CellData = detail::CellData;
  using CellSegment = detail::CellSegment;
  using GridRay = detail::GridRay;
  using Side = detail::Side;

  const ReliefMap& map;
  RaycastOptions options;
  std::vector<CellData> cells;
  // Lookup: dense table, or hash keys / values.
  bool dense{true};
  /// The cells are marched 8 samples at a time (march_avx2).
  bool avx2{false};
  std::vector<std::int32_t> table;
  std::vector<std::uint32_t> keys;
  std::vector<std::int32_t> values;
  std::uint32_t hash_mask{0};
  int hash_shift{0};
  detail::Texels texels{};
  double inv_cs{0.0};
  double steps_per_unit{0.0};  ///< linear samples per world unit of ray in a cell
  double min_steps{1.0};       ///< linear samples at least, in any cell
  /// The grey cells whose maps hold samples, with their grid coordinates (what the cell-order render draws).
  struct UsefulCell {
    std::int32_t g;
    std::int32_t idx[3];
  };
  std::vector<UsefulCell> useful_cells;
  float wall_tolerance{0.0f};  ///< unit-cell distance between hit and stored surface beyond which a hit is a wall

  // The tables (raycast_tables.cpp).
  Impl(const ReliefMap& m, const RaycastOptions& o);
  void set_min_heights(CellData& c, const CellProjection& p, const std::uint16_t (&face_qmin)[6]) const;
  [[nodiscard]] Side side_of(std::size_t g, const float p[3]) const;
  [[nodiscard]] int inside_at(std::size_t g, const float p[3]) const;
  void resolve_interior_cells();

  // Tracing and rendering (relief_raycast.cpp). Declared inline, as they were when defined in the class.
  // With external linkage (their types were in an anonymous namespace before the split) GCC stopped
  // inlining set_up_rays into the tile loop as a function called once: it is always inlined.
  [[nodiscard]] inline GridRay grid_ray(const Vec3& org, const Vec3& dir) const;
  inline bool prepare_segment(const GridRay& r, const CellData& c, const std::int64_t idx[3], double t0, double t1,
                              CellSegment& seg) const;
  [[nodiscard]] inline RayHit make_hit(const GridRay& r, std::int32_t g, const CellSegment& seg, double t0) const;
  template <class Lookup, ReliefFilter F, bool V>
  inline RayHit trace(const Lookup& lookup, const Vec3& org, const Vec3& dir, std::uint64_t& samples) const;
  template <bool V>
  [[gnu::always_inline]] inline void set_up_rays(const Camera& camera, const GridRay& eye, std::uint32_t bx,
                                                 std::uint32_t by, std::uint32_t bx1, std::uint32_t by1,
                                                 detail::TileRays& tile) const;
  template <ReliefFilter F, bool V>
  inline bool render_cells(const Camera& camera, RenderImage& img, std::vector<std::uint8_t>& walls) const;
  template <class Fn>
  inline decltype(auto) dispatch(const Fn& fn) const;
};

}  // namespace gimforge
