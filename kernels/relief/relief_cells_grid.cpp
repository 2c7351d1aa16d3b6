// Cell classification of Apaza & Andújar §3.1 / §3.3.1 (relief_cells.h): grey cells by exact
// triangle-box overlap, regions of non-grey cells, the parity-vote inside test, external faces. The
// OpenVDB inside test (exterior flood fill) is in relief_cells.cpp.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "kernels/core/edge_topology.h"
#include "kernels/core/errors.h"
#include "kernels/relief/relief_cells.h"
#include "kernels/relief/relief_cells_detail.h"

namespace gimforge {

// ---- CellGrid helpers ----

Vec3 CellGrid::cell_min(std::size_t linear) const {
  const auto c = coords(linear);
  return origin + cell_size * Vec3(c[0], c[1], c[2]);
}

Vec3 CellGrid::cell_max(std::size_t linear) const {
  const auto c = coords(linear);
  return origin + cell_size * Vec3(c[0] + 1.0, c[1] + 1.0, c[2] + 1.0);
}

Vec3 CellGrid::cell_center(std::size_t linear) const {
  const auto c = coords(linear);
  return origin + cell_size * Vec3(c[0] + 0.5, c[1] + 0.5, c[2] + 0.5);
}

std::size_t CellGrid::grey_index(std::size_t linear) const {
  const auto it = std::lower_bound(grey_cells.begin(), grey_cells.end(), linear);
  return it != grey_cells.end() && *it == linear ? static_cast<std::size_t>(it - grey_cells.begin()) : grey_cells.size();
}

std::size_t CellGrid::count(CellClass c) const {
  return static_cast<std::size_t>(std::count(cells.begin(), cells.end(), c));
}

// ---- triangle-box overlap ----

bool triangle_box_overlap(const Vec3& box_min, const Vec3& box_max, const Vec3& a, const Vec3& b, const Vec3& c) {
  // Box normals: plain comparisons, exact.
  const Vec3 tmin = a.cwiseMin(b).cwiseMin(c);
  const Vec3 tmax = a.cwiseMax(b).cwiseMax(c);
  if ((tmax.array() < box_min.array()).any() || (tmin.array() > box_max.array()).any()) return false;

  const Vec3 centre = 0.5 * (box_min + box_max);
  const Vec3 h = 0.5 * (box_max - box_min);
  const Vec3 v0 = a - centre, v1 = b - centre, v2 = c - centre;
  const Vec3 e[3] = {v1 - v0, v2 - v1, v0 - v2};
  // Magnitude of the coordinates: rounding errors of the projections below scale with it.
  const double scale = std::max({a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff(), c.cwiseAbs().maxCoeff(),
                                 box_min.cwiseAbs().maxCoeff(), box_max.cwiseAbs().maxCoeff()});
  constexpr double kRelTol = 1e-12;

  // Nine axes: triangle edge x box axis. For L = unit_k x e the projections use two coordinates only.
  for (const Vec3& ed : e) {
    for (int k = 0; k < 3; ++k) {
      const int p = (k + 1) % 3, q = (k + 2) % 3;
      // L = unit_k x ed has components L_p = -ed_q, L_q = ed_p (L_k = 0).
      const double lp = -ed[q], lq = ed[p];
      const double p0 = lp * v0[p] + lq * v0[q];
      const double p1 = lp * v1[p] + lq * v1[q];
      const double p2 = lp * v2[p] + lq * v2[q];
      const double l1 = std::abs(lp) + std::abs(lq);
      const double r = h[p] * std::abs(lp) + h[q] * std::abs(lq);
      const double tol = kRelTol * scale * (l1 + scale);
      if (std::min({p0, p1, p2}) > r + tol || std::max({p0, p1, p2}) < -r - tol) return false;
    }
  }

  // Triangle plane.
  const Vec3 normal = e[0].cross(e[1]);
  const double d = normal.dot(v0);
  const double r = h.dot(normal.cwiseAbs());
  const double tol = kRelTol * scale * (normal.cwiseAbs().sum() + scale * (e[0].cwiseAbs().sum() + e[1].cwiseAbs().sum()));
  return std::abs(d) <= r + tol;
}

// ---- watertightness ----

bool is_closed_edge_manifold(MeshView mesh) {
  const std::size_t nv = mesh.positions.size();
  // Undirected edges bucketed by their smaller vertex (counting sort: linear time).
  std::vector<std::size_t> offset(nv + 1, 0);
  for (const Face& f : mesh.faces) {
    if (has_repeated_index(f)) continue;
    for (std::size_t i = 0; i < 3; ++i) ++offset[std::min(f[i], f[(i + 1) % 3]) + 1];
  }
  for (std::size_t v = 0; v < nv; ++v) offset[v + 1] += offset[v];
  if (offset[nv] == 0) return false;
  std::vector<std::uint32_t> other(offset[nv]);
  std::vector<std::size_t> cursor(offset.begin(), offset.end() - 1);
  for (const Face& f : mesh.faces) {
    if (has_repeated_index(f)) continue;
    for (std::size_t i = 0; i < 3; ++i) {
      const std::uint32_t u = f[i], w = f[(i + 1) % 3];
      other[cursor[std::min(u, w)]++] = std::max(u, w);
    }
  }
  for (std::size_t v = 0; v < nv; ++v) {
    const auto first = other.begin() + static_cast<std::ptrdiff_t>(offset[v]);
    const auto last = other.begin() + static_cast<std::ptrdiff_t>(offset[v + 1]);
    std::sort(first, last);
    for (auto it = first; it != last;) {
      auto end = it;
      while (end != last && *end == *it) ++end;
      if (end - it != 2) return false;
      it = end;
    }
  }
  return true;
}

namespace {

constexpr std::uint32_t kMaxCellsPerAxis = 1024;
constexpr std::uint8_t kGreyBit = 1u << 3;  // work byte: bits 0..2 parity per axis, bit 3 grey
constexpr std::size_t kRegionSamples = 16;         // flood-fill samples per region

/// Grid geometry shared by every step. Cell i on axis a spans [plane(a, i), plane(a, i + 1)].
struct Frame {
  std::uint32_t n{0};
  Vec3 origin{Vec3::Zero()};
  double cs{0.0};
  double inv_cs{0.0};  ///< 1 / cs, for first guesses only (every decision compares against plane / line)
  std::size_t stride[3]{1, 1, 1};

  [[nodiscard]] double plane(int axis, std::int64_t i) const { return origin[axis] + static_cast<double>(i) * cs; }
  /// Coordinate of scanline j on axis `axis` (an offset inside cell j).
  [[nodiscard]] double line(int axis, std::int64_t j, double offset) const {
    return plane(axis, j) + offset * cs;
  }
  /// Integer guess for the cell holding coordinate x (clamped to [0, n - 1]).
  [[nodiscard]] std::int64_t guess(int axis, double x) const {
    const double g = std::floor((x - origin[axis]) * inv_cs);
    return static_cast<std::int64_t>(std::clamp(g, 0.0, static_cast<double>(n - 1)));
  }
  /// Smallest cell i with plane(i + 1) >= lo (lo within the grid).
  [[nodiscard]] std::uint32_t first_cell(int axis, double lo) const {
    std::int64_t g = guess(axis, lo);
    while (g > 0 && plane(axis, g) >= lo) --g;
    while (g + 1 < n && plane(axis, g + 1) < lo) ++g;
    return static_cast<std::uint32_t>(g);
  }
  /// Largest cell i with plane(i) <= hi (hi within the grid).
  [[nodiscard]] std::uint32_t last_cell(int axis, double hi) const {
    std::int64_t g = guess(axis, hi);
    while (g + 1 < n && plane(axis, g + 1) <= hi) ++g;
    while (g > 0 && plane(axis, g) > hi) --g;
    return static_cast<std::uint32_t>(g);
  }
  /// Scanlines j with lo <= line(j) <= hi: [first, end), empty when first >= end.
  [[nodiscard]] std::pair<std::int64_t, std::int64_t> lines_between(int axis, double offset, double lo, double hi) const {
    // first: smallest j with line(j) >= lo; end: smallest j >= first with line(j) > hi (n when none).
    std::int64_t first = guess(axis, lo);
    while (first > 0 && line(axis, first - 1, offset) >= lo) --first;
    while (first < n && line(axis, first, offset) < lo) ++first;
    std::int64_t end = std::max(first, guess(axis, hi));
    while (end > first && line(axis, end - 1, offset) > hi) --end;
    while (end < n && line(axis, end, offset) <= hi) ++end;
    return {first, end};
  }
};

/// Checks the faces of `mesh` (indices in range, finite positions) and returns the bounding box of the
/// vertices they use (empty for a mesh without faces).
BoundingBox checked_part_bounds(MeshView mesh) {
  if (mesh.faces.size() >= std::numeric_limits<std::uint32_t>::max())
    throw InvalidInput(fmt::format("relief cells: {} faces is more than 2^32 - 1", mesh.faces.size()));
  BoundingBox box;
  const std::size_t nv = mesh.positions.size();
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    for (const std::uint32_t v : mesh.faces[f]) {
      if (v >= nv)
        throw InvalidInput(fmt::format("relief cells: face {} refers to vertex {} of {}", f, v, nv));
      const Vec3& p = mesh.positions[v];
      if (!p.allFinite())
        throw InvalidInput(fmt::format("relief cells: vertex {} (face {}) has a non-finite coordinate", v, f));
      box.extend(p);
    }
  }
  return box;
}

/// Checks the mesh and returns the bounding box of the vertices its faces use.
BoundingBox checked_bounds(MeshView mesh) {
  if (mesh.faces.empty()) throw InvalidInput("relief cells: the mesh has no faces");
  return checked_part_bounds(mesh);
}

constexpr double kThinLayer = 0.25;  // a mesh thinner than this many cells along an axis is placed in one layer
constexpr double kThinLift = 0.125;  // its lowest point this many cells above the layer's floor

void check_grid_options(const CellGridOptions& options) {
  if (options.n == 0 || options.n > kMaxCellsPerAxis)
    throw InvalidInput(fmt::format("relief cells: n = {} is out of range [1, {}]", options.n, kMaxCellsPerAxis));
  if (!std::isfinite(options.padding) || options.padding < 0.0)
    throw InvalidInput(fmt::format("relief cells: padding = {} must be finite and >= 0", options.padding));
}

/// The bounding cube: centred on the box, side (1 + padding)·longest extent, enlarged by a few ulps if
/// rounding of origin + n·cell_size would leave a vertex outside the outer planes. Along an axis where the
/// mesh is thinner than a quarter cell (a flat or nearly flat sheet), the cube is placed so that the mesh
/// lies in the middle layer of cells, its lowest point an eighth of a cell above the layer's floor: centred,
/// a flat sheet lay in the plane between two layers (for even n; in their middle for odd n), which holds
/// the centres and axes of projection of its rim cells (cases 3a, 3b, 4b), so those cells saw it edge-on
/// and lost it (docs/relief.md, "Thin meshes").
Frame make_frame(const BoundingBox& box, std::uint32_t n, double padding) {
  const double longest = (box.max - box.min).maxCoeff();
  if (!(longest > 0.0)) throw InvalidInput("relief cells: all vertices of the mesh coincide (zero extent)");
  const Vec3 centre = 0.5 * (box.min + box.max);
  Frame fr;
  fr.n = n;
  fr.stride[1] = n;
  fr.stride[2] = static_cast<std::size_t>(n) * n;
  double side = longest * (1.0 + padding);
  if (!std::isfinite(side / n)) throw InvalidInput(fmt::format("relief cells: padding = {} is too large", padding));
  double grow = longest * 1e-14;
  for (int attempt = 0; attempt < 200; ++attempt) {
    fr.origin = centre - Vec3::Constant(0.5 * side);
    fr.cs = side / n;
    fr.inv_cs = 1.0 / fr.cs;
    for (int a = 0; a < 3; ++a)
      if (box.max[a] - box.min[a] <= kThinLayer * fr.cs)
        fr.origin[a] = box.min[a] - (kThinLift + std::floor(0.5 * n)) * fr.cs;
    bool inside = true;
    for (int a = 0; a < 3; ++a) inside = inside && fr.plane(a, 0) <= box.min[a] && fr.plane(a, n) >= box.max[a];
    if (inside) return fr;
    side += grow;
    grow *= 2.0;
  }
  throw NumericalError("relief cells: cannot place a bounding cube around the mesh (coordinates too large)");
}

/// Key of a (cell, face) pair, sorting by cell then face.
std::uint64_t pair_key(std::size_t cell, std::size_t face) {
  return (static_cast<std::uint64_t>(cell) << 32) | static_cast<std::uint64_t>(face);
}

/// Stable LSD radix sort of (cell, face) keys by their cell bits (the upper half), 11 bits a pass.
void sort_by_cell(std::vector<std::uint64_t>& keys, std::size_t ncells) {
  constexpr int kBits = 11;
  constexpr std::size_t kBuckets = std::size_t{1} << kBits;
  int cell_bits = 1;
  while ((std::size_t{1} << cell_bits) < ncells) ++cell_bits;
  std::vector<std::uint64_t> tmp(keys.size());
  std::vector<std::size_t> start(kBuckets);
  for (int shift = 32; shift < 32 + cell_bits; shift += kBits) {
    std::fill(start.begin(), start.end(), 0);
    for (const std::uint64_t k : keys) ++start[(k >> shift) & (kBuckets - 1)];
    std::size_t sum = 0;
    for (std::size_t& c : start) sum += std::exchange(c, sum);
    for (const std::uint64_t k : keys) tmp[start[(k >> shift) & (kBuckets - 1)]++] = k;
    keys.swap(tmp);
  }
}

/// All (cell, face) overlaps sorted by cell, then face: the face's bounding box selects candidate cells,
/// the exact test decides (a face whose box lies in one cell overlaps it without a test). Faces are
/// processed in fixed chunks whose outputs are joined in order, so the keys arrive sorted by face and a
/// stable sort by cell finishes the job.
std::vector<std::uint64_t> overlap_pairs(MeshView mesh, const Frame& fr) {
  constexpr std::size_t kChunk = 4096;
  const std::size_t nfaces = mesh.faces.size();
  std::vector<std::vector<std::uint64_t>> parts((nfaces + kChunk - 1) / kChunk);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, parts.size()), [&](const auto& range) {
    for (std::size_t part = range.begin(); part != range.end(); ++part) {
      auto& out = parts[part];
      out.reserve(kChunk + kChunk / 4);
      for (std::size_t f = part * kChunk; f < std::min(nfaces, (part + 1) * kChunk); ++f) {
        const Vec3& a = mesh.positions[mesh.faces[f][0]];
        const Vec3& b = mesh.positions[mesh.faces[f][1]];
        const Vec3& c = mesh.positions[mesh.faces[f][2]];
        const Vec3 lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
        std::uint32_t first[3], last[3];
        for (int ax = 0; ax < 3; ++ax) {
          first[ax] = fr.first_cell(ax, lo[ax]);
          last[ax] = fr.last_cell(ax, hi[ax]);
        }
        if (first[0] == last[0] && first[1] == last[1] && first[2] == last[2]) {
          out.push_back(pair_key(first[0] + first[1] * fr.stride[1] + first[2] * fr.stride[2], f));
          continue;
        }
        for (std::uint32_t k = first[2]; k <= last[2]; ++k)
          for (std::uint32_t j = first[1]; j <= last[1]; ++j)
            for (std::uint32_t i = first[0]; i <= last[0]; ++i) {
              const Vec3 bmin(fr.plane(0, i), fr.plane(1, j), fr.plane(2, k));
              const Vec3 bmax(fr.plane(0, i + 1), fr.plane(1, j + 1), fr.plane(2, k + 1));
              if (triangle_box_overlap(bmin, bmax, a, b, c))
                out.push_back(pair_key(i + j * fr.stride[1] + k * fr.stride[2], f));
            }
      }
    }
  });
  std::vector<std::size_t> offset(parts.size() + 1, 0);
  for (std::size_t p = 0; p < parts.size(); ++p) offset[p + 1] = offset[p] + parts[p].size();
  std::vector<std::uint64_t> keys(offset.back());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, parts.size()), [&](const auto& range) {
    for (std::size_t p = range.begin(); p != range.end(); ++p)
      std::copy(parts[p].begin(), parts[p].end(), keys.begin() + static_cast<std::ptrdiff_t>(offset[p]));
  });
  parts.clear();
  sort_by_cell(keys, static_cast<std::size_t>(fr.n) * fr.n * fr.n);
  return keys;
}

/// Maximal runs of non-grey cells along x, per row (j, k), and their connected regions.
struct Regions {
  std::vector<std::size_t> row_offset;   ///< n² + 1: runs of row r are [row_offset[r], row_offset[r + 1])
  std::vector<std::uint32_t> run_start;  ///< first cell (i) of each run
  std::vector<std::uint32_t> run_end;    ///< last cell (i) of each run, inclusive
  std::vector<std::uint32_t> run_region;  ///< region of each run, numbered in order of first run
  std::vector<std::uint8_t> region_on_boundary;  ///< the region has a cell on the grid boundary
  std::vector<std::size_t> region_cells;  ///< cells per region
  std::vector<std::size_t> region_runs;   ///< runs per region
  [[nodiscard]] std::size_t count() const { return region_cells.size(); }
};

Regions find_regions(const std::vector<std::uint8_t>& work, std::uint32_t n) {
  Regions g;
  const std::size_t rows = static_cast<std::size_t>(n) * n;
  const auto is_grey = [&](std::size_t row, std::uint32_t i) { return (work[row * n + i] & kGreyBit) != 0; };
  // Runs: count per row, prefix sums, fill (both passes parallel over rows).
  std::vector<std::size_t> count(rows + 1, 0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows, 64), [&](const auto& range) {
    for (std::size_t r = range.begin(); r != range.end(); ++r) {
      std::size_t runs = 0;
      for (std::uint32_t i = 0; i < n; ++i)
        if (!is_grey(r, i) && (i == 0 || is_grey(r, i - 1))) ++runs;
      count[r + 1] = runs;
    }
  });
  for (std::size_t r = 0; r < rows; ++r) count[r + 1] += count[r];
  g.row_offset = std::move(count);
  const std::size_t nruns = g.row_offset[rows];
  g.run_start.resize(nruns);
  g.run_end.resize(nruns);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows, 64), [&](const auto& range) {
    for (std::size_t r = range.begin(); r != range.end(); ++r) {
      std::size_t s = g.row_offset[r];
      for (std::uint32_t i = 0; i < n; ++i) {
        if (is_grey(r, i)) continue;
        if (i == 0 || is_grey(r, i - 1)) g.run_start[s] = i;
        if (i + 1 == n || is_grey(r, i + 1)) g.run_end[s++] = i;
      }
    }
  });
  // Union of face-adjacent runs: a run touches the overlapping runs of rows (j - 1, k) and (j, k - 1).
  UnionFind sets(nruns);
  const auto link = [&](std::size_t ra, std::size_t rb) {
    std::size_t x = g.row_offset[ra], y = g.row_offset[rb];
    const std::size_t xe = g.row_offset[ra + 1], ye = g.row_offset[rb + 1];
    while (x < xe && y < ye) {
      if (g.run_start[x] <= g.run_end[y] && g.run_start[y] <= g.run_end[x])
        sets.unite(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y));
      if (g.run_end[x] < g.run_end[y]) ++x;
      else ++y;
    }
  };
  for (std::uint32_t k = 0; k < n; ++k)
    for (std::uint32_t j = 0; j < n; ++j) {
      const std::size_t r = static_cast<std::size_t>(k) * n + j;
      if (j > 0) link(r, r - 1);
      if (k > 0) link(r, r - n);
    }
  g.run_region.assign(nruns, kInvalidIndex);
  std::vector<std::uint32_t> root_region(nruns, kInvalidIndex);
  for (std::size_t r = 0; r < rows; ++r) {
    const std::size_t j = r % n, k = r / n;
    const bool edge_row = j == 0 || k == 0 || j + 1 == n || k + 1 == n;
    for (std::size_t s = g.row_offset[r]; s < g.row_offset[r + 1]; ++s) {
      const std::uint32_t root = sets.find(static_cast<std::uint32_t>(s));
      if (root_region[root] == kInvalidIndex) {
        root_region[root] = static_cast<std::uint32_t>(g.region_cells.size());
        g.region_cells.push_back(0);
        g.region_runs.push_back(0);
        g.region_on_boundary.push_back(0);
      }
      const std::uint32_t id = root_region[root];
      g.run_region[s] = id;
      g.region_cells[id] += g.run_end[s] - g.run_start[s] + 1;
      ++g.region_runs[id];
      if (edge_row || g.run_start[s] == 0 || g.run_end[s] + 1 == n) g.region_on_boundary[id] = 1;
    }
  }
  return g;
}

/// Watertight inside test: OpenVDB's exterior flood fill over the grey cells, read at up to
/// kRegionSamples cells of every region (the middle cells of runs evenly spread over the region). A region
/// with a cell on the grid boundary is outside whatever the samples say (the bounding cube contains M);
/// any other region takes the majority of its samples. Returns the class per region; adds the samples
/// that disagree with their region's class to `ambiguous`.
std::vector<CellClass> flood_fill_regions(const std::vector<std::uint32_t>& grey_cells, std::uint32_t n,
                                          const Regions& g, std::size_t& ambiguous) {
  std::vector<CellClass> region_class(g.count(), CellClass::White);
  std::vector<std::array<std::uint32_t, 3>> samples;
  std::vector<std::uint32_t> sample_region;
  std::vector<std::size_t> seen(g.count(), 0);
  const std::size_t rows = static_cast<std::size_t>(n) * n;
  for (std::size_t r = 0; r < rows; ++r)
    for (std::size_t s = g.row_offset[r]; s < g.row_offset[r + 1]; ++s) {
      const std::uint32_t id = g.run_region[s];
      // The runs of region id numbered 0, stride, 2·stride, ... (at most kRegionSamples of them).
      const std::size_t stride = std::max<std::size_t>(1, g.region_runs[id] / kRegionSamples);
      const std::size_t number = seen[id]++;
      if (number % stride != 0 || number / stride >= kRegionSamples) continue;
      samples.push_back({(g.run_start[s] + g.run_end[s]) / 2, static_cast<std::uint32_t>(r % n),
                         static_cast<std::uint32_t>(r / n)});
      sample_region.push_back(id);
    }
  if (samples.empty()) return region_class;
  const std::vector<std::uint8_t> inside = detail::exterior_flood_fill(grey_cells, n, samples);
  std::vector<std::size_t> votes_in(g.count(), 0), votes(g.count(), 0);
  for (std::size_t q = 0; q < samples.size(); ++q) {
    votes_in[sample_region[q]] += inside[q];
    ++votes[sample_region[q]];
  }
  for (std::size_t id = 0; id < g.count(); ++id) {
    const bool black = !g.region_on_boundary[id] && 2 * votes_in[id] > votes[id];
    region_class[id] = black ? CellClass::Black : CellClass::White;
    ambiguous += black ? votes[id] - votes_in[id] : votes_in[id];
  }
  return region_class;
}

/// Orientation of r relative to the directed line p -> q (twice the signed area of p, q, r).
double orient2d(double pu, double pv, double qu, double qv, double ru, double rv) {
  return (qu - pu) * (rv - pv) - (qv - pv) * (ru - pu);
}

/// Parity votes: for every scanline (axis a through cell row (j_u, k_v)) the crossings of the surface,
/// recorded as a toggle in the first cell whose centre lies beyond the crossing (bit a of the work byte)
/// and in the line's total parity. Rasterization with a watertight fill rule: each edge function is
/// evaluated with its endpoints in a canonical order (lexicographic in the projection plane), so two faces
/// sharing an edge (even through duplicated vertices) see exactly opposite values, and a line through an
/// edge or a vertex is counted by exactly one face of a flat fan (by two or none at a fold, which keeps
/// the parity).
void cast_parity_lines(MeshView mesh, const Frame& fr, std::vector<std::uint8_t>& work,
                       std::array<std::vector<std::uint8_t>, 3>& line_parity) {
  const std::uint32_t n = fr.n;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, mesh.faces.size(), 2048), [&](const auto& range) {
    for (std::size_t f = range.begin(); f != range.end(); ++f) {
      const Face& t = mesh.faces[f];
      if (has_repeated_index(t)) continue;
      const Vec3* p[3] = {&mesh.positions[t[0]], &mesh.positions[t[1]], &mesh.positions[t[2]]};
      for (int a = 0; a < 3; ++a) {
        const int u = (a + 1) % 3, v = (a + 2) % 3;
        const double pu[3] = {(*p[0])[u], (*p[1])[u], (*p[2])[u]};
        const double pv[3] = {(*p[0])[v], (*p[1])[v], (*p[2])[v]};
        const double area = orient2d(pu[0], pv[0], pu[1], pv[1], pu[2], pv[2]);
        if (area == 0.0) continue;  // edge-on: the lines meet it in its neighbours
        const auto [j0, j1] = fr.lines_between(u, kParityLineOffsetU, std::min({pu[0], pu[1], pu[2]}),
                                               std::max({pu[0], pu[1], pu[2]}));
        if (j0 >= j1) continue;
        const auto [k0, k1] = fr.lines_between(v, kParityLineOffsetV, std::min({pv[0], pv[1], pv[2]}),
                                               std::max({pv[0], pv[1], pv[2]}));
        if (k0 >= k1) continue;
        const double s = area > 0.0 ? 1.0 : -1.0;
        for (std::int64_t k = k0; k < k1; ++k) {
          const double qv = fr.line(v, k, kParityLineOffsetV);
          for (std::int64_t j = j0; j < j1; ++j) {
            const double qu = fr.line(u, j, kParityLineOffsetU);
            double w[3];
            bool in = true;
            for (std::size_t e = 0; e < 3 && in; ++e) {
              // Edge e runs from corner e+1 to corner e+2 (opposite corner e).
              const std::size_t x = (e + 1) % 3, y = (e + 2) % 3;
              const bool forward = pu[x] < pu[y] || (pu[x] == pu[y] && pv[x] < pv[y]);
              w[e] = forward ? orient2d(pu[x], pv[x], pu[y], pv[y], qu, qv) : -orient2d(pu[y], pv[y], pu[x], pv[x], qu, qv);
              if (s * w[e] > 0.0) continue;
              if (w[e] != 0.0) {
                in = false;
                continue;
              }
              // On the edge: the face counts it when its counter-clockwise direction d along the edge has
              // d_v > 0, or d_v == 0 and d_u > 0; the face on the other side runs along -d exactly.
              const double du = s * (pu[y] - pu[x]), dv = s * (pv[y] - pv[x]);
              in = dv > 0.0 || (dv == 0.0 && du > 0.0);
            }
            if (!in) continue;
            const double sum = w[0] + w[1] + w[2];
            const double depth = (w[0] * (*p[0])[a] + w[1] * (*p[1])[a] + w[2] * (*p[2])[a]) / (sum != 0.0 ? sum : area);
            // First cell whose centre lies beyond the crossing.
            const double first = std::floor((depth - fr.origin[a]) / fr.cs - 0.5) + 1.0;
            const auto cell = static_cast<std::int64_t>(std::clamp(first, 0.0, static_cast<double>(n)));
            const std::size_t row = static_cast<std::size_t>(k) * n + static_cast<std::size_t>(j);
            std::atomic_ref<std::uint8_t>(line_parity[static_cast<std::size_t>(a)][row]).fetch_xor(1, std::memory_order_relaxed);
            if (cell < n) {
              const std::size_t idx = static_cast<std::size_t>(cell) * fr.stride[a] +
                                      static_cast<std::size_t>(j) * fr.stride[u] + static_cast<std::size_t>(k) * fr.stride[v];
              std::atomic_ref<std::uint8_t>(work[idx]).fetch_xor(static_cast<std::uint8_t>(1u << a),
                                                                 std::memory_order_relaxed);
            }
          }
        }
      }
    }
  });
}

/// Toggles -> parity of the crossings before each cell centre (prefix XOR along every line). Lines along y
/// and z are walked a whole x-row at a time, so the inner loops run over contiguous cells.
void prefix_parity(std::vector<std::uint8_t>& work, std::uint32_t n) {
  const std::size_t nn = n;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nn * nn, 256), [&](const auto& range) {
    for (std::size_t row = range.begin(); row != range.end(); ++row) {
      std::uint8_t parity = 0;
      for (std::size_t i = 0; i < nn; ++i) {
        std::uint8_t& cell = work[row * nn + i];
        parity ^= cell & 1u;
        cell = static_cast<std::uint8_t>((cell & ~1u) | parity);
      }
    }
  });
  for (int a = 1; a < 3; ++a) {
    const auto bit = static_cast<std::uint8_t>(1u << a);
    // Axis y: slab k fixed, rows (i, k) walked along j. Axis z: j fixed, rows (i, j) walked along k.
    const std::size_t outer_stride = a == 1 ? nn * nn : nn;
    const std::size_t step = a == 1 ? nn : nn * nn;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nn, 1), [&](const auto& range) {
      std::vector<std::uint8_t> parity(nn);
      for (std::size_t o = range.begin(); o != range.end(); ++o) {
        std::fill(parity.begin(), parity.end(), std::uint8_t{0});
        for (std::size_t c = 0; c < nn; ++c) {
          std::uint8_t* cells = work.data() + o * outer_stride + c * step;
          for (std::size_t i = 0; i < nn; ++i) {
            parity[i] = static_cast<std::uint8_t>(parity[i] ^ (cells[i] & bit));
            cells[i] = static_cast<std::uint8_t>((cells[i] & ~bit) | parity[i]);
          }
        }
      }
    });
  }
}

/// Inside votes (0..6) of a non-grey cell from its parity bits and its three lines' total parities.
int inside_votes(std::uint8_t cell_bits, std::size_t i, std::size_t j, std::size_t k, std::size_t n,
                 const std::array<std::vector<std::uint8_t>, 3>& line_parity) {
  const std::uint8_t total[3] = {line_parity[0][k * n + j], line_parity[1][i * n + k], line_parity[2][j * n + i]};
  int votes = 0;
  for (int a = 0; a < 3; ++a) {
    const int before = (cell_bits >> a) & 1;
    votes += before + (before ^ total[a]);
  }
  return votes;
}

}  // namespace

CellFaceParts cell_face_parts(MeshView part, const BoundingBox& box, const CellGridOptions& options, bool parity) {
  check_grid_options(options);
  const std::uint32_t n = options.n;
  checked_part_bounds(part);
  const Frame fr = make_frame(box, n, options.padding);
  CellFaceParts out;
  out.n = n;
  out.origin = fr.origin;
  out.cell_size = fr.cs;
  const std::size_t ncells = static_cast<std::size_t>(n) * n * n;
  out.pairs = overlap_pairs(part, fr);
  out.grey.assign(ncells, 0);
  for (const std::uint64_t key : out.pairs) out.grey[key >> 32] = 1;
  if (parity) {
    out.toggles.assign(ncells, 0);
    for (auto& l : out.line_parity) l.assign(static_cast<std::size_t>(n) * n, 0);
    cast_parity_lines(part, fr, out.toggles, out.line_parity);
  }
  return out;
}

CellGrid classify_cells(MeshView mesh, const CellGridOptions& options) {
  check_grid_options(options);
  const BoundingBox box = checked_bounds(mesh);
  report_progress(options.progress, "relief cells", 0.0);
  const bool flood_fill = options.inside_test == InsideTest::Automatic && is_closed_edge_manifold(mesh);
  CellFaceParts parts = cell_face_parts(mesh, box, options, !flood_fill);
  report_progress(options.progress, "relief cells", 0.5);
  return finish_cell_grid(std::move(parts), flood_fill, options);
}

CellGrid finish_cell_grid(CellFaceParts parts, bool closed_edge_manifold, const CellGridOptions& options) {
  check_grid_options(options);
  const std::uint32_t n = options.n;
  const std::size_t ncells = static_cast<std::size_t>(n) * n * n;
  const bool flood_fill = options.inside_test == InsideTest::Automatic && closed_edge_manifold;
  if (parts.n != n || parts.grey.size() != ncells || (!flood_fill && parts.toggles.size() != ncells))
    throw InvalidInput(fmt::format("relief cells: the face parts (n = {}, {} cells{}) do not match the grid n = {}",
                                   parts.n, parts.grey.size(), flood_fill ? "" : ", parity needed", n));
  Frame fr;
  fr.n = n;
  fr.origin = parts.origin;
  fr.cs = parts.cell_size;
  fr.inv_cs = 1.0 / fr.cs;
  fr.stride[1] = n;
  fr.stride[2] = static_cast<std::size_t>(n) * n;

  CellGrid grid;
  grid.n = n;
  grid.origin = fr.origin;
  grid.cell_size = fr.cs;

  // Grey cells and the part's faces in them.
  std::vector<std::uint8_t> work = flood_fill ? std::vector<std::uint8_t>(ncells, 0) : std::move(parts.toggles);
  {
    const std::vector<std::uint64_t>& keys = parts.pairs;
    std::size_t s = 0;
    for (std::size_t cell = 0; cell < ncells; ++cell) {
      if (parts.grey[cell] == 0) continue;
      while (s < keys.size() && (keys[s] >> 32) < cell) ++s;
      std::size_t e = s;
      while (e < keys.size() && (keys[e] >> 32) == cell) ++e;
      std::vector<std::uint32_t> faces(e - s);
      for (std::size_t q = s; q < e; ++q) faces[q - s] = static_cast<std::uint32_t>(keys[q] & 0xffffffffu);
      grid.grey_cells.push_back(static_cast<std::uint32_t>(cell));
      grid.grey_triangles.push_back(std::move(faces));
      work[cell] |= kGreyBit;
      s = e;
    }
    parts.pairs = {};
    parts.grey = {};
  }

  // Regions of non-grey cells and their inside / outside state.
  const Regions regions = find_regions(work, n);
  grid.regions = regions.count();
  grid.watertight_inside_test = flood_fill;
  grid.cells.assign(ncells, CellClass::Grey);
  const std::size_t rows = static_cast<std::size_t>(n) * n;
  if (flood_fill) {
    const std::vector<CellClass> region_class = flood_fill_regions(grid.grey_cells, n, regions, grid.ambiguous_cells);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows, 64), [&](const auto& range) {
      for (std::size_t r = range.begin(); r != range.end(); ++r)
        for (std::size_t s = regions.row_offset[r]; s < regions.row_offset[r + 1]; ++s)
          std::fill(grid.cells.begin() + static_cast<std::ptrdiff_t>(r * n + regions.run_start[s]),
                    grid.cells.begin() + static_cast<std::ptrdiff_t>(r * n + regions.run_end[s] + 1),
                    region_class[regions.run_region[s]]);
    });
    grid.inside_method = "watertight mesh: OpenVDB exterior flood fill (tools::traceExteriorBoundaries) over the "
                         "grey-cell voxels, one decision per region of non-grey cells (regions on the grid "
                         "boundary outside)";
  } else {
    const std::array<std::vector<std::uint8_t>, 3>& line_parity = parts.line_parity;
    for (const auto& l : line_parity)
      if (l.size() != rows) throw InvalidInput("relief cells: the face parts' line parities do not match the grid");
    prefix_parity(work, n);
    // Per region: total inside votes (for 3-3 ties).
    tbb::enumerable_thread_specific<std::vector<std::size_t>> local_votes(std::vector<std::size_t>(regions.count(), 0));
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows, 64), [&](const auto& range) {
      std::vector<std::size_t>& votes = local_votes.local();
      for (std::size_t r = range.begin(); r != range.end(); ++r)
        for (std::size_t s = regions.row_offset[r]; s < regions.row_offset[r + 1]; ++s)
          for (std::uint32_t i = regions.run_start[s]; i <= regions.run_end[s]; ++i)
            votes[regions.run_region[s]] +=
                static_cast<std::size_t>(inside_votes(work[r * n + i], i, r % n, r / n, n, line_parity));
    });
    std::vector<std::size_t> region_votes(regions.count(), 0);
    for (const auto& votes : local_votes)
      for (std::size_t id = 0; id < votes.size(); ++id) region_votes[id] += votes[id];
    tbb::enumerable_thread_specific<std::size_t> ambiguous(0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows, 64), [&](const auto& range) {
      std::size_t& amb = ambiguous.local();
      for (std::size_t r = range.begin(); r != range.end(); ++r)
        for (std::size_t s = regions.row_offset[r]; s < regions.row_offset[r + 1]; ++s) {
          const std::uint32_t id = regions.run_region[s];
          const bool region_inside = region_votes[id] * 2 > regions.region_cells[id] * 6;
          for (std::uint32_t i = regions.run_start[s]; i <= regions.run_end[s]; ++i) {
            const int votes = inside_votes(work[r * n + i], i, r % n, r / n, n, line_parity);
            if (votes != 0 && votes != 6) ++amb;
            const bool inside = votes > 3 || (votes == 3 && region_inside);
            grid.cells[r * n + i] = inside ? CellClass::Black : CellClass::White;
          }
        }
    });
    grid.ambiguous_cells = ambiguous.combine(std::plus<>());
    grid.inside_method = options.inside_test == InsideTest::ParityVotes
                             ? "parity votes (requested): 6 axis-parallel rays per non-grey cell, majority"
                             : "mesh not watertight (an edge without exactly two faces): fallback parity votes, 6 "
                               "axis-parallel rays per non-grey cell, majority, ties by region";
  }
  report_progress(options.progress, "relief cells", 0.9);

  // External faces (shared with a white cell or on the grid boundary) and border / interior grey.
  const std::size_t ngrey = grid.grey_cells.size();
  grid.external_faces.assign(ngrey, 0);
  grid.border.assign(ngrey, 0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, ngrey, 1024), [&](const auto& range) {
    for (std::size_t g = range.begin(); g != range.end(); ++g) {
      const std::size_t linear = grid.grey_cells[g];
      const auto c = grid.coords(linear);
      std::uint8_t mask = 0;
      for (int f = 0; f < 6; ++f) {
        const int axis = f / 2;
        const bool high = (f % 2) != 0;
        const bool on_boundary = high ? c[static_cast<std::size_t>(axis)] + 1 == n : c[static_cast<std::size_t>(axis)] == 0;
        const bool external =
            on_boundary || grid.cells[high ? linear + fr.stride[axis] : linear - fr.stride[axis]] == CellClass::White;
        if (external) mask = static_cast<std::uint8_t>(mask | (1u << f));
      }
      grid.external_faces[g] = mask;
      grid.border[g] = mask != 0 ? 1 : 0;
    }
  });
  report_progress(options.progress, "relief cells", 1.0);
  return grid;
}

}  // namespace gimforge
