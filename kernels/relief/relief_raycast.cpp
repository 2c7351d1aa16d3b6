// The relief ray caster: the walk of a ray through the grid (trace), the cell-order render in screen tiles
// (render_cells) and the march of the segments of one cell (march_cell), scalar or with the vector lanes
// of raycast_avx2.cpp. The tables are built in raycast_tables.cpp, the march primitives are in
// raycast_march.h.
#include "kernels/relief/relief_raycast.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "kernels/core/errors.h"
#include "kernels/relief/raycast_avx2.h"
#include "kernels/relief/raycast_impl.h"
#include "kernels/relief/raycast_march.h"
#include "kernels/relief/render_detail.h"

namespace gimforge {
using namespace detail;

namespace {

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

}  // namespace

/// The ray org + t · dir (dir unit) in grid coordinates.
inline GridRay ReliefRaycaster::Impl::grid_ray(const Vec3& org, const Vec3& dir) const {
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
inline bool ReliefRaycaster::Impl::prepare_segment(const GridRay& r, const CellData& c, const std::int64_t idx[3],
                                                   double t0, double t1, CellSegment& seg) const {
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
  if (range_empty(seg.range, seg.len)) return false;
  seg.steps = static_cast<std::uint32_t>(std::max(min_steps, std::ceil(len * steps_per_unit - 1e-6)));
  return true;
}

/// The hit of ray r at march parameter seg.hit (>= 0) of its segment from t0 through grey cell g: position,
/// interpolated normal, wall flag.
inline RayHit ReliefRaycaster::Impl::make_hit(const GridRay& r, std::int32_t g, const CellSegment& seg,
                                             double t0) const {
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
RayHit ReliefRaycaster::Impl::trace(const Lookup& lookup, const Vec3& org, const Vec3& dir,
                                    std::uint64_t& samples) const {
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
void ReliefRaycaster::Impl::set_up_rays(const Camera& camera, const GridRay& eye, std::uint32_t bx, std::uint32_t by,
                                        std::uint32_t bx1, std::uint32_t by1, TileRays& tile) const {
  auto& rays = tile.ray;
  for (std::uint32_t y = by; y <= by1; ++y) {
    const Vec3 row = pixel_row(camera, y);
    std::uint32_t x = bx;
#if GIMFORGE_RELIEF_AVX2
    if constexpr (V) {
      const PixelRow frame{{row[0], row[1], row[2]},
                           {camera.right[0], camera.right[1], camera.right[2]},
                           static_cast<double>(camera.width),
                           camera.tan_half_fov,
                           static_cast<double>(camera.width) / camera.height};
      for (; x + 3 <= bx1; x += 4) {
        double dir[3][4], dg[3][4], inv[3][4];
        pixel_rays4(frame, x, inv_cs, dir, dg, inv);
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
bool ReliefRaycaster::Impl::render_cells(const Camera& camera, RenderImage& img,
                                         std::vector<std::uint8_t>& walls) const {
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
decltype(auto) ReliefRaycaster::Impl::dispatch(const Fn& fn) const {
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

}  // namespace gimforge
