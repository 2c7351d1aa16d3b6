#include "kernels/sphere/octa_disk.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <tuple>
#include <unordered_map>

#include <fmt/format.h>

#include "kernels/core/edge_topology.h"
#include "kernels/core/errors.h"
#include "kernels/core/topology.h"
#include "kernels/sphere/domain_map.h"
#include "kernels/sphere/sphere_resample.h"
#include "kernels/sphere/spherical_domain.h"

namespace gimforge {
namespace {

constexpr double kOnLine = 1e-12;  // a point this close to a tile line lies on it
constexpr std::size_t kMinFaces = 1024;  // coarser meshes are subdivided first

double det3(const Vec3& a, const Vec3& b, const Vec3& c) { return a.dot(b.cross(c)); }

/// A coordinate t along a side, nudged by at most an ulp so that its mate 1 − t is exact both ways
/// (1 − t is exact for t in [½, 1]; below ½ the coordinate is taken as 1 − (1 − t)).
double foldable(double t) { return t >= 0.5 ? t : 1.0 - (1.0 - t); }

/// The square point of a point p of the plane: the tile holding p, mapped back; a point on a side has a
/// foldable coordinate along it.
Vec2 to_square(const Vec2& p, std::int64_t i, std::int64_t j) {
  const double di = static_cast<double>(i), dj = static_cast<double>(j);
  Vec2 q = (i + j) % 2 == 0 ? Vec2(p.x() - di, p.y() - dj) : Vec2(di + 1.0 - p.x(), dj + 1.0 - p.y());
  for (int c = 0; c < 2; ++c) {
    if (std::abs(q[c]) < kOnLine) q[c] = 0.0;
    if (std::abs(q[c] - 1.0) < kOnLine) q[c] = 1.0;
    q[c] = std::clamp(q[c], 0.0, 1.0);
  }
  for (int c = 0; c < 2; ++c)
    if (q[c] == 0.0 || q[c] == 1.0) q[1 - c] = foldable(q[1 - c]);
  return q;
}

/// The image of square point q in tile (i, j).
Vec2 in_tile(const Vec2& q, std::int64_t i, std::int64_t j) {
  const double di = static_cast<double>(i), dj = static_cast<double>(j);
  return (i + j) % 2 == 0 ? Vec2(q.x() + di, q.y() + dj) : Vec2(di + 1.0 - q.x(), dj + 1.0 - q.y());
}

/// The image of square point q nearest to `near` (a point of the plane).
Vec2 nearest_image(const Vec2& q, const Vec2& near) {
  const auto ti = static_cast<std::int64_t>(std::floor(near.x())), tj = static_cast<std::int64_t>(std::floor(near.y()));
  Vec2 best = q;
  double best_d = std::numeric_limits<double>::infinity();
  for (std::int64_t dj = -1; dj <= 1; ++dj)
    for (std::int64_t di = -1; di <= 1; ++di) {
      const Vec2 p = in_tile(q, ti + di, tj + dj);
      const double d = (p - near).squaredNorm();
      if (d < best_d) best_d = d, best = p;
    }
  return best;
}

/// Every point of the square that is the same domain point as q (q itself first): one inside, two on a
/// side, four at a corner, one at a side midpoint.
std::vector<Vec2> square_copies(const Vec2& q) {
  std::vector<Vec2> out{q};
  const auto add = [&](const Vec2& p) {
    for (const Vec2& o : out)
      if ((o - p).squaredNorm() < 1e-24) return;
    out.push_back(p);
  };
  const bool x0 = q.x() == 0.0 || q.x() == 1.0, y0 = q.y() == 0.0 || q.y() == 1.0;
  if (x0 && y0) {
    for (const Vec2& c : {Vec2(0, 0), Vec2(1, 0), Vec2(1, 1), Vec2(0, 1)}) add(c);
  } else if (x0) {
    add(Vec2(q.x(), 1.0 - q.y()));
  } else if (y0) {
    add(Vec2(1.0 - q.x(), q.y()));
  }
  return out;
}

std::size_t nearest_of(std::span<const Vec2> copies, const Vec2& q) {
  std::size_t best = 0;
  for (std::size_t k = 1; k < copies.size(); ++k)
    if ((copies[k] - q).squaredNorm() < (copies[best] - q).squaredNorm()) best = k;
  return best;
}

/// The working mesh: positions, sphere points and faces, with each face's input face.
struct Work {
  std::vector<Vec3> positions, sphere;
  std::vector<Face> faces;
  std::vector<std::uint32_t> origin;
  std::vector<char> node;  ///< the vertex is a seam point (pole, side midpoint)
  std::vector<Vec2> node_uv;

  std::uint32_t add_vertex(const Vec3& p, const Vec3& s) {
    positions.push_back(p);
    sphere.push_back(s);
    node.push_back(0);
    node_uv.emplace_back(0.0, 0.0);
    return static_cast<std::uint32_t>(positions.size() - 1);
  }
};

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  return (std::uint64_t{std::min(a, b)} << 32) | std::max(a, b);
}

/// Whether every face around vertex v is positively oriented on the sphere.
bool ring_positive(const Work& w, std::uint32_t v) {
  for (const Face& f : w.faces)
    if ((f[0] == v || f[1] == v || f[2] == v) && !(det3(w.sphere[f[0]], w.sphere[f[1]], w.sphere[f[2]]) > 0.0)) return false;
  return true;
}

/// Makes corner k of `face` the seam point x when x is within a fifth of that vertex's shortest edge and
/// its faces stay positively oriented with the vertex moved there on the sphere (a vertex close to a seam
/// point would otherwise sit next to it with edges that no straight layout in the square can hold).
std::uint32_t merge_into_corner(Work& w, const Face& face, const Vec3& x) {
  for (const std::uint32_t v : face) {
    double shortest = std::numeric_limits<double>::infinity();
    for (const Face& f : w.faces)
      for (std::size_t k = 0; k < 3; ++k)
        if (f[k] == v) {
          shortest = std::min(shortest, (w.sphere[f[(k + 1) % 3]] - w.sphere[v]).norm());
          shortest = std::min(shortest, (w.sphere[f[(k + 2) % 3]] - w.sphere[v]).norm());
        }
    if (!((x - w.sphere[v]).norm() < 0.2 * shortest)) continue;
    const Vec3 before = w.sphere[v];
    w.sphere[v] = x;
    if (ring_positive(w, v)) return v;
    w.sphere[v] = before;
  }
  return kInvalidIndex;
}

/// Inserts the seam point x (unit vector, square point uv) as a vertex: a vertex close to it becomes it,
/// or the edge holding it (or near it) is split in two, or the face holding it in three.
void insert_node(Work& w, const Vec3& x, const Vec2& uv) {
  std::size_t face = w.faces.size();
  Vec3 bary = Vec3::Zero();
  for (std::size_t f = 0; f < w.faces.size() && face == w.faces.size(); ++f) {
    const Vec3 &a = w.sphere[w.faces[f][0]], &b = w.sphere[w.faces[f][1]], &c = w.sphere[w.faces[f][2]];
    const Vec3 d(det3(x, b, c), det3(a, x, c), det3(a, b, x));  // all ≥ 0 with a positive sum: not the antipode
    if (d.minCoeff() >= -1e-15 * d.cwiseAbs().sum() && d.sum() > 0.0) face = f, bary = d.cwiseMax(0.0) / d.cwiseMax(0.0).sum();
  }
  if (face == w.faces.size()) throw NumericalError("flat-octahedron cut: a seam point lies in no spherical triangle");
  const Face f = w.faces[face];
  std::uint32_t v = merge_into_corner(w, f, x);
  for (std::size_t k = 0; k < 3 && v == kInvalidIndex; ++k)
    if (bary[static_cast<Eigen::Index>(k)] > 1.0 - 1e-9) v = f[k];
  if (v == kInvalidIndex) {
    const Vec3 p = bary[0] * w.positions[f[0]] + bary[1] * w.positions[f[1]] + bary[2] * w.positions[f[2]];
    v = w.add_vertex(p, x);
    // A point near an edge goes onto it (a sliver would leave the point next to the far triangle's edge),
    // unless the far triangle's halves would turn over on the sphere.
    std::size_t zero = 3;
    for (std::size_t k = 0; k < 3; ++k)
      if (bary[static_cast<Eigen::Index>(k)] < 0.05 && (zero == 3 || bary[static_cast<Eigen::Index>(k)] < bary[static_cast<Eigen::Index>(zero)]))
        zero = k;
    if (zero < 3) {
      const std::uint32_t a = f[(zero + 1) % 3], b = f[(zero + 2) % 3];
      for (const Face& h : w.faces)
        for (std::size_t k = 0; k < 3; ++k)
          if (h[k] == b && h[(k + 1) % 3] == a) {
            const Vec3& d = w.sphere[h[(k + 2) % 3]];
            if (!(det3(w.sphere[b], x, d) > 0.0) || !(det3(x, w.sphere[a], d) > 0.0)) zero = 3;
          }
    }
    if (zero < 3) {
      bary[static_cast<Eigen::Index>(zero)] = 0.0;
      bary /= bary.sum();
      w.positions.back() = bary[0] * w.positions[f[0]] + bary[1] * w.positions[f[1]] + bary[2] * w.positions[f[2]];
    }
    if (zero == 3) {
      const std::uint32_t o = w.origin[face];
      w.faces[face] = {f[0], f[1], v};
      w.faces.push_back({f[1], f[2], v});
      w.faces.push_back({f[2], f[0], v});
      w.origin.push_back(o);
      w.origin.push_back(o);
    } else {
      // On the edge opposite corner `zero`: split both faces of that edge.
      const std::uint32_t a = f[(zero + 1) % 3], b = f[(zero + 2) % 3];
      for (std::size_t g = 0, end = w.faces.size(); g < end; ++g)
        for (std::size_t k = 0; k < 3; ++k) {
          const Face h = w.faces[g];
          const bool forward = h[k] == a && h[(k + 1) % 3] == b, backward = h[k] == b && h[(k + 1) % 3] == a;
          if (!forward && !backward) continue;
          const std::uint32_t c = h[(k + 2) % 3];
          w.faces[g] = {h[k], v, c};
          w.faces.push_back({v, h[(k + 1) % 3], c});
          w.origin.push_back(w.origin[g]);
          break;
        }
    }
  }
  w.node[v] = 1;  // its sphere point: x, or (a vertex within 1e-9 of it, not merged) its own
  w.node_uv[v] = uv;
}

/// Distance from x to the segment [a, b].
double segment_distance(const Vec3& x, const Vec3& a, const Vec3& b) {
  const Vec3 e = b - a;
  const double t = std::clamp((x - a).dot(e) / std::max(e.squaredNorm(), 1e-300), 0.0, 1.0);
  return (a + t * e - x).norm();
}

/// Splits every edge longer than max_angle on the sphere, and every edge not ending at a seam point that
/// is longer than half its distance to a side midpoint (`cones`; red-green: one, two or three split edges per face), until
/// none is or after 24 passes. Near a side midpoint the domain map folds the sphere's full turn into a
/// half turn: a triangle there must be small against its distance to the point to be laid out straight.
/// One pass of conforming (red-green) refinement: every edge for which split(a, b) holds is split at its
/// midpoint (a surface point; its sphere point the normalized mean); faces with one, two or three split
/// edges become two, three or four. Returns whether anything was split.
template <class Split>
bool split_edges(Work& w, const Split& split) {
  {
    std::unordered_map<std::uint64_t, std::uint32_t> mid;
    for (const Face& f : w.faces)
      for (std::size_t k = 0; k < 3; ++k) {
        const std::uint32_t a = f[k], b = f[(k + 1) % 3];
        if (mid.contains(edge_key(a, b)) || !split(a, b)) continue;
        mid[edge_key(a, b)] = w.add_vertex(0.5 * (w.positions[a] + w.positions[b]), (w.sphere[a] + w.sphere[b]).normalized());
      }
    if (mid.empty()) return false;
    std::vector<Face> faces;
    std::vector<std::uint32_t> origin;
    const auto emit = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t o) {
      faces.push_back({a, b, c});
      origin.push_back(o);
    };
    for (std::size_t g = 0; g < w.faces.size(); ++g) {
      const Face& f = w.faces[g];
      const std::uint32_t o = w.origin[g];
      std::array<std::uint32_t, 3> m{kInvalidIndex, kInvalidIndex, kInvalidIndex};  // midpoint of edge k→k+1
      int count = 0;
      for (std::size_t k = 0; k < 3; ++k)
        if (const auto it = mid.find(edge_key(f[k], f[(k + 1) % 3])); it != mid.end()) m[k] = it->second, ++count;
      if (count == 0) {
        emit(f[0], f[1], f[2], o);
      } else if (count == 3) {
        emit(f[0], m[0], m[2], o);
        emit(m[0], f[1], m[1], o);
        emit(m[2], m[1], f[2], o);
        emit(m[0], m[1], m[2], o);
      } else {
        // Rotate so that edge 0 (f0→f1) is split; with two, edge 1 or edge 2 is the other.
        std::size_t r = 0;
        while (m[r] == kInvalidIndex || (count == 2 && m[(r + 2) % 3] != kInvalidIndex)) ++r;
        const std::uint32_t a = f[r], b = f[(r + 1) % 3], c = f[(r + 2) % 3], mab = m[r], mbc = m[(r + 1) % 3];
        if (count == 1) {
          emit(a, mab, c, o);
          emit(mab, b, c, o);
        } else {
          emit(mab, b, mbc, o);
          emit(a, mab, mbc, o);
          emit(a, mbc, c, o);
        }
      }
    }
    w.faces = std::move(faces);
    w.origin = std::move(origin);
  }
  return true;
}

void refine(Work& w, double max_angle, std::span<const Vec3> cones) {
  const double min_dot = std::cos(max_angle);
  const auto too_long = [&](std::uint32_t a, std::uint32_t b) {
    if (w.sphere[a].dot(w.sphere[b]) < min_dot) return true;
    if (w.node[a] != 0 || w.node[b] != 0) return false;
    const double length = (w.sphere[a] - w.sphere[b]).norm();
    for (const Vec3& x : cones)
      if (length > 0.5 * segment_distance(x, w.sphere[a], w.sphere[b])) return true;
    return false;
  };
  for (int pass = 0; pass < 24 && split_edges(w, too_long); ++pass) {
  }
}

/// The table of the built-in flat-octahedron map as a mesh over the square (positions (u, v, 0)) with its
/// sphere points, for the inverse S → D.
struct DomainTable {
  std::vector<Vec3> square;
  std::vector<Vec3> sphere;
  std::vector<Face> faces;
};

DomainTable domain_table() {
  const DomainSphereMap& map = builtin_domain_map(SphericalDomain::FlatOctahedron);
  const DomainImage image(SphericalDomain::FlatOctahedron, map.n);
  DomainTable t;
  const std::int32_t w = image.width(), n = image.n();
  t.square.resize(image.num_samples());
  t.sphere = map.sphere;
  for (std::int32_t j = 0; j < w; ++j)
    for (std::int32_t i = 0; i < w; ++i)
      t.square[image.linear_index({0, i, j})] = Vec3(static_cast<double>(i) / (w - 1), static_cast<double>(j) / (w - 1), 0.0);
  const auto at = [&](std::int32_t i, std::int32_t j) { return static_cast<std::uint32_t>(image.linear_index({0, i, j})); };
  for (std::int32_t j = 0; j + 1 < w; ++j)
    for (std::int32_t i = 0; i + 1 < w; ++i) {
      const std::int32_t cx = 2 * i + 1 - 2 * n, cy = 2 * j + 1 - 2 * n;
      if ((cx > 0) != (cy > 0)) {  // the diagonal parallel to the domain face edge (domain_map.cpp)
        t.faces.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
        t.faces.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
      } else {
        t.faces.push_back({at(i, j), at(i + 1, j), at(i, j + 1)});
        t.faces.push_back({at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)});
      }
    }
  return t;
}

/// A point of a laid-out polygon: its place in the plane and its barycentric coordinates in the triangle.
struct PolyPoint {
  Vec2 p;
  Vec3 bary;
};

/// Splits a convex polygon by the line coordinate[axis] = value into the parts below and above it.
std::pair<std::vector<PolyPoint>, std::vector<PolyPoint>> split(const std::vector<PolyPoint>& poly, int axis, double value) {
  std::vector<PolyPoint> lo, hi;
  const std::size_t m = poly.size();
  for (std::size_t k = 0; k < m; ++k) {
    const PolyPoint &a = poly[k], &b = poly[(k + 1) % m];
    const double da = a.p[axis] - value, db = b.p[axis] - value;
    const int sa = std::abs(da) <= kOnLine ? 0 : (da < 0 ? -1 : 1), sb = std::abs(db) <= kOnLine ? 0 : (db < 0 ? -1 : 1);
    if (sa <= 0) lo.push_back(a);
    if (sa >= 0) hi.push_back(a);
    if (sa * sb < 0) {
      const double t = da / (da - db);
      PolyPoint c{a.p + t * (b.p - a.p), a.bary + t * (b.bary - a.bary)};
      c.p[axis] = value;
      lo.push_back(c);
      hi.push_back(c);
    }
  }
  return {lo, hi};
}

/// Twice the signed area of disk face f in the square.
double twice_area(const OctaDisk& d, const Face& f) {
  const Vec2 e1 = d.uv[f[1]] - d.uv[f[0]], e2 = d.uv[f[2]] - d.uv[f[0]];
  return e1.x() * e2.y() - e1.y() * e2.x();
}

void count_flipped(OctaDisk& d) {
  d.flipped = 0;
  d.flipped_area = 0.0;
  for (const Face& f : d.disk.faces)
    if (const double twice = twice_area(d, f); twice < 0.0) ++d.flipped, d.flipped_area -= 0.5 * twice;
}

/// Straightens faces turned over in the square (slivers near a side midpoint, where the straight layout
/// misses the domain map's half-turn fold), one vertex at a time: a vertex of a turned face (not on the
/// square's sides) moves towards the mean of its neighbours when that leaves fewer of its faces turned and
/// turns none that was not (only its own faces change). The count never rises; surface points do not move, only the parametrization
/// near the fold.
void untangle(OctaDisk& d) {
  count_flipped(d);
  if (d.flipped == 0) return;
  const std::size_t n = d.uv.size();
  std::vector<std::vector<std::uint32_t>> around(n), ring(n);  // faces and neighbours of every vertex
  for (std::size_t f = 0; f < d.disk.faces.size(); ++f)
    for (std::size_t k = 0; k < 3; ++k) {
      const Face& g = d.disk.faces[f];
      around[g[k]].push_back(static_cast<std::uint32_t>(f));
      ring[g[k]].push_back(g[(k + 1) % 3]);
      ring[g[k]].push_back(g[(k + 2) % 3]);
    }
  const auto turned = [&](std::uint32_t v) {
    std::size_t count = 0;
    for (const std::uint32_t f : around[v])
      if (twice_area(d, d.disk.faces[f]) <= 0.0) ++count;
    return count;
  };
  for (int pass = 0; pass < 20; ++pass) {
    bool moved = false;
    for (const Face& f : d.disk.faces) {
      if (twice_area(d, f) > 0.0) continue;
      for (const std::uint32_t v : f) {
        const Vec2 q = d.uv[v];
        if (q.x() == 0.0 || q.x() == 1.0 || q.y() == 0.0 || q.y() == 1.0) continue;
        Vec2 mean = Vec2::Zero();
        for (const std::uint32_t u : ring[v]) mean += d.uv[u];
        mean /= static_cast<double>(ring[v].size());
        const std::size_t before = turned(v);
        std::vector<char> positive;
        for (const std::uint32_t g : around[v]) positive.push_back(twice_area(d, d.disk.faces[g]) > 0.0 ? 1 : 0);
        const auto keeps_positive = [&] {
          for (std::size_t k = 0; k < around[v].size(); ++k)
            if (positive[k] != 0 && !(twice_area(d, d.disk.faces[around[v][k]]) > 0.0)) return false;
          return true;
        };
        for (const double t : {1.0, 0.5, 0.25}) {
          d.uv[v] = q + t * (mean - q);
          if (turned(v) < before && keeps_positive()) {
            moved = true;
            break;
          }
          d.uv[v] = q;
        }
      }
    }
    if (!moved) break;
  }
  count_flipped(d);
}

/// The perimeter coordinate (0..4: bottom, right, top, left, counter-clockwise from (0, 0)) of a point on
/// the square's sides.
double perimeter_coordinate(const Vec2& q) {
  if (q.y() == 0.0 && q.x() < 1.0) return q.x();
  if (q.x() == 1.0 && q.y() < 1.0) return 1.0 + q.y();
  if (q.y() == 1.0 && q.x() > 0.0) return 2.0 + (1.0 - q.x());
  return 3.0 + (1.0 - q.y());
}

/// Throws NumericalError unless the cut is a disk covering the square once, whose boundary runs once round
/// the square along its sides, and whose every boundary point's mate (mirrored about its side's midpoint)
/// is a boundary point holding the same surface point (what every user of it relies on). Faces turned over
/// inside are counted, not refused (OctaDisk::flipped); so are steps back along a side (a turned sliver
/// with two corners there) up to a hundredth of a side in all (cow: 4.5e-4 each way).
void check_disk(const OctaDisk& d) {
  const TopologyReport t = analyze_topology(d.disk);
  double area = 0.0;
  for (const Face& f : d.disk.faces) area += 0.5 * twice_area(d, f);
  std::string problem;
  if (t.euler_characteristic != 1 || t.boundary_loops != 1 || t.nonmanifold_edges != 0 || t.nonmanifold_vertices != 0)
    problem = fmt::format("not a disk (Euler characteristic {}, {} boundary loops, {} non-manifold edges, {} "
                          "non-manifold vertices)",
                          t.euler_characteristic, t.boundary_loops, t.nonmanifold_edges, t.nonmanifold_vertices);
  else if (!(std::abs(area - 1.0) < 1e-9))
    problem = fmt::format("it covers {} of the square", area);
  if (problem.empty()) {
    // The boundary edges, directed as their faces run (counter-clockwise: forward round the square).
    const EdgeTopology topo = build_edge_topology(d.disk);
    std::map<std::pair<double, double>, Vec3> at;  // boundary point → surface point
    double turn = 0.0, backwards = 0.0;
    for (std::size_t e = 0; e < topo.num_edges() && problem.empty(); ++e) {
      if (topo.valence(e) != 1) continue;
      const std::size_t h = topo.edge_halfedges[topo.edge_offsets[e]];
      const std::uint32_t a = halfedge_tail(d.disk, h), b = halfedge_head(d.disk, h);
      const Vec2 &p = d.uv[a], &q = d.uv[b];
      const auto on_side = [](const Vec2& r) { return r.x() == 0.0 || r.x() == 1.0 || r.y() == 0.0 || r.y() == 1.0; };
      if (!on_side(p) || !on_side(q)) {
        problem = fmt::format("boundary vertex at ({}, {}) is off the square's sides", on_side(p) ? q.x() : p.x(),
                              on_side(p) ? q.y() : p.y());
        break;
      }
      // Along one side, forward: a step back is a fold of the layout at the seam (a turned sliver with two
      // corners on the side, as inside: counted, up to a hundredth of a side in all).
      double step = perimeter_coordinate(q) - perimeter_coordinate(p);
      if (step <= -2.0) step += 4.0;
      if (step >= 2.0) step -= 4.0;
      const bool same_side = (p.x() == q.x() && (p.x() == 0.0 || p.x() == 1.0)) || (p.y() == q.y() && (p.y() == 0.0 || p.y() == 1.0));
      if (!same_side) problem = fmt::format("its boundary leaves the square's side at ({}, {})", p.x(), p.y());
      if (step <= 0.0) backwards -= step;
      turn += step;
      at[{p.x(), p.y()}] = d.disk.positions[a];
    }
    if (problem.empty() && !(std::abs(turn - 4.0) < 1e-9)) problem = fmt::format("its boundary runs {} times round the square", turn / 4.0);
    if (problem.empty() && backwards > 0.01)
      problem = fmt::format("its boundary folds back along the sides by {} of a side in all", backwards);
    for (auto it = at.begin(); problem.empty() && it != at.end(); ++it)
      for (const Vec2& mate : square_copies(Vec2(it->first.first, it->first.second))) {
        const auto m = at.find({mate.x(), mate.y()});
        if (m == at.end() || m->second != it->second)
          problem = fmt::format("the boundary point ({}, {}) has no mate holding its surface point", it->first.first,
                                it->first.second);
      }
  }
  if (!problem.empty())
    throw NumericalError(fmt::format("flat-octahedron cut of the spherical parametrization failed: {} (use uniform "
                                     "sampling)",
                                     problem));
}

}  // namespace

OctaDisk cut_flat_octahedron(const EmbreeDevice& device, MeshView mesh, std::span<const Vec3> sphere, double max_angle) {
  if (sphere.size() != mesh.positions.size())
    throw InvalidInput(fmt::format("flat-octahedron cut: {} sphere points for {} vertices", sphere.size(), mesh.positions.size()));
  if (!(max_angle > 0.0) || max_angle > 1.0) throw InvalidInput(fmt::format("flat-octahedron cut: max_angle {} is outside (0, 1]", max_angle));
  Work w;
  w.positions.assign(mesh.positions.begin(), mesh.positions.end());
  w.sphere.assign(sphere.begin(), sphere.end());
  w.faces.assign(mesh.faces.begin(), mesh.faces.end());
  w.node.assign(w.positions.size(), 0);
  w.node_uv.assign(w.positions.size(), Vec2::Zero());
  w.origin.resize(w.faces.size());
  for (std::size_t f = 0; f < w.origin.size(); ++f) w.origin[f] = static_cast<std::uint32_t>(f);

  // The seam points: the lower pole (the corners) and the four equator vertices (the side midpoints).
  const DomainTable table = domain_table();
  const DomainSphereMap& map = builtin_domain_map(SphericalDomain::FlatOctahedron);
  const DomainImage image(SphericalDomain::FlatOctahedron, map.n);
  const std::int32_t n = image.n(), last = image.width() - 1;
  const std::array<std::array<std::int32_t, 2>, 5> seam{{{0, 0}, {n, 0}, {last, n}, {n, last}, {0, n}}};
  // A coarse mesh is subdivided first (every face in four, new vertices at edge midpoints: the surface
  // and its map stay as they are): around a side midpoint the red-green splits of a few large faces leave
  // slivers whose straight layout turns over, even across a side (a review found it on 20- to 320-face
  // spheres under random rotations).
  while (w.faces.size() < kMinFaces) (void)split_edges(w, [](std::uint32_t, std::uint32_t) { return true; });
  std::vector<Vec3> nodes;
  for (const auto& [i, j] : seam) {
    nodes.push_back(map.sphere[image.linear_index({0, i, j})]);
    insert_node(w, nodes.back(), Vec2(static_cast<double>(i) / last, static_cast<double>(j) / last));
  }
  refine(w, max_angle, std::span<const Vec3>(nodes).subspan(1));  // the pole is no cone: four quarter turns

  // Every vertex's square point through the inverse of the domain map.
  const SphericalLocator locator(device, MeshView(table.square, table.faces), table.sphere);
  std::vector<Vec2> uv;
  const auto place_new_vertices = [&] {
  for (std::size_t v = uv.size(); v < w.positions.size(); ++v) {
    uv.emplace_back(0.0, 0.0);
    if (w.node[v] != 0) {
      uv[v] = w.node_uv[v];
      continue;
    }
    // Points within 1e-9 of a side lie on it (the seam): laid out around a vertex, the others' images
    // then stay clear of the tile lines by far more than rounding or exactly on them.
    const Vec3 q = locator.position(w.sphere[v]);
    uv[v] = to_square(Vec2(q.x(), q.y()), 0, 0);
    for (int c = 0; c < 2; ++c) {
      if (uv[v][c] < 1e-9) uv[v][c] = 0.0;
      if (uv[v][c] > 1.0 - 1e-9) uv[v][c] = 1.0;
    }
    uv[v] = to_square(uv[v], 0, 0);
  }
  };
  place_new_vertices();
  // A triangle laid out around a vertex (not a seam point) with the nearest images of the others.
  const auto lay_out = [&](const Face& f) {
    std::size_t pivot = 0;
    while (pivot < 3 && w.node[f[pivot]] != 0) ++pivot;
    if (pivot == 3) throw NumericalError("flat-octahedron cut: a triangle joins three seam points (the mesh is too coarse)");
    std::array<Vec2, 3> p;
    p[pivot] = uv[f[pivot]];
    for (std::size_t k = 0; k < 3; ++k)
      if (k != pivot) p[k] = nearest_image(uv[f[k]], p[pivot]);
    return p;
  };
  OctaDisk out;
  std::map<std::tuple<std::uint64_t, std::uint32_t, std::uint32_t>, std::uint32_t> index;  // (key, crossing, copy)
  const auto disk_vertex = [&](std::uint64_t key, std::uint32_t crossing, std::uint32_t copy, const Vec3& p, const Vec2& q) {
    const auto [it, fresh] = index.try_emplace({key, crossing, copy}, static_cast<std::uint32_t>(out.uv.size()));
    if (fresh) {
      out.disk.positions.push_back(p);
      out.uv.push_back(q);
    }
    return it->second;
  };
  // Edge crossings with the tile lines, computed once per edge in its own direction (lower index first):
  // the parameter t along the edge and the two square points of each.
  struct Crossing {
    double t;
    std::array<Vec2, 2> copies;
  };
  std::unordered_map<std::uint64_t, std::vector<Crossing>> crossings;
  const auto edge_crossings = [&](std::uint32_t a, std::uint32_t b) -> const std::vector<Crossing>& {
    const std::uint64_t key = edge_key(a, b);
    if (const auto it = crossings.find(key); it != crossings.end()) return it->second;
    std::vector<Crossing>& list = crossings[key];
    const std::uint32_t lo = std::min(a, b), hi = std::max(a, b);
    if (w.node[lo] != 0 || w.node[hi] != 0) return list;  // an edge from a seam point stays on one side
    const Vec2 pa = uv[lo], pb = nearest_image(uv[hi], pa);
    for (int axis = 0; axis < 2; ++axis) {
      const double from = std::min(pa[axis], pb[axis]), to = std::max(pa[axis], pb[axis]);
      for (double line = std::floor(from) + 1.0; line < to; line += 1.0) {
        if (line - from <= kOnLine || to - line <= kOnLine) continue;
        const double t = (line - pa[axis]) / (pb[axis] - pa[axis]);
        Vec2 c = pa + t * (pb - pa);
        c[axis] = line;
        Vec2 below = c, above = c;
        below[axis] -= 0.5;
        above[axis] += 0.5;
        const auto tile = [](const Vec2& p) {
          return std::pair{static_cast<std::int64_t>(std::floor(p.x())), static_cast<std::int64_t>(std::floor(p.y()))};
        };
        const auto [bi, bj] = tile(below);
        const auto [ai, aj] = tile(above);
        list.push_back({t, {to_square(c, bi, bj), to_square(c, ai, aj)}});
      }
    }
    std::sort(list.begin(), list.end(), [](const Crossing& x, const Crossing& y) { return x.t < y.t; });
    return list;
  };

  std::vector<std::vector<Vec2>> copies(w.positions.size());
  for (std::size_t v = 0; v < copies.size(); ++v) copies[v] = square_copies(uv[v]);
  std::size_t mismatched = 0;
  for (std::size_t g = 0; g < w.faces.size(); ++g) {
    const Face& f = w.faces[g];
    const std::array<Vec2, 3> p = lay_out(f);
    std::vector<PolyPoint> poly{{p[0], Vec3(1, 0, 0)}, {p[1], Vec3(0, 1, 0)}, {p[2], Vec3(0, 0, 1)}};
    // Clip by every tile line crossing the triangle's box.
    std::vector<std::vector<PolyPoint>> pieces{poly};
    for (int axis = 0; axis < 2; ++axis) {
      const double from = std::min({p[0][axis], p[1][axis], p[2][axis]}), to = std::max({p[0][axis], p[1][axis], p[2][axis]});
      for (double line = std::floor(from) + 1.0; line < to; line += 1.0) {
        std::vector<std::vector<PolyPoint>> next;
        for (const auto& piece : pieces) {
          auto [lo, hi] = split(piece, axis, line);
          if (lo.size() >= 3) next.push_back(std::move(lo));
          if (hi.size() >= 3) next.push_back(std::move(hi));
        }
        pieces = std::move(next);
      }
    }
    for (const auto& piece : pieces) {
      Vec2 centre = Vec2::Zero();
      for (const PolyPoint& q : piece) centre += q.p;
      centre /= static_cast<double>(piece.size());
      const auto ti = static_cast<std::int64_t>(std::floor(centre.x())), tj = static_cast<std::int64_t>(std::floor(centre.y()));
      std::vector<std::uint32_t> ids;
      for (const PolyPoint& q : piece) {
        const Vec2 s = to_square(q.p, ti, tj);
        const Vec3 pos = q.bary[0] * w.positions[f[0]] + q.bary[1] * w.positions[f[1]] + q.bary[2] * w.positions[f[2]];
        std::size_t corner = 3;
        for (std::size_t k = 0; k < 3; ++k)
          if (q.bary[static_cast<Eigen::Index>(k)] > 1.0 - 1e-12) corner = k;
        if (corner < 3) {
          const std::uint32_t v = f[corner];
          const auto c = static_cast<std::uint32_t>(nearest_of(copies[v], s));
          ids.push_back(disk_vertex(v, kInvalidIndex, c, w.positions[v], copies[v][c]));
          continue;
        }
        // On the edge between the two corners with weight: find its crossing.
        std::size_t zero = 0;
        for (std::size_t k = 1; k < 3; ++k)
          if (q.bary[static_cast<Eigen::Index>(k)] < q.bary[static_cast<Eigen::Index>(zero)]) zero = k;
        const std::uint32_t a = f[(zero + 1) % 3], b = f[(zero + 2) % 3];
        const double along_ab = q.bary[static_cast<Eigen::Index>((zero + 2) % 3)];
        const double t = a < b ? along_ab : 1.0 - along_ab;
        const std::vector<Crossing>& list = edge_crossings(a, b);
        std::size_t best = list.size();
        for (std::size_t k = 0; k < list.size(); ++k)
          if (best == list.size() || std::abs(list[k].t - t) < std::abs(list[best].t - t)) best = k;
        if (best == list.size() || std::abs(list[best].t - t) > 1e-6) {
          ++mismatched;
          ids.push_back(disk_vertex(edge_key(a, b), static_cast<std::uint32_t>(1000000 + mismatched), 0, pos, s));
          continue;
        }
        const auto c = static_cast<std::uint32_t>(nearest_of(list[best].copies, s));
        const std::uint32_t lo = std::min(a, b), hi = std::max(a, b);
        const Vec3 at = w.positions[lo] + list[best].t * (w.positions[hi] - w.positions[lo]);
        ids.push_back(disk_vertex(edge_key(a, b), static_cast<std::uint32_t>(best), c, at, list[best].copies[c]));
      }
      // Fan: the piece is convex; skip repeated points (a corner on a tile line appears once per side).
      ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
      while (ids.size() > 1 && ids.front() == ids.back()) ids.pop_back();
      for (std::size_t k = 1; k + 1 < ids.size(); ++k) {
        out.disk.faces.push_back({ids[0], ids[k], ids[k + 1]});
        out.face_origin.push_back(w.origin[g]);
      }
    }
  }
  if (mismatched > 0)
    throw NumericalError(fmt::format("flat-octahedron cut: {} edge crossings differ between the two faces of an edge", mismatched));
  untangle(out);
  check_disk(out);
  return out;
}

PerimeterGlue flat_octahedron_glue(std::function<Vec3(const Vec2&)> surface_point) {
  PerimeterGlue glue;
  const auto mate = [](double c) {
    const double side = std::floor(c);
    return 2.0 * side + 1.0 - c;
  };
  glue.mate = [mate](double c) { return c >= 4.0 ? mate(c - 4.0) : mate(c); };
  glue.node = [](double c) {
    const double frac = c - std::floor(c);
    return frac < 1e-12 || frac > 1.0 - 1e-12 || std::abs(frac - 0.5) < 1e-12;
  };
  glue.position = [mate, surface_point = std::move(surface_point)](double c) {
    const double wrapped = c - 4.0 * std::floor(c / 4.0);
    const Vec2 p = square_perimeter_point(wrapped), q = square_perimeter_point(mate(wrapped));
    // The mate nearer the square's origin (smaller x, then y): the sample the image's sampler evaluates.
    return surface_point(std::tie(p.x(), p.y()) <= std::tie(q.x(), q.y()) ? p : q);
  };
  return glue;
}

}  // namespace gimforge
