#include "kernels/relief/relief_raycast.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>

#include <embree3/rtcore.h>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "kernels/core/embree_scene.h"
#include "kernels/core/errors.h"

// The vectorized march (AVX2, chosen at run time) on x86-64 with GCC or Clang.
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define GIMFORGE_RELIEF_AVX2 1
#include <immintrin.h>
#else
#define GIMFORGE_RELIEF_AVX2 0
#endif

namespace gimforge {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr float kInfF = std::numeric_limits<float>::infinity();
/// Rows per task of a render.
constexpr std::uint32_t kRowGrain = 4;
/// Side of the square screen tiles of the cell-order render, in pixels.
constexpr std::uint32_t kTile = 16;
/// Largest n whose cell lookup is a dense n³ table (16 MiB of int32); a hash of the grey cells above.
constexpr std::uint32_t kMaxDenseGrid = 160;
/// A hit farther than this many texel spacings from the stored surface of its texel lies on a wall (a
/// discontinuity of the stored distances), whose stored normal is that of another surface.
constexpr float kWallTexels = 4.0f;
/// "No layer": the face is not a domain face of the cell.
constexpr std::uint32_t kNoLayer = 0xffffffffu;

// ---------------------------------------------------------------------------------------------------
// Per-map tables of the ray caster.

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

/// Whether the segment e → x (unit-cell points) of a border cell may hold an inside sample: an upper bound
/// of the projected distance along it is at least the cell's smallest stored distance. Perspective and
/// axial: the distance |P' − P| = |P' − C| − |P − C| is at most reach − (distance from C, or the axis, to
/// the segment). Parallel and planar projections need no such test: their projected distance is the height
/// above a face, which may_range bounds exactly.
bool may_hit(const CellData& c, const float e[3], const float x[3]) {
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

/// The samples s in [0, len] of the segment e + s · dl through a border cell that may be inside the object,
/// from CellData::min_height: those with s <= first_end or s >= last_begin (the heights above the faces are
/// linear in s, so each face allows a prefix or a suffix of the segment). Samples strictly between the two
/// are outside and need no inside test.
struct MayRange {
  float first_end;
  float last_begin;
  [[nodiscard]] bool empty(float len) const { return first_end < 0.0f && last_begin > len; }
  [[nodiscard]] bool skips(float s) const { return s > first_end && s < last_begin; }
};

MayRange may_range(const CellData& c, const float e[3], const float dl[3]) {
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

/// How the samples of a cell are classified (see sample_flag).
enum CellMode : std::uint8_t {
  kBorderCell = 0,        ///< border grey: domain faces are external (outside the object)
  kInteriorOutside = 1,   ///< interior grey whose centre of projection is outside the object
  kInteriorInside = 2,    ///< interior grey whose centre of projection is inside the object
  kInteriorRelative = 3,  ///< interior grey, centre undecided: any change of side along the ray
};

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

[[gnu::always_inline]] inline float clamp01(float x) { return std::min(std::max(x, 0.0f), 1.0f); }

/// Projects the unit-cell point p (already clamped to the cell) with a projection of type P. Returns false
/// where the direction is undefined (p on the centre / axis).
#define GIMFORGE_INLINE [[gnu::always_inline]] inline

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

/// The segment [t0, t1] (t0 >= 0) of ray r in the cell with coordinates idx, from lo[a] = idx[a] − og[a]
/// and hi[a] = idx[a] + 1 − og[a]; true when it has positive length.
GIMFORGE_INLINE bool cell_segment(const GridRay& r, const std::int64_t idx[3], const double lo[3], const double hi[3],
                                  double& t0, double& t1) {
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

/// Where a sample lies on its projection segment: no surface on the segment (empty texel), between the
/// domain face and the stored (nearest) surface, or beyond it.
enum class Side : std::uint8_t { Empty, Before, Beyond };

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
/// changes. Returns the middle of the last interval.
template <ProjectionType P, ReliefFilter F, CellMode M>
float refine(const CellData& c, const Texels& tx, const float e[3], const float dl[3], float lo, float hi, bool start,
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
      if (range.skips(s)) {  // outside: no inside test
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

#if GIMFORGE_RELIEF_AVX2
// ---------------------------------------------------------------------------------------------------
// The march with 8 samples at a time (AVX2). Every lane performs the operations of sample_flag<P, F, M> in
// the same order and precision (no fused multiply-add: the file is compiled with -ffp-contract=off), so
// the flags, and with them the image, equal the scalar path's.

#define GIMFORGE_AVX2_INLINE __attribute__((target("avx2"), always_inline)) inline

/// The constants of one cell, broadcast.
struct alignas(32) CellLanes {
  __m256 point[3];
  __m256 num_up[3];   ///< 1 − point[a]: distance from the centre to the face ahead when d_a >= 0
  __m256 face_qmin;   ///< CellData::face_qmin, indexed by face (lanes 6, 7 unused)
  __m256i layer_base; ///< CellData::layer_base, indexed by face
  __m256 inv_scale, tm1;
  __m256i T, Tm2;
};

GIMFORGE_AVX2_INLINE __m256 select(__m256 mask, __m256 if_set, __m256 if_clear) {
  return _mm256_blendv_ps(if_clear, if_set, mask);
}
GIMFORGE_AVX2_INLINE __m256i select(__m256i mask, __m256i if_set, __m256i if_clear) {
  return _mm256_blendv_epi8(if_clear, if_set, mask);
}
/// clamp01 lane-wise: max_ps(0, x) is (0 > x ? 0 : x) and min_ps(1, y) is (1 < y ? 1 : y), as std::max /
/// std::min with the arguments of clamp01 (NaN and signed zeros included).
GIMFORGE_AVX2_INLINE __m256 clamp01_lanes(__m256 x) {
  return _mm256_min_ps(_mm256_set1_ps(1.0f), _mm256_max_ps(_mm256_setzero_ps(), x));
}

/// The crossing flags of mode M (see sample_flag) from the lanes whose side is Beyond and those that are not
/// Empty, as a movemask.
template <CellMode M>
GIMFORGE_AVX2_INLINE int flag_mask(__m256 beyond, __m256 filled, __m256 valid) {
  if constexpr (M == kBorderCell) return _mm256_movemask_ps(beyond);
  const __m256 before = _mm256_andnot_ps(beyond, filled);
  if constexpr (M == kInteriorInside) return _mm256_movemask_ps(_mm256_andnot_ps(before, valid));
  return _mm256_movemask_ps(before);
}

/// One ray's entry point and direction, broadcast.
struct alignas(32) RayLanes {
  __m256 e[3], dl[3];
};

/// The crossing flags (sample_flag<P, F, M>) of the samples e + s[n] · dl of N rays of one cell in the lanes
/// of valid[n], as movemasks. The operations of the N rays are interleaved stage by stage, so that their
/// dependency chains overlap in the pipeline (one ray's chain is long: projection, division, gathers).
template <ProjectionType P, ReliefFilter F, CellMode M, std::size_t N>
GIMFORGE_AVX2_INLINE void flags8(const CellData& c, const CellLanes& L, const Texels& tx,
                                 const RayLanes* const (&ray)[N], const __m256 (&s)[N], const __m256 (&valid)[N],
                                 int (&out)[N]) {
#define GIMFORGE_EACH _Pragma("GCC unroll 4") for (std::size_t n = 0; n < N; ++n)
  const __m256 one = _mm256_set1_ps(1.0f);
  const __m256 zero = _mm256_setzero_ps();
  __m256 p[N][3];
  GIMFORGE_EACH {
    for (int k = 0; k < 3; ++k)
      p[n][k] = clamp01_lanes(_mm256_add_ps(ray[n]->e[k], _mm256_mul_ps(s[n], ray[n]->dl[k])));
  }
  __m256 dist[N], u[N], v[N], ok[N];
  __m256i face[N];
  GIMFORGE_EACH ok[n] = valid[n];
  if constexpr (P == ProjectionType::Parallel || P == ProjectionType::Planar) {
    const int a = c.axis;
    GIMFORGE_EACH {
      u[n] = p[n][a == 2 ? 0 : a + 1];
      v[n] = p[n][a == 0 ? 2 : a - 1];
      if constexpr (P == ProjectionType::Parallel) {
        dist[n] = c.side != 0 ? _mm256_sub_ps(one, p[n][a]) : p[n][a];
        face[n] = _mm256_set1_epi32(2 * a + c.side);
      } else {
        const __m256 high = _mm256_cmp_ps(p[n][a], _mm256_set1_ps(0.5f), _CMP_GE_OQ);
        dist[n] = select(high, _mm256_sub_ps(one, p[n][a]), p[n][a]);
        face[n] = _mm256_sub_epi32(_mm256_set1_epi32(2 * a), _mm256_castps_si256(high));  // + 1 where high
      }
    }
  } else {
    __m256 d[N][3];
    GIMFORGE_EACH {
      for (int k = 0; k < 3; ++k) d[n][k] = _mm256_sub_ps(p[n][k], L.point[k]);
      if constexpr (P == ProjectionType::Axial) d[n][c.axis] = zero;
    }
    const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
    __m256 best_num[N], best_den[N];
    __m256i fa[N];
    GIMFORGE_EACH {
      best_num[n] = one;
      best_den[n] = zero;
      fa[n] = _mm256_setzero_si256();
    }
    for (int a = 0; a < 3; ++a) {
      GIMFORGE_EACH {
        const __m256 den = _mm256_and_ps(d[n][a], abs_mask);
        const __m256 num = select(_mm256_cmp_ps(d[n][a], zero, _CMP_GE_OQ), L.num_up[a], L.point[a]);
        const __m256 closer =
            _mm256_cmp_ps(_mm256_mul_ps(num, best_den[n]), _mm256_mul_ps(best_num[n], den), _CMP_LT_OQ);
        const __m256 take = _mm256_and_ps(_mm256_cmp_ps(den, zero, _CMP_GT_OQ), closer);
        best_num[n] = select(take, num, best_num[n]);
        best_den[n] = select(take, den, best_den[n]);
        fa[n] = select(_mm256_castps_si256(take), _mm256_set1_epi32(a), fa[n]);
      }
    }
    __m256 best[N], len[N];
    GIMFORGE_EACH {
      ok[n] = _mm256_and_ps(ok[n], _mm256_cmp_ps(best_den[n], zero, _CMP_GT_OQ));
      best[n] = _mm256_div_ps(best_num[n], best_den[n]);
      len[n] = _mm256_sqrt_ps(_mm256_add_ps(
          _mm256_add_ps(_mm256_mul_ps(d[n][0], d[n][0]), _mm256_mul_ps(d[n][1], d[n][1])),
          _mm256_mul_ps(d[n][2], d[n][2])));
    }
    GIMFORGE_EACH {
      const __m256 fa0 = _mm256_castsi256_ps(_mm256_cmpeq_epi32(fa[n], _mm256_setzero_si256()));
      const __m256 fa1 = _mm256_castsi256_ps(_mm256_cmpeq_epi32(fa[n], _mm256_set1_epi32(1)));
      // Per lane, the components along fa, au = (fa + 1) % 3 and av = (fa + 2) % 3.
      const __m256 d_fa = select(fa0, d[n][0], select(fa1, d[n][1], d[n][2]));
      const __m256 d_au = select(fa0, d[n][1], select(fa1, d[n][2], d[n][0]));
      const __m256 d_av = select(fa0, d[n][2], select(fa1, d[n][0], d[n][1]));
      const __m256 c_au = select(fa0, L.point[1], select(fa1, L.point[2], L.point[0]));
      const __m256 c_av = select(fa0, L.point[2], select(fa1, L.point[0], L.point[1]));
      face[n] = _mm256_sub_epi32(_mm256_add_epi32(fa[n], fa[n]),
                                 _mm256_castps_si256(_mm256_cmp_ps(d_fa, zero, _CMP_GT_OQ)));
      dist[n] = _mm256_mul_ps(_mm256_max_ps(zero, _mm256_sub_ps(best[n], one)), len[n]);
      __m256 qu = _mm256_add_ps(c_au, _mm256_mul_ps(best[n], d_au));
      __m256 qv = _mm256_add_ps(c_av, _mm256_mul_ps(best[n], d_av));
      if constexpr (P == ProjectionType::Axial) {
        // The axis coordinate is kept: au == axis where fa == (axis + 2) % 3, av == axis where
        // fa == (axis + 1) % 3.
        const int a = c.axis;
        const __m256 au_axis = _mm256_castsi256_ps(_mm256_cmpeq_epi32(fa[n], _mm256_set1_epi32((a + 2) % 3)));
        const __m256 av_axis = _mm256_castsi256_ps(_mm256_cmpeq_epi32(fa[n], _mm256_set1_epi32((a + 1) % 3)));
        qu = select(au_axis, p[n][a], qu);
        qv = select(av_axis, p[n][a], qv);
      }
      u[n] = clamp01_lanes(qu);
      v[n] = clamp01_lanes(qv);
    }
  }
  // The lanes that read texels (pass); the others are Side::Empty (or, border cells, before every stored
  // sample). No early exit where no lane reads texels: that branch would mispredict often and hold back
  // the other rays; the gathers of such lanes read the first texel.
  const auto* words = reinterpret_cast<const int*>(tx.dist);
  const __m256i low16 = _mm256_set1_epi32(0xffff);
  __m256 dq[N], pass[N], x[N], y[N];
  GIMFORGE_EACH {
    dq[n] = _mm256_mul_ps(dist[n], L.inv_scale);
    const __m256i base = _mm256_permutevar8x32_epi32(L.layer_base, face[n]);
    const __m256i no_layer = _mm256_cmpeq_epi32(base, _mm256_set1_epi32(static_cast<int>(kNoLayer)));
    pass[n] = _mm256_andnot_ps(_mm256_castsi256_ps(no_layer), ok[n]);
    if constexpr (M == kBorderCell)
      pass[n] = _mm256_and_ps(pass[n],
                              _mm256_cmp_ps(dq[n], _mm256_permutevar8x32_ps(L.face_qmin, face[n]), _CMP_NLT_UQ));
    x[n] = _mm256_mul_ps(u[n], L.tm1);
    y[n] = _mm256_mul_ps(v[n], L.tm1);
    face[n] = base;  // from here on: the first texel of the layer
  }
  if constexpr (F == ReliefFilter::Nearest) {
    const __m256 half = _mm256_set1_ps(0.5f);
    GIMFORGE_EACH {
      const __m256i i = _mm256_cvttps_epi32(_mm256_add_ps(x[n], half));
      const __m256i j = _mm256_cvttps_epi32(_mm256_add_ps(y[n], half));
      // Two texels (i', i' + 1) from one 32-bit read with i' = min(i, T − 2), so that it stays in the layer.
      const __m256i ic = _mm256_min_epi32(i, L.Tm2);
      const __m256i idx = _mm256_and_si256(_mm256_castps_si256(pass[n]),
                                           _mm256_add_epi32(face[n], _mm256_add_epi32(_mm256_mullo_epi32(j, L.T), ic)));
      const __m256i pair = _mm256_i32gather_epi32(words, idx, 2);
      const __m256i q =
          select(_mm256_cmpgt_epi32(i, L.Tm2), _mm256_srli_epi32(pair, 16), _mm256_and_si256(pair, low16));
      const __m256 filled = _mm256_andnot_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(q, low16)), pass[n]);
      out[n] = flag_mask<M>(_mm256_and_ps(filled, _mm256_cmp_ps(dq[n], _mm256_cvtepi32_ps(q), _CMP_GE_OQ)), filled,
                            valid[n]);
    }
  } else {
    __m256 fx[N], fy[N];
    __m256i ab[N], ce[N];
    GIMFORGE_EACH {
      const __m256i i0 = _mm256_min_epi32(_mm256_cvttps_epi32(x[n]), L.Tm2);
      const __m256i j0 = _mm256_min_epi32(_mm256_cvttps_epi32(y[n]), L.Tm2);
      fx[n] = _mm256_sub_ps(x[n], _mm256_cvtepi32_ps(i0));
      fy[n] = _mm256_sub_ps(y[n], _mm256_cvtepi32_ps(j0));
      const __m256i idx = _mm256_and_si256(_mm256_castps_si256(pass[n]),
                                           _mm256_add_epi32(face[n], _mm256_add_epi32(_mm256_mullo_epi32(j0, L.T), i0)));
      ab[n] = _mm256_i32gather_epi32(words, idx, 2);                         // row[0], row[1]
      ce[n] = _mm256_i32gather_epi32(words, _mm256_add_epi32(idx, L.T), 2);  // row[T], row[T + 1]
    }
    const __m256 half = _mm256_set1_ps(0.5f);
    GIMFORGE_EACH {
      const __m256i a = _mm256_and_si256(ab[n], low16), b = _mm256_srli_epi32(ab[n], 16);
      const __m256i cc = _mm256_and_si256(ce[n], low16), ee = _mm256_srli_epi32(ce[n], 16);
      const __m256i empty_ab = _mm256_or_si256(_mm256_cmpeq_epi32(a, low16), _mm256_cmpeq_epi32(b, low16));
      const __m256i empty_ce = _mm256_or_si256(_mm256_cmpeq_epi32(cc, low16), _mm256_cmpeq_epi32(ee, low16));
      const __m256 emptyf = _mm256_castsi256_ps(_mm256_or_si256(empty_ab, empty_ce));
      const __m256 fa = _mm256_cvtepi32_ps(a), fb = _mm256_cvtepi32_ps(b);
      const __m256 fc = _mm256_cvtepi32_ps(cc), fe = _mm256_cvtepi32_ps(ee);
      const __m256 lo = _mm256_add_ps(fa, _mm256_mul_ps(fx[n], _mm256_sub_ps(fb, fa)));
      const __m256 hi = _mm256_add_ps(fc, _mm256_mul_ps(fx[n], _mm256_sub_ps(fe, fc)));
      const __m256 bilinear =
          _mm256_cmp_ps(dq[n], _mm256_add_ps(lo, _mm256_mul_ps(fy[n], _mm256_sub_ps(hi, lo))), _CMP_GE_OQ);
      // Next to an empty texel the nearest texel alone decides (computed for all lanes, selected without a
      // branch).
      const __m256i left = _mm256_castps_si256(_mm256_cmp_ps(fx[n], half, _CMP_LT_OQ));
      const __m256i top = _mm256_castps_si256(_mm256_cmp_ps(fy[n], half, _CMP_LT_OQ));
      const __m256i q = select(top, select(left, a, b), select(left, cc, ee));
      const __m256 near_filled = _mm256_andnot_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(q, low16)), pass[n]);
      const __m256 near_beyond =
          _mm256_and_ps(near_filled, _mm256_cmp_ps(dq[n], _mm256_cvtepi32_ps(q), _CMP_GE_OQ));
      out[n] = flag_mask<M>(select(emptyf, near_beyond, _mm256_and_ps(pass[n], bilinear)),
                            select(emptyf, near_filled, pass[n]), valid[n]);
    }
  }
#undef GIMFORGE_EACH
}

GIMFORGE_AVX2_INLINE CellLanes cell_lanes(const CellData& c, const Texels& tx) {
  CellLanes L;
  for (int k = 0; k < 3; ++k) {
    L.point[k] = _mm256_set1_ps(c.point[k]);
    L.num_up[k] = _mm256_set1_ps(1.0f - c.point[k]);
  }
  L.face_qmin = _mm256_setr_ps(c.face_qmin[0], c.face_qmin[1], c.face_qmin[2], c.face_qmin[3], c.face_qmin[4],
                               c.face_qmin[5], 0.0f, 0.0f);
  L.layer_base = _mm256_setr_epi32(static_cast<int>(c.layer_base[0]), static_cast<int>(c.layer_base[1]),
                                   static_cast<int>(c.layer_base[2]), static_cast<int>(c.layer_base[3]),
                                   static_cast<int>(c.layer_base[4]), static_cast<int>(c.layer_base[5]),
                                   static_cast<int>(kNoLayer), static_cast<int>(kNoLayer));
  L.inv_scale = _mm256_set1_ps(tx.inv_scale);
  L.tm1 = _mm256_set1_ps(tx.tm1);
  L.T = _mm256_set1_epi32(tx.T);
  L.Tm2 = _mm256_set1_epi32(tx.T - 2);
  return L;
}

/// The flags (flags8) of n rays of one cell, two at a time.
template <ProjectionType P, ReliefFilter F, CellMode M>
GIMFORGE_AVX2_INLINE void flags_of(const CellData& c, const CellLanes& L, const Texels& tx, int n,
                                   const RayLanes* const* rl, const __m256* s, const __m256* valid, int* out) {
  int q = 0;
  for (; q + 2 <= n; q += 2) {
    const RayLanes* const r2[2] = {rl[q], rl[q + 1]};
    const __m256 s2[2] = {s[q], s[q + 1]};
    const __m256 v2[2] = {valid[q], valid[q + 1]};
    int o2[2];
    flags8<P, F, M, 2>(c, L, tx, r2, s2, v2, o2);
    out[q] = o2[0];
    out[q + 1] = o2[1];
  }
  if (q < n) {
    const RayLanes* const r1[1] = {rl[q]};
    const __m256 s1[1] = {s[q]};
    const __m256 v1[1] = {valid[q]};
    int o1[1];
    flags8<P, F, M, 1>(c, L, tx, r1, s1, v1, o1);
    out[q] = o1[0];
  }
}

/// A crossing found by the linear search: the segment, the interval of the change, the flag at the start.
struct Crossing {
  int seg;
  float lo, hi;
  bool start;
};

/// The lanes whose bit is set in the movemask `bits`, as a mask.
GIMFORGE_AVX2_INLINE __m256 lane_mask(int bits) {
  const __m256i lane_bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
  return _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(bits), lane_bit), lane_bit));
}

/// The binary refinement (refine<P, F, M>) of n <= 8 · N crossings at once, crossing 8 · v + l in lane l
/// of vector v: every lane tests the middle of its interval and keeps the half where its flag changes.
template <ProjectionType P, ReliefFilter F, CellMode M, std::size_t N>
GIMFORGE_AVX2_INLINE void refine_lanes(const CellData& c, const CellLanes& L, const Texels& tx, CellSegment* segs,
                                       const Crossing* cr, int n, std::uint32_t halvings) {
  RayLanes rl[N];
  const RayLanes* rp[N];
  __m256 lo[N], hi[N], start[N], valid[N], mid[N];
  const __m256 half = _mm256_set1_ps(0.5f);
  for (std::size_t v = 0; v < N; ++v) {
    alignas(32) float e[3][8] = {}, dl[3][8] = {}, l0[8] = {}, h0[8] = {};
    int bits = 0, used = 0;
    for (int l = 0; l < 8; ++l) {
      const int q = 8 * static_cast<int>(v) + l;
      if (q >= n) break;
      const CellSegment& g = segs[cr[q].seg];
      for (int k = 0; k < 3; ++k) {
        e[k][l] = g.e[k];
        dl[k][l] = g.dl[k];
      }
      l0[l] = cr[q].lo;
      h0[l] = cr[q].hi;
      bits |= cr[q].start ? 1 << l : 0;
      used |= 1 << l;
    }
    for (int k = 0; k < 3; ++k) {
      rl[v].e[k] = _mm256_load_ps(e[k]);
      rl[v].dl[k] = _mm256_load_ps(dl[k]);
    }
    rp[v] = &rl[v];
    lo[v] = _mm256_load_ps(l0);
    hi[v] = _mm256_load_ps(h0);
    start[v] = lane_mask(bits);
    valid[v] = lane_mask(used);
  }
  for (std::uint32_t r = 0; r < halvings; ++r) {
    int flags[N];
    for (std::size_t v = 0; v < N; ++v) mid[v] = _mm256_mul_ps(half, _mm256_add_ps(lo[v], hi[v]));
    flags8<P, F, M, N>(c, L, tx, rp, mid, valid, flags);
    for (std::size_t v = 0; v < N; ++v) {
      const __m256 changed = _mm256_xor_ps(lane_mask(flags[v]), start[v]);
      hi[v] = select(changed, mid[v], hi[v]);
      lo[v] = select(changed, lo[v], mid[v]);
    }
  }
  for (std::size_t v = 0; v < N; ++v) {
    alignas(32) float hit[8];
    _mm256_store_ps(hit, _mm256_mul_ps(half, _mm256_add_ps(lo[v], hi[v])));
    for (int l = 0; l < 8; ++l) {
      const int q = 8 * static_cast<int>(v) + l;
      if (q < n) segs[cr[q].seg].hit = hit[l];
    }
  }
}

/// march<P, F, M> for `count` (<= kMaxMarch) segments of one cell: the same hit parameters and inside-test
/// counts. The linear search tests 8 samples of a segment at a time, kMarchBatch segments in lockstep (one
/// batch of 8 of every segment before the next), the tests of two segments interleaved; then the crossings
/// are refined 8 at a time, one per lane, two vectors interleaved (a lone crossing by the scalar code).
/// Both keep independent dependency chains side by side in the pipeline.
template <ProjectionType P, ReliefFilter F, CellMode M>
__attribute__((target("avx2"))) void march_avx2(const CellData& c, const Texels& tx, CellSegment* segs, int count,
                                                std::uint32_t halvings, std::uint64_t& samples) {
  const CellLanes L = cell_lanes(c, tx);
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  struct alignas(32) Ray {
    RayLanes lanes;
    float ds;
    int start;         // the flags of the lanes at the entry point
    std::uint32_t k0;  // first linear sample of the next batch
  };
  Crossing crossings[kMaxMarch];
  int n_cross = 0;
  for (int b0 = 0; b0 < count; b0 += kMarchBatch) {
    Ray rays[kMarchBatch];
    int linear[kMarchBatch];  // the segments (of this batch) still searching
    int n_linear = 0;
    for (int i = 0; i < std::min(kMarchBatch, count - b0); ++i) {
      const CellSegment& g = segs[b0 + i];
      Ray& r = rays[i];
      for (int k = 0; k < 3; ++k) {
        r.lanes.e[k] = _mm256_set1_ps(g.e[k]);
        r.lanes.dl[k] = _mm256_set1_ps(g.dl[k]);
      }
      r.ds = g.len / static_cast<float>(g.steps);
      r.start = 0;
      if constexpr (M == kInteriorRelative) {
        r.start = sample_flag<P, F, M>(c, tx, g.e, g.dl, 0.0f) ? 0xff : 0;
        ++samples;
      }
      r.k0 = 1;
      segs[b0 + i].hit = -1.0f;
      linear[n_linear++] = i;
    }
    alignas(32) float at[kMarchBatch][8];  // the samples of the last batch of each segment
    int found[kMarchBatch], tested_bits[kMarchBatch];
    const RayLanes* lanes[kMarchBatch];
    __m256 points[kMarchBatch], tested[kMarchBatch];
    while (n_linear > 0) {
      for (int q = 0; q < n_linear; ++q) {
        const Ray& r = rays[linear[q]];
        const CellSegment& g = segs[b0 + linear[q]];
        const __m256i k = _mm256_add_epi32(_mm256_set1_epi32(static_cast<int>(r.k0)), lane);
        const __m256 s =
            select(_mm256_castsi256_ps(_mm256_cmpeq_epi32(k, _mm256_set1_epi32(static_cast<int>(g.steps)))),
                   _mm256_set1_ps(g.len), _mm256_mul_ps(_mm256_cvtepi32_ps(k), _mm256_set1_ps(r.ds)));
        const __m256 in_segment =
            _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(static_cast<int>(g.steps) + 1), k));
        const __m256 skipped = _mm256_and_ps(_mm256_cmp_ps(s, _mm256_set1_ps(g.range.first_end), _CMP_GT_OQ),
                                             _mm256_cmp_ps(s, _mm256_set1_ps(g.range.last_begin), _CMP_LT_OQ));
        tested[q] = _mm256_andnot_ps(skipped, in_segment);
        tested_bits[q] = _mm256_movemask_ps(tested[q]);
        points[q] = s;
        lanes[q] = &r.lanes;
        _mm256_store_ps(at[q], s);
      }
      flags_of<P, F, M>(c, L, tx, n_linear, lanes, points, tested, found);
      int still = 0;
      for (int q = 0; q < n_linear; ++q) {
        const int i = linear[q];
        Ray& r = rays[i];
        const int hits = (found[q] ^ r.start) & tested_bits[q];
        if (hits == 0) {
          samples += static_cast<std::uint32_t>(std::popcount(static_cast<unsigned>(tested_bits[q])));
          r.k0 += 8;
          if (r.k0 <= segs[b0 + i].steps) linear[still++] = i;
          continue;
        }
        const int j = std::countr_zero(static_cast<unsigned>(hits)) & 7;
        samples +=
            static_cast<std::uint32_t>(std::popcount(static_cast<unsigned>(tested_bits[q]) & ((2u << j) - 1u)));
        const float lo = j > 0 ? at[q][j - 1] : (r.k0 > 1 ? static_cast<float>(r.k0 - 1) * r.ds : 0.0f);
        crossings[n_cross++] = {b0 + i, lo, at[q][j], r.start != 0};
      }
      n_linear = still;
    }
  }
  samples += static_cast<std::uint64_t>(n_cross) * halvings;
  if (n_cross == 1) {
    std::uint64_t counted = 0;  // already added
    const Crossing& x = crossings[0];
    CellSegment& g = segs[x.seg];
    g.hit = refine<P, F, M>(c, tx, g.e, g.dl, x.lo, x.hi, x.start, halvings, counted);
    return;
  }
  for (int q = 0; q < n_cross; q += 16) {
    const int n = std::min(16, n_cross - q);
    if (n > 8)
      refine_lanes<P, F, M, 2>(c, L, tx, segs, crossings + q, n, halvings);
    else
      refine_lanes<P, F, M, 1>(c, L, tx, segs, crossings + q, n, halvings);
  }
}
/// pixel_direction for pixels x .. x + 3 of a row, and their directions in grid units (times inv_cs) with
/// the reciprocals: the same operations in the same order, 4 pixels at a time.
__attribute__((target("avx2"))) void pixel_rays4(const Camera& camera, const Vec3& row, std::uint32_t x,
                                                 double inv_cs, double (&dir)[3][4], double (&dg)[3][4],
                                                 double (&inv)[3][4]) {
  const double aspect = static_cast<double>(camera.width) / camera.height;
  const auto x0 = static_cast<double>(x);
  __m256d sx = _mm256_add_pd(_mm256_setr_pd(x0, x0 + 1.0, x0 + 2.0, x0 + 3.0), _mm256_set1_pd(0.5));
  sx = _mm256_div_pd(sx, _mm256_set1_pd(static_cast<double>(camera.width)));
  sx = _mm256_sub_pd(_mm256_mul_pd(sx, _mm256_set1_pd(2.0)), _mm256_set1_pd(1.0));
  sx = _mm256_mul_pd(_mm256_mul_pd(sx, _mm256_set1_pd(camera.tan_half_fov)), _mm256_set1_pd(aspect));
  __m256d d[3];
  for (int k = 0; k < 3; ++k)
    d[k] = _mm256_add_pd(_mm256_set1_pd(row[k]), _mm256_mul_pd(sx, _mm256_set1_pd(camera.right[k])));
  const __m256d norm = _mm256_sqrt_pd(_mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(d[0], d[0]), _mm256_mul_pd(d[1], d[1])),
                                                    _mm256_mul_pd(d[2], d[2])));
  for (int k = 0; k < 3; ++k) {
    const __m256d u = _mm256_div_pd(d[k], norm);
    const __m256d g = _mm256_mul_pd(u, _mm256_set1_pd(inv_cs));
    _mm256_storeu_pd(dir[k], u);
    _mm256_storeu_pd(dg[k], g);
    _mm256_storeu_pd(inv[k], _mm256_div_pd(_mm256_set1_pd(1.0), g));
  }
}
/// cell_segment and the empty-space bounds of prepare (may_hit, may_range, the step count) for the rays of
/// 4 pixels (lanes) through cell c, none with a zero direction component: dg[a] and inv[a] point to their 4
/// values on axis a, og is their common origin, lo / hi as for cell_segment. The same operations in the
/// same order as the scalar functions, lane by lane. Returns the lanes of `lanes` whose ray crosses the
/// cell and may meet the surface there, with their segments in segs[q] and entry parameters in t0[q].
__attribute__((target("avx2"))) int prepare4(const CellData& c, const double lo[3], const double hi[3],
                                             const double og[3], const std::int64_t idx[3], const double* const dg[3],
                                             const double* const inv[3], int lanes, double min_steps,
                                             double steps_per_unit, CellSegment (&segs)[4], double (&t0)[4]) {
  constexpr float kSlack = 1e-4f;
  __m256d first = _mm256_setzero_pd(), last = _mm256_set1_pd(kInf), g[3];
  for (int a = 0; a < 3; ++a) {
    g[a] = _mm256_loadu_pd(dg[a]);
    const __m256d iv = _mm256_loadu_pd(inv[a]);
    const __m256d p = _mm256_mul_pd(_mm256_set1_pd(lo[a]), iv), q = _mm256_mul_pd(_mm256_set1_pd(hi[a]), iv);
    first = _mm256_max_pd(_mm256_min_pd(q, p), first);  // std::max(first, std::min(p, q))
    last = _mm256_min_pd(_mm256_max_pd(q, p), last);    // std::min(last, std::max(p, q))
  }
  int ok = lanes & _mm256_movemask_pd(_mm256_cmp_pd(last, first, _CMP_GT_OQ));
  if (ok == 0) return 0;
  const __m256d len = _mm256_sub_pd(last, first);
  const __m128 flen = _mm256_cvtpd_ps(len);
  __m128 e[3], dl[3], ec[3], xc[3];
  const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f);
  for (int a = 0; a < 3; ++a) {
    e[a] = _mm256_cvtpd_ps(_mm256_sub_pd(_mm256_add_pd(_mm256_set1_pd(og[a]), _mm256_mul_pd(first, g[a])),
                                         _mm256_set1_pd(static_cast<double>(idx[a]))));
    dl[a] = _mm256_cvtpd_ps(g[a]);
    ec[a] = _mm_min_ps(one, _mm_max_ps(zero, e[a]));
    xc[a] = _mm_min_ps(one, _mm_max_ps(zero, _mm_add_ps(e[a], _mm_mul_ps(flen, dl[a]))));
  }
  const auto type = static_cast<ProjectionType>(c.type);
  if (c.min_dist > 0.0f && (type == ProjectionType::Perspective || type == ProjectionType::Axial)) {  // may_hit
    __m128 w[3], v[3];
    for (int k = 0; k < 3; ++k) {
      w[k] = _mm_sub_ps(ec[k], _mm_set1_ps(c.point[k]));
      v[k] = _mm_sub_ps(xc[k], ec[k]);
    }
    if (type == ProjectionType::Axial) w[c.axis] = v[c.axis] = zero;
    const __m128 vv = _mm_add_ps(_mm_add_ps(_mm_mul_ps(v[0], v[0]), _mm_mul_ps(v[1], v[1])), _mm_mul_ps(v[2], v[2]));
    const __m128 wv = _mm_add_ps(_mm_add_ps(_mm_mul_ps(w[0], v[0]), _mm_mul_ps(w[1], v[1])), _mm_mul_ps(w[2], v[2]));
    const __m128 x = _mm_div_ps(_mm_xor_ps(wv, _mm_set1_ps(-0.0f)), vv);
    const __m128 clamped =
        _mm_blendv_ps(_mm_blendv_ps(x, one, _mm_cmplt_ps(one, x)), zero, _mm_cmplt_ps(x, zero));  // std::clamp
    const __m128 sv = _mm_blendv_ps(zero, clamped, _mm_cmpgt_ps(vv, zero));
    __m128 r2 = zero;
    for (int k = 0; k < 3; ++k) {
      const __m128 t = _mm_add_ps(w[k], _mm_mul_ps(sv, v[k]));
      r2 = _mm_add_ps(r2, _mm_mul_ps(t, t));
    }
    const __m128 bound = _mm_add_ps(_mm_sub_ps(_mm_set1_ps(c.reach), _mm_sqrt_ps(r2)), _mm_set1_ps(kSlack));
    ok &= _mm_movemask_ps(_mm_cmpge_ps(bound, _mm_set1_ps(c.min_dist)));
  }
  __m128 first_end = _mm_set1_ps(kInfF), last_begin = _mm_set1_ps(kInfF);
  if (c.mode == kBorderCell) {  // may_range
    first_end = _mm_set1_ps(-kInfF);
    __m128 unbounded = zero;
    for (int f = 0; f < 6; ++f) {
      const float need = c.min_height[f] - kSlack;
      if (!(need <= 1.0f)) continue;
      const int a = f / 2;
      const __m128 h0 = (f & 1) ? _mm_sub_ps(one, e[a]) : e[a];
      const __m128 hd = (f & 1) ? _mm_xor_ps(dl[a], _mm_set1_ps(-0.0f)) : dl[a];
      const __m128 x = _mm_div_ps(_mm_sub_ps(_mm_set1_ps(need), h0), hd);
      last_begin = _mm_blendv_ps(last_begin, _mm_min_ps(x, last_begin), _mm_cmpgt_ps(hd, zero));
      first_end = _mm_blendv_ps(first_end, _mm_max_ps(x, first_end), _mm_cmplt_ps(hd, zero));
      unbounded = _mm_or_ps(unbounded, _mm_and_ps(_mm_cmpeq_ps(hd, zero), _mm_cmpge_ps(h0, _mm_set1_ps(need))));
    }
    first_end = _mm_blendv_ps(first_end, _mm_set1_ps(kInfF), unbounded);
    last_begin = _mm_blendv_ps(last_begin, _mm_set1_ps(kInfF), unbounded);
  }
  ok &= ~_mm_movemask_ps(_mm_and_ps(_mm_cmplt_ps(first_end, zero), _mm_cmpgt_ps(last_begin, flen)));  // !empty
  const __m256d steps = _mm256_max_pd(
      _mm256_round_pd(_mm256_sub_pd(_mm256_mul_pd(len, _mm256_set1_pd(steps_per_unit)), _mm256_set1_pd(1e-6)),
                      _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC),
      _mm256_set1_pd(min_steps));
  alignas(32) float ev[3][4], dv[3][4], lv[4], fe[4], lb[4];
  alignas(32) double sv[4], tv[4];
  for (int a = 0; a < 3; ++a) {
    _mm_store_ps(ev[a], e[a]);
    _mm_store_ps(dv[a], dl[a]);
  }
  _mm_store_ps(lv, flen);
  _mm_store_ps(fe, first_end);
  _mm_store_ps(lb, last_begin);
  _mm256_store_pd(sv, steps);
  _mm256_store_pd(tv, first);
  for (int bits = ok; bits != 0; bits &= bits - 1) {
    const int q = std::countr_zero(static_cast<unsigned>(bits));
    CellSegment& seg = segs[q];
    for (int a = 0; a < 3; ++a) {
      seg.e[a] = ev[a][q];
      seg.dl[a] = dv[a][q];
    }
    seg.len = lv[q];
    seg.range = {fe[q], lb[q]};
    seg.steps = static_cast<std::uint32_t>(sv[q]);
    t0[q] = tv[q];
  }
  return ok;
}
#endif  // GIMFORGE_RELIEF_AVX2

/// The marches of `count` (<= kMaxMarch) segments through cell c with the functions for its mode and
/// projection type: march_avx2 with Vectorized, else march, one segment after the other; then the
/// projections of the hits.
template <ReliefFilter F, bool Vectorized>
void march_cell(const CellData& c, const Texels& tx, CellSegment* segs, int count, std::uint32_t halvings,
                std::uint64_t& samples) {
  constexpr auto kParallel = ProjectionType::Parallel, kPlanar = ProjectionType::Planar;
  constexpr auto kPersp = ProjectionType::Perspective, kAxial = ProjectionType::Axial;
  auto run = [&]<ProjectionType P, CellMode M>() {
#if GIMFORGE_RELIEF_AVX2
    if constexpr (Vectorized) {
      march_avx2<P, F, M>(c, tx, segs, count, halvings, samples);
      return;
    }
#endif
    for (int i = 0; i < count; ++i) {
      CellSegment& g = segs[i];
      g.hit = march<P, F, M>(c, tx, g.e, g.dl, g.len, g.steps, halvings, g.range, samples);
    }
  };
  // The march, then the projection of each hit (for its texels).
  auto run_and_project = [&]<ProjectionType P, CellMode M>() {
    run.template operator()<P, M>();
    for (int i = 0; i < count; ++i) {
      CellSegment& g = segs[i];
      if (g.hit < 0.0f) continue;
      const float p[3] = {clamp01(g.e[0] + g.hit * g.dl[0]), clamp01(g.e[1] + g.hit * g.dl[1]),
                          clamp01(g.e[2] + g.hit * g.dl[2])};
      g.projected = project<P>(c, p, g.at_hit);
      // The hit's normals are read after every hit of the cell is projected: fetch their two rows now.
      const std::uint32_t base = g.projected ? c.layer_base[g.at_hit.face] : kNoLayer;
      if (base != kNoLayer) {
        const std::int32_t i0 = std::min(static_cast<std::int32_t>(g.at_hit.u * tx.tm1), tx.T - 2);
        const std::int32_t j0 = std::min(static_cast<std::int32_t>(g.at_hit.v * tx.tm1), tx.T - 2);
        const std::size_t first = base + static_cast<std::size_t>(j0 * tx.T + i0);
        __builtin_prefetch(tx.normals + 3 * first);
        __builtin_prefetch(tx.normals + 3 * (first + static_cast<std::size_t>(tx.T)));
      }
    }
  };
  switch (c.mode) {
    case kInteriorOutside: return run_and_project.template operator()<kPersp, kInteriorOutside>();
    case kInteriorInside: return run_and_project.template operator()<kPersp, kInteriorInside>();
    case kInteriorRelative: return run_and_project.template operator()<kPersp, kInteriorRelative>();
    default: break;
  }
  switch (static_cast<ProjectionType>(c.type)) {
    case ProjectionType::Parallel: return run_and_project.template operator()<kParallel, kBorderCell>();
    case ProjectionType::Planar: return run_and_project.template operator()<kPlanar, kBorderCell>();
    case ProjectionType::Perspective: return run_and_project.template operator()<kPersp, kBorderCell>();
    case ProjectionType::Axial: return run_and_project.template operator()<kAxial, kBorderCell>();
  }
}

/// What a hit at (u, v) of the layer at `base` reads, from one read of the 2×2 texels around (u, v): the
/// stored distance (unit cell) as the bilinear filter reads it (+inf where the deciding texel is empty),
/// for the wall test, and the stored normal, interpolated bilinearly over the non-empty texels of the 2×2
/// (the quantized normals need no scaling before the normalization); with no weight on them, any
/// non-empty texel of the 2×2, else the nearest non-empty texel within two texels; zero if none.
struct HitTexels {
  float stored;
  Vec3 normal;
};

HitTexels read_hit_texels(const Texels& tx, std::uint32_t base, float u, float v) {
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

void check_options(const RaycastOptions& o) {
  if (o.linear_steps < 1 || o.linear_steps > 1024)
    throw InvalidInput(fmt::format("relief ray casting: linear steps {} out of range 1..1024", o.linear_steps));
  if (o.binary_steps > 32)
    throw InvalidInput(fmt::format("relief ray casting: binary steps {} out of range 0..32", o.binary_steps));
  if (!(o.ambient >= 0.0 && o.ambient <= 1.0))
    throw InvalidInput(fmt::format("relief ray casting: ambient {} out of range 0..1", o.ambient));
}

void check_camera(const Camera& camera) {
  if (camera.width == 0 || camera.height == 0)
    throw InvalidInput(fmt::format("render: image size {}x{} is empty", camera.width, camera.height));
  if (static_cast<std::uint64_t>(camera.width) * camera.height > (std::uint64_t{1} << 28))
    throw InvalidInput(fmt::format("render: image size {}x{} is too large", camera.width, camera.height));
  if (!camera.eye.allFinite() || !camera.forward.allFinite() || !camera.right.allFinite() || !camera.up.allFinite() ||
      !(camera.tan_half_fov > 0.0) || !std::isfinite(camera.tan_half_fov))
    throw InvalidInput("render: camera with non-finite position, axes or field of view");
}

RenderImage blank_image(const Camera& camera) {
  RenderImage img;
  img.width = camera.width;
  img.height = camera.height;
  const std::size_t n = static_cast<std::size_t>(camera.width) * camera.height;
  img.mask.assign(n, 0);
  img.depth.assign(n, std::numeric_limits<float>::infinity());
  img.position.assign(n, Vec3f::Zero());
  img.normal.assign(n, Vec3f::Zero());
  img.shaded.assign(n, 0);
  img.rays = n;
  return img;
}

/// The part of the ray directions of pixel row y that the row shares: forward + sy · up.
Vec3 pixel_row(const Camera& camera, std::uint32_t y) {
  const double sy = (1.0 - (y + 0.5) / camera.height * 2.0) * camera.tan_half_fov;
  return camera.forward + sy * camera.up;
}

/// The unit direction of the ray through pixel x of a row (Camera::ray_direction up to rounding). Every
/// renderer computes it in this order, so that the traversals of a relief render cast the same rays.
Vec3 pixel_direction(const Camera& camera, const Vec3& row, std::uint32_t x) {
  const double aspect = static_cast<double>(camera.width) / camera.height;
  const double sx = ((x + 0.5) / camera.width * 2.0 - 1.0) * camera.tan_half_fov * aspect;
  const double d[3] = {row[0] + sx * camera.right[0], row[1] + sx * camera.right[1], row[2] + sx * camera.right[2]};
  const double norm = std::sqrt((d[0] * d[0] + d[1] * d[1]) + d[2] * d[2]);
  return Vec3(d[0] / norm, d[1] / norm, d[2] / norm);
}

/// Writes the hit of pixel p, whose ray has the unit direction dir, into the image (and flags walls).
void record_hit(RenderImage& img, std::vector<std::uint8_t>* walls, std::size_t p, const RayHit& hit, const Vec3& dir,
                double ambient) {
  img.mask[p] = 1;
  img.depth[p] = static_cast<float>(hit.t);
  img.position[p] = hit.position.cast<float>();
  img.normal[p] = hit.normal.cast<float>();
  img.shaded[p] = shade_grey(hit.normal, dir, ambient);
  if (walls) (*walls)[p] = hit.discontinuity ? 1 : 0;
}

/// Renders with `trace(origin, unit direction, samples) -> RayHit`, rows in parallel.
template <class Trace>
void render_rows(const Camera& camera, double ambient, RenderImage& img, const Trace& trace,
                 std::vector<std::uint8_t>* walls = nullptr) {
  std::atomic<std::uint64_t> hits{0}, samples{0};
  const auto t0 = Clock::now();
  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, camera.height, kRowGrain),
                    [&](const tbb::blocked_range<std::uint32_t>& rows) {
                      std::uint64_t h = 0, s = 0;
                      for (std::uint32_t y = rows.begin(); y != rows.end(); ++y) {
                        const Vec3 row = pixel_row(camera, y);
                        for (std::uint32_t x = 0; x < camera.width; ++x) {
                          const Vec3 dir = pixel_direction(camera, row, x);
                          const RayHit hit = trace(camera.eye, dir, s);
                          if (!hit.hit) continue;
                          ++h;
                          record_hit(img, walls, static_cast<std::size_t>(y) * camera.width + x, hit, dir, ambient);
                        }
                      }
                      hits += h;
                      samples += s;
                    });
  img.seconds = seconds_since(t0);
  img.hits = hits.load();
  img.samples = samples.load();
}

/// Replaces the normals of wall hits (flagged in `walls`) by the normal of the rendered surface itself,
/// from the world positions of the neighbouring pixels (central differences where both neighbours are
/// hits on the same surface, else one-sided), and shades them again. Neighbours across a depth jump of
/// more than kWallDepthPixels pixel footprints are not used; without usable neighbours on both axes the
/// stored normal stays.
void fix_wall_normals(const Camera& camera, double ambient, const std::vector<std::uint8_t>& walls, RenderImage& img) {
  constexpr double kWallDepthPixels = 8.0;
  constexpr std::int64_t kWallReach = 1;
  const double footprint = 2.0 * camera.tan_half_fov / camera.height;  // per unit depth
  const std::uint32_t W = camera.width, H = camera.height;
  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, H, 16), [&](const tbb::blocked_range<std::uint32_t>& rows) {
    for (std::uint32_t y = rows.begin(); y != rows.end(); ++y) {
      for (std::uint32_t x = 0; x < W; ++x) {
        const std::size_t p = static_cast<std::size_t>(y) * W + x;
        if (!walls[p]) continue;
        const double limit = kWallDepthPixels * footprint * static_cast<double>(img.depth[p]);
        auto usable = [&](std::int64_t xx, std::int64_t yy) {
          if (xx < 0 || yy < 0 || xx >= W || yy >= H) return false;
          const std::size_t q = static_cast<std::size_t>(yy) * W + static_cast<std::size_t>(xx);
          return img.mask[q] != 0 &&
                 std::abs(static_cast<double>(img.depth[q]) - static_cast<double>(img.depth[p])) <= limit;
        };
        auto pos = [&](std::int64_t xx, std::int64_t yy) {
          return img.position[static_cast<std::size_t>(yy) * W + static_cast<std::size_t>(xx)].cast<double>();
        };
        // The difference of the positions of the nearest usable (hit, no depth jump) pixels within
        // kWallReach on either side along (dx, dy), or the pixel itself on one side.
        auto difference = [&](int dx, int dy, Vec3& out) {
          const auto xi = static_cast<std::int64_t>(x), yi = static_cast<std::int64_t>(y);
          std::int64_t fwd = 0, bwd = 0;
          for (std::int64_t k = 1; k <= kWallReach && fwd == 0; ++k)
            if (usable(xi + k * dx, yi + k * dy)) fwd = k;
          for (std::int64_t k = 1; k <= kWallReach && bwd == 0; ++k)
            if (usable(xi - k * dx, yi - k * dy)) bwd = k;
          if (fwd == 0 && bwd == 0) return false;
          const Vec3 a = fwd ? pos(xi + fwd * dx, yi + fwd * dy) : pos(xi, yi);
          const Vec3 b = bwd ? pos(xi - bwd * dx, yi - bwd * dy) : pos(xi, yi);
          out = a - b;
          return true;
        };
        Vec3 du, dv;
        if (!difference(1, 0, du) || !difference(0, 1, dv)) continue;
        const Vec3 nrm = du.cross(dv);
        if (!(nrm.squaredNorm() > 0.0) || !nrm.allFinite()) continue;
        const Vec3 unit = nrm.normalized();
        img.normal[p] = unit.cast<float>();
        img.shaded[p] = shade_grey(unit, camera.ray_direction(x, y), ambient);
      }
    }
  });
}

}  // namespace

// ---------------------------------------------------------------------------------------------------
// Camera, shading, bounds.

Vec3 Camera::ray_direction(double x, double y) const {
  const double aspect = static_cast<double>(width) / static_cast<double>(height);
  const double sx = ((x + 0.5) / width * 2.0 - 1.0) * tan_half_fov * aspect;
  const double sy = (1.0 - (y + 0.5) / height * 2.0) * tan_half_fov;
  return (forward + sx * right + sy * up).normalized();
}

Camera orbit_camera(const BoundingBox& box, const OrbitView& view, std::uint32_t width, std::uint32_t height) {
  if (box.empty() || !box.min.allFinite() || !box.max.allFinite())
    throw InvalidInput("render: the bounding box to frame is empty or not finite");
  if (width == 0 || height == 0) throw InvalidInput(fmt::format("render: image size {}x{} is empty", width, height));
  if (!(view.elevation_deg >= -90.0 && view.elevation_deg <= 90.0))
    throw InvalidInput(fmt::format("render: elevation {} out of range -90..90", view.elevation_deg));
  if (!std::isfinite(view.azimuth_deg)) throw InvalidInput("render: azimuth is not finite");
  if (!(view.fov_deg >= 1.0 && view.fov_deg <= 170.0))
    throw InvalidInput(fmt::format("render: field of view {} out of range 1..170", view.fov_deg));
  if (view.up_axis < 0 || view.up_axis > 2)
    throw InvalidInput(fmt::format("render: up axis {} out of range 0..2", view.up_axis));
  if (!(view.margin > 0.0) || !std::isfinite(view.margin))
    throw InvalidInput(fmt::format("render: margin {} must be positive", view.margin));
  const double deg = std::numbers::pi / 180.0;
  const double az = view.azimuth_deg * deg, el = view.elevation_deg * deg;
  const int a = view.up_axis, b = (a + 1) % 3, c = (a + 2) % 3;
  Vec3 e, tangent;  // eye direction from the centre and its derivative in elevation (screen up)
  e[b] = std::cos(el) * std::cos(az);
  e[c] = std::cos(el) * std::sin(az);
  e[a] = std::sin(el);
  tangent[b] = -std::sin(el) * std::cos(az);
  tangent[c] = -std::sin(el) * std::sin(az);
  tangent[a] = std::cos(el);
  const Vec3 centre = 0.5 * (box.min + box.max);
  double radius = 0.5 * box.diagonal() * view.margin;
  if (!(radius > 0.0)) radius = 1e-6 * std::max(1.0, centre.norm());
  Camera cam;
  cam.width = width;
  cam.height = height;
  cam.tan_half_fov = std::tan(0.5 * view.fov_deg * deg);
  const double tan_narrow = cam.tan_half_fov * std::min(1.0, static_cast<double>(width) / height);
  const double distance = radius / std::sin(std::atan(tan_narrow));
  cam.eye = centre + distance * e;
  cam.forward = -e.normalized();
  cam.up = tangent.normalized();
  cam.right = cam.forward.cross(cam.up).normalized();
  return cam;
}

BoundingBox relief_surface_bounds(const ReliefMap& map) {
  const std::uint32_t T = map.texture;
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, map.num_layers(), 16), BoundingBox{},
      [&](const tbb::blocked_range<std::size_t>& range, BoundingBox box) {
        for (std::size_t l = range.begin(); l != range.end(); ++l)
          for (std::uint32_t j = 0; j < T; ++j)
            for (std::uint32_t i = 0; i < T; ++i)
              if (map.distances[map.texel_index(l, i, j)] != kEmptyTexel) box.extend(map.texel_surface_point(l, i, j));
        return box;
      },
      [](BoundingBox x, const BoundingBox& y) {
        x.min = x.min.cwiseMin(y.min);
        x.max = x.max.cwiseMax(y.max);
        return x;
      });
}

std::uint8_t shade_grey(const Vec3& normal, const Vec3& direction, double ambient) {
  const double lambert = std::min(1.0, std::abs(normal.dot(direction)));
  return static_cast<std::uint8_t>(std::lround(std::clamp(255.0 * (ambient + (1.0 - ambient) * lambert), 0.0, 255.0)));
}

std::vector<std::uint8_t> RenderImage::shaded_rgb() const {
  std::vector<std::uint8_t> rgb(3 * shaded.size());
  for (std::size_t p = 0; p < shaded.size(); ++p) rgb[3 * p] = rgb[3 * p + 1] = rgb[3 * p + 2] = shaded[p];
  return rgb;
}

// ---------------------------------------------------------------------------------------------------
// The relief ray caster.

struct ReliefRaycaster::Impl {
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
  Texels texels{};
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

  Impl(const ReliefMap& m, const RaycastOptions& o) : map(m), options(o) {
    check_options(o);
    map.check();
    const std::size_t G = map.cells.size();
    const std::uint32_t T = map.texture;
    const std::size_t tpl = map.texels_per_layer();
    cells.resize(G);
    std::vector<std::uint8_t> useful(G, 0);  // the cell's maps hold at least one surface sample
    for (std::size_t g = 0; g < G; ++g) {
      const CellProjection& p = map.projections[g];
      CellData& c = cells[g];
      for (int a = 0; a < 3; ++a) c.point[a] = static_cast<float>(p.point[a]);
      c.type = static_cast<std::uint8_t>(p.type);
      c.axis = p.axis;
      c.side = p.type == ProjectionType::Parallel && p.direction[p.axis] > 0.0 ? 1 : 0;
      c.mode = map.external_faces[g] == 0 ? kInteriorRelative : kBorderCell;
      std::fill(std::begin(c.layer_base), std::end(c.layer_base), kNoLayer);
      std::uint16_t qmin = kEmptyTexel;
      std::uint16_t face_qmin[6];
      std::fill(std::begin(face_qmin), std::end(face_qmin), kEmptyTexel);
      for (std::uint32_t l = map.first_layer[g]; l < map.first_layer[g + 1]; ++l) {
        c.layer_base[map.layer_face[l]] = static_cast<std::uint32_t>(l * tpl);
        const auto* first = map.distances.data() + l * tpl;
        face_qmin[map.layer_face[l]] = *std::min_element(first, first + tpl);
        qmin = std::min(qmin, face_qmin[map.layer_face[l]]);
      }
      useful[g] = qmin != kEmptyTexel ? 1 : 0;
      c.min_dist = c.mode == kBorderCell && useful[g]
                       ? static_cast<float>(dequantize_distance(qmin, map.distance_scale) / map.cell_size)
                       : -1.0f;
      // Farthest cell corner from the centre of projection (axial: in the plane across the axis).
      double reach = 0.0;
      for (int corner = 0; corner < 8; ++corner) {
        Vec3 d = Vec3((corner & 1) ? 1.0 : 0.0, (corner & 2) ? 1.0 : 0.0, (corner & 4) ? 1.0 : 0.0) - p.point;
        if (p.type == ProjectionType::Axial) d[p.axis] = 0.0;
        reach = std::max(reach, d.norm());
      }
      c.reach = static_cast<float>(reach * (1.0 + 1e-6));
      set_min_heights(c, p, face_qmin);
      for (int f = 0; f < 6; ++f) c.face_qmin[f] = static_cast<float>(face_qmin[f]);
      if (!options.cull_empty_space) {  // bounds that never cull
        c.min_dist = -1.0f;
        for (int f = 0; f < 6; ++f) {
          c.min_height[f] = 0.0f;
          c.face_qmin[f] = -1.0f;
        }
      }
    }
    const std::uint64_t n = map.n;
    for (std::size_t g = 0; g < G; ++g) {
      if (!useful[g]) continue;
      const std::uint32_t linear = map.cells[g];
      useful_cells.push_back({static_cast<std::int32_t>(g),
                              {static_cast<std::int32_t>(linear % n), static_cast<std::int32_t>(linear / n % n),
                               static_cast<std::int32_t>(linear / (n * n))}});
    }
    dense = map.n <= kMaxDenseGrid;
    if (dense) {
      table.assign(n * n * n, -1);
      for (std::size_t g = 0; g < G; ++g)
        if (useful[g]) table[map.cells[g]] = static_cast<std::int32_t>(g);
    } else {
      const std::size_t count = static_cast<std::size_t>(std::count(useful.begin(), useful.end(), std::uint8_t{1}));
      const std::uint32_t capacity = std::bit_ceil(static_cast<std::uint32_t>(std::max<std::size_t>(2 * count, 16)));
      hash_mask = capacity - 1;
      hash_shift = 32 - std::countr_zero(capacity);
      keys.assign(capacity, HashLookup::kEmptyKey);
      values.assign(capacity, -1);
      const HashLookup h{keys.data(), values.data(), hash_mask, hash_shift};
      for (std::size_t g = 0; g < G; ++g) {
        if (!useful[g]) continue;
        std::uint32_t s = h.slot(map.cells[g]);
        while (keys[s] != HashLookup::kEmptyKey) s = (s + 1) & hash_mask;
        keys[s] = map.cells[g];
        values[s] = static_cast<std::int32_t>(g);
      }
    }
    texels.dist = map.distances.data();
    texels.normals = map.normals.data();
    texels.T = static_cast<std::int32_t>(T);
    texels.tm1 = static_cast<float>(T - 1);
    texels.inv_scale = static_cast<float>(map.cell_size / map.distance_scale);
    inv_cs = 1.0 / map.cell_size;
    wall_tolerance = kWallTexels / static_cast<float>(T - 1);
    steps_per_unit = options.linear_steps * inv_cs;
    min_steps = std::max(1u, (options.linear_steps + 1) / 2);
    resolve_interior_cells();
#if GIMFORGE_RELIEF_AVX2
    // The gathers index the distances with 32-bit signed texel offsets.
    avx2 = o.vectorized && map.distances.size() < (std::size_t{1} << 31) - 2 * std::size_t{T} &&
           __builtin_cpu_supports("avx2");
#endif
  }

  /// CellData::min_height of border cell c with projection p and per-face smallest quantized distances.
  void set_min_heights(CellData& c, const CellProjection& p, const std::uint16_t (&face_qmin)[6]) const {
    for (int f = 0; f < 6; ++f) {
      c.min_height[f] = 0.0f;
      if (c.mode != kBorderCell) continue;
      const int a = f / 2;
      const double plane = (f & 1) ? 1.0 : 0.0;
      if (c.layer_base[f] == kNoLayer || face_qmin[f] == kEmptyTexel ||
          (c.type == static_cast<std::uint8_t>(ProjectionType::Parallel) && f != 2 * c.axis + c.side) ||
          (c.type == static_cast<std::uint8_t>(ProjectionType::Planar) && a != c.axis) ||
          (c.type == static_cast<std::uint8_t>(ProjectionType::Axial) && a == c.axis)) {
        c.min_height[f] = kInfF;  // no sample projects onto f, or f's maps are empty
        continue;
      }
      double k = 1.0;  // parallel, planar: the projected distance is the height
      if (c.type == static_cast<std::uint8_t>(ProjectionType::Perspective) ||
          c.type == static_cast<std::uint8_t>(ProjectionType::Axial)) {
        const double normal = std::abs(plane - p.point[a]);
        if (!(normal > 1e-9)) continue;  // centre on the plane of f: no bound
        const int b = (a + 1) % 3, d = (a + 2) % 3;
        double longest = 0.0;  // over the corners of f: the farthest from the centre (axial: from the axis)
        for (int corner = 0; corner < 4; ++corner) {
          Vec3 q;
          q[a] = plane;
          q[b] = (corner & 1) ? 1.0 : 0.0;
          q[d] = (corner & 2) ? 1.0 : 0.0;
          Vec3 v = q - p.point;
          if (c.type == static_cast<std::uint8_t>(ProjectionType::Axial)) v[p.axis] = 0.0;
          longest = std::max(longest, v.norm());
        }
        k = longest / normal * (1.0 + 1e-6);
      }
      const double m = dequantize_distance(face_qmin[f], map.distance_scale) / map.cell_size;
      c.min_height[f] = static_cast<float>(m / k);
    }
  }

  /// Side of the unit-cell point p of grey cell g (any projection type; bilinear filter).
  [[nodiscard]] Side side_of(std::size_t g, const float p[3]) const {
    const CellData& c = cells[g];
    switch (static_cast<ProjectionType>(c.type)) {
      case ProjectionType::Parallel: return point_side<ProjectionType::Parallel, ReliefFilter::Bilinear>(c, texels, p);
      case ProjectionType::Planar: return point_side<ProjectionType::Planar, ReliefFilter::Bilinear>(c, texels, p);
      case ProjectionType::Perspective:
        return point_side<ProjectionType::Perspective, ReliefFilter::Bilinear>(c, texels, p);
      case ProjectionType::Axial: return point_side<ProjectionType::Axial, ReliefFilter::Bilinear>(c, texels, p);
    }
    return Side::Empty;
  }

  /// Whether the unit-cell point p of grey cell g is inside the object as the cell's maps tell: 1, 0, or
  /// −1 when g is an interior cell whose centre is undecided.
  [[nodiscard]] int inside_at(std::size_t g, const float p[3]) const {
    const Side side = side_of(g, p);
    switch (cells[g].mode) {
      case kBorderCell: return side == Side::Beyond ? 1 : 0;
      case kInteriorOutside: return side == Side::Before ? 1 : 0;
      case kInteriorInside: return side != Side::Before ? 1 : 0;
      default: return -1;
    }
  }

  /// Decides, for every interior grey cell, whether its centre C (the centre of projection) is inside the
  /// object, by votes over a grid of about 16 × 16 texels of each of its six faces: a texel point P' whose
  /// status is known (the neighbour across the face is not grey, hence black: inside; or it is a border
  /// cell or a decided interior cell, whose maps classify P') votes "C on the same side as P'" when its
  /// segment is empty and "C on the other side" when it holds a surface sample. Repeated while cells get
  /// decided (an interior cell surrounded by interior cells waits for its neighbours); cells without
  /// votes stay kInteriorRelative.
  void resolve_interior_cells() {
    const std::uint32_t n = map.n, T = map.texture;
    const std::uint32_t stride = std::max<std::uint32_t>(1, (T - 1) / 15);
    auto grey_at = [&](std::uint64_t linear) -> std::int64_t {
      const auto it = std::lower_bound(map.cells.begin(), map.cells.end(), linear);
      return it != map.cells.end() && *it == linear ? it - map.cells.begin() : -1;
    };
    std::vector<std::size_t> pending;
    for (std::size_t g = 0; g < cells.size(); ++g)
      if (cells[g].mode == kInteriorRelative) pending.push_back(g);
    for (int pass = 0; pass < 64 && !pending.empty(); ++pass) {
      std::vector<std::size_t> still;
      for (const std::size_t g : pending) {
        const std::uint64_t linear = map.cells[g];
        const std::uint64_t ijk[3] = {linear % n, linear / n % n, linear / (static_cast<std::uint64_t>(n) * n)};
        std::int64_t votes_in = 0, votes_out = 0;
        for (int f = 0; f < 6; ++f) {
          const int a = f / 2;
          const bool high = (f % 2) != 0;
          std::uint64_t nb[3] = {ijk[0], ijk[1], ijk[2]};
          if (high ? nb[a] + 1 >= n : nb[a] == 0) continue;  // cannot happen for an interior cell
          nb[a] = high ? nb[a] + 1 : nb[a] - 1;
          const std::int64_t h = grey_at((nb[2] * n + nb[1]) * n + nb[0]);
          const std::uint32_t base = cells[g].layer_base[f];
          if (base == kNoLayer) continue;
          for (std::uint32_t j = 0; j < T; j += stride) {
            for (std::uint32_t i = 0; i < T; i += stride) {
              const Vec3 q = face_point(f, map.texel_coord(i), map.texel_coord(j));
              int face_inside = 1;  // black neighbour
              if (h >= 0) {
                float ph[3] = {static_cast<float>(q[0]), static_cast<float>(q[1]), static_cast<float>(q[2])};
                ph[a] = high ? 0.0f : 1.0f;
                face_inside = inside_at(static_cast<std::size_t>(h), ph);
                if (face_inside < 0) continue;
              }
              const bool empty = map.distances[base + static_cast<std::size_t>(j) * T + i] == kEmptyTexel;
              const bool centre_inside = empty ? face_inside == 1 : face_inside == 0;
              (centre_inside ? votes_in : votes_out) += 1;
            }
          }
        }
        if (votes_in == votes_out)
          still.push_back(g);
        else
          cells[g].mode = votes_in > votes_out ? kInteriorInside : kInteriorOutside;
      }
      if (still.size() == pending.size()) break;
      pending.swap(still);
    }
  }

  /// The ray org + t · dir (dir unit) in grid coordinates.
  [[nodiscard]] GridRay grid_ray(const Vec3& org, const Vec3& dir) const {
    GridRay r;
    r.org = org;
    r.dir = dir;
    const Vec3 og = (org - map.origin) * inv_cs;  // t stays a world distance
    const Vec3 dg = dir * inv_cs;
    const double nd = static_cast<double>(map.n);
    for (int a = 0; a < 3; ++a) {
      r.og[a] = og[a];
      r.dg[a] = dg[a];
      r.inv[a] = dg[a] != 0.0 ? 1.0 / dg[a] : 0.0;
      r.fixed[a] = dg[a] != 0.0 || !(og[a] >= 0.0 && og[a] <= nd)
                       ? -1
                       : static_cast<std::int64_t>(std::min(std::floor(og[a]), nd - 1.0));
    }
    return r;
  }

  /// The segment [t0, t1] of ray r through grey cell c (coordinates idx) as the march takes it; false when
  /// the empty-space bounds prove that the ray meets no surface there.
  bool prepare_segment(const GridRay& r, const CellData& c, const std::int64_t idx[3], double t0, double t1,
                       CellSegment& seg) const {
    for (int a = 0; a < 3; ++a) {
      seg.dl[a] = static_cast<float>(r.dg[a]);
      seg.e[a] = static_cast<float>(r.og[a] + t0 * r.dg[a] - static_cast<double>(idx[a]));
    }
    const float* e = seg.e;
    const float* dl = seg.dl;
    const double len = t1 - t0;
    seg.len = static_cast<float>(len);
    const float ec[3] = {clamp01(e[0]), clamp01(e[1]), clamp01(e[2])};
    const float xc[3] = {clamp01(e[0] + seg.len * dl[0]), clamp01(e[1] + seg.len * dl[1]),
                         clamp01(e[2] + seg.len * dl[2])};
    if (!may_hit(c, ec, xc)) return false;
    seg.range = c.mode == kBorderCell ? may_range(c, e, dl) : MayRange{kInfF, kInfF};
    if (seg.range.empty(seg.len)) return false;
    seg.steps = static_cast<std::uint32_t>(std::max(min_steps, std::ceil(len * steps_per_unit - 1e-6)));
    return true;
  }

  /// The hit of ray r at march parameter seg.hit (>= 0) of its segment from t0 through grey cell g: position,
  /// interpolated normal, wall flag.
  [[nodiscard]] RayHit make_hit(const GridRay& r, std::int32_t g, const CellSegment& seg, double t0) const {
    const CellData& c = cells[static_cast<std::size_t>(g)];
    const float s = seg.hit;
    RayHit out;
    out.hit = true;
    out.t = t0 + static_cast<double>(s);
    out.position = r.org + out.t * r.dir;
    out.grey_cell = static_cast<std::uint32_t>(g);
    const Projected& pr = seg.at_hit;
    out.discontinuity = true;
    if (seg.projected && c.layer_base[pr.face] != kNoLayer) {
      const HitTexels read = read_hit_texels(texels, c.layer_base[pr.face], pr.u, pr.v);
      out.normal = read.normal;
      out.discontinuity = !(std::abs(pr.dist - read.stored) <= wall_tolerance);
    }
    if (out.normal.squaredNorm() == 0.0) out.normal = -r.dir;
    return out;
  }

  /// The hit (if any) of the ray org + t · dir, dir unit, by walking the grid cells it crosses in order
  /// (3D DDA with the plane crossings of GridRay); adds the inside tests to `samples`.
  template <class Lookup, ReliefFilter F, bool V>
  RayHit trace(const Lookup& lookup, const Vec3& org, const Vec3& dir, std::uint64_t& samples) const {
    RayHit out;
    const GridRay r = grid_ray(org, dir);
    const auto n = static_cast<std::int64_t>(map.n);
    const double nd = static_cast<double>(map.n);
    auto plane = [&](int a, std::int64_t i) { return (static_cast<double>(i) - r.og[a]) * r.inv[a]; };
    double tmin = 0.0, tmax = kInf;
    for (int a = 0; a < 3; ++a) {
      if (r.dg[a] == 0.0) {
        if (r.fixed[a] < 0) return out;
        continue;
      }
      const double t1 = plane(a, 0), t2 = plane(a, n);
      tmin = std::max(tmin, std::min(t1, t2));
      tmax = std::min(tmax, std::max(t1, t2));
    }
    if (!(tmin < tmax)) return out;
    // The cell at tmin, as the plane crossings place it (not rounded differently by og + tmin · dg), and
    // the next crossing on each axis.
    std::int64_t cell[3], step[3];
    double tnext[3];
    for (int a = 0; a < 3; ++a) {
      if (r.dg[a] == 0.0) {
        cell[a] = r.fixed[a];
        step[a] = 0;
        tnext[a] = kInf;
        continue;
      }
      auto c = static_cast<std::int64_t>(std::clamp(std::floor(r.og[a] + tmin * r.dg[a]), 0.0, nd - 1.0));
      if (r.dg[a] > 0.0) {
        while (c > 0 && plane(a, c) > tmin) --c;
        while (c < n - 1 && plane(a, c + 1) <= tmin) ++c;
        step[a] = 1;
        tnext[a] = plane(a, c + 1);
      } else {
        while (c < n - 1 && plane(a, c + 1) > tmin) ++c;
        while (c > 0 && plane(a, c) <= tmin) --c;
        step[a] = -1;
        tnext[a] = plane(a, c);
      }
      cell[a] = c;
    }
    // The walk, with its state in scalars (registers) and the linear index stepped by strides.
    std::int64_t ci = cell[0], cj = cell[1], ck = cell[2];
    double tx = tnext[0], ty = tnext[1], tz = tnext[2];
    const std::int64_t up[3] = {step[0] > 0 ? 1 : 0, step[1] > 0 ? 1 : 0, step[2] > 0 ? 1 : 0};
    const std::int64_t stride_y = step[1] * n, stride_z = step[2] * n * n;
    std::int64_t linear = (ck * n + cj) * n + ci;
    const auto un = static_cast<std::uint64_t>(n);
    while (true) {
      const double t_next = std::min(std::min(tx, ty), tz);
      const std::int32_t g = lookup.find(static_cast<std::uint32_t>(linear));
      if (g >= 0) {
        const std::int64_t idx[3] = {ci, cj, ck};
        const double lo[3] = {static_cast<double>(ci) - r.og[0], static_cast<double>(cj) - r.og[1],
                              static_cast<double>(ck) - r.og[2]};
        const double hi[3] = {static_cast<double>(ci + 1) - r.og[0], static_cast<double>(cj + 1) - r.og[1],
                              static_cast<double>(ck + 1) - r.og[2]};
        double t0 = 0.0, t1 = 0.0;
        CellSegment seg;
        const CellData& c = cells[static_cast<std::size_t>(g)];
        if (cell_segment(r, idx, lo, hi, t0, t1) && prepare_segment(r, c, idx, t0, t1, seg)) {
          march_cell<F, V>(c, texels, &seg, 1, options.binary_steps, samples);
          if (seg.hit >= 0.0f) return make_hit(r, g, seg, t0);
        }
      }
      if (t_next >= tmax) break;
      if (tx == t_next) {
        ci += step[0];
        if (static_cast<std::uint64_t>(ci) >= un) break;
        linear += step[0];
        tx = plane(0, ci + up[0]);
      } else if (ty == t_next) {
        cj += step[1];
        if (static_cast<std::uint64_t>(cj) >= un) break;
        linear += stride_y;
        ty = plane(1, cj + up[1]);
      } else {
        ck += step[2];
        if (static_cast<std::uint64_t>(ck) >= un) break;
        linear += stride_z;
        tz = plane(2, ck + up[2]);
      }
    }
    return out;
  }

  /// The rays (grid_ray) of pixels bx..bx1 × by..by1 of a tile into rays[(y − by) · kTile + x − bx]; with
  /// AVX2 4 pixels at a time (pixel_rays4, the same values).
  template <bool V>
  void set_up_rays(const Camera& camera, const GridRay& eye, std::uint32_t bx, std::uint32_t by, std::uint32_t bx1,
                   std::uint32_t by1, TileRays& tile) const {
    auto& rays = tile.ray;
    for (std::uint32_t y = by; y <= by1; ++y) {
      const Vec3 row = pixel_row(camera, y);
      std::uint32_t x = bx;
#if GIMFORGE_RELIEF_AVX2
      if constexpr (V) {
        for (; x + 3 <= bx1; x += 4) {
          double dir[3][4], dg[3][4], inv[3][4];
          pixel_rays4(camera, row, x, inv_cs, dir, dg, inv);
          for (std::uint32_t q = 0; q < 4; ++q) {
            GridRay& r = rays[(y - by) * kTile + (x + q - bx)];
            r.org = camera.eye;
            r.dir = Vec3(dir[0][q], dir[1][q], dir[2][q]);
            for (int a = 0; a < 3; ++a) {
              r.og[a] = eye.og[a];
              r.dg[a] = dg[a][q];
              r.inv[a] = inv[a][q];
            }
            if (r.dg[0] == 0.0 || r.dg[1] == 0.0 || r.dg[2] == 0.0) r = grid_ray(camera.eye, r.dir);
            else r.fixed[0] = r.fixed[1] = r.fixed[2] = -1;
          }
        }
      }
#endif
      for (; x <= bx1; ++x) rays[(y - by) * kTile + (x - bx)] = grid_ray(camera.eye, pixel_direction(camera, row, x));
      for (x = bx; x <= bx1; ++x) {
        const std::uint32_t l = (y - by) * kTile + (x - bx);
        const GridRay& r = rays[l];
        for (int a = 0; a < 3; ++a) {
          tile.dg[a][l] = r.dg[a];
          tile.inv[a][l] = r.inv[a];
        }
        tile.zero_component[l] = r.dg[0] == 0.0 || r.dg[1] == 0.0 || r.dg[2] == 0.0 ? 1 : 0;
      }
    }
  }

  /// RenderTraversal::CellOrder (the paper's drawing of the grey cells, §3.5.2). Each useful grey cell
  /// gets the rectangle of pixels whose rays may cross it: the bounds of its projection, clipped to the
  /// half-space 1e-3 cells in front of the eye (the whole image for a cell that reaches into the small
  /// pyramid of visible points nearer than that). The cells are sorted by the grid (Manhattan) distance
  /// of their coordinates from the eye's cell, which grows by one with every cell a ray from the eye
  /// enters, so along every ray the cells come in the order the walk meets them; they are binned into
  /// screen tiles in that order. Each tile (in parallel) visits its cells and, per pixel of a cell's
  /// rectangle not hit yet, marches the segment of the pixel's ray in the cell (GridRay, as the walk does)
  /// — the same cells, segments and hits as the walk, without walking the empty cells. Returns false,
  /// leaving the image untouched, for a camera with degenerate axes or an eye more than 2^40 cells away.
  template <ReliefFilter F, bool V>
  bool render_cells(const Camera& camera, RenderImage& img, std::vector<std::uint8_t>& walls) const {
    const auto t_start = Clock::now();
    // Camera coordinates (X, Y, Z): P − eye = X · right + Y · up + Z · forward; the ray of pixel (x, y)
    // runs through the points with X / Z = sx and Y / Z = sy (pixel_direction), Z > 0 ahead of the eye.
    const Vec3& cr = camera.right;
    const Vec3& cu = camera.up;
    const Vec3& cf = camera.forward;
    const Vec3 rx = cu.cross(cf), ry = cf.cross(cr), rz = cr.cross(cu);
    const double det = cr.dot(rx);
    if (!std::isfinite(det) || !(std::abs(det) > 1e-9 * cr.norm() * cu.norm() * cf.norm())) return false;
    const GridRay eye = grid_ray(camera.eye, camera.forward);
    double eye_cell[3];
    for (int a = 0; a < 3; ++a) {
      if (!(std::abs(eye.og[a]) < 0x1p40)) return false;
      eye_cell[a] = std::floor(eye.og[a]);
    }
    const std::uint32_t W = camera.width, H = camera.height;
    const double SX = camera.tan_half_fov * static_cast<double>(W) / H, SY = camera.tan_half_fov;
    const double eps = 1e-3 * map.cell_size;

    struct Entry {
      std::int64_t key;
      std::int32_t g;
      std::int32_t idx[3];
      std::int32_t x0, y0, x1, y1;  ///< pixel rectangle, inclusive
    };
    std::vector<Entry> entries;
    entries.reserve(useful_cells.size());
    for (const UsefulCell& uc : useful_cells) {
      double X[8], Y[8], Z[8];
      double lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf};  // bounds of X, Y, Z
      for (int k = 0; k < 8; ++k) {
        const Vec3 corner(static_cast<double>(uc.idx[0] + (k & 1)), static_cast<double>(uc.idx[1] + ((k >> 1) & 1)),
                          static_cast<double>(uc.idx[2] + ((k >> 2) & 1)));
        const Vec3 d = map.origin + map.cell_size * corner - camera.eye;
        X[k] = rx.dot(d) / det;
        Y[k] = ry.dot(d) / det;
        Z[k] = rz.dot(d) / det;
        const double v[3] = {X[k], Y[k], Z[k]};
        for (int a = 0; a < 3; ++a) {
          lo[a] = std::min(lo[a], v[a]);
          hi[a] = std::max(hi[a], v[a]);
        }
      }
      Entry e{};
      e.g = uc.g;
      for (int a = 0; a < 3; ++a) e.idx[a] = uc.idx[a];
      const bool near_eye = hi[2] >= 0.0 && lo[2] <= eps && hi[0] >= -eps * SX && lo[0] <= eps * SX &&
                            hi[1] >= -eps * SY && lo[1] <= eps * SY;
      if (near_eye) {
        e.x0 = e.y0 = 0;
        e.x1 = static_cast<std::int32_t>(W - 1);
        e.y1 = static_cast<std::int32_t>(H - 1);
      } else {
        // Bounds of sx, sy over the vertices of the cell clipped to Z >= eps: its corners there and the
        // crossings of its edges with Z = eps.
        double sx0 = kInf, sx1 = -kInf, sy0 = kInf, sy1 = -kInf;
        auto add = [&](double x, double y, double z) {
          sx0 = std::min(sx0, x / z);
          sx1 = std::max(sx1, x / z);
          sy0 = std::min(sy0, y / z);
          sy1 = std::max(sy1, y / z);
        };
        for (int k = 0; k < 8; ++k) {
          if (Z[k] >= eps) add(X[k], Y[k], Z[k]);
          for (int bit = 1; bit < 8; bit <<= 1) {
            const int m = k | bit;
            if (m == k || (Z[k] >= eps) == (Z[m] >= eps)) continue;
            const double w = (eps - Z[k]) / (Z[m] - Z[k]);
            add(X[k] + w * (X[m] - X[k]), Y[k] + w * (Y[m] - Y[k]), eps);
          }
        }
        if (!(sx0 <= sx1)) continue;  // wholly behind the eye: no ray reaches it
        // Pixel x looks along sx = ((x + 0.5) / W · 2 − 1) · SX; pixel y along sy = (1 − (y + 0.5) / H · 2) · SY.
        // One pixel of slack against rounding; clamped before the conversion.
        auto to_x = [&](double sx) { return std::clamp((sx / SX + 1.0) * W / 2.0 - 0.5, -2.0, W + 1.0); };
        auto to_y = [&](double sy) { return std::clamp((1.0 - sy / SY) * H / 2.0 - 0.5, -2.0, H + 1.0); };
        e.x0 = std::max(0, static_cast<std::int32_t>(std::floor(to_x(sx0))) - 1);
        e.x1 = std::min(static_cast<std::int32_t>(W) - 1, static_cast<std::int32_t>(std::ceil(to_x(sx1))) + 1);
        e.y0 = std::max(0, static_cast<std::int32_t>(std::floor(to_y(sy1))) - 1);
        e.y1 = std::min(static_cast<std::int32_t>(H) - 1, static_cast<std::int32_t>(std::ceil(to_y(sy0))) + 1);
        if (e.x0 > e.x1 || e.y0 > e.y1) continue;  // off screen
      }
      double key = 0.0;
      for (int a = 0; a < 3; ++a) key += std::abs(static_cast<double>(uc.idx[a]) - eye_cell[a]);
      e.key = static_cast<std::int64_t>(key);
      entries.push_back(e);
    }
    std::sort(entries.begin(), entries.end(),
              [](const Entry& a, const Entry& b) { return a.key != b.key ? a.key < b.key : a.g < b.g; });

    // Tiles of kTile × kTile pixels, each with the entries that overlap it, front to back.
    const std::uint32_t tiles_x = (W + kTile - 1) / kTile, tiles_y = (H + kTile - 1) / kTile;
    const std::size_t tiles = static_cast<std::size_t>(tiles_x) * tiles_y;
    std::vector<std::size_t> first(tiles + 1, 0);
    auto for_tiles = [&](const Entry& e, const auto& fn) {
      for (auto ty = static_cast<std::uint32_t>(e.y0) / kTile; ty <= static_cast<std::uint32_t>(e.y1) / kTile; ++ty)
        for (auto tx = static_cast<std::uint32_t>(e.x0) / kTile; tx <= static_cast<std::uint32_t>(e.x1) / kTile; ++tx)
          fn(static_cast<std::size_t>(ty) * tiles_x + tx);
    };
    for (const Entry& e : entries) for_tiles(e, [&](std::size_t t) { ++first[t + 1]; });
    for (std::size_t t = 0; t < tiles; ++t) first[t + 1] += first[t];
    std::vector<std::uint32_t> binned(first[tiles]);
    {
      std::vector<std::size_t> fill(first.begin(), first.end() - 1);
      for (std::size_t k = 0; k < entries.size(); ++k)
        for_tiles(entries[k], [&](std::size_t t) { binned[fill[t]++] = static_cast<std::uint32_t>(k); });
    }

    std::atomic<std::uint64_t> hits{0}, samples{0};
    const double ambient = options.ambient;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, tiles, 1), [&](const tbb::blocked_range<std::size_t>& range) {
      std::uint64_t h = 0, s = 0;
      TileRays tile;
      const auto& rays = tile.ray;
      std::array<std::uint8_t, kTile * kTile> state;  // 1: hit
      // The segments of the current cell in the tile, their pixels and entry parameters: all prepared first
      // (4 pixels at a time with AVX2), then marched in one call (march_cell).
      std::array<CellSegment, kTile * kTile> segs;
      std::array<std::uint32_t, kTile * kTile> seg_pixel;
      std::array<double, kTile * kTile> seg_t0;
      auto march_all = [&](int count, const CellData& c, std::int32_t g, std::uint32_t bx, std::uint32_t by) {
        march_cell<F, V>(c, texels, segs.data(), count, options.binary_steps, s);
        for (int i = 0; i < count; ++i) {
          const auto ui = static_cast<std::size_t>(i);
          if (segs[ui].hit < 0.0f) continue;
          const std::uint32_t l = seg_pixel[ui];
          const GridRay& r = rays[l];
          const RayHit hit = make_hit(r, g, segs[ui], seg_t0[ui]);
          state[l] = 1;
          ++h;
          const std::size_t p = static_cast<std::size_t>(by + l / kTile) * W + bx + l % kTile;
          record_hit(img, &walls, p, hit, r.dir, ambient);
        }
      };
      for (std::size_t t = range.begin(); t != range.end(); ++t) {
        if (first[t] == first[t + 1]) continue;
        const std::uint32_t bx = static_cast<std::uint32_t>(t % tiles_x) * kTile;
        const std::uint32_t by = static_cast<std::uint32_t>(t / tiles_x) * kTile;
        const auto bx1 = static_cast<std::int32_t>(std::min(W, bx + kTile)) - 1;
        const auto by1 = static_cast<std::int32_t>(std::min(H, by + kTile)) - 1;
        set_up_rays<V>(camera, eye, bx, by, static_cast<std::uint32_t>(bx1), static_cast<std::uint32_t>(by1), tile);
        state.fill(0);
        for (std::size_t k = first[t]; k != first[t + 1]; ++k) {
          const Entry& e = entries[binned[k]];
          const CellData& c = cells[static_cast<std::size_t>(e.g)];
          const std::int32_t x0 = std::max(e.x0, static_cast<std::int32_t>(bx)), x1 = std::min(e.x1, bx1);
          const std::int32_t y0 = std::max(e.y0, static_cast<std::int32_t>(by)), y1 = std::min(e.y1, by1);
          const std::int64_t idx[3] = {e.idx[0], e.idx[1], e.idx[2]};
          const double lo[3] = {static_cast<double>(idx[0]) - eye.og[0], static_cast<double>(idx[1]) - eye.og[1],
                                static_cast<double>(idx[2]) - eye.og[2]};
          const double hi[3] = {static_cast<double>(idx[0] + 1) - eye.og[0],
                                static_cast<double>(idx[1] + 1) - eye.og[1],
                                static_cast<double>(idx[2] + 1) - eye.og[2]};
          int count = 0;
          // Pixel l's segment, if its ray crosses the cell and may meet the surface there.
          auto collect = [&](std::uint32_t l) {
            const GridRay& r = rays[l];
            double t0 = 0.0, t1 = 0.0;
            const auto slot = static_cast<std::size_t>(count);
            if (!cell_segment(r, idx, lo, hi, t0, t1) || !prepare_segment(r, c, idx, t0, t1, segs[slot])) return;
            seg_pixel[slot] = l;
            seg_t0[slot] = t0;
            ++count;
          };
          for (std::int32_t y = y0; y <= y1; ++y) {
            const auto ly = static_cast<std::uint32_t>(y) - by;
            const std::uint32_t row_first = ly * kTile - bx;  // + x: the pixel's index in the tile
            std::int32_t x = x0;
#if GIMFORGE_RELIEF_AVX2
            if constexpr (V) {  // 4 pixels at a time, rays with a zero direction component one by one
              for (; x + 3 <= x1; x += 4) {
                const std::uint32_t l = row_first + static_cast<std::uint32_t>(x);
                int lanes = 0, single = 0;
                for (int q = 0; q < 4; ++q) {
                  if (state[l + static_cast<std::uint32_t>(q)] != 0) continue;
                  (tile.zero_component[l + static_cast<std::uint32_t>(q)] ? single : lanes) |= 1 << q;
                }
                if (lanes != 0) {
                  CellSegment four[4];
                  double t0[4];
                  const double* const dg[3] = {&tile.dg[0][l], &tile.dg[1][l], &tile.dg[2][l]};
                  const double* const inv[3] = {&tile.inv[0][l], &tile.inv[1][l], &tile.inv[2][l]};
                  for (int ok = prepare4(c, lo, hi, eye.og, idx, dg, inv, lanes, min_steps, steps_per_unit, four, t0);
                       ok != 0; ok &= ok - 1) {
                    const int q = std::countr_zero(static_cast<unsigned>(ok));
                    const auto slot = static_cast<std::size_t>(count++);
                    segs[slot] = four[q];
                    seg_pixel[slot] = l + static_cast<std::uint32_t>(q);
                    seg_t0[slot] = t0[q];
                  }
                }
                for (; single != 0; single &= single - 1)
                  collect(l + static_cast<std::uint32_t>(std::countr_zero(static_cast<unsigned>(single))));
              }
            }
#endif
            for (; x <= x1; ++x) {
              const std::uint32_t l = row_first + static_cast<std::uint32_t>(x);
              if (state[l] == 0) collect(l);
            }
          }
          if (count > 0) march_all(count, c, e.g, bx, by);
        }
      }
      hits += h;
      samples += s;
    });
    img.seconds = seconds_since(t_start);
    img.hits = hits.load();
    img.samples = samples.load();
    return true;
  }

  template <class Fn>
  decltype(auto) dispatch(const Fn& fn) const {
    auto with_vector = [&](const auto& lookup, auto filter) {
      if (avx2) return fn(lookup, filter, std::true_type{});
      return fn(lookup, filter, std::false_type{});
    };
    auto with_filter = [&](const auto& lookup) {
      if (options.filter == ReliefFilter::Nearest)
        return with_vector(lookup, std::integral_constant<ReliefFilter, ReliefFilter::Nearest>{});
      return with_vector(lookup, std::integral_constant<ReliefFilter, ReliefFilter::Bilinear>{});
    };
    if (dense) return with_filter(DenseLookup{table.data()});
    return with_filter(HashLookup{keys.data(), values.data(), hash_mask, hash_shift});
  }
};

ReliefRaycaster::ReliefRaycaster(const ReliefMap& map, const RaycastOptions& options)
    : impl_(std::make_unique<Impl>(map, options)) {}
ReliefRaycaster::~ReliefRaycaster() = default;
ReliefRaycaster::ReliefRaycaster(ReliefRaycaster&&) noexcept = default;
ReliefRaycaster& ReliefRaycaster::operator=(ReliefRaycaster&&) noexcept = default;

const RaycastOptions& ReliefRaycaster::options() const { return impl_->options; }
bool ReliefRaycaster::vectorized() const { return impl_->avx2; }

RayHit ReliefRaycaster::trace(const Vec3& origin, const Vec3& direction) const {
  const double len = direction.norm();
  if (!origin.allFinite() || !direction.allFinite() || !(len > 0.0))
    throw InvalidInput("relief ray casting: ray with a non-finite origin or a zero direction");
  const Vec3 dir = direction / len;
  std::uint64_t samples = 0;
  return impl_->dispatch([&](const auto& lookup, auto filter, auto vectorized) {
    return impl_->trace<std::decay_t<decltype(lookup)>, decltype(filter)::value, decltype(vectorized)::value>(
        lookup, origin, dir, samples);
  });
}

RenderImage ReliefRaycaster::render(const Camera& camera) const {
  check_camera(camera);
  RenderImage img = blank_image(camera);
  std::vector<std::uint8_t> walls(img.mask.size(), 0);
  impl_->dispatch([&](const auto& lookup, auto filter, auto vectorized) {
    constexpr ReliefFilter kFilter = decltype(filter)::value;
    constexpr bool kVectorized = decltype(vectorized)::value;
    if (impl_->options.traversal == RenderTraversal::CellOrder &&
        impl_->template render_cells<kFilter, kVectorized>(camera, img, walls))
      return 0;
    render_rows(
        camera, impl_->options.ambient, img,
        [&](const Vec3& org, const Vec3& dir, std::uint64_t& samples) {
          return impl_->trace<std::decay_t<decltype(lookup)>, kFilter, kVectorized>(lookup, org, dir, samples);
        },
        &walls);
    return 0;
  });
  if (impl_->options.wall_normals) {
    const auto t0 = Clock::now();
    fix_wall_normals(camera, impl_->options.ambient, walls, img);
    img.seconds += seconds_since(t0);
  }
  return img;
}

RenderImage raycast_relief(const ReliefMap& map, const Camera& camera, const RaycastOptions& options) {
  return ReliefRaycaster(map, options).render(camera);
}

// ---------------------------------------------------------------------------------------------------
// The Embree reference.

struct MeshRenderer::Impl {
  const TriMesh& mesh;
  double ambient;
  detail::EmbreeScene scene;

  Impl(const EmbreeDevice& device, const TriMesh& m, double amb)
      : mesh(m),
        ambient(amb),
        scene(device, (m.faces.empty() ? throw InvalidInput("render: the reference mesh has no faces") : m.positions),
              m.faces, RTC_BUILD_QUALITY_HIGH, "building the reference render BVH") {
    if (!(amb >= 0.0 && amb <= 1.0)) throw InvalidInput(fmt::format("render: ambient {} out of range 0..1", amb));
  }

  RayHit trace(const Vec3& org, const Vec3& dir, RTCIntersectContext& context) const {
    RTCRayHit rh{};
    rh.ray.org_x = static_cast<float>(org.x());
    rh.ray.org_y = static_cast<float>(org.y());
    rh.ray.org_z = static_cast<float>(org.z());
    rh.ray.dir_x = static_cast<float>(dir.x());
    rh.ray.dir_y = static_cast<float>(dir.y());
    rh.ray.dir_z = static_cast<float>(dir.z());
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = std::numeric_limits<float>::infinity();
    rh.ray.mask = 0xffffffffu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene.get(), &context, &rh);
    RayHit out;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return out;
    out.hit = true;
    out.t = static_cast<double>(rh.ray.tfar);
    out.position = org + out.t * dir;
    const Face& f = mesh.faces[rh.hit.primID];
    const Vec3& a = mesh.positions[f[0]];
    const Vec3 nrm = (mesh.positions[f[1]] - a).cross(mesh.positions[f[2]] - a);
    out.normal = nrm.squaredNorm() > 0.0
                     ? nrm.normalized()
                     : Vec3(static_cast<double>(rh.hit.Ng_x), static_cast<double>(rh.hit.Ng_y),
                            static_cast<double>(rh.hit.Ng_z)).normalized();
    if (!out.normal.allFinite()) out.normal = -dir;
    return out;
  }
};

MeshRenderer::MeshRenderer(const EmbreeDevice& device, const TriMesh& mesh, double ambient)
    : impl_(std::make_unique<Impl>(device, mesh, ambient)) {}
MeshRenderer::~MeshRenderer() = default;
MeshRenderer::MeshRenderer(MeshRenderer&&) noexcept = default;
MeshRenderer& MeshRenderer::operator=(MeshRenderer&&) noexcept = default;

RayHit MeshRenderer::trace(const Vec3& origin, const Vec3& direction) const {
  const double len = direction.norm();
  if (!origin.allFinite() || !direction.allFinite() || !(len > 0.0))
    throw InvalidInput("render: ray with a non-finite origin or a zero direction");
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  return impl_->trace(origin, direction / len, context);
}

RenderImage MeshRenderer::render(const Camera& camera) const {
  check_camera(camera);
  RenderImage img = blank_image(camera);
  render_rows(camera, impl_->ambient, img, [&](const Vec3& org, const Vec3& dir, std::uint64_t&) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    return impl_->trace(org, dir, context);
  });
  return img;
}

// ---------------------------------------------------------------------------------------------------
// Comparison.

RenderComparison compare_renders(const RenderImage& a, const RenderImage& b) {
  if (a.width != b.width || a.height != b.height || a.shaded.size() != b.shaded.size() ||
      a.mask.size() != b.mask.size() || a.mask.size() != a.shaded.size())
    throw InvalidInput(fmt::format("render comparison: image sizes differ ({}x{} and {}x{})", a.width, a.height,
                                   b.width, b.height));
  RenderComparison r;
  double se = 0.0;
  std::vector<double> depth_errors;
  double angle_sum = 0.0, depth_sq = 0.0, depth_abs = 0.0;
  for (std::size_t p = 0; p < a.shaded.size(); ++p) {
    const double d = static_cast<double>(a.shaded[p]) - static_cast<double>(b.shaded[p]);
    se += d * d;
    const bool ha = a.mask[p] != 0, hb = b.mask[p] != 0;
    r.hits_a += ha;
    r.hits_b += hb;
    r.hits_both += ha && hb;
    r.hits_either += ha || hb;
    if (ha && hb) {
      const double e = std::abs(static_cast<double>(a.depth[p]) - static_cast<double>(b.depth[p]));
      depth_errors.push_back(e);
      depth_abs += e;
      depth_sq += e * e;
      const double c = std::min(1.0, std::abs(static_cast<double>(a.normal[p].dot(b.normal[p]))));
      angle_sum += std::acos(c) * 180.0 / std::numbers::pi;
    }
  }
  const auto pixels = static_cast<double>(std::max<std::size_t>(a.shaded.size(), 1));
  r.mse = se / pixels;
  r.psnr = r.mse > 0.0 ? 10.0 * std::log10(255.0 * 255.0 / r.mse) : kInf;
  r.iou = r.hits_either == 0 ? 1.0 : static_cast<double>(r.hits_both) / static_cast<double>(r.hits_either);
  if (!depth_errors.empty()) {
    const auto count = static_cast<double>(depth_errors.size());
    r.depth_mean_abs = depth_abs / count;
    r.depth_rms = std::sqrt(depth_sq / count);
    r.normal_mean_deg = angle_sum / count;
    const auto k = static_cast<std::size_t>(std::floor(0.95 * (count - 1.0)));
    std::nth_element(depth_errors.begin(), depth_errors.begin() + static_cast<std::ptrdiff_t>(k), depth_errors.end());
    r.depth_p95 = depth_errors[k];
  }
  return r;
}

}  // namespace gimforge
