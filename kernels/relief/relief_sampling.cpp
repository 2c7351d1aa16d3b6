// Sampling of relief maps (Apaza & Andújar §3.3.2) on the CPU, the way the paper's GPU pass does it: per
// grey cell, only the triangles overlapping the cell are "rasterized" onto each domain face. A triangle is
// clipped to the cell; the projection of the clipped polygon onto the face bounds a rectangle of texels;
// the projection segment of every texel in that rectangle is intersected exactly with the triangle, and
// the nearest hit wins (the paper's depth test).
#include <algorithm>
#include <array>
#include <span>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "kernels/core/errors.h"
#include "kernels/relief/relief_map_detail.h"

namespace gimforge::detail {
namespace {

// Tolerances, in unit-cell units (the cell is [0, 1]³; projection segments are 0.5 to √3 long).
/// Cell clipping keeps [−kClipSlack, 1 + kClipSlack]³, so that triangles lying on a cell face (within
/// rounding) are not lost; the segment test decides.
constexpr double kClipSlack = 1e-9;
/// Perspective / axial projection: before the central projection onto the face plane, the polygon is
/// clipped to the part at least kFrontSlack in front of the centre of projection (or the axis). Points of
/// the dropped slab farther than kNearRadius from the centre (axis) project more than
/// 0.5 · kNearRadius / kFrontSlack = 500 face widths away, outside the face; triangles nearer than
/// kNearRadius to the centre (axis) test the whole face (the whole cross-section for the axis).
constexpr double kFrontSlack = 1e-9;
constexpr double kNearRadius = 1e-6;
/// Texel rectangles cover the projected bounding box widened by this much in face coordinates: far more
/// than the rounding of the clipping and of the projection (below 1e-9 where it matters, see above),
/// far less than a texel.
constexpr double kRectMargin = 1e-6;
/// Ray–triangle test: barycentric slack (a segment through a shared edge hits at least one of its
/// triangles whatever the rounding) and slack of the segment parameter τ ∈ [0, 1] at both ends.
constexpr double kBaryTolerance = 1e-12;
constexpr double kTauTolerance = 1e-10;
/// Hits within this distance of the nearest one on their segment are the same surface point.
constexpr double kSamePoint = 1e-9;
/// Triangles of a cell loaded at a time (Scratch: about 180 bytes each).
constexpr std::size_t kLoadChunk = 1u << 16;

std::int8_t to_snorm8(double x) {
  return static_cast<std::int8_t>(std::lround(std::clamp(x, -1.0, 1.0) * 127.0));
}
std::uint8_t to_unorm8(double x) {
  return static_cast<std::uint8_t>(std::lround(std::clamp(x, 0.0, 1.0) * 255.0));
}

/// A convex polygon (up to rounding) of the unit cell.
constexpr std::size_t kMaxPolygon = 24;
struct Polygon {
  std::array<Vec3, kMaxPolygon> v;
  std::size_t n{0};
};

/// Vertices of a polygon stored elsewhere.
struct PolygonView {
  const Vec3* v{nullptr};
  std::size_t n{0};
};

/// Sutherland–Hodgman step: `out` = the part of `in` where sign · (p[axis] − bound) >= 0; new vertices
/// lie exactly on the plane. Returns false if `out` would overflow (never for convex input: each step adds
/// at most one vertex).
bool clip(PolygonView in, int axis, double bound, double sign, Polygon& out) {
  out.n = 0;
  for (std::size_t i = 0; i < in.n; ++i) {
    const Vec3& p = in.v[i];
    const Vec3& q = in.v[i + 1 == in.n ? 0 : i + 1];
    const double dp = sign * (p[axis] - bound);
    const double dq = sign * (q[axis] - bound);
    if (out.n + 2 > kMaxPolygon) return false;
    if (dp >= 0.0) out.v[out.n++] = p;
    if ((dp >= 0.0) != (dq >= 0.0)) {
      Vec3 x = p + (dp / (dp - dq)) * (q - p);
      x[axis] = bound;
      out.v[out.n++] = x;
    }
  }
  return true;
}

/// The part of `in` where sign · (p[axis] − bound) >= 0: `in` itself when all of it is, an empty view when
/// none of it is, else the clipped polygon, stored in `scratch`. False if clipping overflowed.
bool half_space(PolygonView in, int axis, double bound, double sign, Polygon& scratch, PolygonView& out) {
  std::size_t kept = 0;
  for (std::size_t k = 0; k < in.n; ++k) kept += sign * (in.v[k][axis] - bound) >= 0.0 ? 1u : 0u;
  if (kept == in.n) {
    out = in;
    return true;
  }
  if (kept == 0) {
    out = {};
    return true;
  }
  if (!clip(in, axis, bound, sign, scratch)) return false;
  out = {scratch.v.data(), scratch.n};
  return true;
}

/// A triangle of the current grey cell, in unit-cell coordinates.
struct CellTriangle {
  std::uint32_t face{0};             ///< mesh face index
  Vec3 a{Vec3::Zero()};              ///< first vertex
  Vec3 e1{Vec3::Zero()};             ///< b − a
  Vec3 e2{Vec3::Zero()};             ///< c − a
  std::array<std::int8_t, 3> normal{};  ///< unit normal (from the world coordinates) as snorm8
  std::uint32_t first_vertex{0};     ///< clipped polygon: Scratch::vertices[first_vertex, + num_vertices)
  std::uint32_t num_vertices{0};
  bool clip_failed{false};           ///< the clipped polygon overflowed: test the whole face
  bool near_end{false};              ///< within kNearRadius of the centre of projection / the axis
};

/// Per texel of the current layer: the nearest hit so far and the hit counts.
struct TexelHit {
  double tau{0.0};                   ///< segment parameter of the nearest hit: P = P' + τ·D, D = −direction · length
  double length{0.0};                ///< |D| (set at the first hit)
  float u{0.0f};                     ///< barycentric weights of the triangle's second and third vertex
  float v{0.0f};
  std::uint32_t tri{0};              ///< the nearest hit's triangle, as numbered by the caller of add_hit
  std::uint32_t hits{0};             ///< all hits on the segment
  std::uint32_t same{0};             ///< hits at the nearest surface point (within kSamePoint)
  std::uint32_t face{0};             ///< the nearest hit's mesh face (sample_cell)
  std::array<std::int8_t, 3> normal{};  ///< and its normal
};

/// The sampler's depth test: adds a hit at segment parameter `tau` of triangle k (barycentric u, v) to `h`;
/// `length()` gives |D| of the hit's segment (read at the texel's first hit only). Used by sample_cell and,
/// for hits gathered from several processes in triangle order, by resolve_relief_hits.
/// Returns whether the hit became the nearest one.
template <class Length>
bool add_hit(TexelHit& h, double tau, Length&& length, std::uint32_t k, double u, double v) {
  if (h.hits == 0) h.length = length();
  const double same = kSamePoint / h.length;
  bool take = false;
  if (h.hits == 0 || tau < h.tau - same) {
    take = true;
    h.same = 1;
  } else if (tau <= h.tau + same) {
    ++h.same;
    take = tau < h.tau;  // equal τ: the earlier (lower-index) triangle stays
  }
  ++h.hits;
  if (take) {
    h.tau = tau;
    h.tri = k;
    h.u = static_cast<float>(u);
    h.v = static_cast<float>(v);
  }
  return take;
}

/// Adds texel h's counts to `counts` and stores its distance at texel `out` of `map`.
void store_distance(ReliefMap& map, std::size_t out, const TexelHit& h, ReliefSampleCounts& counts) {
  counts.occluded += h.hits - h.same;
  counts.samples += 1 + h.hits - h.same;
  const double t = std::clamp(h.tau, 0.0, 1.0) * h.length * map.cell_size;
  map.distances[out] = quantize_distance(t, map.distance_scale);
}

struct Scratch {
  std::vector<CellTriangle> triangles;
  std::vector<Vec3> vertices;
  std::vector<TexelHit> hits;
};

struct TexelRect {
  std::uint32_t i0{1}, i1{0}, j0{1}, j1{0};
  [[nodiscard]] bool empty() const { return i0 > i1 || j0 > j1; }
};

/// Bounding box in face coordinates (u, v).
struct FaceBox {
  double u0{1e300}, u1{-1e300}, v0{1e300}, v1{-1e300};
  void add(double u, double v) {
    u0 = std::min(u0, u);
    u1 = std::max(u1, u);
    v0 = std::min(v0, v);
    v1 = std::max(v1, v);
  }
};

/// Texels i whose coordinate i / (T − 1) lies in [lo − margin, hi + margin] (empty: first > second).
std::pair<std::uint32_t, std::uint32_t> texel_range(double lo, double hi, std::uint32_t T) {
  const double scale = static_cast<double>(T - 1);
  const double a = std::clamp(lo - kRectMargin, -1.0, 2.0) * scale;
  const double b = std::clamp(hi + kRectMargin, -1.0, 2.0) * scale;
  if (b < 0.0 || a > scale || a > b) return {1, 0};
  // ceil(a) and floor(b) on [0, scale] without a libm call (no SSE4.1 rounding in the baseline ISA).
  auto first = a > 0.0 ? static_cast<std::uint32_t>(a) : 0u;
  if (static_cast<double>(first) < a) ++first;
  const auto last = static_cast<std::uint32_t>(std::min(b, scale));
  return {first, last};
}

TexelRect rect_of(const FaceBox& box, std::uint32_t T) {
  TexelRect r;
  const auto [i0, i1] = texel_range(box.u0, box.u1, T);
  if (i0 > i1) return r;
  const auto [j0, j1] = texel_range(box.v0, box.v1, T);
  if (j0 > j1) return r;
  return {i0, i1, j0, j1};
}

/// The texels of face `face` (0..5) whose projection segments can meet the polygon `poly` (a triangle
/// clipped to the cell) under projection `proj`.
TexelRect texel_rect(const CellProjection& proj, int face, const CellTriangle& tri, PolygonView poly,
                     std::uint32_t T, Polygon& scratch) {
  const TexelRect all{0, T - 1, 0, T - 1};
  if (tri.clip_failed) return all;
  const int a = face / 2;
  const int side = face % 2;
  const int ua = (a + 1) % 3;
  const int va = (a + 2) % 3;
  const double sign = side != 0 ? 1.0 : -1.0;
  FaceBox box;
  PolygonView front;
  switch (proj.type) {
    case ProjectionType::Parallel:  // (u, v) unchanged
      for (std::size_t k = 0; k < poly.n; ++k) box.add(poly.v[k][ua], poly.v[k][va]);
      break;
    case ProjectionType::Planar:  // (u, v) unchanged, only the half of the cell on the face's side
      if (!half_space(poly, a, proj.point[a] - sign * kClipSlack, sign, scratch, front)) return all;
      for (std::size_t k = 0; k < front.n; ++k) box.add(front.v[k][ua], front.v[k][va]);
      break;
    case ProjectionType::Perspective: {  // central projection from C onto the face plane
      if (tri.near_end) return all;
      const Vec3& C = proj.point;
      if (!half_space(poly, a, C[a] + sign * kFrontSlack, sign, scratch, front)) return all;
      const double h = static_cast<double>(side) - C[a];
      for (std::size_t k = 0; k < front.n; ++k) {
        const Vec3& p = front.v[k];
        const double s = h / (p[a] - C[a]);
        box.add(C[ua] + (p[ua] - C[ua]) * s, C[va] + (p[va] - C[va]) * s);
      }
      break;
    }
    case ProjectionType::Axial: {
      // Coordinate along the axis unchanged; the other one (axis c) a 2D central projection from the
      // axis point in the cross-section. Both are monotone along segments, so the vertices bound them.
      const int X = proj.axis;
      const int c = 3 - X - a;
      const Vec3& A = proj.point;
      double x0 = 1e300, x1 = -1e300, c0 = 1e300, c1 = -1e300;
      if (tri.near_end) {
        for (std::size_t k = 0; k < poly.n; ++k) {
          x0 = std::min(x0, poly.v[k][X]);
          x1 = std::max(x1, poly.v[k][X]);
        }
        c0 = 0.0;
        c1 = 1.0;
      } else {
        if (!half_space(poly, a, A[a] + sign * kFrontSlack, sign, scratch, front)) return all;
        const double h = static_cast<double>(side) - A[a];
        for (std::size_t k = 0; k < front.n; ++k) {
          const Vec3& p = front.v[k];
          const double w = A[c] + (p[c] - A[c]) * (h / (p[a] - A[a]));
          x0 = std::min(x0, p[X]);
          x1 = std::max(x1, p[X]);
          c0 = std::min(c0, w);
          c1 = std::max(c1, w);
        }
      }
      if (x0 > x1) return {};
      if (ua == X) {
        box.add(x0, c0);
        box.add(x1, c1);
      } else {
        box.add(c0, x0);
        box.add(c1, x1);
      }
      break;
    }
  }
  if (box.u0 > box.u1) return {};
  return rect_of(box, T);
}

/// Loads the triangles of grey cell g into `s` (unit-cell coordinates, clipped polygons, flags).
void load_cell(std::size_t g, const ReliefMap& map, MeshView mesh, std::span<const std::uint32_t> faces, Scratch& s) {
  const CellProjection& proj = map.projections[g];
  const Vec3 cmin = map.cell_min(g);
  const double cell = map.cell_size;
  s.triangles.clear();
  s.vertices.clear();
  Polygon p0, p1;
  for (const std::uint32_t f : faces) {
    const Face& face = mesh.faces[f];
    const Vec3& wa = mesh.positions[face[0]];
    const Vec3& wb = mesh.positions[face[1]];
    const Vec3& wc = mesh.positions[face[2]];
    CellTriangle t;
    t.face = f;
    const Vec3 normal = (wb - wa).cross(wc - wa);
    const double len = normal.norm();
    if (!(len > 0.0)) continue;  // degenerate: no segment meets it (the determinant test is 0)
    for (int k = 0; k < 3; ++k) t.normal[static_cast<std::size_t>(k)] = to_snorm8(normal[k] / len);
    const Vec3 a = (wa - cmin) / cell;
    const Vec3 b = (wb - cmin) / cell;
    const Vec3 c = (wc - cmin) / cell;
    t.a = a;
    t.e1 = b - a;
    t.e2 = c - a;
    // Clip to the (slightly enlarged) cell.
    p0.v[0] = a;
    p0.v[1] = b;
    p0.v[2] = c;
    p0.n = 3;
    Polygon* in = &p0;
    Polygon* out = &p1;
    for (int axis = 0; axis < 3 && in->n > 0 && !t.clip_failed; ++axis) {
      for (const double sign : {1.0, -1.0}) {
        const double bound = sign > 0.0 ? -kClipSlack : 1.0 + kClipSlack;
        PolygonView kept;
        if (!half_space({in->v.data(), in->n}, axis, bound, sign, *out, kept)) {
          t.clip_failed = true;
          break;
        }
        if (kept.v == out->v.data()) {
          std::swap(in, out);
        } else if (kept.n == 0) {
          in->n = 0;
          break;
        }
      }
    }
    if (!t.clip_failed && in->n == 0) continue;  // touches the cell only within the classification's tolerance
    t.first_vertex = static_cast<std::uint32_t>(s.vertices.size());
    t.num_vertices = t.clip_failed ? 0u : static_cast<std::uint32_t>(in->n);
    for (std::size_t k = 0; k < t.num_vertices; ++k) s.vertices.push_back(in->v[k]);
    // Triangles (nearly) through the end of the segments: the centre of projection or the axis.
    const Vec3 r = Vec3::Constant(kNearRadius);
    if (proj.type == ProjectionType::Perspective) {
      t.near_end = triangle_box_overlap(proj.point - r, proj.point + r, a, b, c);
    } else if (proj.type == ProjectionType::Axial) {
      Vec3 lo = proj.point - r, hi = proj.point + r;
      lo[proj.axis] = -kNearRadius;
      hi[proj.axis] = 1.0 + kNearRadius;
      t.near_end = triangle_box_overlap(lo, hi, a, b, c);
    }
    s.triangles.push_back(t);
  }
}

/// Calls on_hit(ti, k, tau, d, u, v) for every hit of a triangle of `s` (loaded for grey cell g) on the
/// segment of texel ti of layer l: triangle k, segment parameter tau, segment vector d, barycentric u, v.
template <class OnHit>
void trace_layer(std::size_t g, std::size_t l, const ReliefMap& map, const std::vector<double>& coord, const Scratch& s,
                 OnHit&& on_hit) {
  const CellProjection& proj = map.projections[g];
  const std::uint32_t T = map.texture;
  Polygon scratch;
  const int face = map.layer_face[l];
  const int a = face / 2;
  const int ua = (a + 1) % 3;
  const int va = (a + 2) % 3;
  const double side = face % 2;
  for (std::uint32_t k = 0; k < s.triangles.size(); ++k) {
    const CellTriangle& tri = s.triangles[k];
    const PolygonView poly{s.vertices.data() + tri.first_vertex, tri.num_vertices};
    const TexelRect rect = texel_rect(proj, face, tri, poly, T, scratch);
    if (rect.empty()) continue;
    const Vec3 e1 = tri.e1, e2 = tri.e2;
    // The segment of texel P' is P' + τ·D, τ ∈ [0, 1], with D = base − mask ∘ (P' − a).
    Vec3 base = Vec3::Zero();
    Vec3 mask = Vec3::Zero();
    switch (proj.type) {
      case ProjectionType::Parallel:  // towards the opposite face
        base = -proj.direction;
        break;
      case ProjectionType::Planar:  // towards the plane
        base[a] = proj.point[a] - side;
        break;
      case ProjectionType::Perspective:  // towards the centre: D = C − P'
        base = proj.point - tri.a;
        mask = Vec3::Ones();
        break;
      case ProjectionType::Axial:  // towards the axis, perpendicular to it
        base = proj.point - tri.a;
        base[proj.axis] = 0.0;
        mask = Vec3::Ones();
        mask[proj.axis] = 0.0;
        break;
    }
    // P' − a = row + coord[i] · axis_u, with row = (side on the face axis, coord[j] on v) − a; built
    // without writing single components in the inner loop (that defeats store-to-load forwarding).
    Vec3 axis_u = Vec3::Zero();
    axis_u[ua] = 1.0;
    Vec3 row0 = -tri.a;
    row0[a] = side - tri.a[a];
    for (std::uint32_t j = rect.j0; j <= rect.j1; ++j) {
      Vec3 rowv = row0;
      rowv[va] = coord[j] - tri.a[va];
      const std::size_t row = static_cast<std::size_t>(j) * T;
      for (std::uint32_t i = rect.i0; i <= rect.i1; ++i) {
        const Vec3 tvec = rowv + coord[i] * axis_u;
        const Vec3 d = base - mask.cwiseProduct(tvec);
        // Möller–Trumbore on P' + τ·D.
        const Vec3 pvec = d.cross(e2);
        const double det = e1.dot(pvec);
        if (det == 0.0) continue;  // segment parallel to the triangle's plane
        const double inv = 1.0 / det;
        const double u = tvec.dot(pvec) * inv;
        if (u < -kBaryTolerance || u > 1.0 + kBaryTolerance) continue;
        const Vec3 qvec = tvec.cross(e1);
        const double v = d.dot(qvec) * inv;
        if (v < -kBaryTolerance || u + v > 1.0 + kBaryTolerance) continue;
        const double tau = e2.dot(qvec) * inv;
        if (tau < -kTauTolerance || tau > 1.0 + kTauTolerance) continue;
        on_hit(row + i, k, tau, d, u, v);
      }
    }
  }
}

/// Samples the layers of grey cell g; adds its hit counts to `counts`. The cell's triangles are loaded
/// kLoadChunk at a time (a coarse cell of a huge mesh holds millions of them: 180 bytes each loaded) and
/// traced through the cell's layers; each texel still meets them in the order of the cell's list. A cell of
/// one load keeps the hits of one layer at a time, a larger one those of all its layers.
void sample_cell(std::size_t g, ReliefMap& map, const TriMesh& mesh, const CellGrid& grid,
                 const std::vector<double>& coord, Scratch& s, ReliefSampleCounts& counts) {
  const std::size_t tpl = map.texels_per_layer();
  const std::size_t first = map.first_layer[g], layers = map.first_layer[g + 1] - first;
  const std::vector<std::uint32_t>& faces = grid.grey_triangles[g];
  const auto trace = [&](std::size_t li, TexelHit* hits, std::uint32_t offset) {
    trace_layer(g, first + li, map, coord, s, [&](std::size_t ti, std::uint32_t k, double tau, const Vec3& d, double u, double v) {
      TexelHit& h = hits[ti];
      if (add_hit(h, tau, [&] { return d.norm(); }, offset + k, u, v)) {
        h.face = s.triangles[k].face;
        h.normal = s.triangles[k].normal;
      }
    });
  };
  const auto store = [&](std::size_t li, const TexelHit* hits) {
    const std::size_t base = (first + li) * tpl;
    for (std::size_t ti = 0; ti < tpl; ++ti) {
      const TexelHit& h = hits[ti];
      if (h.hits == 0) continue;
      const std::size_t out = base + ti;
      store_distance(map, out, h, counts);
      for (std::size_t c = 0; c < 3; ++c) map.normals[3 * out + c] = h.normal[c];
      if (!map.colors.empty()) {
        const Face& f = mesh.faces[h.face];
        const Vec3f col = (1.0f - h.u - h.v) * mesh.colors[f[0]] + h.u * mesh.colors[f[1]] + h.v * mesh.colors[f[2]];
        for (std::size_t c = 0; c < 3; ++c)
          map.colors[3 * out + c] = to_unorm8(static_cast<double>(col[static_cast<int>(c)]));
      }
    }
  };
  if (faces.size() <= kLoadChunk) {
    load_cell(g, map, mesh, faces, s);
    for (std::size_t li = 0; li < layers; ++li) {
      s.hits.assign(tpl, TexelHit{});
      trace(li, s.hits.data(), 0);
      store(li, s.hits.data());
    }
    return;
  }
  s.hits.assign(layers * tpl, TexelHit{});
  for (std::size_t begin = 0; begin < faces.size(); begin += kLoadChunk) {
    const std::size_t count = std::min(kLoadChunk, faces.size() - begin);
    load_cell(g, map, mesh, std::span<const std::uint32_t>(faces).subspan(begin, count), s);
    for (std::size_t li = 0; li < layers; ++li) trace(li, s.hits.data() + li * tpl, static_cast<std::uint32_t>(begin));
  }
  for (std::size_t li = 0; li < layers; ++li) store(li, s.hits.data() + li * tpl);
}

}  // namespace

ReliefSampleCounts sample_relief_layers(ReliefMap& map, const TriMesh& mesh, const CellGrid& grid,
                                        const ProgressCallback& progress) {
  const std::size_t G = map.cells.size();
  if (grid.grey_cells.size() != G || grid.grey_triangles.size() != G || map.first_layer.size() != G + 1)
    throw InvalidInput(fmt::format("relief sampling: the cell table ({} grey cells) does not match the grid ({})", G,
                                   grid.grey_cells.size()));
  const std::size_t layers = map.num_layers();
  const std::size_t tpl = map.texels_per_layer();
  const std::uint32_t T = map.texture;
  map.distances.assign(layers * tpl, kEmptyTexel);
  map.normals.assign(layers * tpl * 3, 0);
  map.colors.assign(mesh.has_colors() ? layers * tpl * 3 : 0, 0);
  std::vector<double> coord(T);
  for (std::uint32_t i = 0; i < T; ++i) coord[i] = map.texel_coord(i);

  tbb::enumerable_thread_specific<Scratch> scratch;
  std::atomic<std::uint64_t> samples_total{0}, occluded_total{0};
  std::atomic<std::size_t> layers_done{0};
  std::atomic<bool> cancelled{false};
  // Each task writes only the layers of its own cells, so the maps do not depend on the scheduling.
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, G, 1), [&](const tbb::blocked_range<std::size_t>& range) {
    if (cancelled.load(std::memory_order_relaxed)) return;
    Scratch& s = scratch.local();
    ReliefSampleCounts counts;
    std::size_t done_here = 0;
    for (std::size_t g = range.begin(); g != range.end(); ++g) {
      sample_cell(g, map, mesh, grid, coord, s, counts);
      done_here += map.first_layer[g + 1] - map.first_layer[g];
    }
    samples_total += counts.samples;
    occluded_total += counts.occluded;
    const std::size_t done = layers_done += done_here;
    if (progress) {
      try {
        report_progress(progress, "relief sampling", layers == 0 ? 1.0 : static_cast<double>(done) / static_cast<double>(layers));
      } catch (const Cancelled&) {
        cancelled = true;
      }
    }
  });
  if (cancelled) throw Cancelled("relief sampling: cancelled");
  return {samples_total.load(), occluded_total.load()};
}

}  // namespace gimforge::detail

namespace gimforge {

std::vector<ReliefHit> sample_relief_hits(const ReliefMap& layout, MeshView part, const CellGrid& grid,
                                          std::span<const std::uint64_t> face_ids) {
  const std::size_t G = layout.cells.size();
  if (grid.grey_cells.size() != G || grid.grey_triangles.size() != G || layout.first_layer.size() != G + 1)
    throw InvalidInput(fmt::format("relief sampling: the cell table ({} grey cells) does not match the grid ({})", G,
                                   grid.grey_cells.size()));
  if (face_ids.size() != part.faces.size())
    throw InvalidInput(fmt::format("relief sampling: {} face ids for {} faces", face_ids.size(), part.faces.size()));
  const std::uint32_t T = layout.texture;
  const std::size_t tpl = layout.texels_per_layer();
  std::vector<double> coord(T);
  for (std::uint32_t i = 0; i < T; ++i) coord[i] = layout.texel_coord(i);
  // Cells in fixed chunks whose hits are joined in order: the result does not depend on the threads.
  constexpr std::size_t kChunk = 64;
  std::vector<std::vector<ReliefHit>> parts((G + kChunk - 1) / kChunk);
  tbb::enumerable_thread_specific<detail::Scratch> scratch;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, parts.size(), 1), [&](const tbb::blocked_range<std::size_t>& range) {
    detail::Scratch& s = scratch.local();
    for (std::size_t c = range.begin(); c != range.end(); ++c)
      for (std::size_t g = c * kChunk; g < std::min(G, (c + 1) * kChunk); ++g) {
        const std::vector<std::uint32_t>& faces = grid.grey_triangles[g];
        for (std::size_t begin = 0; begin < faces.size(); begin += detail::kLoadChunk) {
          const std::size_t count = std::min(detail::kLoadChunk, faces.size() - begin);
          detail::load_cell(g, layout, part, std::span<const std::uint32_t>(faces).subspan(begin, count), s);
          for (std::size_t l = layout.first_layer[g]; l < layout.first_layer[g + 1]; ++l)
            detail::trace_layer(g, l, layout, coord, s,
                                [&](std::size_t ti, std::uint32_t k, double tau, const Vec3& d, double, double) {
                                  const detail::CellTriangle& tri = s.triangles[k];
                                  parts[c].push_back({l * tpl + ti, face_ids[tri.face], tau, d.norm(), tri.normal, {}});
                                });
        }
      }
  });
  std::size_t total = 0;
  for (const auto& p : parts) total += p.size();
  std::vector<ReliefHit> hits;
  hits.reserve(total);
  for (auto& p : parts) {
    hits.insert(hits.end(), p.begin(), p.end());
    p = {};
  }
  return hits;
}

ReliefSampleCounts resolve_relief_hits(ReliefMap& map, std::span<const ReliefHit> hits) {
  const std::size_t texels = map.num_layers() * map.texels_per_layer();
  map.distances.assign(texels, kEmptyTexel);
  map.normals.assign(3 * texels, 0);
  map.colors.clear();
  ReliefSampleCounts counts;
  for (std::size_t s = 0; s < hits.size();) {
    const std::uint64_t texel = hits[s].texel;
    if (texel >= texels) throw InvalidInput(fmt::format("relief hits: texel {} of {}", texel, texels));
    detail::TexelHit h;
    std::size_t e = s;
    for (; e < hits.size() && hits[e].texel == texel; ++e) {
      if (e > s && hits[e].face <= hits[e - 1].face)
        throw InvalidInput("relief hits: not sorted by texel, then face");
      detail::add_hit(h, hits[e].tau, [&] { return hits[e].length; }, static_cast<std::uint32_t>(e - s), 0.0, 0.0);
    }
    if (e < hits.size() && hits[e].texel < texel) throw InvalidInput("relief hits: not sorted by texel, then face");
    detail::store_distance(map, static_cast<std::size_t>(texel), h, counts);
    for (std::size_t c = 0; c < 3; ++c) map.normals[3 * texel + c] = hits[s + h.tri].normal[c];
    s = e;
  }
  return counts;
}

}  // namespace gimforge
