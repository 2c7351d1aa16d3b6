#pragma once
/// \file raycast_avx2.h
/// Internal to kernels/relief/: the vector lanes of the relief ray caster (AVX2), defined in
/// raycast_avx2.cpp, the one translation unit compiled with -mavx2. Each function performs the operations
/// of its scalar counterpart in the same order and precision, lane by lane, so that both paths give the
/// same image and inside-test count.
///
/// **Callers must make sure the CPU has AVX2 before calling any of these** (ReliefRaycaster::Impl::avx2,
/// set from __builtin_cpu_supports("avx2"), selects the template instances that call them); they execute
/// AVX2 instructions unconditionally.
#include <cstdint>

#include "kernels/relief/raycast_march.h"

// The vectorized march (AVX2, chosen at run time) on x86-64 with GCC or Clang.
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define GIMFORGE_RELIEF_AVX2 1
#else
#define GIMFORGE_RELIEF_AVX2 0
#endif

namespace gimforge::detail {

#if GIMFORGE_RELIEF_AVX2

/// march<P, F, M> for `count` (<= kMaxMarch) segments of one cell: the same hit parameters (segs[i].hit)
/// and inside-test counts (added to `samples`), 8 samples of a segment at a time. Instantiated in
/// raycast_avx2.cpp for every (P, M) that march_cell dispatches to (M != kBorderCell: perspective only),
/// both filters.
template <ProjectionType P, ReliefFilter F, CellMode M>
void march_avx2(const CellData& c, const Texels& tx, CellSegment* segs, int count, std::uint32_t halvings,
                std::uint64_t& samples);

/// What the rays of one pixel row share (pixel_row, pixel_direction): forward + sy · up, the camera's
/// right axis, the image width, tan_half_fov and width / height.
struct PixelRow {
  double row[3];
  double right[3];
  double width;
  double tan_half_fov;
  double aspect;
};

/// pixel_direction for pixels x .. x + 3 of a row, and their directions in grid units (times inv_cs) with
/// the reciprocals: the same operations in the same order, 4 pixels at a time.
void pixel_rays4(const PixelRow& row, std::uint32_t x, double inv_cs, double (&dir)[3][4], double (&dg)[3][4],
                 double (&inv)[3][4]);

/// cell_segment and the empty-space bounds of prepare_segment (may_hit, may_range, the step count) for the
/// rays of 4 pixels (lanes) through cell c, none with a zero direction component: dg[a] and inv[a] point
/// to their 4 values on axis a, og is their common origin, lo / hi as for cell_segment. The same
/// operations in the same order as the scalar functions, lane by lane. Returns the lanes of `lanes` whose
/// ray crosses the cell and may meet the surface there, with their segments in segs[q] and entry
/// parameters in t0[q].
int prepare4(const CellData& c, const double lo[3], const double hi[3], const double og[3], const std::int64_t idx[3],
             const double* const dg[3], const double* const inv[3], int lanes, double min_steps, double steps_per_unit,
             CellSegment (&segs)[4], double (&t0)[4]);

#endif  // GIMFORGE_RELIEF_AVX2

}  // namespace gimforge::detail
