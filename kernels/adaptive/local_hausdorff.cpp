#include "kernels/adaptive/local_hausdorff.h"

#include "kernels/adaptive/grid_quad.h"

#include <algorithm>
#include <bit>
#include <array>
#include <unordered_map>
#include <cmath>
#include <functional>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "kernels/adaptive/point_triangle.h"
#include "kernels/core/errors.h"

namespace gimforge {
namespace {

struct Box {
  Vec2 lo{Vec2::Constant(std::numeric_limits<double>::infinity())};
  Vec2 hi{Vec2::Constant(-std::numeric_limits<double>::infinity())};
  void add(const Vec2& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  void add(const Box& b) {
    lo = lo.cwiseMin(b.lo);
    hi = hi.cwiseMax(b.hi);
  }
  [[nodiscard]] bool overlaps(const Box& b) const {
    return lo.x() <= b.hi.x() && b.lo.x() <= hi.x() && lo.y() <= b.hi.y() && b.lo.y() <= hi.y();
  }
};

constexpr unsigned kMaxFineLattice = 32;
/// Lattice level verify() searches the worst original faces on: 45 points.
constexpr unsigned kRefineLattice = 8;
/// Lattice level of the reconstruction triangles (D2): 15 points.
constexpr unsigned kTriangleLattice = 4;
/// Half side of a probe's candidate box, in uniform grid spacings: the quad holding the probe's parameter
/// point and the quads within a spacing of it.
constexpr double kProbeRadius = 1.0;
/// Candidate boxes of one probe: its own, a learned one (verify) and glued perimeter points.
constexpr std::size_t kMaxProbeBoxes = 12;
/// The shortest side a quad may get from a move, in uniform grid spacings (the strips' narrowest too).
constexpr double kMinSide = 1.0 / 16.0;

/// Barycentric lattice of level L: (i, j, k)/L with i + j + k = L.
std::vector<Vec3> lattice(unsigned level) {
  std::vector<Vec3> out;
  for (unsigned i = 0; i <= level; ++i)
    for (unsigned j = 0; i + j <= level; ++j)
      out.emplace_back(static_cast<double>(i) / level, static_cast<double>(j) / level,
                       static_cast<double>(level - i - j) / level);
  return out;
}

/// Segment tree of the maximum of a vector, with the index that attains it.
class MaxTree {
 public:
  explicit MaxTree(std::size_t n) : leaves_(1) {
    while (leaves_ < std::max<std::size_t>(n, 1)) leaves_ *= 2;
    tree_.assign(2 * leaves_, -1.0);
  }
  void set(std::size_t i, double v) {
    std::size_t k = leaves_ + i;
    tree_[k] = v;
    for (k /= 2; k >= 1; k /= 2) tree_[k] = std::max(tree_[2 * k], tree_[2 * k + 1]);
  }
  [[nodiscard]] double max() const { return tree_[1]; }
  [[nodiscard]] std::uint32_t argmax() const {
    std::size_t k = 1;
    while (k < leaves_) k = tree_[2 * k] >= tree_[2 * k + 1] ? 2 * k : 2 * k + 1;
    return static_cast<std::uint32_t>(k - leaves_);
  }

 private:
  std::size_t leaves_;
  std::vector<double> tree_;
};

/// A uniform grid of buckets over the unit square.
class Buckets {
 public:
  explicit Buckets(std::uint32_t cells) : g_(std::max(cells, 1u)), cells_(static_cast<std::size_t>(g_) * g_) {}
  struct Range {
    std::uint32_t i0, i1, j0, j1;
  };
  [[nodiscard]] Range range(const Box& b) const {
    auto cell = [&](double x) {
      return static_cast<std::uint32_t>(std::clamp(std::floor(x * g_), 0.0, static_cast<double>(g_ - 1)));
    };
    return {cell(b.lo.x()), cell(b.hi.x()), cell(b.lo.y()), cell(b.hi.y())};
  }
  void insert(const Range& r, std::uint32_t item) {
    for (std::uint32_t j = r.j0; j <= r.j1; ++j)
      for (std::uint32_t i = r.i0; i <= r.i1; ++i) cells_[static_cast<std::size_t>(j) * g_ + i].push_back(item);
  }
  void erase(const Range& r, std::uint32_t item) {
    for (std::uint32_t j = r.j0; j <= r.j1; ++j)
      for (std::uint32_t i = r.i0; i <= r.i1; ++i) {
        auto& cell = cells_[static_cast<std::size_t>(j) * g_ + i];
        const auto it = std::find(cell.begin(), cell.end(), item);
        if (it != cell.end()) {
          *it = cell.back();
          cell.pop_back();
        }
      }
  }
  /// Items of the cells `b` touches, sorted and without repeats.
  void gather(const Box& b, std::vector<std::uint32_t>& out) const {
    out.clear();
    const Range r = range(b);
    for (std::uint32_t j = r.j0; j <= r.j1; ++j)
      for (std::uint32_t i = r.i0; i <= r.i1; ++i) {
        const auto& cell = cells_[static_cast<std::size_t>(j) * g_ + i];
        out.insert(out.end(), cell.begin(), cell.end());
      }
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
  }

 private:
  std::uint32_t g_;
  std::vector<std::vector<std::uint32_t>> cells_;
};

}  // namespace

Vec2 square_perimeter_point(double c) {
  c = std::fmod(c, 4.0);
  if (c < 0.0) c += 4.0;
  const double side = std::floor(c), t = c - side;
  if (side < 1.0) return {t, 0.0};
  if (side < 2.0) return {1.0, t};
  if (side < 3.0) return {1.0 - t, 1.0};
  return {0.0, 1.0 - t};
}

struct LocalHausdorff::Impl {
  MeshView original;
  std::vector<Vec2> original_uv;
  std::uint32_t n;
  double radius;  // half side of a probe's candidate box in the parameter square
  std::vector<Vec2> uv;
  std::vector<Vec3> pos;
  std::vector<std::uint8_t> diagonal;  // per quad: 0 = a–c, 1 = b–d
  std::vector<Vec3> lattice;
  const EmbreeDevice& bvh_device;
  TriangleBvh bvh;
  Buckets quad_cells;
  std::vector<Buckets::Range> quad_range;
  /// D1 probes: every original vertex (probes 0..V−1), and, for a face wider in the parameter square than
  /// the grid spacing, the other points of a lattice with a point every spacing or closer (the distance to
  /// a locally flat reconstruction is affine over a small face: its largest value is at a corner). Each
  /// probe has its parameter point and its squared distance to the closest candidate triangle.
  std::vector<std::uint32_t> inner_first;  // per face, its first inner probe; nf + 1 entries
  std::vector<std::uint32_t> inner_face;   // per inner probe (index − V), its face
  std::vector<Vec3> probe_bary;            // per inner probe, its place in its face
  std::vector<std::uint32_t> vertex_faces_first, vertex_faces;  // faces around each vertex (CSR)
  std::vector<Vec3> probe_pos;
  std::vector<Vec2> probe_uv;
  std::vector<double> probe_d2;
  std::vector<std::uint32_t> probe_tri;
  Buckets probe_cells;
  std::vector<double> original_area;
  std::vector<FaceDistance> d1, d2;
  MaxTree t1, t2;
  std::function<double(double)> mate;
  /// Probes whose closest reconstruction point lies far from them in the parameter square (found by
  /// verify()): the parameter point around which their extra candidate box lies.
  std::unordered_map<std::uint32_t, Vec2> learned;
  /// Probes verify() added where a face's largest distance lies between its lattice points (inner-probe
  /// indices, past the faces' own ranges).
  std::unordered_map<std::uint32_t, std::vector<std::uint32_t>> extra;
  std::vector<std::uint32_t> stamp;  // per original face, for move()
  std::uint32_t epoch{0};

  Impl(const EmbreeDevice& device, MeshView m, std::span<const Vec2> ouv, std::uint32_t size, std::vector<Vec2> suv,
       std::vector<Vec3> spos, std::function<double(double)> perimeter_mate)
      : original(m), original_uv(ouv.begin(), ouv.end()), n(size), radius(kProbeRadius / (size - 1)),
        uv(std::move(suv)), pos(std::move(spos)), lattice(gimforge::lattice(kTriangleLattice)), bvh_device(device), bvh(device, m),
        quad_cells(size - 1), probe_cells(size - 1), t1(m.faces.size()),
        t2(2 * static_cast<std::size_t>(size - 1) * (size - 1)), mate(std::move(perimeter_mate)) {}

  [[nodiscard]] std::uint32_t quads() const { return (n - 1) * (n - 1); }
  [[nodiscard]] std::array<std::uint32_t, 4> corners(std::uint32_t q) const {
    const std::uint32_t i = q % (n - 1), j = q / (n - 1);
    const std::uint32_t a = j * n + i;
    return {a, a + 1, a + n + 1, a + n};
  }
  [[nodiscard]] Face triangle(std::uint32_t t) const {
    const auto [a, b, c, d] = corners(t / 2);
    if (diagonal[t / 2] == 0) return t % 2 == 0 ? Face{a, b, c} : Face{a, c, d};
    return t % 2 == 0 ? Face{a, b, d} : Face{b, c, d};
  }
  [[nodiscard]] Box quad_box(std::uint32_t q) const {
    Box b;
    for (std::uint32_t s : corners(q)) b.add(uv[s]);
    return b;
  }
  [[nodiscard]] Box probe_box(std::uint32_t p) const {
    Box b;
    b.lo = probe_uv[p] - Vec2::Constant(radius);
    b.hi = probe_uv[p] + Vec2::Constant(radius);
    return b;
  }
  /// The probe's candidate boxes: its own, and where its parameter point lies within `radius` of a glued
  /// side of the square, boxes around the points glued to the perimeter within 2·radius of its foot point
  /// (the surface goes on across the cut; near a cut-node, at every copy of the node). Returns how many of
  /// `out` are set.
  std::size_t probe_boxes(std::uint32_t p, std::array<Box, kMaxProbeBoxes>& out) const {
    out[0] = probe_box(p);
    std::size_t count = 1;
    const Vec2& at = probe_uv[p];
    const std::array<std::pair<bool, double>, 4> sides{{{at.y() < radius, at.x()},
                                                        {1.0 - at.x() < radius, 1.0 + at.y()},
                                                        {1.0 - at.y() < radius, 2.0 + (1.0 - at.x())},
                                                        {at.x() < radius, 3.0 + (1.0 - at.y())}}};
    if (const auto it = learned.find(p); it != learned.end()) {
      out[count].lo = it->second - Vec2::Constant(radius);
      out[count].hi = it->second + Vec2::Constant(radius);
      ++count;
    }
    for (const auto& [near, c] : sides) {
      if (!near || !mate) continue;
      for (int k = -2; k <= 2 && count < out.size(); ++k) {
        const double m = mate(c + k * radius);
        if (!std::isfinite(m)) continue;
        const Vec2 q = square_perimeter_point(m);
        bool known = false;
        for (std::size_t b = 1; b < count && !known; ++b)
          known = (0.5 * (out[b].lo + out[b].hi) - q).cwiseAbs().maxCoeff() < 0.5 * radius;
        if (known) continue;
        out[count].lo = q - Vec2::Constant(radius);
        out[count].hi = q + Vec2::Constant(radius);
        ++count;
      }
    }
    return count;
  }
  [[nodiscard]] std::uint8_t shorter_diagonal(std::uint32_t q) const {
    const auto [a, b, c, d] = corners(q);
    return (pos[a] - pos[c]).squaredNorm() <= (pos[b] - pos[d]).squaredNorm() ? 0 : 1;
  }

  /// Files probe p where a move can reach it: at the centre of each of its candidate boxes (its parameter
  /// point and its glued perimeter points).
  void file_probe(std::uint32_t p) {
    std::array<Box, kMaxProbeBoxes> boxes;
    const std::size_t count = probe_boxes(p, boxes);
    for (std::size_t b = 0; b < count; ++b) {
      Box at;
      at.add(Vec2(0.5 * (boxes[b].lo + boxes[b].hi)));
      probe_cells.insert(probe_cells.range(at), p);
    }
  }

  /// Probe p against the triangles of the quads its candidate boxes overlap.
  void measure_probe(std::uint32_t p, std::vector<std::uint32_t>& scratch) {
    std::array<Box, kMaxProbeBoxes> boxes;
    const std::size_t count = probe_boxes(p, boxes);
    double best = std::numeric_limits<double>::infinity();
    std::uint32_t best_t = 0;
    for (std::size_t b = 0; b < count; ++b) {
      quad_cells.gather(boxes[b], scratch);
      for (std::uint32_t q : scratch) {
        if (!quad_box(q).overlaps(boxes[b])) continue;
        for (std::uint32_t t = 2 * q; t < 2 * q + 2; ++t) {
          const Face tri = triangle(t);
          const double sq = closest_feature(probe_pos[p], pos[tri[0]], pos[tri[1]], pos[tri[2]]).squared_distance;
          if (sq < best) best = sq, best_t = t;
        }
      }
    }
    if (!std::isfinite(best))
      throw NumericalError(fmt::format("local Hausdorff: parameter point ({}, {}) of the original lies outside the grid",
                                       probe_uv[p].x(), probe_uv[p].y()));
    probe_d2[p] = best;
    probe_tri[p] = best_t;
  }

  /// D1 of original face f from its probes: its corners and its inner lattice points.
  [[nodiscard]] FaceDistance original_value(std::uint32_t f) const {
    FaceDistance out;
    out.distance = -1.0;
    const auto take = [&](std::uint32_t p, const Vec3& bary) {
      const double d = std::sqrt(probe_d2[p]);
      if (d > out.distance) out.distance = d, out.bary = bary, out.target = probe_tri[p];
    };
    const Face& face = original.faces[f];
    for (std::size_t k = 0; k < 3; ++k) take(face[k], Vec3::Unit(static_cast<Eigen::Index>(k)));
    const auto vertices = static_cast<std::uint32_t>(original.positions.size());
    for (std::uint32_t i = inner_first[f]; i < inner_first[f + 1]; ++i) take(vertices + i, probe_bary[i]);
    if (const auto it = extra.find(f); it != extra.end())
      for (std::uint32_t i : it->second) take(vertices + i, probe_bary[i]);  // for the max only
    if (inner_first[f + 1] - inner_first[f] == 1) {
      // A face smaller than a quad: the distance is nearly affine over it (to a locally flat reconstruction;
      // its centre probe sees a crease of the reconstruction through it), and the mean of an affine d²
      // over a triangle is (Σ d_i² + Σ_{i<j} d_i d_j) / 6.
      const double a = std::sqrt(probe_d2[face[0]]), b = std::sqrt(probe_d2[face[1]]), c = std::sqrt(probe_d2[face[2]]);
      out.mean_squared = (a * a + b * b + c * c + a * b + b * c + c * a) / 6.0;
    } else {
      // The lattice of level L splits the face into L² equal triangles; each point weighs by the number of
      // them it is a corner of (1 at a corner, 3 on an edge, 6 inside): the composite linear rule.
      const std::uint32_t count = inner_first[f + 1] - inner_first[f];
      std::uint32_t level = 1;
      while ((level + 1) * (level + 2) / 2 - 3 < count) ++level;
      double weighted = probe_d2[face[0]] + probe_d2[face[1]] + probe_d2[face[2]];
      for (std::uint32_t i = inner_first[f]; i < inner_first[f + 1]; ++i)
        weighted += ((probe_bary[i].array() > 0.0).all() ? 6.0 : 3.0) * probe_d2[vertices + i];
      out.mean_squared = weighted / (3.0 * level * level);
    }
    return out;
  }

  /// The original faces probe p belongs to.
  template <class F>
  void faces_of_probe(std::uint32_t p, F&& visit) const {
    const auto vertices = static_cast<std::uint32_t>(original.positions.size());
    if (p >= vertices) {
      visit(inner_face[p - vertices]);
      return;
    }
    for (std::uint32_t k = vertex_faces_first[p]; k < vertex_faces_first[p + 1]; ++k) visit(vertex_faces[k]);
  }

  /// D2 of reconstruction triangle t: over the whole original (Embree).
  [[nodiscard]] FaceDistance measure_triangle(std::uint32_t t) const {
    const Face tri = triangle(t);
    FaceDistance out;
    out.distance = -1.0;
    double sum = 0.0;
    std::uint32_t previous = kNoFace;
    for (const Vec3& w : lattice) {
      const Vec3 p = w[0] * pos[tri[0]] + w[1] * pos[tri[1]] + w[2] * pos[tri[2]];
      const double bound =
          previous == kNoFace ? std::numeric_limits<double>::infinity() : bvh.distance_to_face(p, previous);
      const ClosestPoint cp = bvh.closest_point(p, bound);
      if (!cp.found()) throw NumericalError("local Hausdorff: no closest point on the original");
      previous = cp.face;
      // The composite linear rule over the lattice's L² small triangles (see original_value): the corners
      // lie on the surface, and equal weights would pull the mean down.
      const auto corners = (w.array() == 1.0).count(), inner = (w.array() > 0.0).count();
      sum += (corners == 1 ? 1.0 : inner == 3 ? 6.0 : 3.0) * cp.distance * cp.distance;
      if (cp.distance > out.distance) out.distance = cp.distance, out.bary = w, out.target = cp.face;
    }
    out.mean_squared = sum / (3.0 * kTriangleLattice * kTriangleLattice);
    return out;
  }

  void set(Direction d, std::uint32_t f, const FaceDistance& v) {
    (d == Direction::OriginalToGrid ? d1 : d2)[f] = v;
    (d == Direction::OriginalToGrid ? t1 : t2).set(f, v.distance);
  }
};

LocalHausdorff::LocalHausdorff(const EmbreeDevice& device, MeshView original, std::span<const Vec2> original_uv,
                               std::uint32_t n, std::vector<Vec2> sample_uv, std::vector<Vec3> sample_pos,
                               const LocalHausdorffOptions& options) {
  if (n < 2 || sample_uv.size() != std::size_t{n} * n || sample_pos.size() != sample_uv.size() ||
      original_uv.size() != original.positions.size() || original.faces.empty())
    throw InvalidInput(fmt::format("local Hausdorff: {} sample points and {} positions for a {}x{} grid, {} parameter "
                                   "points for {} vertices, {} faces",
                                   sample_uv.size(), sample_pos.size(), n, n, original_uv.size(),
                                   original.positions.size(), original.faces.size()));
  const auto outside = [](const Vec2& p) { return !(p.x() >= 0.0 && p.x() <= 1.0 && p.y() >= 0.0 && p.y() <= 1.0); };
  if (const auto bad = std::find_if(sample_uv.begin(), sample_uv.end(), outside); bad != sample_uv.end())
    throw InvalidInput(fmt::format("local Hausdorff: sample {} lies at ({}, {}), outside the unit square",
                                   bad - sample_uv.begin(), bad->x(), bad->y()));
  if (const auto bad = std::find_if(original_uv.begin(), original_uv.end(), outside); bad != original_uv.end())
    throw InvalidInput(fmt::format("local Hausdorff: vertex {} has parameter point ({}, {}), outside the unit square",
                                   bad - original_uv.begin(), bad->x(), bad->y()));
  impl_ = std::make_unique<Impl>(device, original, original_uv, n, std::move(sample_uv), std::move(sample_pos),
                                 options.glue.mate);
  Impl& m = *impl_;
  m.diagonal.resize(m.quads());
  m.quad_range.resize(m.quads());
  for (std::uint32_t q = 0; q < m.quads(); ++q) {
    m.diagonal[q] = m.shorter_diagonal(q);
    m.quad_range[q] = m.quad_cells.range(m.quad_box(q));
    m.quad_cells.insert(m.quad_range[q], q);
  }
  const std::size_t nf = original.faces.size();
  m.original_area.resize(nf);
  m.stamp.assign(nf, 0);
  const auto nv = static_cast<std::uint32_t>(original.positions.size());
  m.probe_pos.assign(original.positions.begin(), original.positions.end());
  m.probe_uv = m.original_uv;
  m.vertex_faces_first.assign(nv + 1, 0);
  for (const Face& face : original.faces)
    for (std::uint32_t v : face) ++m.vertex_faces_first[v + 1];
  for (std::uint32_t v = 0; v < nv; ++v) m.vertex_faces_first[v + 1] += m.vertex_faces_first[v];
  m.vertex_faces.resize(m.vertex_faces_first[nv]);
  {
    std::vector<std::uint32_t> fill(m.vertex_faces_first.begin(), m.vertex_faces_first.end() - 1);
    for (std::uint32_t f = 0; f < nf; ++f)
      for (std::uint32_t v : original.faces[f]) m.vertex_faces[fill[v]++] = f;
  }
  std::vector<std::vector<Vec3>> lattices(kMaxFineLattice + 1);
  for (unsigned level = 1; level <= kMaxFineLattice; ++level) lattices[level] = lattice(level);
  const double spacing = 1.0 / (n - 1);
  m.inner_first.push_back(0);
  for (std::uint32_t f = 0; f < nf; ++f) {
    const Face& face = original.faces[f];
    double longest = 0.0;
    for (std::size_t k = 0; k < 3; ++k)
      longest = std::max(longest, (m.original_uv[face[k]] - m.original_uv[face[(k + 1) % 3]]).norm());
    {
      // Level 3 for a face smaller than a quad: its centre only (the corners are the vertex probes).
      const auto level = longest > spacing
                             ? static_cast<unsigned>(std::min(std::ceil(longest / spacing) + 1.0, double{kMaxFineLattice}))
                             : 3u;
      for (const Vec3& w : lattices[level]) {
        if (level == 3 && longest <= spacing && !(w.array() > 0.0).all()) continue;
        if (w.maxCoeff() == 1.0) continue;  // a corner: the vertex probe
        m.probe_bary.push_back(w);
        m.inner_face.push_back(f);
        m.probe_pos.push_back(w[0] * original.positions[face[0]] + w[1] * original.positions[face[1]] +
                              w[2] * original.positions[face[2]]);
        m.probe_uv.push_back(w[0] * m.original_uv[face[0]] + w[1] * m.original_uv[face[1]] +
                             w[2] * m.original_uv[face[2]]);
      }
    }
    m.inner_first.push_back(static_cast<std::uint32_t>(m.probe_bary.size()));
    m.original_area[f] = 0.5 * (original.positions[face[1]] - original.positions[face[0]])
                                   .cross(original.positions[face[2]] - original.positions[face[0]])
                                   .norm();
  }
  const auto probes = static_cast<std::uint32_t>(m.probe_uv.size());
  m.probe_d2.resize(probes);
  m.probe_tri.resize(probes);
  for (std::uint32_t p = 0; p < probes; ++p) m.file_probe(p);
  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, probes, 1024), [&](const tbb::blocked_range<std::uint32_t>& r) {
    std::vector<std::uint32_t> scratch;
    for (std::uint32_t p = r.begin(); p < r.end(); ++p) m.measure_probe(p, scratch);
  });
  m.d1.resize(nf);
  for (std::uint32_t f = 0; f < nf; ++f) m.d1[f] = m.original_value(f);
  m.d2.resize(2 * std::size_t{m.quads()});
  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, static_cast<std::uint32_t>(m.d2.size()), 256),
                    [&](const tbb::blocked_range<std::uint32_t>& r) {
                      for (std::uint32_t t = r.begin(); t < r.end(); ++t) m.d2[t] = m.measure_triangle(t);
                    });
  for (std::uint32_t f = 0; f < nf; ++f) m.t1.set(f, m.d1[f].distance);
  for (std::uint32_t t = 0; t < m.d2.size(); ++t) m.t2.set(t, m.d2[t].distance);
}

LocalHausdorff::~LocalHausdorff() = default;

std::uint32_t LocalHausdorff::size() const { return impl_->n; }
const std::vector<Vec2>& LocalHausdorff::sample_uv() const { return impl_->uv; }
const std::vector<Vec3>& LocalHausdorff::sample_pos() const { return impl_->pos; }
Face LocalHausdorff::triangle(std::uint32_t t) const { return impl_->triangle(t); }
std::uint32_t LocalHausdorff::triangles() const { return 2 * impl_->quads(); }
MeshView LocalHausdorff::original() const { return impl_->original; }

const FaceDistance& LocalHausdorff::face(Direction d, std::uint32_t f) const {
  return (d == Direction::OriginalToGrid ? impl_->d1 : impl_->d2).at(f);
}
std::size_t LocalHausdorff::faces(Direction d) const {
  return (d == Direction::OriginalToGrid ? impl_->d1 : impl_->d2).size();
}
std::uint32_t LocalHausdorff::argmax(Direction d) const {
  return (d == Direction::OriginalToGrid ? impl_->t1 : impl_->t2).argmax();
}

DirectedSummary LocalHausdorff::summary(Direction d) const {
  const Impl& m = *impl_;
  double weighted = 0.0, area = 0.0;
  if (d == Direction::OriginalToGrid) {
    for (std::size_t f = 0; f < m.d1.size(); ++f) {
      weighted += m.original_area[f] * m.d1[f].mean_squared;
      area += m.original_area[f];
    }
  } else {
    for (std::uint32_t t = 0; t < m.d2.size(); ++t) {
      const Face tri = m.triangle(t);
      const double a = 0.5 * (m.pos[tri[1]] - m.pos[tri[0]]).cross(m.pos[tri[2]] - m.pos[tri[0]]).norm();
      weighted += a * m.d2[t].mean_squared;
      area += a;
    }
  }
  return {std::max(0.0, (d == Direction::OriginalToGrid ? m.t1 : m.t2).max()),
          area > 0.0 ? std::sqrt(weighted / area) : 0.0};
}

LocalHausdorff::Change LocalHausdorff::move(std::span<const std::uint32_t> samples, std::span<const Vec2> uv,
                                            std::span<const Vec3> pos) {
  Impl& m = *impl_;
  Change c;
  c.samples.assign(samples.begin(), samples.end());
  for (std::uint32_t s : samples) {
    c.old_uv.push_back(m.uv[s]);
    c.old_pos.push_back(m.pos[s]);
    const std::uint32_t i = s % m.n, j = s / m.n;
    for (std::uint32_t dj = 0; dj < 2; ++dj)
      for (std::uint32_t di = 0; di < 2; ++di)
        if (i >= di && j >= dj && i - di < m.n - 1 && j - dj < m.n - 1) c.quads.push_back((j - dj) * (m.n - 1) + i - di);
  }
  std::sort(c.quads.begin(), c.quads.end());
  c.quads.erase(std::unique(c.quads.begin(), c.quads.end()), c.quads.end());
  std::vector<Vec3> old_normal;
  std::vector<Box> old_box;
  // Per quad: which of its two triangles are turned against the quad's normal (bit 0: the first).
  const auto turned = [&m](std::uint32_t q, const Vec3& normal) {
    unsigned bits = 0;
    for (std::uint32_t t = 2 * q; t < 2 * q + 2; ++t) {
      const Face tri = m.triangle(t);
      const Vec3 nrm = (m.pos[tri[1]] - m.pos[tri[0]]).cross(m.pos[tri[2]] - m.pos[tri[0]]);
      if (!(nrm.dot(normal) > 0.0)) bits |= 1u << (t - 2 * q);
    }
    return bits;
  };
  std::vector<unsigned> old_turned;
  for (std::uint32_t q : c.quads) {
    const auto [a, b, cc, d] = m.corners(q);
    old_normal.push_back((m.pos[cc] - m.pos[a]).cross(m.pos[d] - m.pos[b]));
    old_box.push_back(m.quad_box(q));
    c.old_diagonals.push_back(m.diagonal[q]);
    old_turned.push_back(turned(q, old_normal.back()));
  }
  for (std::size_t k = 0; k < samples.size(); ++k) {
    m.uv[samples[k]] = uv[k];
    m.pos[samples[k]] = pos[k];
  }
  // Folds: every quad around a moved sample stays sound in the parameter square (grid_quad.h: convex with a
  // margin, also in float32, no side shorter than kMinSide of the uniform spacing: moves that halve a gap
  // again and again would otherwise draw two samples onto one point), and no reconstruction triangle turns
  // against its quad's previous normal: with the quad's diagonal unchanged, no triangle that was not turned
  // is turned after; with the other diagonal, no more turned triangles than before. (A quad across a crease
  // can hold a turned triangle already; refusing every move that leaves it turned froze the very samples
  // that would fix it: kitten's largest distances.)
  const double shortest = kMinSide / (m.n - 1);
  for (std::size_t k = 0; k < c.quads.size() && !c.folded; ++k) {
    const std::uint32_t q = c.quads[k];
    const auto cs = m.corners(q);
    if (!sound_quad({m.uv[cs[0]], m.uv[cs[1]], m.uv[cs[2]], m.uv[cs[3]]}, shortest)) c.folded = true;
    m.diagonal[q] = m.shorter_diagonal(q);
    if (!c.folded && old_normal[k].squaredNorm() > 0.0) {
      const unsigned now = turned(q, old_normal[k]);
      c.folded = m.diagonal[q] == c.old_diagonals[k] ? (now & ~old_turned[k]) != 0
                                                     : std::popcount(now) > std::popcount(old_turned[k]);
    }
  }
  if (c.folded) {
    for (std::size_t k = 0; k < samples.size(); ++k) {
      m.uv[samples[k]] = c.old_uv[k];
      m.pos[samples[k]] = c.old_pos[k];
    }
    for (std::size_t k = 0; k < c.quads.size(); ++k) m.diagonal[c.quads[k]] = c.old_diagonals[k];
    c.quads.clear();
    return c;
  }
  Box region;
  for (std::size_t k = 0; k < c.quads.size(); ++k) {
    const std::uint32_t q = c.quads[k];
    m.quad_cells.erase(m.quad_range[q], q);
    const Box b = m.quad_box(q);
    m.quad_range[q] = m.quad_cells.range(b);
    m.quad_cells.insert(m.quad_range[q], q);
    region.add(b);
    region.add(old_box[k]);
  }
  // Entries to re-measure: the triangles of the quads (D2), and the probes whose candidate box overlaps an
  // old or new quad (their candidates or distances may change), with the original faces they belong to.
  for (std::uint32_t q : c.quads) {
    c.entries.emplace_back(Direction::GridToOriginal, 2 * q);
    c.entries.emplace_back(Direction::GridToOriginal, 2 * q + 1);
  }
  Box reach = region;
  reach.lo -= Vec2::Constant(m.radius);
  reach.hi += Vec2::Constant(m.radius);
  std::vector<std::uint32_t> nearby, scratch;
  m.probe_cells.gather(reach, nearby);
  ++m.epoch;
  std::array<Box, kMaxProbeBoxes> boxes;
  for (std::uint32_t p : nearby) {
    const std::size_t count = m.probe_boxes(p, boxes);
    const auto within = [&](const Box& b) {
      for (std::size_t k = 0; k < count; ++k)
        if (boxes[k].overlaps(b)) return true;
      return false;
    };
    bool hit = false;
    for (std::size_t k = 0; k < c.quads.size() && !hit; ++k) hit = within(old_box[k]) || within(m.quad_box(c.quads[k]));
    if (!hit) continue;
    c.probes.push_back(p);
    c.old_probe_d2.push_back(m.probe_d2[p]);
    c.old_probe_tri.push_back(m.probe_tri[p]);
    if (std::binary_search(c.quads.begin(), c.quads.end(), m.probe_tri[p] / 2)) {
      m.measure_probe(p, scratch);  // its closest triangle moved: every candidate again
    } else {
      // The other candidates did not move: only the moved quads now within its box can come closer.
      for (std::uint32_t q : c.quads) {
        if (!within(m.quad_box(q))) continue;
        for (std::uint32_t t = 2 * q; t < 2 * q + 2; ++t) {
          const Face tri = m.triangle(t);
          const double sq = closest_feature(m.probe_pos[p], m.pos[tri[0]], m.pos[tri[1]], m.pos[tri[2]]).squared_distance;
          if (sq < m.probe_d2[p]) m.probe_d2[p] = sq, m.probe_tri[p] = t;
        }
      }
    }
    m.faces_of_probe(p, [&](std::uint32_t f) {
      if (m.stamp[f] == m.epoch) return;
      m.stamp[f] = m.epoch;
      c.entries.emplace_back(Direction::OriginalToGrid, f);
    });
  }
  c.max_before = c.max_after = 0.0;
  for (const auto& [d, f] : c.entries) {
    const FaceDistance& old = face(d, f);
    c.old_values.push_back(old);
    c.max_before = std::max(c.max_before, old.distance);
    const FaceDistance now = d == Direction::OriginalToGrid ? m.original_value(f) : m.measure_triangle(f);
    c.max_after = std::max(c.max_after, now.distance);
    m.set(d, f, now);
  }
  return c;
}

std::size_t LocalHausdorff::verify(double threshold) {
  Impl& m = *impl_;
  std::vector<Face> triangles(m.d2.size());
  for (std::uint32_t t = 0; t < triangles.size(); ++t) triangles[t] = m.triangle(t);
  const TriangleBvh whole(m.bvh_device, MeshView(m.pos, triangles));
  const auto probes = static_cast<std::uint32_t>(m.probe_d2.size());
  std::vector<std::uint32_t> suspects;
  for (std::uint32_t p = 0; p < probes; ++p)
    if (m.probe_d2[p] > threshold * threshold) suspects.push_back(p);
  std::vector<ClosestPoint> found(suspects.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, suspects.size(), 64), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t k = r.begin(); k < r.end(); ++k) found[k] = whole.closest_point(m.probe_pos[suspects[k]]);
  });
  std::size_t learned = 0;
  std::vector<std::uint32_t> scratch;
  std::vector<std::uint32_t> faces;
  for (std::size_t k = 0; k < suspects.size(); ++k) {
    const std::uint32_t p = suspects[k];
    if (!found[k].found() || !(found[k].distance * found[k].distance < m.probe_d2[p] * (1.0 - 1e-9))) continue;
    const Face tri = triangles[found[k].face];
    const Vec2 where = (m.uv[tri[0]] + m.uv[tri[1]] + m.uv[tri[2]]) / 3.0;
    m.learned[p] = where;
    Box at;
    at.add(where);
    m.probe_cells.insert(m.probe_cells.range(at), p);
    m.measure_probe(p, scratch);
    m.faces_of_probe(p, [&](std::uint32_t f) { faces.push_back(f); });
    ++learned;
  }
  std::sort(faces.begin(), faces.end());
  faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
  for (std::uint32_t f : faces) m.set(Direction::OriginalToGrid, f, m.original_value(f));
  // The worst faces on a fine lattice against the whole reconstruction: where the largest distance lies
  // between a face's probes (a sharp feature wider than a quad), a probe is added there.
  const double hot = std::max(threshold, 0.5 * m.t1.max());
  std::vector<std::uint32_t> hot_faces;
  for (std::uint32_t f = 0; f < m.d1.size(); ++f)
    if (m.d1[f].distance >= hot) hot_faces.push_back(f);
  const std::vector<Vec3> fine = lattice(kRefineLattice);
  std::vector<std::pair<double, Vec3>> peak(hot_faces.size(), {0.0, Vec3::Zero()});
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, hot_faces.size(), 16), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t k = r.begin(); k < r.end(); ++k) {
      const Face& face = m.original.faces[hot_faces[k]];
      for (const Vec3& w : fine) {
        const Vec3 p = w[0] * m.original.positions[face[0]] + w[1] * m.original.positions[face[1]] +
                       w[2] * m.original.positions[face[2]];
        const double d = whole.closest_point(p).distance;
        if (d > peak[k].first) peak[k] = {d, w};
      }
    }
  });
  const auto vertices = static_cast<std::uint32_t>(m.original.positions.size());
  for (std::size_t k = 0; k < hot_faces.size(); ++k) {
    const std::uint32_t f = hot_faces[k];
    if (!(peak[k].first > m.d1[f].distance * (1.0 + 1e-6))) continue;
    const Face& face = m.original.faces[f];
    const Vec3& w = peak[k].second;
    const auto i = static_cast<std::uint32_t>(m.inner_face.size());
    m.inner_face.push_back(f);
    m.probe_bary.push_back(w);
    m.probe_pos.push_back(w[0] * m.original.positions[face[0]] + w[1] * m.original.positions[face[1]] +
                          w[2] * m.original.positions[face[2]]);
    m.probe_uv.push_back(w[0] * m.original_uv[face[0]] + w[1] * m.original_uv[face[1]] + w[2] * m.original_uv[face[2]]);
    m.probe_d2.push_back(0.0);
    m.probe_tri.push_back(0);
    const std::uint32_t p = vertices + i;
    m.file_probe(p);
    m.measure_probe(p, scratch);
    m.extra[f].push_back(i);
    faces.push_back(f);
    ++learned;
  }
  std::sort(faces.begin(), faces.end());
  faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
  for (std::uint32_t f : faces) m.set(Direction::OriginalToGrid, f, m.original_value(f));
  return learned;
}

void LocalHausdorff::undo(const Change& c) {
  if (c.folded) return;
  Impl& m = *impl_;
  for (std::size_t k = 0; k < c.samples.size(); ++k) {
    m.uv[c.samples[k]] = c.old_uv[k];
    m.pos[c.samples[k]] = c.old_pos[k];
  }
  for (std::size_t k = 0; k < c.quads.size(); ++k) {
    const std::uint32_t q = c.quads[k];
    m.diagonal[q] = c.old_diagonals[k];
    m.quad_cells.erase(m.quad_range[q], q);
    m.quad_range[q] = m.quad_cells.range(m.quad_box(q));
    m.quad_cells.insert(m.quad_range[q], q);
  }
  for (std::size_t k = 0; k < c.probes.size(); ++k) {
    m.probe_d2[c.probes[k]] = c.old_probe_d2[k];
    m.probe_tri[c.probes[k]] = c.old_probe_tri[k];
  }
  for (std::size_t k = 0; k < c.entries.size(); ++k) m.set(c.entries[k].first, c.entries[k].second, c.old_values[k]);
}

}  // namespace gimforge
