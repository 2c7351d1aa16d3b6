#include "kernels/mcgim/chart_raster.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Geometry>

#include "kernels/core/errors.h"

namespace gimforge {
namespace {

/// The 8 neighbours in counter-clockwise order from east: E, NE, N, NW, W, SW, S, SE.
constexpr std::array<std::array<int, 2>, 8> kRing{{{1, 0}, {1, 1}, {0, 1}, {-1, 1}, {-1, 0}, {-1, -1}, {0, -1}, {1, -1}}};

/// A lattice of cells with a margin, in which a chart is rasterized before it is cropped.
struct Canvas {
  std::int64_t x0{0}, y0{0};  // lattice coordinates of cell (0, 0)
  std::uint32_t width{0}, height{0};
  std::vector<std::uint8_t> mask;
  std::vector<Vec3> positions;
  std::vector<double> boundary_distance;  // of cells defined by boundary rasterization

  [[nodiscard]] std::size_t index(std::int64_t x, std::int64_t y) const {
    return static_cast<std::size_t>(y - y0) * width + static_cast<std::size_t>(x - x0);
  }
};

/// Link of cell (x, y) as bitmasks of neighbour pairs; returns true when non-empty and connected.
bool link_connected(const std::array<bool, 8>& n) {
  // Link edges between neighbour slots; each quad k spans slots 2k (side), 2k+1 (diagonal), 2k+2 (side).
  std::array<int, 8> parent{0, 1, 2, 3, 4, 5, 6, 7};
  const auto find = [&](int a) {
    while (parent[static_cast<std::size_t>(a)] != a) a = parent[static_cast<std::size_t>(a)];
    return a;
  };
  std::array<bool, 8> used{};
  int edges = 0;
  const auto join = [&](int a, int b) {
    used[static_cast<std::size_t>(a)] = used[static_cast<std::size_t>(b)] = true;
    parent[static_cast<std::size_t>(find(a))] = find(b);
    ++edges;
  };
  for (int k = 0; k < 4; ++k) {
    const int s1 = 2 * k, d = 2 * k + 1, s2 = (2 * k + 2) % 8;
    const bool a = n[static_cast<std::size_t>(s1)], b = n[static_cast<std::size_t>(d)], c = n[static_cast<std::size_t>(s2)];
    if (a && c) join(s1, s2);      // 4 defined (either diagonal) or the diagonal sample missing
    else if (a && b) join(s1, d);  // side 2 missing: triangle (p, side 1, diagonal)
    else if (b && c) join(d, s2);  // side 1 missing: triangle (p, diagonal, side 2)
  }
  if (edges == 0) return false;
  int root = -1;
  for (int i = 0; i < 8; ++i) {
    if (!used[static_cast<std::size_t>(i)]) continue;
    if (root < 0) root = find(i);
    else if (find(i) != root) return false;
  }
  return true;
}

std::array<bool, 8> neighbours(std::span<const std::uint8_t> mask, std::uint32_t width, std::uint32_t height,
                               std::int64_t x, std::int64_t y) {
  std::array<bool, 8> n{};
  for (std::size_t i = 0; i < 8; ++i) {
    const std::int64_t nx = x + kRing[i][0], ny = y + kRing[i][1];
    n[i] = nx >= 0 && ny >= 0 && nx < width && ny < height && mask[static_cast<std::size_t>(ny) * width + static_cast<std::size_t>(nx)] != 0;
  }
  return n;
}

double cross2(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

/// Interior rasterization of every face.
void rasterize_faces(const ChartMesh& chart, const std::vector<Vec2>& q, Canvas& canvas, std::size_t& count) {
  for (const Face& f : chart.mesh.faces) {
    const Vec2 &a = q[f[0]], &b = q[f[1]], &c = q[f[2]];
    const double area = cross2(b - a, c - a);
    if (!(std::abs(area) > 0.0)) continue;
    const double eps = 1e-9 * std::abs(area);
    const auto xlo = static_cast<std::int64_t>(std::ceil(std::min({a.x(), b.x(), c.x()})));
    const auto xhi = static_cast<std::int64_t>(std::floor(std::max({a.x(), b.x(), c.x()})));
    const auto ylo = static_cast<std::int64_t>(std::ceil(std::min({a.y(), b.y(), c.y()})));
    const auto yhi = static_cast<std::int64_t>(std::floor(std::max({a.y(), b.y(), c.y()})));
    for (std::int64_t y = ylo; y <= yhi; ++y)
      for (std::int64_t x = xlo; x <= xhi; ++x) {
        const Vec2 p(static_cast<double>(x), static_cast<double>(y));
        double wa = cross2(b - p, c - p), wb = cross2(c - p, a - p), wc = cross2(a - p, b - p);
        if (area < 0.0) wa = -wa, wb = -wb, wc = -wc;
        if (wa < -eps || wb < -eps || wc < -eps) continue;
        const std::size_t i = canvas.index(x, y);
        if (canvas.mask[i]) continue;
        const double s = wa + wb + wc;
        canvas.mask[i] = 1;
        canvas.positions[i] = (wa * chart.mesh.positions[f[0]] + wb * chart.mesh.positions[f[1]] +
                               wc * chart.mesh.positions[f[2]]) / s;
        ++count;
      }
  }
}

/// True when segment a → a + e meets the cell square [−½, ½]² around p (Liang–Barsky clipping).
bool segment_meets_cell(const Vec2& a, const Vec2& e, const Vec2& p) {
  double t0 = 0.0, t1 = 1.0;
  const Vec2 d = a - p;
  for (int axis = 0; axis < 2; ++axis) {
    const double o = d[axis], v = e[axis];
    if (v == 0.0) {
      if (o < -0.5 || o > 0.5) return false;
      continue;
    }
    double ta = (-0.5 - o) / v, tb = (0.5 - o) / v;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

/// Boundary rasterization: the 1-sample-wide band along every boundary edge, taken as the cells whose square
/// the edge crosses (its supercover). That band is 4-connected, so the §3 triangulation keeps a thin part
/// of the chart in one piece: a band of cells only diagonally adjacent (what the lattice points within ½ of
/// the edge give on a slanted edge) forms no triangle between them.
void rasterize_boundary(const ChartMesh& chart, const std::vector<Vec2>& q, Canvas& canvas, std::size_t& count) {
  std::vector<std::uint8_t> interior = canvas.mask;
  const std::size_t m = chart.boundary.size();
  for (std::size_t i = 0; i < m; ++i) {
    const std::uint32_t u = chart.boundary[i], v = chart.boundary[(i + 1) % m];
    const Vec2 a = q[u], e = q[v] - q[u];
    const double len2 = e.squaredNorm();
    const auto xlo = static_cast<std::int64_t>(std::ceil(std::min(a.x(), a.x() + e.x()) - 0.5));
    const auto xhi = static_cast<std::int64_t>(std::floor(std::max(a.x(), a.x() + e.x()) + 0.5));
    const auto ylo = static_cast<std::int64_t>(std::ceil(std::min(a.y(), a.y() + e.y()) - 0.5));
    const auto yhi = static_cast<std::int64_t>(std::floor(std::max(a.y(), a.y() + e.y()) + 0.5));
    for (std::int64_t y = ylo; y <= yhi; ++y)
      for (std::int64_t x = xlo; x <= xhi; ++x) {
        const std::size_t c = canvas.index(x, y);
        if (interior[c]) continue;
        const Vec2 cell(static_cast<double>(x), static_cast<double>(y));
        if (!segment_meets_cell(a, e, cell)) continue;
        const Vec2 p = cell - a;
        const double t = len2 > 0.0 ? std::clamp(p.dot(e) / len2, 0.0, 1.0) : 0.0;
        const double d = (p - t * e).norm();
        if (d >= canvas.boundary_distance[c]) continue;
        if (!canvas.mask[c]) ++count;
        canvas.mask[c] = 1;
        canvas.boundary_distance[c] = d;
        canvas.positions[c] = (1.0 - t) * chart.mesh.positions[u] + t * chart.mesh.positions[v];
      }
  }
}

/// Defines a minimal set of undefined neighbours of a non-manifold cell (singles, then pairs, then all).
std::size_t repair_cell(Canvas& canvas, std::int64_t x, std::int64_t y) {
  const std::array<bool, 8> n = neighbours(canvas.mask, canvas.width, canvas.height, x - canvas.x0, y - canvas.y0);
  std::vector<std::size_t> free;
  for (std::size_t i = 0; i < 8; ++i)
    if (!n[i]) free.push_back(i);
  std::vector<std::size_t> chosen;
  for (std::size_t i : free) {
    std::array<bool, 8> t = n;
    t[i] = true;
    if (link_connected(t)) { chosen = {i}; break; }
  }
  for (std::size_t a = 0; chosen.empty() && a < free.size(); ++a)
    for (std::size_t b = a + 1; b < free.size(); ++b) {
      std::array<bool, 8> t = n;
      t[free[a]] = t[free[b]] = true;
      if (link_connected(t)) { chosen = {free[a], free[b]}; break; }
    }
  if (chosen.empty()) chosen = free;
  const Vec3 p = canvas.positions[canvas.index(x, y)];
  for (std::size_t i : chosen) {
    const std::size_t c = canvas.index(x + kRing[i][0], y + kRing[i][1]);
    canvas.mask[c] = 1;
    canvas.positions[c] = p;
  }
  return chosen.size();
}

/// Joins 4-adjacent defined cells that no triangle of the §3 rules joins (a straight one-cell-wide band
/// forms no triangle at all): the cell beside the pair becomes defined at the first cell's position.
/// Returns the number of cells added.
std::size_t connect_pairs(Canvas& canvas) {
  const std::uint32_t w = canvas.width, h = canvas.height;
  const auto on = [&](std::uint32_t x, std::uint32_t y) { return canvas.mask[std::size_t{y} * w + x] != 0; };
  std::size_t added = 0;
  for (std::uint32_t y = 1; y + 2 < h; ++y)
    for (std::uint32_t x = 1; x + 2 < w; ++x) {
      if (!on(x, y)) continue;
      const Vec3 p = canvas.positions[std::size_t{y} * w + x];
      const auto define = [&](std::uint32_t cx, std::uint32_t cy) {
        canvas.mask[std::size_t{cy} * w + cx] = 1;
        canvas.positions[std::size_t{cy} * w + cx] = p;
        ++added;
      };
      // East pair: a triangle above needs (x, y+1) or (x+1, y+1); below (x, y−1) or (x+1, y−1).
      if (on(x + 1, y) && !on(x, y + 1) && !on(x + 1, y + 1) && !on(x, y - 1) && !on(x + 1, y - 1))
        define(x, y + 1);
      // North pair: right needs (x+1, y) or (x+1, y+1); left (x−1, y) or (x−1, y+1).
      if (on(x, y + 1) && !on(x + 1, y) && !on(x + 1, y + 1) && !on(x - 1, y) && !on(x - 1, y + 1))
        define(x + 1, y);
    }
  return added;
}

/// Fills holes: undefined cells that no 8-connected path of undefined cells links to the canvas border
/// enclose a region the §3 triangulation leaves uncovered inside the chart (a disk must have none). They
/// become defined, from the outside of the hole inwards, at the mean of their defined neighbours. Returns
/// the number of cells filled.
std::size_t fill_holes(Canvas& canvas) {
  const std::uint32_t w = canvas.width, h = canvas.height;
  std::vector<std::uint8_t> open(canvas.mask.size(), 0);
  std::vector<std::size_t> stack;
  for (std::uint32_t y = 0; y < h; ++y)
    for (std::uint32_t x = 0; x < w; ++x)
      if ((x == 0 || y == 0 || x + 1 == w || y + 1 == h) && !canvas.mask[std::size_t{y} * w + x]) {
        open[std::size_t{y} * w + x] = 1;
        stack.push_back(std::size_t{y} * w + x);
      }
  while (!stack.empty()) {
    const std::size_t c = stack.back();
    stack.pop_back();
    const auto x = static_cast<std::int64_t>(c % w), y = static_cast<std::int64_t>(c / w);
    for (const auto& d : kRing) {
      const std::int64_t nx = x + d[0], ny = y + d[1];
      if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
      const std::size_t n = static_cast<std::size_t>(ny) * w + static_cast<std::size_t>(nx);
      if (canvas.mask[n] || open[n]) continue;
      open[n] = 1;
      stack.push_back(n);
    }
  }
  std::size_t filled = 0;
  for (bool progress = true; progress;) {
    progress = false;
    for (std::uint32_t y = 1; y + 1 < h; ++y)
      for (std::uint32_t x = 1; x + 1 < w; ++x) {
        const std::size_t c = std::size_t{y} * w + x;
        if (canvas.mask[c] || open[c]) continue;
        Vec3 sum = Vec3::Zero();
        int count = 0;
        for (const auto& d : kRing) {
          const std::size_t n = static_cast<std::size_t>(std::int64_t{y} + d[1]) * w +
                                static_cast<std::size_t>(std::int64_t{x} + d[0]);
          if (canvas.mask[n] == 1) sum += canvas.positions[n], ++count;
        }
        if (count == 0) continue;
        canvas.positions[c] = sum / static_cast<double>(count);
        canvas.mask[c] = 2;  // defined in this pass: not a neighbour of the same pass
        ++filled;
        progress = true;
      }
    for (std::uint8_t& m : canvas.mask) m = m != 0 ? 1 : 0;
  }
  return filled;
}

}  // namespace

bool sample_is_manifold(std::span<const std::uint8_t> mask, std::uint32_t width, std::uint32_t height, std::int64_t x,
                        std::int64_t y) {
  return link_connected(neighbours(mask, width, height, x, y));
}

ChartRaster rasterize_chart(const ChartMesh& chart, std::span<const Vec2> uv, double angle, double scale) {
  if (uv.size() != chart.mesh.num_vertices()) throw InvalidInput("rasterize_chart: one uv per chart vertex expected");
  if (!(scale > 0.0) || !std::isfinite(scale) || !std::isfinite(angle)) throw InvalidInput("rasterize_chart: bad scale or angle");
  Vec2 centroid = Vec2::Zero();
  for (const Vec2& p : uv) centroid += p;
  centroid /= static_cast<double>(uv.size());
  const Eigen::Rotation2Dd rotation(angle);
  std::vector<Vec2> q(uv.size());
  Eigen::AlignedBox2d box;
  for (std::size_t i = 0; i < uv.size(); ++i) {
    q[i] = scale * (rotation * (uv[i] - centroid));
    box.extend(q[i]);
  }
  // A margin of 3 cells holds the boundary rectangles (0.5) and a few dilation steps beyond them.
  constexpr std::int64_t kMargin = 4;
  Canvas canvas;
  canvas.x0 = static_cast<std::int64_t>(std::floor(box.min().x())) - kMargin;
  canvas.y0 = static_cast<std::int64_t>(std::floor(box.min().y())) - kMargin;
  const auto x1 = static_cast<std::int64_t>(std::ceil(box.max().x())) + kMargin;
  const auto y1 = static_cast<std::int64_t>(std::ceil(box.max().y())) + kMargin;
  if (x1 - canvas.x0 > (1 << 20) || y1 - canvas.y0 > (1 << 20)) throw InvalidInput("rasterize_chart: chart too large for the lattice");
  canvas.width = static_cast<std::uint32_t>(x1 - canvas.x0 + 1);
  canvas.height = static_cast<std::uint32_t>(y1 - canvas.y0 + 1);
  const std::size_t cells = std::size_t{canvas.width} * canvas.height;
  canvas.mask.assign(cells, 0);
  canvas.positions.assign(cells, Vec3::Zero());
  canvas.boundary_distance.assign(cells, std::numeric_limits<double>::infinity());

  ChartRaster out;
  rasterize_faces(chart, q, canvas, out.interior);
  rasterize_boundary(chart, q, canvas, out.boundary);
  // Non-manifold dilation until every sample is manifold, and no hole (bounded: a cell inside the margin).
  out.manifold = false;
  for (int pass = 0; pass < 16; ++pass) {
    const std::size_t filled = connect_pairs(canvas) + fill_holes(canvas);
    out.dilated += filled;
    bool changed = filled > 0;
    for (std::uint32_t y = 1; y + 1 < canvas.height; ++y)
      for (std::uint32_t x = 1; x + 1 < canvas.width; ++x) {
        if (!canvas.mask[std::size_t{y} * canvas.width + x]) continue;
        if (sample_is_manifold(canvas.mask, canvas.width, canvas.height, x, y)) continue;
        out.dilated += repair_cell(canvas, canvas.x0 + x, canvas.y0 + y);
        changed = true;
      }
    if (!changed) {
      out.manifold = true;
      break;
    }
  }
  // Crop to the defined cells.
  std::uint32_t xmin = canvas.width, xmax = 0, ymin = canvas.height, ymax = 0;
  for (std::uint32_t y = 0; y < canvas.height; ++y)
    for (std::uint32_t x = 0; x < canvas.width; ++x)
      if (canvas.mask[std::size_t{y} * canvas.width + x]) {
        xmin = std::min(xmin, x), xmax = std::max(xmax, x), ymin = std::min(ymin, y), ymax = std::max(ymax, y);
      }
  if (xmin > xmax) return out;  // no sample
  out.vertex_cells.resize(q.size());
  for (std::size_t i = 0; i < q.size(); ++i)
    out.vertex_cells[i] = q[i] - Vec2(static_cast<double>(canvas.x0 + xmin), static_cast<double>(canvas.y0 + ymin));
  out.shape.width = xmax - xmin + 1;
  out.shape.height = ymax - ymin + 1;
  out.shape.cells.assign(std::size_t{out.shape.width} * out.shape.height, 0);
  out.positions.assign(out.shape.cells.size(), Vec3::Zero());
  for (std::uint32_t y = 0; y < out.shape.height; ++y)
    for (std::uint32_t x = 0; x < out.shape.width; ++x) {
      const std::size_t from = std::size_t{y + ymin} * canvas.width + (x + xmin);
      const std::size_t to = std::size_t{y} * out.shape.width + x;
      out.shape.cells[to] = canvas.mask[from];
      out.positions[to] = canvas.positions[from];
    }
  return out;
}

}  // namespace gimforge
