#include "kernels/scan/bricks.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge {

// ---------------------------------------------------------------------------------------------------------
// CentroidHistogram

CentroidHistogram::CentroidHistogram(const BoundingBox& box, std::array<std::uint32_t, 3> dims) : box_(box), dims_(dims) {
  if (box.empty() || !box.min.allFinite() || !box.max.allFinite())
    throw InvalidInput("centroid histogram: the box is empty or not finite");
  std::uint64_t cells = 1;
  for (const std::uint32_t d : dims) {
    if (d == 0) throw InvalidInput("centroid histogram: a dimension is 0");
    cells *= d;
    if (cells > (std::uint64_t{1} << 26))
      throw InvalidInput(fmt::format("centroid histogram: {}×{}×{} cells is too many", dims[0], dims[1], dims[2]));
  }
  counts_.assign(cells, 0);
}

namespace {

/// The cell of `p` in the grid of `dims` cells over `box`: non-finite or below the box, cell 0; at or beyond
/// the far face, the last cell.
std::array<std::uint32_t, 3> grid_cell(const BoundingBox& box, const std::array<std::uint32_t, 3>& dims, const Vec3& p) {
  std::array<std::uint32_t, 3> c{};
  for (int k = 0; k < 3; ++k) {
    const auto a = static_cast<std::size_t>(k);
    const double extent = box.max[k] - box.min[k];
    const double t = extent > 0.0 ? (p[k] - box.min[k]) / extent * dims[a] : 0.0;
    c[a] = !(t > 0.0) ? 0u : t >= static_cast<double>(dims[a]) ? dims[a] - 1 : static_cast<std::uint32_t>(t);
  }
  return c;
}

}  // namespace

std::array<std::uint32_t, 3> CentroidHistogram::cell_of(const Vec3& p) const { return grid_cell(box_, dims_, p); }

void CentroidHistogram::add(const Vec3& p, std::uint64_t count) {
  const auto c = cell_of(p);
  counts_[(std::size_t{c[2]} * dims_[1] + c[1]) * dims_[0] + c[0]] += count;
}

void CentroidHistogram::add_face_centroids(std::span<const Vec3> positions, std::span<const Face> faces) {
  for (const Face& f : faces) add((positions[f[0]] + positions[f[1]] + positions[f[2]]) / 3.0);
}

std::uint64_t CentroidHistogram::total() const {
  std::uint64_t t = 0;
  for (const std::uint64_t c : counts_) t += c;
  return t;
}

// ---------------------------------------------------------------------------------------------------------
// BrickPartition

std::size_t BrickPartition::brick_of(const Vec3& p) const {
  const std::array<std::uint32_t, 3> c = grid_cell(box, dims, p);
  std::uint32_t n = 0;
  while (nodes[n].axis >= 0) n = c[static_cast<std::size_t>(nodes[n].axis)] < nodes[n].plane ? nodes[n].left : nodes[n].right;
  return nodes[n].left;
}

BoundingBox BrickPartition::bounds(std::size_t b) const {
  BoundingBox r;
  for (int k = 0; k < 3; ++k) {
    const auto a = static_cast<std::size_t>(k);
    const double cell = (box.max[k] - box.min[k]) / dims[a];
    r.min[k] = lo[b][a] == 0 ? box.min[k] : box.min[k] + cell * lo[b][a];
    r.max[k] = hi[b][a] == dims[a] ? box.max[k] : box.min[k] + cell * hi[b][a];
  }
  return r;
}

namespace {

struct Splitter {
  const CentroidHistogram& h;
  BrickPartition& out;

  [[nodiscard]] std::uint64_t at(std::uint32_t x, std::uint32_t y, std::uint32_t z) const {
    return h.counts()[(std::size_t{z} * h.dims()[1] + y) * h.dims()[0] + x];
  }

  /// Counts of the slabs of box [lo, hi) along `axis`.
  [[nodiscard]] std::vector<std::uint64_t> slabs(const std::array<std::uint32_t, 3>& lo, const std::array<std::uint32_t, 3>& hi,
                                                 std::size_t axis) const {
    std::vector<std::uint64_t> s(hi[axis] - lo[axis], 0);
    for (std::uint32_t z = lo[2]; z < hi[2]; ++z)
      for (std::uint32_t y = lo[1]; y < hi[1]; ++y)
        for (std::uint32_t x = lo[0]; x < hi[0]; ++x) {
          const std::array<std::uint32_t, 3> c{x, y, z};
          s[c[axis] - lo[axis]] += at(x, y, z);
        }
    return s;
  }

  /// Adds the subtree of box [lo, hi) holding `count` points cut into k bricks; returns its node index.
  std::uint32_t split(const std::array<std::uint32_t, 3>& lo, const std::array<std::uint32_t, 3>& hi, std::uint64_t count,
                      std::size_t k) {
    const auto node = static_cast<std::uint32_t>(out.nodes.size());
    out.nodes.emplace_back();
    const std::size_t left_bricks = k / 2;
    // Per splittable axis: the plane whose count before it is closest to the left share of the count.
    struct Choice {
      std::size_t axis{3};
      std::uint32_t plane{0};
      std::uint64_t before{0};
      double error{std::numeric_limits<double>::infinity()};
      double extent{0.0};
    };
    std::array<Choice, 3> choices{};
    double best_error = std::numeric_limits<double>::infinity();
    if (k > 1) {
      const double target = static_cast<double>(count) * static_cast<double>(left_bricks) / static_cast<double>(k);
      for (std::size_t a = 0; a < 3; ++a) {
        if (hi[a] - lo[a] < 2) continue;
        const std::vector<std::uint64_t> s = slabs(lo, hi, a);
        Choice& c = choices[a];
        c.axis = a;
        c.extent = (h.box().max[static_cast<int>(a)] - h.box().min[static_cast<int>(a)]) / h.dims()[a] * (hi[a] - lo[a]);
        std::uint64_t before = 0;
        for (std::size_t i = 0; i + 1 < s.size(); ++i) {
          before += s[i];
          const double e = std::abs(static_cast<double>(before) - target);
          if (e < c.error) {
            c.error = e;
            c.plane = lo[a] + static_cast<std::uint32_t>(i) + 1;
            c.before = before;
          }
        }
        best_error = std::min(best_error, c.error);
      }
    }
    // Among the axes within 2 % of the count of the best balance, the longest in space (compact bricks).
    const Choice* pick = nullptr;
    for (const Choice& c : choices)
      if (c.axis < 3 && c.error <= best_error + 0.02 * static_cast<double>(count) && (pick == nullptr || c.extent > pick->extent))
        pick = &c;
    if (pick == nullptr) {  // one brick, or a single cell: a leaf (and empty bricks for the rest)
      out.nodes[node] = {-1, 0, static_cast<std::uint32_t>(out.lo.size()), 0};
      out.lo.push_back(lo);
      out.hi.push_back(hi);
      out.count.push_back(count);
      for (std::size_t e = 1; e < k; ++e) {
        out.lo.push_back(lo);
        out.hi.push_back(lo);
        out.count.push_back(0);
      }
      return node;
    }
    const Choice c = *pick;
    std::array<std::uint32_t, 3> mid_hi = hi, mid_lo = lo;
    mid_hi[c.axis] = c.plane;
    mid_lo[c.axis] = c.plane;
    const std::uint32_t left = split(lo, mid_hi, c.before, left_bricks);
    const std::uint32_t right = split(mid_lo, hi, count - c.before, k - left_bricks);
    out.nodes[node] = {static_cast<int>(c.axis), c.plane, left, right};
    return node;
  }
};

}  // namespace

BrickPartition partition_bricks(const CentroidHistogram& histogram, std::size_t bricks) {
  if (bricks == 0) throw InvalidInput("partition_bricks: 0 bricks");
  if (bricks > (std::size_t{1} << 20)) throw InvalidInput(fmt::format("partition_bricks: {} bricks is too many", bricks));
  BrickPartition p;
  p.box = histogram.box();
  p.dims = histogram.dims();
  Splitter s{histogram, p};
  (void)s.split({0, 0, 0}, histogram.dims(), histogram.total(), bricks);
  return p;
}

}  // namespace gimforge
