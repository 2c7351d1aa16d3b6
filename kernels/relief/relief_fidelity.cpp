#include "kernels/relief/relief_fidelity.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include <embree3/rtcore.h>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "kernels/core/closest_point.h"
#include "kernels/core/errors.h"
#include "kernels/core/surface_sampling.h"

namespace gimforge {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// Leaves of a domain face's quadtree hold kLeafQuads × kLeafQuads texel quads.
constexpr std::uint32_t kLeafQuads = 4;

/// How reconstruct_relief triangulates one texel quad, as bits (0: no triangle). Corners: 0 = (i, j),
/// 1 = (i + 1, j), 2 = (i + 1, j + 1), 3 = (i, j + 1). The orientation (reconstruct_relief swaps two
/// vertices where the stored normals disagree) changes neither areas nor distances beyond rounding; only
/// the sample points depend on it, so it is decided where a triangle receives samples (oriented()).
enum QuadBits : std::uint8_t {
  kSplitBD = 1,  ///< split along the diagonal 1-3 (else 0-2)
  kFirst = 2,    ///< the first triangle is kept
  kSecond = 4,   ///< the second triangle is kept
};

[[nodiscard]] bool has_triangle(std::uint8_t code, std::size_t k) { return (code & (k == 0 ? kFirst : kSecond)) != 0; }

/// Corner indices of triangle k (0, 1) of a quad, in reconstruct_relief's vertex order before its
/// orientation step.
[[nodiscard]] std::array<std::uint8_t, 3> quad_triangle(std::uint8_t code, std::size_t k) {
  using Tri = std::array<std::uint8_t, 3>;
  return (code & kSplitBD) != 0 ? (k == 0 ? Tri{0, 1, 3} : Tri{1, 2, 3}) : (k == 0 ? Tri{0, 1, 2} : Tri{0, 2, 3});
}

/// The reconstruction in texel form: every quad's triangles; texel points are computed where needed (per
/// layer into a LayerPoints scratch for the passes over whole layers, per texel for the queries), never
/// stored for the whole map: 24 bytes per texel were 0.5 GB at N = 32, T = 64, and writing them cost more
/// than computing them.
struct Reconstruction {
  const ReliefMap* map{nullptr};
  std::uint32_t T{0};
  double max_edge2{0.0};
  bool with_normals{false};
  std::vector<std::uint8_t> quads;   ///< per quad (quad_index): QuadBits

  [[nodiscard]] std::size_t quad_index(std::size_t l, std::uint32_t i, std::uint32_t j) const {
    return (l * (T - 1) + j) * (T - 1) + i;
  }
  [[nodiscard]] std::array<std::size_t, 4> corner_texels(std::size_t l, std::uint32_t i, std::uint32_t j) const {
    const std::size_t at = map->texel_index(l, i, j);
    return {at, at + 1, at + T + 1, at + T};
  }
  /// Texel (i, j) of layer l's point, as ReliefMap::texel_surface_point computes it; zero when empty.
  [[nodiscard]] Vec3 point(std::size_t l, std::uint32_t i, std::uint32_t j) const {
    const std::uint16_t d = map->distances[map->texel_index(l, i, j)];
    if (d == kEmptyTexel) return Vec3::Zero();
    const std::size_t g = map->layer_cell[l];
    const Vec3 q = face_point(map->layer_face[l], map->texel_coord(i), map->texel_coord(j));
    const ProjectionRay pr = projection_ray(map->projections[g], q);
    return (map->cell_min(g) + map->cell_size * q) - dequantize_distance(d, map->distance_scale) * pr.direction;
  }
};

/// One layer's texel points (T × T, row j = texel row j), computed by compute_points.
struct LayerPoints {
  std::uint32_t T{0};
  std::vector<Vec3> p;
  [[nodiscard]] std::array<const Vec3*, 4> corners(std::uint32_t i, std::uint32_t j) const {
    const std::size_t at = static_cast<std::size_t>(j) * T + i;
    return {&p[at], &p[at + 1], &p[at + T + 1], &p[at + T]};
  }
};

Reconstruction make_reconstruction(const ReliefMap& map, double max_edge_texels) {
  Reconstruction r;
  r.map = &map;
  r.T = map.texture;
  const double spacing = map.cell_size / (map.texture - 1);
  const double max_edge = max_edge_texels * spacing;
  r.max_edge2 = max_edge * max_edge;
  r.with_normals = map.normals.size() == map.distances.size() * 3;
  r.quads.resize(map.num_layers() * (r.T - 1) * (r.T - 1));
  return r;
}

/// Layer l's texel points into `out`, as ReliefMap::texel_surface_point computes them (the cell's corner
/// hoisted; the same operations in the same order as Reconstruction::point).
void compute_points(const Reconstruction& r, std::size_t l, LayerPoints& out) {
  const ReliefMap& map = *r.map;
  const std::size_t g = map.layer_cell[l];
  const Vec3 corner = map.cell_min(g);
  out.T = r.T;
  out.p.resize(static_cast<std::size_t>(r.T) * r.T);
  std::size_t at = 0;
  for (std::uint32_t j = 0; j < r.T; ++j)
    for (std::uint32_t i = 0; i < r.T; ++i, ++at) {
      const std::uint16_t d = map.distances[map.texel_index(l, i, j)];
      if (d == kEmptyTexel) {
        out.p[at] = Vec3::Zero();
        continue;
      }
      const Vec3 q = face_point(map.layer_face[l], map.texel_coord(i), map.texel_coord(j));
      const ProjectionRay pr = projection_ray(map.projections[g], q);
      out.p[at] = (corner + map.cell_size * q) - dequantize_distance(d, map.distance_scale) * pr.direction;
    }
}

Vec3f stored_normal(const ReliefMap& map, std::size_t ti) {
  return {map.normals[3 * ti] / 127.0f, map.normals[3 * ti + 1] / 127.0f, map.normals[3 * ti + 2] / 127.0f};
}

/// reconstruct_relief's triangulation of quad (i, j) of layer l, whose points are `lp`.
std::uint8_t quad_code(const Reconstruction& r, const LayerPoints& lp, std::size_t l, std::uint32_t i, std::uint32_t j) {
  const ReliefMap& map = *r.map;
  for (std::size_t t : r.corner_texels(l, i, j))
    if (map.distances[t] == kEmptyTexel) return 0;
  const std::array<const Vec3*, 4> c = lp.corners(i, j);
  const double ac = (*c[0] - *c[2]).squaredNorm();
  const double bd = (*c[1] - *c[3]).squaredNorm();
  if (std::min(ac, bd) > r.max_edge2) return 0;
  std::uint8_t code = ac <= bd ? 0 : kSplitBD;
  for (std::size_t k = 0; k < 2; ++k) {
    const std::array<std::uint8_t, 3> t = quad_triangle(code, k);
    const Vec3& p0 = *c[t[0]];
    const Vec3& p1 = *c[t[1]];
    const Vec3& p2 = *c[t[2]];
    const Vec3 e1 = p1 - p0;
    const Vec3 e2 = p2 - p0;
    if (e1.squaredNorm() > r.max_edge2 || e2.squaredNorm() > r.max_edge2 || (p2 - p1).squaredNorm() > r.max_edge2)
      continue;
    const Vec3 nrm = e1.cross(e2);
    if (nrm.squaredNorm() == 0.0) continue;
    code = static_cast<std::uint8_t>(code | (k == 0 ? kFirst : kSecond));
  }
  return code;
}

/// Triangle t (corner indices of quad (i, j) of layer l) with reconstruct_relief's orientation: its last
/// two vertices swapped when its normal disagrees with the sum of the stored normals.
std::array<std::uint8_t, 3> oriented(const Reconstruction& r, const LayerPoints& lp, std::size_t l, std::uint32_t i,
                                     std::uint32_t j, std::array<std::uint8_t, 3> t) {
  if (!r.with_normals) return t;
  const std::array<std::size_t, 4> ti = r.corner_texels(l, i, j);
  const std::array<const Vec3*, 4> c = lp.corners(i, j);
  const Vec3 nrm = (*c[t[1]] - *c[t[0]]).cross(*c[t[2]] - *c[t[0]]);
  const Vec3f sn = stored_normal(*r.map, ti[t[0]]) + stored_normal(*r.map, ti[t[1]]) + stored_normal(*r.map, ti[t[2]]);
  if (nrm.dot(sn.cast<double>()) < 0.0) std::swap(t[1], t[2]);
  return t;
}

/// Calls f(i, j, k, a, b, c) for every triangle of layer l (whose points are `lp`), in reconstruct_relief's
/// order.
template <class F>
void for_each_triangle(const Reconstruction& r, const LayerPoints& lp, std::size_t l, F&& f) {
  for (std::uint32_t j = 0; j + 1 < r.T; ++j)
    for (std::uint32_t i = 0; i + 1 < r.T; ++i) {
      const std::uint8_t code = r.quads[r.quad_index(l, i, j)];
      if (code == 0) continue;
      const std::array<const Vec3*, 4> c = lp.corners(i, j);
      for (std::size_t k = 0; k < 2; ++k) {
        if (!has_triangle(code, k)) continue;
        const std::array<std::uint8_t, 3> t = quad_triangle(code, k);
        f(i, j, k, t, *c[t[0]], *c[t[1]], *c[t[2]]);
      }
    }
}

/// Area as triangle_area (kernels/core/mesh.h) computes it.
double area_of(const Vec3& a, const Vec3& b, const Vec3& c) { return 0.5 * (b - a).cross(c - a).norm(); }

// ---------------------------------------------------------------------------------------------------------
// Bounding boxes: per layer, a quadtree over blocks of kLeafQuads² quads (float, rounded outwards).

struct Box {
  std::array<float, 3> lo{std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity(),
                          std::numeric_limits<float>::infinity()};
  std::array<float, 3> hi{-std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                          -std::numeric_limits<float>::infinity()};
  [[nodiscard]] bool empty() const { return lo[0] > hi[0]; }
  void add(const Box& b) {
    for (std::size_t k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], b.lo[k]);
      hi[k] = std::max(hi[k], b.hi[k]);
    }
  }
};

float round_down(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) > x) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}
float round_up(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) < x) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

/// Squared distance from p to a box (+infinity for an empty box).
double box_distance2(const Box& b, const Vec3& p) {
  double d2 = 0.0;
  for (int k = 0; k < 3; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    const double d = std::max({static_cast<double>(b.lo[ku]) - p[k], 0.0, p[k] - static_cast<double>(b.hi[ku])});
    d2 += d * d;
  }
  return d2;
}

/// Layout of one layer's quadtree: level 0 = leaves, the last level = the root.
struct TreeLayout {
  std::vector<std::uint32_t> size;    ///< nodes per side of each level
  std::vector<std::size_t> offset;    ///< first node of each level
  std::size_t nodes{0};               ///< per layer

  explicit TreeLayout(std::uint32_t T) {
    std::uint32_t s = (T - 1 + kLeafQuads - 1) / kLeafQuads;
    while (true) {
      size.push_back(s);
      offset.push_back(nodes);
      nodes += static_cast<std::size_t>(s) * s;
      if (s == 1) break;
      s = (s + 1) / 2;
    }
  }
  [[nodiscard]] std::size_t node(std::size_t level, std::uint32_t x, std::uint32_t y) const {
    return offset[level] + static_cast<std::size_t>(y) * size[level] + x;
  }
  [[nodiscard]] std::size_t root() const { return offset.back(); }
};

/// What the first pass learns about one layer.
struct LayerSummary {
  double area{0.0};              ///< sum of its triangles' areas, in reconstruct_relief's order
  std::size_t faces{0};
  std::size_t vertices{0};       ///< non-empty texels
  std::size_t referenced{0};     ///< texels that are a vertex of some triangle
};

/// Per-thread scratch of the passes over whole layers.
struct LayerScratch {
  LayerPoints points;
  std::vector<char> referenced;
  std::vector<std::array<double, 6>> leaf;
};

/// Pass 1 over one layer: its quads' triangles and areas, and its quadtree's boxes (written to `boxes`).
LayerSummary summarize_layer(Reconstruction& r, const TreeLayout& tree, std::size_t l, LayerScratch& scratch,
                             Box* boxes) {
  const ReliefMap& map = *r.map;
  const LayerPoints& lp = scratch.points;
  compute_points(r, l, scratch.points);
  for (std::uint32_t j = 0; j + 1 < r.T; ++j)
    for (std::uint32_t i = 0; i + 1 < r.T; ++i) r.quads[r.quad_index(l, i, j)] = quad_code(r, lp, l, i, j);
  LayerSummary s;
  const std::size_t first = map.texel_index(l, 0, 0);
  for (std::size_t t = first; t < first + map.texels_per_layer(); ++t) s.vertices += map.distances[t] != kEmptyTexel ? 1u : 0u;
  std::vector<char>& referenced = scratch.referenced;
  referenced.assign(map.texels_per_layer(), 0);
  std::vector<std::array<double, 6>>& leaf = scratch.leaf;
  leaf.assign(static_cast<std::size_t>(tree.size[0]) * tree.size[0], {kInf, kInf, kInf, -kInf, -kInf, -kInf});
  for_each_triangle(r, lp, l, [&](std::uint32_t i, std::uint32_t j, std::size_t, const std::array<std::uint8_t, 3>& t,
                              const Vec3& a, const Vec3& b, const Vec3& c) {
    s.area += area_of(a, b, c);
    ++s.faces;
    std::array<double, 6>& box = leaf[tree.node(0, i / kLeafQuads, j / kLeafQuads)];
    const std::array<std::size_t, 4> ti = r.corner_texels(l, i, j);
    for (std::uint8_t v : t) referenced[ti[v] - first] = 1;
    for (const Vec3* p : {&a, &b, &c})
      for (int k = 0; k < 3; ++k) {
        const auto ku = static_cast<std::size_t>(k);
        box[ku] = std::min(box[ku], (*p)[k]);
        box[ku + 3] = std::max(box[ku + 3], (*p)[k]);
      }
  });
  for (char c : referenced) s.referenced += c != 0 ? 1u : 0u;
  const std::uint32_t s0 = tree.size[0];
  for (std::uint32_t y = 0; y < s0; ++y)
    for (std::uint32_t x = 0; x < s0; ++x) {
      const std::array<double, 6>& b = leaf[tree.node(0, x, y)];
      Box& out = boxes[tree.node(0, x, y)];
      out = Box{};
      if (b[0] > b[3]) continue;
      for (std::size_t a = 0; a < 3; ++a) {
        out.lo[a] = round_down(b[a]);
        out.hi[a] = round_up(b[a + 3]);
      }
    }
  for (std::size_t level = 1; level < tree.size.size(); ++level) {
    const std::uint32_t below = tree.size[level - 1];
    for (std::uint32_t y = 0; y < tree.size[level]; ++y)
      for (std::uint32_t x = 0; x < tree.size[level]; ++x) {
        Box b;
        for (std::uint32_t dy = 0; dy < 2; ++dy)
          for (std::uint32_t dx = 0; dx < 2; ++dx)
            if (2 * x + dx < below && 2 * y + dy < below) b.add(boxes[tree.node(level - 1, 2 * x + dx, 2 * y + dy)]);
        boxes[tree.node(level, x, y)] = b;
      }
  }
  return s;
}

// ---------------------------------------------------------------------------------------------------------
// Original -> reconstruction: exact closest points through an Embree BVH over the layers' root boxes.

/// The triangle a query ended on, to bound the next (nearby) query from above.
struct TriangleRef {
  std::uint32_t layer{0xffffffffu};
  std::uint32_t i{0};
  std::uint32_t j{0};
  std::uint32_t k{0};
};

/// Texel points of recently visited quadtree leaves, per thread: consecutive queries are nearby samples
/// and visit mostly the same leaves, whose points are then computed once.
struct LeafCache {
  static constexpr std::uint32_t kW = kLeafQuads + 1;  ///< texels per side of a leaf
  static_assert(kW * kW <= 32, "one bit per texel of a leaf");
  struct Entry {
    std::uint32_t layer{0xffffffffu};
    std::uint32_t x{0};
    std::uint32_t y{0};
    std::uint32_t have{0};  ///< bit k: pts[k] is computed
    std::array<Vec3, kW * kW> pts;
  };
  std::vector<Entry> entries = std::vector<Entry>(256);
  Entry& find(std::uint32_t layer, std::uint32_t x, std::uint32_t y) {
    const std::uint32_t h = (layer * 0x9E3779B1u) ^ (x * 0x85EBCA77u) ^ (y * 0xC2B2AE3Du);
    Entry& e = entries[(h ^ (h >> 15)) & (entries.size() - 1)];
    if (e.layer != layer || e.x != x || e.y != y) {
      e.layer = layer;
      e.x = x;
      e.y = y;
      e.have = 0;
    }
    return e;
  }
};

class ReconstructionLocator {
 public:
  ReconstructionLocator(const EmbreeDevice& device, const Reconstruction& recon, const TreeLayout& tree,
                        const std::vector<Box>& boxes, std::vector<std::uint32_t> layers)
      : recon_(recon), tree_(tree), boxes_(boxes), layers_(std::move(layers)) {
    for (std::uint32_t l : layers_) {
      const Box& b = root(l);
      for (std::size_t a = 0; a < 3; ++a)
        max_abs_ = std::max({max_abs_, std::abs(static_cast<double>(b.lo[a])), std::abs(static_cast<double>(b.hi[a]))});
    }
    auto* rtc = static_cast<RTCDevice>(device.native());
    RTCGeometry geom = rtcNewGeometry(rtc, RTC_GEOMETRY_TYPE_USER);
    device.check("relief fidelity: creating the layer geometry");
    if (!geom) throw LibraryError("Embree: relief fidelity: cannot create a user geometry");
    rtcSetGeometryUserPrimitiveCount(geom, static_cast<unsigned>(layers_.size()));
    rtcSetGeometryUserData(geom, this);  // what the bounds function receives as geometryUserPtr
    rtcSetGeometryBoundsFunction(geom, &ReconstructionLocator::bounds, this);
    rtcCommitGeometry(geom);
    scene_ = rtcNewScene(rtc);
    rtcAttachGeometry(scene_, geom);
    rtcReleaseGeometry(geom);
    rtcCommitScene(scene_);
    device.check("relief fidelity: building the layer BVH");
  }
  ~ReconstructionLocator() {
    if (scene_) rtcReleaseScene(scene_);
  }
  ReconstructionLocator(const ReconstructionLocator&) = delete;
  ReconstructionLocator& operator=(const ReconstructionLocator&) = delete;

  /// Exact distance from p to the reconstruction; `hint` (the previous answer's triangle, if any) bounds
  /// the search and is replaced by this answer's triangle.
  [[nodiscard]] double distance(const Vec3& p, TriangleRef& hint, LeafCache& cache) const {
    Query q{this, p, kInf, kInf, 0.0, hint, &cache};
    q.margin = 1e-6 * std::max({max_abs_, std::abs(p.x()), std::abs(p.y()), std::abs(p.z()), 1e-30});
    if (hint.layer != 0xffffffffu) {
      q.best2 = hint_distance2(p, hint, cache);
      q.best = std::sqrt(q.best2);
    }
    projection_bound(q);
    RTCPointQuery query;
    query.x = static_cast<float>(p.x());
    query.y = static_cast<float>(p.y());
    query.z = static_cast<float>(p.z());
    query.time = 0.0f;
    query.radius = std::isfinite(q.best) ? static_cast<float>(q.best * (1.0 + 1e-6) + q.margin)
                                         : std::numeric_limits<float>::infinity();
    RTCPointQueryContext context;
    rtcInitPointQueryContext(&context);
    rtcPointQuery(scene_, &query, &context, &ReconstructionLocator::query_layer, &q);
    hint = q.result;
    return q.best;
  }

 private:
  struct Query {
    const ReconstructionLocator* self;
    Vec3 p;
    double best2;
    double best;
    double margin;
    TriangleRef result;
    LeafCache* cache;
  };

  [[nodiscard]] const Box& root(std::uint32_t l) const { return boxes_[l * tree_.nodes + tree_.root()]; }

  static void bounds(const RTCBoundsFunctionArguments* args) {
    const auto* self = static_cast<const ReconstructionLocator*>(args->geometryUserPtr);
    const Box& b = self->root(self->layers_[args->primID]);
    args->bounds_o->lower_x = b.lo[0];
    args->bounds_o->lower_y = b.lo[1];
    args->bounds_o->lower_z = b.lo[2];
    args->bounds_o->upper_x = b.hi[0];
    args->bounds_o->upper_y = b.hi[1];
    args->bounds_o->upper_z = b.hi[2];
  }

  static bool query_layer(RTCPointQueryFunctionArguments* args) {
    auto* q = static_cast<Query*>(args->userPtr);
    const double before = q->best2;
    q->self->search_layer(*q, q->self->layers_[args->primID]);
    if (q->best2 < before) {
      args->query->radius = static_cast<float>(q->best * (1.0 + 1e-6) + q->margin);
      return true;
    }
    return false;
  }

  /// Lowers q's bound to the triangles of the quad that q.p projects to in its grey cell (§3.2: the point's
  /// own texel). Where q.p is represented, that quad lies within about a texel of it, far below the bound
  /// the previous sample leaves (often tens of texels), so the exact search below visits a leaf or two.
  void projection_bound(Query& q) const {
    const ReliefMap& map = *recon_.map;
    const Vec3 local = (q.p - map.origin) / map.cell_size;
    std::array<std::uint32_t, 3> c{};
    for (int k = 0; k < 3; ++k) {
      const double f = std::floor(local[k]);
      if (!(f >= 0.0)) c[static_cast<std::size_t>(k)] = 0;
      else c[static_cast<std::size_t>(k)] = static_cast<std::uint32_t>(std::min(f, static_cast<double>(map.n - 1)));
    }
    const std::uint32_t linear = (c[2] * map.n + c[1]) * map.n + c[0];
    const auto it = std::lower_bound(map.cells.begin(), map.cells.end(), linear);
    if (it == map.cells.end() || *it != linear) return;
    const auto g = static_cast<std::size_t>(it - map.cells.begin());
    const Vec3 unit = local - Vec3(c[0], c[1], c[2]);
    FaceProjection fp;
    if (!project_point(map.projections[g], unit, fp)) return;
    for (std::uint32_t l = map.first_layer[g]; l < map.first_layer[g + 1]; ++l) {
      if (map.layer_face[l] != fp.face) continue;
      const double span = static_cast<double>(recon_.T - 1);
      const auto cell_of = [&](double t) {
        const double x = std::floor(std::clamp(t, 0.0, 1.0) * span);
        return static_cast<std::uint32_t>(std::min(x, span - 1.0));
      };
      const std::uint32_t i = cell_of(fp.u), j = cell_of(fp.v);
      const std::uint8_t code = recon_.quads[recon_.quad_index(l, i, j)];
      for (std::uint32_t k = 0; k < 2; ++k) {
        if (!has_triangle(code, k)) continue;
        const TriangleRef ref{l, i, j, k};
        const double d2 = hint_distance2(q.p, ref, *q.cache);
        if (d2 < q.best2) {
          q.best2 = d2;
          q.best = std::sqrt(d2);
          q.result = ref;
        }
      }
    }
  }

  /// Squared distance from p to the triangle `ref`.
  [[nodiscard]] double hint_distance2(const Vec3& p, const TriangleRef& ref, LeafCache& cache) const {
    const std::array<std::uint8_t, 3> t = quad_triangle(recon_.quads[recon_.quad_index(ref.layer, ref.i, ref.j)], ref.k);
    const std::array<const Vec3*, 4> c = quad_corners(cache, ref.layer, ref.i, ref.j);
    return squared_distance_to_triangle(p, *c[t[0]], *c[t[1]], *c[t[2]]);
  }

  /// The corners of quad (i, j) of layer l through the cache entry of its leaf.
  [[nodiscard]] std::array<const Vec3*, 4> quad_corners(LeafCache& cache, std::uint32_t l, std::uint32_t i,
                                                        std::uint32_t j) const {
    const std::uint32_t x = i / kLeafQuads, y = j / kLeafQuads;
    LeafCache::Entry& leaf = cache.find(l, x, y);
    const std::uint32_t i0 = x * kLeafQuads, j0 = y * kLeafQuads;
    const auto at = [&](std::uint32_t ti, std::uint32_t tj) -> const Vec3* {
      const std::uint32_t k = (tj - j0) * LeafCache::kW + (ti - i0);
      if ((leaf.have & (1u << k)) == 0) {
        leaf.pts[k] = recon_.point(l, ti, tj);
        leaf.have |= 1u << k;
      }
      return &leaf.pts[k];
    };
    return {at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)};
  }

  /// Best-first descent of layer l's quadtree.
  void search_layer(Query& q, std::uint32_t l) const {
    const Box* boxes = &boxes_[l * tree_.nodes];
    struct Entry {
      std::uint32_t level, x, y;
    };
    std::array<Entry, 128> stack;  // not value-initialized: written before read
    std::size_t top = 0;
    const auto top_level = static_cast<std::uint32_t>(tree_.size.size() - 1);
    stack[top++] = {top_level, 0, 0};
    while (top > 0) {
      const Entry e = stack[--top];
      if (box_distance2(boxes[tree_.node(e.level, e.x, e.y)], q.p) >= q.best2) continue;
      if (e.level == 0) {
        search_leaf(q, l, e.x, e.y);
        continue;
      }
      // Children nearest last on the stack, so that they are searched first.
      std::array<std::pair<double, Entry>, 4> kids{};
      int n = 0;
      const std::uint32_t below = tree_.size[e.level - 1];
      for (std::uint32_t dy = 0; dy < 2; ++dy)
        for (std::uint32_t dx = 0; dx < 2; ++dx) {
          const std::uint32_t x = 2 * e.x + dx, y = 2 * e.y + dy;
          if (x >= below || y >= below) continue;
          const double d2 = box_distance2(boxes[tree_.node(e.level - 1, x, y)], q.p);
          if (d2 < q.best2) kids[static_cast<std::size_t>(n++)] = {d2, Entry{e.level - 1, x, y}};
        }
      for (int a = 1; a < n; ++a)  // insertion sort, farthest first
        for (int b = a; b > 0 && kids[static_cast<std::size_t>(b - 1)].first < kids[static_cast<std::size_t>(b)].first; --b)
          std::swap(kids[static_cast<std::size_t>(b - 1)], kids[static_cast<std::size_t>(b)]);
      for (int k = 0; k < n; ++k) stack[top++] = kids[static_cast<std::size_t>(k)].second;
    }
  }

  void search_leaf(Query& q, std::uint32_t l, std::uint32_t x, std::uint32_t y) const {
    const std::uint32_t quads = recon_.T - 1;
    const std::uint32_t i0 = x * kLeafQuads, j0 = y * kLeafQuads;
    const std::uint32_t i1 = std::min(i0 + kLeafQuads, quads), j1 = std::min(j0 + kLeafQuads, quads);
    for (std::uint32_t j = j0; j < j1; ++j)
      for (std::uint32_t i = i0; i < i1; ++i) {
        const std::uint8_t code = recon_.quads[recon_.quad_index(l, i, j)];
        if (code == 0) continue;
        // The leaf's texel points are computed when a quad first needs them, and kept for the next queries.
        const std::array<const Vec3*, 4> c = quad_corners(*q.cache, l, i, j);
        // The quad's box first: most quads of a visited leaf lie beyond the best distance.
        double d2 = 0.0;
        for (int a = 0; a < 3; ++a) {
          const double lo = std::min(std::min((*c[0])[a], (*c[1])[a]), std::min((*c[2])[a], (*c[3])[a]));
          const double hi = std::max(std::max((*c[0])[a], (*c[1])[a]), std::max((*c[2])[a], (*c[3])[a]));
          const double d = std::max({lo - q.p[a], 0.0, q.p[a] - hi});
          d2 += d * d;
        }
        if (d2 >= q.best2) continue;
        for (std::size_t k = 0; k < 2; ++k) {
          if (!has_triangle(code, k)) continue;
          const std::array<std::uint8_t, 3> t = quad_triangle(code, k);
          const TrianglePoint tp = closest_point_on_triangle(q.p, *c[t[0]], *c[t[1]], *c[t[2]]);
          const double e2 = (tp.point - q.p).squaredNorm();
          if (e2 < q.best2) {
            q.best2 = e2;
            q.best = std::sqrt(e2);
            q.result = {l, i, j, static_cast<std::uint32_t>(k)};
          }
        }
      }
  }

  const Reconstruction& recon_;
  const TreeLayout& tree_;
  const std::vector<Box>& boxes_;
  std::vector<std::uint32_t> layers_;  ///< layers with triangles (the user primitives)
  double max_abs_{0.0};
  RTCScene scene_{nullptr};
};

/// Distances from `points` to the reconstruction, in parallel blocks of consecutive points (as
/// distances_to_surface does, each query bounded by its predecessor's triangle and its projection's quad).
std::vector<double> distances_to_reconstruction(std::span<const Vec3> points, const ReconstructionLocator& locator,
                                                const ProgressCallback& progress, std::string_view stage) {
  return distances_in_blocks(
      points,
      [&locator](std::span<const Vec3> block, std::span<double> out) {
        TriangleRef hint;
        LeafCache cache;
        for (std::size_t i = 0; i < block.size(); ++i) out[i] = locator.distance(block[i], hint, cache);
      },
      progress, stage);
}

// ---------------------------------------------------------------------------------------------------------
// Reconstruction -> original: sample_surface's samples, drawn layer by layer.

/// sample_surface's target for sample i of n on a surface of area `total`.
double sample_target(std::size_t i, std::size_t n, double total, std::uint64_t seed) {
  return (static_cast<double>(i) + uniform01(seed, 3 * static_cast<std::uint64_t>(i))) / static_cast<double>(n) * total;
}

/// The first sample whose target is >= c.
std::size_t first_sample_at(double c, std::size_t n, double total, std::uint64_t seed) {
  const double guess = std::floor(c / total * static_cast<double>(n)) - 2.0;
  std::size_t i = guess > 0.0 ? std::min(n, static_cast<std::size_t>(guess)) : 0;
  while (i > 0 && sample_target(i - 1, n, total, seed) >= c) --i;
  while (i < n && sample_target(i, n, total, seed) < c) ++i;
  return i;
}

/// Writes the samples first..end−1 that fall on layer l (cumulative area from `start`) into `points`.
void sample_layer(const Reconstruction& r, const LayerPoints& lp, std::size_t l, double start, std::size_t first, std::size_t end,
                  std::size_t n, double total, std::uint64_t seed, std::vector<Vec3>& points) {
  if (first >= end) return;
  std::size_t s = first;
  double cdf = start;
  // The layer's last triangle with area, for targets past the layer's rounded end.
  std::array<std::uint32_t, 2> last_quad{0, 0};
  std::array<std::uint8_t, 3> last{0, 0, 0};
  const auto emit = [&](std::uint32_t i, std::uint32_t j, const std::array<std::uint8_t, 3>& t, std::size_t sample) {
    const std::array<const Vec3*, 4> c = lp.corners(i, j);
    const std::array<std::uint8_t, 3> o = oriented(r, lp, l, i, j, t);
    const auto stream = 3 * static_cast<std::uint64_t>(sample);
    const double r1 = std::sqrt(uniform01(seed, stream + 1));
    const double r2 = uniform01(seed, stream + 2);
    points[sample] = (1.0 - r1) * *c[o[0]] + r1 * (1.0 - r2) * *c[o[1]] + r1 * r2 * *c[o[2]];
  };
  for_each_triangle(r, lp, l, [&](std::uint32_t i, std::uint32_t j, std::size_t, const std::array<std::uint8_t, 3>& t,
                                  const Vec3& a, const Vec3& b, const Vec3& c) {
    if (s >= end) return;
    const double next = cdf + area_of(a, b, c);
    if (next > cdf) {
      last_quad = {i, j};
      last = t;
    }
    while (s < end && sample_target(s, n, total, seed) < next) emit(i, j, t, s++);
    cdf = next;
  });
  while (s < end) emit(last_quad[0], last_quad[1], last, s++);
}

}  // namespace

struct ReliefReconstructionIndex::Impl {
  Reconstruction recon;
  TreeLayout tree;
  std::vector<Box> boxes;
  std::vector<double> start;  ///< cumulative area before each layer, and the total
  std::optional<ReconstructionLocator> locator;
  std::size_t faces{0}, vertices{0}, referenced{0};
  Impl(const ReliefMap& map, double max_edge_texels) : recon(make_reconstruction(map, max_edge_texels)), tree(map.texture) {}
};

ReliefReconstructionIndex::ReliefReconstructionIndex(const EmbreeDevice& device, const ReliefMap& map,
                                                     double max_edge_texels)
    : map_(&map), impl_(std::make_unique<Impl>(map, max_edge_texels)) {
  Impl& m = *impl_;
  const std::size_t L = map.num_layers();
  // Per layer, its triangles' area and count, and its quadtree.
  m.boxes.resize(L * m.tree.nodes);
  std::vector<LayerSummary> layers(L);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, L, 1), [&](const tbb::blocked_range<std::size_t>& range) {
    LayerScratch scratch;
    for (std::size_t l = range.begin(); l < range.end(); ++l)
      layers[l] = summarize_layer(m.recon, m.tree, l, scratch, &m.boxes[l * m.tree.nodes]);
  });
  m.start.assign(L + 1, 0.0);
  std::vector<std::uint32_t> with_faces;
  for (std::size_t l = 0; l < L; ++l) {
    m.start[l + 1] = m.start[l] + layers[l].area;
    m.vertices += layers[l].vertices;
    m.faces += layers[l].faces;
    m.referenced += layers[l].referenced;
    if (layers[l].faces > 0) with_faces.push_back(static_cast<std::uint32_t>(l));
  }
  const double total = m.start[L];
  if (m.faces == 0 || !(total > 0.0) || !std::isfinite(total))
    throw InvalidInput(fmt::format("relief fidelity: the relief map (N = {}, {}x{} texels) reconstructs to no "
                                   "triangles with area",
                                   map.n, map.texture, map.texture));
  m.locator.emplace(device, m.recon, m.tree, m.boxes, std::move(with_faces));
}

ReliefReconstructionIndex::~ReliefReconstructionIndex() = default;

std::size_t ReliefReconstructionIndex::faces() const { return impl_->faces; }
std::size_t ReliefReconstructionIndex::vertices() const { return impl_->vertices; }
std::size_t ReliefReconstructionIndex::referenced_vertices() const { return impl_->referenced; }

std::vector<double> ReliefReconstructionIndex::distances(std::span<const Vec3> points, const ProgressCallback& progress,
                                                         std::string_view stage) const {
  if (!impl_->locator) throw InvalidInput("relief fidelity: the distance index was released");
  return distances_to_reconstruction(points, *impl_->locator, progress, stage);
}

void ReliefReconstructionIndex::release_distances() {
  impl_->locator.reset();
  impl_->boxes = {};
}

std::vector<Vec3> ReliefReconstructionIndex::area_samples(std::size_t n, std::uint64_t seed) const {
  const Impl& m = *impl_;
  const std::size_t L = map_->num_layers();
  const double total = m.start[L];
  std::vector<Vec3> points(n);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, L, 1), [&](const tbb::blocked_range<std::size_t>& range) {
    LayerPoints lp;
    for (std::size_t l = range.begin(); l < range.end(); ++l) {
      const std::size_t first = first_sample_at(m.start[l], n, total, seed);
      const std::size_t end = l + 1 == L ? n : first_sample_at(m.start[l + 1], n, total, seed);
      if (first >= end) continue;
      compute_points(m.recon, l, lp);
      sample_layer(m.recon, lp, l, m.start[l], first, end, n, total, seed, points);
    }
  });
  return points;
}

double ReliefReconstructionIndex::vertex_bound() const {
  // Every vertex is a texel point within half a quantization step (plus the sampler's tolerances) of the
  // original triangle its texel hit.
  const ReliefMap& map = *map_;
  return 0.5 * map.distance_scale + 1e-9 * map.cell_size * (1.0 + map.n) +
         1e-12 * (map.origin.cwiseAbs().maxCoeff() + map.n * map.cell_size);
}

void ReliefReconstructionIndex::for_each_vertex_batch(const std::function<void(std::span<const Vec3>)>& batch) const {
  const ReliefMap& map = *map_;
  const Reconstruction& recon = impl_->recon;
  const std::size_t L = map.num_layers();
  std::vector<Vec3> points;
  std::vector<char> used;
  LayerPoints lp;
  for (std::size_t l = 0; l < L; ++l) {
    const std::size_t first = map.texel_index(l, 0, 0);
    used.assign(map.texels_per_layer(), 0);
    compute_points(recon, l, lp);
    for_each_triangle(recon, lp, l, [&](std::uint32_t i, std::uint32_t j, std::size_t, const std::array<std::uint8_t, 3>& t,
                                    const Vec3&, const Vec3&, const Vec3&) {
      const std::array<std::size_t, 4> ti = recon.corner_texels(l, i, j);
      for (std::uint8_t v : t) used[ti[v] - first] = 1;
    });
    for (std::size_t t = 0; t < used.size(); ++t)
      if (used[t]) points.push_back(lp.p[t]);
    if (points.size() >= (1u << 20) || l + 1 == L) {
      batch(points);
      points.clear();
    }
  }
}

ReliefFidelity relief_fidelity(const EmbreeDevice& device, MeshView original, const ReliefMap& map,
                               const HausdorffOptions& options, double max_edge_texels) {
  if (options.samples == 0) throw InvalidInput("relief fidelity: the number of samples must be positive");
  if (original.faces.empty()) throw InvalidInput("relief fidelity: the original mesh has no faces");
  ReliefReconstructionIndex index(device, map, max_edge_texels);
  ReliefFidelity out;
  out.reconstruction_vertices = index.referenced_vertices();
  out.reconstruction_faces = index.faces();
  HausdorffResult& h = out.hausdorff;
  h.diag = bounding_box(original).diagonal();

  // Original -> reconstruction: the samples of one_sided_distance, exact distances through the layers.
  {
    const MeasuredPoints samples = measured_points(original, options);
    const std::vector<double> dist = index.distances(samples.points, options.progress, "distance A->B");
    h.ab = summarize_distances(dist, samples.area_samples);
  }
  index.release_distances();

  // Reconstruction -> original: sample_surface's samples of the reconstruction.
  const TriangleBvh bvh_a(device, original);
  h.ba = summarize_distances(distances_to_surface(index.area_samples(options.samples, options.seed), bvh_a,
                                                  options.progress, "distance B->A"),
                             options.samples);
  if (options.include_vertices) {
    if (h.ba.max < index.vertex_bound())  // rare: the area samples all lie that close to the original
      index.for_each_vertex_batch([&](std::span<const Vec3> points) {
        for (double d : distances_to_surface(points, bvh_a, {}, "distance B->A")) h.ba.max = std::max(h.ba.max, d);
      });
    h.ba.vertex_samples = index.referenced_vertices();
  }
  h.max = std::max(h.ab.max, h.ba.max);
  h.rms = std::sqrt((h.ab.rms * h.ab.rms + h.ba.rms * h.ba.rms) / 2.0);
  h.psnr = psnr_db(h.diag, h.rms);
  return out;
}

}  // namespace gimforge
