#include "kernels/relief/raycast_avx2.h"

// The march with 8 samples at a time (AVX2). Every lane performs the operations of sample_flag<P, F, M> in
// the same order and precision (no fused multiply-add: every TU of the march is compiled with
// -ffp-contract=off, and -mavx2 does not enable FMA), so the flags, and with them the image, equal the
// scalar path's.
//
// This translation unit is compiled with -mavx2 (kernels/CMakeLists.txt) instead of marking each function
// with __attribute__((target("avx2"))): the whole file is vector code, and the intrinsics, the helpers and
// the scalar functions of raycast_march.h it calls are all compiled for AVX2 alike. What keeps it safe on
// a CPU without AVX2:
// - Nothing here runs unless the caller checked the CPU (raycast_avx2.h); the file has no static
//   initializers.
// - No code compiled here can be picked for generic callers: the helpers below and all functions of
//   raycast_march.h are in anonymous namespaces (internal linkage, no COMDAT copy to share), and the
//   entry points (march_avx2's explicit instantiations, pixel_rays4, prepare4) are defined only here.
//   The file uses no Eigen (its headers come in through relief_map.h, unused), TBB or other library code
//   that would be instantiated as inline functions with external linkage: `nm -C --defined-only` on its
//   object file lists the entry points (T, and W for the explicit instantiations) and otherwise local
//   symbols only (t, r); check it after changing this file. Under `qemu-x86_64 -cpu Nehalem -d in_asm`
//   (CPUID without AVX2) no code of this file runs in a render; under `-cpu Haswell` it does.
#if GIMFORGE_RELIEF_AVX2
#ifndef __AVX2__
#error "raycast_avx2.cpp must be compiled with -mavx2 (see kernels/CMakeLists.txt)"
#endif

#include <immintrin.h>

#include <algorithm>
#include <bit>
#include <cstddef>

namespace gimforge::detail {
namespace {

/// The constants of one cell, broadcast.
struct alignas(32) CellLanes {
  __m256 point[3];
  __m256 num_up[3];   ///< 1 − point[a]: distance from the centre to the face ahead when d_a >= 0
  __m256 face_qmin;   ///< CellData::face_qmin, indexed by face (lanes 6, 7 unused)
  __m256i layer_base; ///< CellData::layer_base, indexed by face
  __m256 inv_scale, tm1;
  __m256i T, Tm2;
};

GIMFORGE_INLINE __m256 select(__m256 mask, __m256 if_set, __m256 if_clear) {
  return _mm256_blendv_ps(if_clear, if_set, mask);
}
GIMFORGE_INLINE __m256i select(__m256i mask, __m256i if_set, __m256i if_clear) {
  return _mm256_blendv_epi8(if_clear, if_set, mask);
}
/// clamp01 lane-wise: max_ps(0, x) is (0 > x ? 0 : x) and min_ps(1, y) is (1 < y ? 1 : y), as std::max /
/// std::min with the arguments of clamp01 (NaN and signed zeros included).
GIMFORGE_INLINE __m256 clamp01_lanes(__m256 x) {
  return _mm256_min_ps(_mm256_set1_ps(1.0f), _mm256_max_ps(_mm256_setzero_ps(), x));
}

/// The crossing flags of mode M (see sample_flag) from the lanes whose side is Beyond and those that are not
/// Empty, as a movemask.
template <CellMode M>
GIMFORGE_INLINE int flag_mask(__m256 beyond, __m256 filled, __m256 valid) {
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
GIMFORGE_INLINE void flags8(const CellData& c, const CellLanes& L, const Texels& tx,
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

GIMFORGE_INLINE CellLanes cell_lanes(const CellData& c, const Texels& tx) {
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
GIMFORGE_INLINE void flags_of(const CellData& c, const CellLanes& L, const Texels& tx, int n,
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
GIMFORGE_INLINE __m256 lane_mask(int bits) {
  const __m256i lane_bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
  return _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(bits), lane_bit), lane_bit));
}

/// The binary refinement (refine<P, F, M>) of n <= 8 · N crossings at once, crossing 8 · v + l in lane l
/// of vector v: every lane tests the middle of its interval and keeps the half where its flag changes.
template <ProjectionType P, ReliefFilter F, CellMode M, std::size_t N>
GIMFORGE_INLINE void refine_lanes(const CellData& c, const CellLanes& L, const Texels& tx, CellSegment* segs,
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

}  // namespace

/// march<P, F, M> for `count` (<= kMaxMarch) segments of one cell: the same hit parameters and inside-test
/// counts. The linear search tests 8 samples of a segment at a time, kMarchBatch segments in lockstep (one
/// batch of 8 of every segment before the next), the tests of two segments interleaved; then the crossings
/// are refined 8 at a time, one per lane, two vectors interleaved (a lone crossing by the scalar code).
/// Both keep independent dependency chains side by side in the pipeline.
template <ProjectionType P, ReliefFilter F, CellMode M>
void march_avx2(const CellData& c, const Texels& tx, CellSegment* segs, int count, std::uint32_t halvings,
                std::uint64_t& samples) {
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

// The instances march_cell (relief_raycast.cpp) calls: border cells of every projection type, interior
// cells (perspective) of every mode, both filters.
#define GIMFORGE_MARCH_AVX2(P, F, M)                                                                       \
  template void march_avx2<ProjectionType::P, ReliefFilter::F, M>(const CellData&, const Texels&, CellSegment*, \
                                                                   int, std::uint32_t, std::uint64_t&);
#define GIMFORGE_MARCH_AVX2_FILTERS(P, M) GIMFORGE_MARCH_AVX2(P, Nearest, M) GIMFORGE_MARCH_AVX2(P, Bilinear, M)
GIMFORGE_MARCH_AVX2_FILTERS(Parallel, kBorderCell)
GIMFORGE_MARCH_AVX2_FILTERS(Planar, kBorderCell)
GIMFORGE_MARCH_AVX2_FILTERS(Perspective, kBorderCell)
GIMFORGE_MARCH_AVX2_FILTERS(Axial, kBorderCell)
GIMFORGE_MARCH_AVX2_FILTERS(Perspective, kInteriorOutside)
GIMFORGE_MARCH_AVX2_FILTERS(Perspective, kInteriorInside)
GIMFORGE_MARCH_AVX2_FILTERS(Perspective, kInteriorRelative)
#undef GIMFORGE_MARCH_AVX2_FILTERS
#undef GIMFORGE_MARCH_AVX2

void pixel_rays4(const PixelRow& row, std::uint32_t x, double inv_cs, double (&dir)[3][4], double (&dg)[3][4],
                 double (&inv)[3][4]) {
  const double aspect = row.aspect;
  const auto x0 = static_cast<double>(x);
  __m256d sx = _mm256_add_pd(_mm256_setr_pd(x0, x0 + 1.0, x0 + 2.0, x0 + 3.0), _mm256_set1_pd(0.5));
  sx = _mm256_div_pd(sx, _mm256_set1_pd(row.width));
  sx = _mm256_sub_pd(_mm256_mul_pd(sx, _mm256_set1_pd(2.0)), _mm256_set1_pd(1.0));
  sx = _mm256_mul_pd(_mm256_mul_pd(sx, _mm256_set1_pd(row.tan_half_fov)), _mm256_set1_pd(aspect));
  __m256d d[3];
  for (int k = 0; k < 3; ++k)
    d[k] = _mm256_add_pd(_mm256_set1_pd(row.row[k]), _mm256_mul_pd(sx, _mm256_set1_pd(row.right[k])));
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

int prepare4(const CellData& c, const double lo[3], const double hi[3], const double og[3], const std::int64_t idx[3],
             const double* const dg[3], const double* const inv[3], int lanes, double min_steps, double steps_per_unit,
             CellSegment (&segs)[4], double (&t0)[4]) {
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

}  // namespace gimforge::detail

#endif  // GIMFORGE_RELIEF_AVX2
