#pragma once
/// \file raycast_march.h
/// Internal to kernels/relief/: the per-cell data of the relief ray caster and the scalar march
/// (empty-space bounds, projection, texel side tests, crossing flags, linear search and refinement), in
/// single precision and unit-cell coordinates. Included by relief_raycast.cpp and raycast_tables.cpp
/// (generic code) and by raycast_avx2.cpp, which is compiled with -mavx2 (see kernels/CMakeLists.txt).
///
/// Linkage rule of this header: the types are plain data (no member functions), and every function is in
/// an anonymous namespace, so each translation unit gets its own copy with internal linkage. An inline
/// function with external linkage would be a COMDAT symbol: the copy compiled with -mavx2 in
/// raycast_avx2.cpp could be the one the linker keeps for the generic callers, which would then execute
/// AVX2 instructions on a CPU without them. Keep it that way when adding code here (a member function or
/// an inline function outside the anonymous namespace breaks it); `nm -C --defined-only` on
/// raycast_avx2.cpp.o must list no weak symbols but the march_avx2 instantiations.
///
/// Every translation unit that includes this header is compiled with -ffp-contract=off, so that the scalar
/// and the vector march round identically (no fused multiply-add).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "kernels/relief/relief_map.h"
#include "kernels/relief/relief_raycast.h"

namespace gimforge::detail {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr float kInfF = std::numeric_limits<float>::infinity();
/// Side of the square screen tiles of the cell-order render, in pixels.
constexpr std::uint32_t kTile = 16;
/// "No layer": the face is not a domain face of the cell.
constexpr std::uint32_t kNoLayer = 0xffffffffu;

/// One grey cell as the inner loop needs it (40 bytes).
struct CellData {
  float point[3];                 ///< projection point (unit cell)
  std::uint8_t type;              ///< ProjectionType
  std::uint8_t axis;              ///< parallel / planar: axis of the direction / plane normal; axial: the axis
  std::uint8_t side;              ///< parallel: 1 when the direction of projection is +e_axis
  std::uint8_t mode;              ///< CellMode
  std::uint32_t layer_base[6];    ///< per face: first texel of its layer (l · T²), or kNoLayer
  /// Border cells: the smallest stored distance of the cell (unit cell); a segment along which the projected
  /// distance stays below it cannot meet the surface. Negative (no culling) for interior cells.
  float min_dist;
  /// Perspective: the largest distance from the centre of projection to the cell; axial: from the axis.
  float reach;
  /// Border cells, per face f: a sample at distance h from the plane of f that projects onto f lies at
  /// projected distance at most h · k_f (k_f = 1 for parallel and planar projections; perspective and
  /// axial: the largest 1 / cos of the angle between a projection direction onto f and the normal of f),
  /// so it can only be inside when h >= (smallest stored distance of f) / k_f, which is min_height[f].
  /// +inf for faces no sample projects onto or whose maps are empty, 0 where nothing bounds (interior
  /// cells, a centre on the plane of f).
  float min_height[6];
  /// Per face: the smallest quantized distance of its layer (65535 when it has none or only empty texels).
  /// A sample projected onto f at a smaller distance is before every stored surface sample of f.
  float face_qmin[6];
};

/// How the samples of a cell are classified (see sample_flag).
enum CellMode : std::uint8_t {
  kBorderCell = 0,        ///< border grey: domain faces are external (outside the object)
  kInteriorOutside = 1,   ///< interior grey whose centre of projection is outside the object
  kInteriorInside = 2,    ///< interior grey whose centre of projection is inside the object
  kInteriorRelative = 3,  ///< interior grey, centre undecided: any change of side along the ray
};

/// The samples s in [0, len] of the segment e + s · dl through a border cell that may be inside the object,
/// from CellData::min_height: those with s <= first_end or s >= last_begin (the heights above the faces are
/// linear in s, so each face allows a prefix or a suffix of the segment). Samples strictly between the two
/// are outside and need no inside test.
struct MayRange {
  float first_end;
  float last_begin;
};

/// What the inside test needs of the distance maps.
struct Texels {
  const std::uint16_t* dist;
  const std::int8_t* normals;
  std::int32_t T;
  float tm1;        ///< T − 1
  float inv_scale;  ///< unit-cell distance → quantization steps
};

/// A sample projected onto a domain face.
struct Projected {
  int face;
  float u, v, dist;
};

/// One ray's segment through a cell as the march takes it: the entry point e and the direction dl in
/// unit-cell coordinates, the length len (in t) with `steps` linear samples, and the part that may be
/// inside (may_range). `hit` receives the parameter of the crossing in [0, len], or −1.
struct CellSegment {
  float e[3], dl[3];
  float len;
  std::uint32_t steps;
  MayRange range;
  float hit;
  Projected at_hit;  ///< at a hit: its projection (march_cell), valid where `projected`
  bool projected;
};

/// Segments of one cell whose linear searches run in lockstep (march_avx2).
constexpr int kMarchBatch = 4;
/// Most segments of one cell marched in one call: those of one screen tile.
constexpr int kMaxMarch = static_cast<int>(kTile * kTile);

/// Where a sample lies on its projection segment: no surface on the segment (empty texel), between the
/// domain face and the stored (nearest) surface, or beyond it.
enum class Side : std::uint8_t { Empty, Before, Beyond };

// Internal linkage for all code of this header (see the file comment).
namespace {

#define GIMFORGE_INLINE [[gnu::always_inline]] inline

/// MayRange: whether no sample of a segment of length len may be inside.
GIMFORGE_INLINE bool range_empty(const MayRange& r, float len) { return r.first_end < 0.0f && r.last_begin > len; }
/// MayRange: whether the sample at s is outside (needs no inside test).
GIMFORGE_INLINE bool range_skips(const MayRange& r, float s) { return s > r.first_end && s < r.last_begin; }

/// Whether the segment e → x (unit-cell points) of a border cell may hold an inside sample: an upper bound
/// of the projected distance along it is at least the cell's smallest stored distance. Perspective and
/// axial: the distance |P' − P| = |P' − C| − |P − C| is at most reach − (distance from C, or the axis, to
/// the segment). Parallel and planar projections need no such test: their projected distance is the height
/// above a face, which may_range bounds exactly.
inline bool may_hit(const CellData& c, const float e[3], const float x[3]) {
  if (c.min_dist <= 0.0f) return true;
  constexpr float kSlack = 1e-4f;
  const int a = c.axis;
  switch (static_cast<ProjectionType>(c.type)) {
    case ProjectionType::Parallel:
    case ProjectionType::Planar:
      return true;
    case ProjectionType::Perspective:
    case ProjectionType::Axial: {
      float w[3], v[3];
      for (int k = 0; k < 3; ++k) {
        w[k] = e[k] - c.point[k];
        v[k] = x[k] - e[k];
      }
      if (static_cast<ProjectionType>(c.type) == ProjectionType::Axial) w[a] = v[a] = 0.0f;
      const float vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
      const float wv = w[0] * v[0] + w[1] * v[1] + w[2] * v[2];
      const float s = vv > 0.0f ? std::clamp(-wv / vv, 0.0f, 1.0f) : 0.0f;
      float r2 = 0.0f;
      for (int k = 0; k < 3; ++k) r2 += (w[k] + s * v[k]) * (w[k] + s * v[k]);
      return c.reach - std::sqrt(r2) + kSlack >= c.min_dist;
    }
  }
  return true;
}

inline MayRange may_range(const CellData& c, const float e[3], const float dl[3]) {
  constexpr float kSlack = 1e-4f;
  MayRange r{-kInfF, kInfF};
  for (int f = 0; f < 6; ++f) {
    const float need = c.min_height[f] - kSlack;
    if (!(need <= 1.0f)) continue;  // +inf or above any height in the cell
    const int a = f / 2;
    const float h0 = (f & 1) ? 1.0f - e[a] : e[a];
    const float hd = (f & 1) ? -dl[a] : dl[a];
    if (hd > 0.0f) {
      r.last_begin = std::min(r.last_begin, (need - h0) / hd);
    } else if (hd < 0.0f) {
      r.first_end = std::max(r.first_end, (need - h0) / hd);
    } else if (h0 >= need) {
      return {kInfF, kInfF};
    }
  }
  return r;
}

[[gnu::always_inline]] inline float clamp01(float x) { return std::min(std::max(x, 0.0f), 1.0f); }

/// Projects the unit-cell point p (already clamped to the cell) with a projection of type P. Returns false
/// where the direction is undefined (p on the centre / axis).
template <ProjectionType P>
GIMFORGE_INLINE bool project(const CellData& c, const float p[3], Projected& out) {
  if constexpr (P == ProjectionType::Parallel || P == ProjectionType::Planar) {
    const int a = c.axis;
    const int side = P == ProjectionType::Parallel ? c.side : (p[a] >= 0.5f ? 1 : 0);
    out.face = 2 * a + side;
    out.dist = side != 0 ? 1.0f - p[a] : p[a];
    out.u = p[a == 2 ? 0 : a + 1];
    out.v = p[a == 0 ? 2 : a - 1];
    return true;
  } else {
    float d[3] = {p[0] - c.point[0], p[1] - c.point[1], p[2] - c.point[2]};
    if constexpr (P == ProjectionType::Axial) d[c.axis] = 0.0f;
    // Exit of the unit cube from the centre of projection along d: the smallest num_a / |d_a| over the axes
    // with d_a != 0, num_a the distance from the centre to the face ahead; compared by cross
    // multiplication so that one division remains.
    float best_num = 1.0f, best_den = 0.0f;
    int fa = 0;
    for (int a = 0; a < 3; ++a) {
      const float den = std::abs(d[a]);
      const float num = d[a] >= 0.0f ? 1.0f - c.point[a] : c.point[a];
      if (den > 0.0f && num * best_den < best_num * den) {
        best_num = num;
        best_den = den;
        fa = a;
      }
    }
    if (!(best_den > 0.0f)) return false;
    const float best = best_num / best_den;
    const float len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    out.face = 2 * fa + (d[fa] > 0.0f ? 1 : 0);
    out.dist = std::max(best - 1.0f, 0.0f) * len;
    const int au = fa == 2 ? 0 : fa + 1;
    const int av = fa == 0 ? 2 : fa - 1;
    float qu = c.point[au] + best * d[au];
    float qv = c.point[av] + best * d[av];
    if constexpr (P == ProjectionType::Axial) {
      if (au == c.axis) qu = p[au];
      if (av == c.axis) qv = p[av];
    }
    out.u = clamp01(qu);
    out.v = clamp01(qv);
    return true;
  }
}

/// The side of a sample at face coordinates (u, v) of the layer starting at `base`, at projected distance
/// `dist` (unit cell): Beyond when dist >= the stored distance (read with filter F).
template <ReliefFilter F>
GIMFORGE_INLINE Side texel_side(const Texels& tx, std::uint32_t base, float u, float v, float dist) {
  const float dq = dist * tx.inv_scale;
  const float x = u * tx.tm1;
  const float y = v * tx.tm1;
  if constexpr (F == ReliefFilter::Nearest) {
    const auto i = static_cast<std::int32_t>(x + 0.5f);
    const auto j = static_cast<std::int32_t>(y + 0.5f);
    const std::uint32_t q = tx.dist[base + static_cast<std::uint32_t>(j * tx.T + i)];
    if (q == kEmptyTexel) return Side::Empty;
    return dq >= static_cast<float>(q) ? Side::Beyond : Side::Before;
  } else {
    const std::int32_t i0 = std::min(static_cast<std::int32_t>(x), tx.T - 2);
    const std::int32_t j0 = std::min(static_cast<std::int32_t>(y), tx.T - 2);
    const float fx = x - static_cast<float>(i0);
    const float fy = y - static_cast<float>(j0);
    const std::uint16_t* row = tx.dist + base + static_cast<std::uint32_t>(j0 * tx.T + i0);
    const std::uint32_t a = row[0], b = row[1];
    const std::uint32_t c = row[tx.T], e = row[tx.T + 1];
    if (std::max(std::max(a, b), std::max(c, e)) == kEmptyTexel) {
      // Next to an empty texel: the nearest texel alone decides.
      const std::uint32_t q = fy < 0.5f ? (fx < 0.5f ? a : b) : (fx < 0.5f ? c : e);
      if (q == kEmptyTexel) return Side::Empty;
      return dq >= static_cast<float>(q) ? Side::Beyond : Side::Before;
    }
    const float fa = static_cast<float>(a), fb = static_cast<float>(b);
    const float fc = static_cast<float>(c), fe = static_cast<float>(e);
    const float lo = fa + fx * (fb - fa);
    const float hi = fc + fx * (fe - fc);
    return dq >= lo + fy * (hi - lo) ? Side::Beyond : Side::Before;
  }
}

/// The side of the unit-cell point p (in the cell) relative to the stored surface of cell c.
template <ProjectionType P, ReliefFilter F>
GIMFORGE_INLINE Side point_side(const CellData& c, const Texels& tx, const float p[3]) {
  Projected pr;
  if (!project<P>(c, p, pr)) return Side::Empty;
  const std::uint32_t base = c.layer_base[pr.face];
  if (base == kNoLayer) return Side::Empty;
  return texel_side<F>(tx, base, pr.u, pr.v, pr.dist);
}

/// The crossing flag of the sample at ray parameter s of a cell with projection type P and mode M: whether
/// the sample is inside the object. Border grey cells project onto external faces, whose points are
/// outside: inside = Beyond (an empty texel means the whole segment is outside). Interior grey cells
/// project from their centre C onto internal faces, which may lie inside or outside: Before means the
/// sample is on the other side of the surface than C (one crossing between them), Empty and Beyond on the
/// side of C, so inside = (Before) xor (C inside). With C undecided (kInteriorRelative) the flag is Before
/// and march() looks for any change of it.
template <ProjectionType P, ReliefFilter F, CellMode M>
GIMFORGE_INLINE bool sample_flag(const CellData& c, const Texels& tx, const float e[3], const float dl[3], float s) {
  const float p[3] = {clamp01(e[0] + s * dl[0]), clamp01(e[1] + s * dl[1]), clamp01(e[2] + s * dl[2])};
  if constexpr (M == kBorderCell) {
    Projected pr;
    if (!project<P>(c, p, pr)) return false;
    // Before the nearest stored sample of the face (or no layer): outside, without reading the texels.
    if (pr.dist * tx.inv_scale < c.face_qmin[pr.face] || c.layer_base[pr.face] == kNoLayer) return false;
    return texel_side<F>(tx, c.layer_base[pr.face], pr.u, pr.v, pr.dist) == Side::Beyond;
  }
  const Side side = point_side<P, F>(c, tx, p);
  if constexpr (M == kInteriorInside) return side != Side::Before;
  return side == Side::Before;
}

/// Refinement of a crossing between the samples lo (flag == start) and hi (flag != start): `halvings`
/// steps of a binary search, each testing the middle of the interval and keeping the half where the flag
/// changes. Returns the middle of the last interval. Not inlined (it runs once per hit, after the linear
/// search): inlined into march, where the split made it a function called once, it cost the scalar render
/// 5 % more instructions.
template <ProjectionType P, ReliefFilter F, CellMode M>
[[gnu::noinline]] float refine(const CellData& c, const Texels& tx, const float e[3], const float dl[3], float lo, float hi, bool start,
             std::uint32_t halvings, std::uint64_t& samples) {
  for (std::uint32_t r = 0; r < halvings; ++r) {
    ++samples;
    const float mid = 0.5f * (lo + hi);
    if (sample_flag<P, F, M>(c, tx, e, dl, mid) != start)
      hi = mid;
    else
      lo = mid;
  }
  return 0.5f * (lo + hi);
}

/// Linear search then refinement along the segment s in [0, len] of the ray e + s · dl through one cell,
/// for the first change of the crossing flag from its state at the entry point: outside (the ray has met
/// no surface before), or, in kInteriorRelative cells, the flag evaluated there. Returns the hit parameter
/// or −1. The linear samples are s_k = k · len / steps (k = 1..steps, s_steps = len); the crossing is
/// refined between s_(k−1) (0 for k = 1) and the first s_k whose flag changed.
template <ProjectionType P, ReliefFilter F, CellMode M>
float march(const CellData& c, const Texels& tx, const float e[3], const float dl[3], float len, std::uint32_t steps,
            std::uint32_t halvings, const MayRange& range, std::uint64_t& samples) {
  bool start = false;
  if constexpr (M == kInteriorRelative) {
    start = sample_flag<P, F, M>(c, tx, e, dl, 0.0f);
    ++samples;
  }
  const float ds = len / static_cast<float>(steps);
  float prev = 0.0f;
  for (std::uint32_t k = 1; k <= steps; ++k) {
    const float s = k == steps ? len : static_cast<float>(k) * ds;
    if constexpr (M == kBorderCell) {
      if (range_skips(range, s)) {  // outside: no inside test
        prev = s;
        continue;
      }
    }
    ++samples;
    if (sample_flag<P, F, M>(c, tx, e, dl, s) != start)
      return refine<P, F, M>(c, tx, e, dl, prev, s, start, halvings, samples);
    prev = s;
  }
  return -1.0f;
}

}  // namespace
}  // namespace gimforge::detail
