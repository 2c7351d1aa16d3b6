#include "kernels/adaptive/roi.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <Eigen/SparseLU>
#include <fmt/format.h>

#include "kernels/adaptive/grid_quad.h"
#include "kernels/adaptive/sample_adjust.h"
#include "kernels/core/errors.h"

namespace gimforge {
namespace {

constexpr double kMinSide = 1.0 / 16.0;  // shortest quad side, in uniform spacings (as local_hausdorff.cpp)
constexpr double kMargin = 2.0;          // the weights' ROI is the ROI grown by this many uniform spacings
constexpr double kDamping = 0.5;         // step towards the frozen-coefficient solution
constexpr double kSettled = 1e-2;        // a step moving no sample farther (in uniform spacings) has settled
constexpr std::uint32_t kStall = 10;     // iterations after which a ROI that gained < 1 % of what it misses pulls harder

std::uint32_t cell_of(double t, std::uint32_t size) {
  const double c = std::floor(std::clamp(t, 0.0, 1.0) * size);
  return std::min(static_cast<std::uint32_t>(c), size - 1);
}

double cross2(const Vec2& o, const Vec2& a, const Vec2& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

/// The ROI's bounding box in the square and the region (0: ROI; 1 left, 2 right, 3 below, 4 above) of a point.
class Regions {
 public:
  explicit Regions(const RoiMask& roi) : roi_(roi) {
    const std::uint32_t s = roi.size;
    Vec2 lo(1.0, 1.0), hi(0.0, 0.0);
    for (std::uint32_t j = 0; j < s; ++j)
      for (std::uint32_t i = 0; i < s; ++i)
        if (roi.inside[std::size_t{j} * s + i]) {
          lo = lo.cwiseMin(Vec2(static_cast<double>(i) / s, static_cast<double>(j) / s));
          hi = hi.cwiseMax(Vec2(static_cast<double>(i + 1) / s, static_cast<double>(j + 1) / s));
        }
    centre_ = 0.5 * (lo + hi);
    half_ = (0.5 * (hi - lo)).cwiseMax(Vec2(1e-9, 1e-9));
  }
  [[nodiscard]] int of(const Vec2& p) const {
    if (roi_.contains(p)) return 0;
    const double dx = (p.x() - centre_.x()) / half_.x(), dy = (p.y() - centre_.y()) / half_.y();
    if (std::abs(dx) >= std::abs(dy)) return dx < 0.0 ? 1 : 2;
    return dy < 0.0 ? 3 : 4;
  }

 private:
  const RoiMask& roi_;
  Vec2 centre_, half_;
};

/// A weight over the square, continuous: per raster cell base + w_roi · roi, both blurred by a box of
/// `radius` cells (so E below is continuous in the sample positions), read bilinearly.
class WeightField {
 public:
  WeightField(const RoiMask& grown, const Regions& regions, const std::array<double, 5>& weight, std::uint32_t radius)
      : size_(grown.size), base_(std::size_t{size_} * size_), roi_(base_.size()) {
    for (std::uint32_t j = 0; j < size_; ++j)
      for (std::uint32_t i = 0; i < size_; ++i) {
        const std::size_t c = std::size_t{j} * size_ + i;
        const int r = regions.of(Vec2((i + 0.5) / size_, (j + 0.5) / size_));
        roi_[c] = r == 0 ? 1.0 : 0.0;
        base_[c] = r == 0 ? 0.0 : weight[static_cast<std::size_t>(r)];
      }
    blur(base_, radius);
    blur(roi_, radius);
  }
  void set_roi_weight(double w) { roi_weight_ = w; }
  [[nodiscard]] double at(const Vec2& p) const {
    const double x = std::clamp(p.x() * size_ - 0.5, 0.0, size_ - 1.0), y = std::clamp(p.y() * size_ - 0.5, 0.0, size_ - 1.0);
    const auto i = std::min(static_cast<std::uint32_t>(x), size_ - 2), j = std::min(static_cast<std::uint32_t>(y), size_ - 2);
    const double fx = x - i, fy = y - j;
    const auto v = [&](std::uint32_t a, std::uint32_t b) {
      const std::size_t c = std::size_t{b} * size_ + a;
      return base_[c] + roi_weight_ * roi_[c];
    };
    return (1 - fy) * ((1 - fx) * v(i, j) + fx * v(i + 1, j)) + fy * ((1 - fx) * v(i, j + 1) + fx * v(i + 1, j + 1));
  }

 private:
  void blur(std::vector<double>& f, std::uint32_t radius) const {
    std::vector<double> line(size_), prefix(size_ + 1);
    for (int pass = 0; pass < 2; ++pass)
      for (std::uint32_t a = 0; a < size_; ++a) {
        const auto idx = [&](std::uint32_t k) { return pass == 0 ? std::size_t{a} * size_ + k : std::size_t{k} * size_ + a; };
        for (std::uint32_t k = 0; k < size_; ++k) prefix[k + 1] = prefix[k] + f[idx(k)];
        for (std::uint32_t k = 0; k < size_; ++k) {
          const std::uint32_t lo = k >= radius ? k - radius : 0, hi = std::min(size_ - 1, k + radius);
          line[k] = (prefix[hi + 1] - prefix[lo]) / (hi + 1 - lo);
        }
        for (std::uint32_t k = 0; k < size_; ++k) f[idx(k)] = line[k];
      }
  }
  std::uint32_t size_;
  std::vector<double> base_, roi_;
  double roi_weight_{0.0};
};

/// `roi` grown by `cells` cells each way (a square structuring element: two sliding-window passes).
RoiMask dilated(const RoiMask& roi, std::uint32_t cells) {
  const std::uint32_t s = roi.size;
  RoiMask rows{s, std::vector<std::uint8_t>(roi.inside.size(), 0)}, out = rows;
  const auto pass = [&](const RoiMask& in, RoiMask& to, bool along_x) {
    for (std::uint32_t line = 0; line < s; ++line) {
      const auto at = [&](std::uint32_t k) -> std::size_t {
        return along_x ? std::size_t{line} * s + k : std::size_t{k} * s + line;
      };
      std::uint32_t last_inside = std::numeric_limits<std::uint32_t>::max();  // nearest inside cell at or before k
      for (std::uint32_t k = 0; k < s; ++k) {
        if (in.inside[at(k)]) last_inside = k;
        if (last_inside != std::numeric_limits<std::uint32_t>::max() && k - last_inside <= cells) to.inside[at(k)] = 1;
      }
      last_inside = std::numeric_limits<std::uint32_t>::max();
      for (std::uint32_t k = s; k-- > 0;) {
        if (in.inside[at(k)]) last_inside = k;
        if (last_inside != std::numeric_limits<std::uint32_t>::max() && last_inside - k <= cells) to.inside[at(k)] = 1;
      }
    }
  };
  pass(roi, rows, true);
  pass(rows, out, false);
  return out;
}

}  // namespace

bool RoiMask::contains(const Vec2& uv) const {
  if (size == 0) return false;
  return inside[std::size_t{cell_of(uv.y(), size)} * size + cell_of(uv.x(), size)] != 0;
}

std::size_t RoiMask::area_cells() const {
  return static_cast<std::size_t>(std::count_if(inside.begin(), inside.end(), [](std::uint8_t c) { return c != 0; }));
}

std::uint32_t roi_raster_size(std::uint32_t n) { return std::max<std::uint32_t>(1024, n > 1 ? 2 * (n - 1) : 2); }

RoiMask roi_from_vertices(MeshView disk, std::span<const Vec2> uv, std::span<const std::uint8_t> vertex_in,
                          std::uint32_t raster) {
  if (vertex_in.size() != disk.positions.size())
    throw InvalidInput(fmt::format("region of interest: {} flags for {} vertices", vertex_in.size(), disk.positions.size()));
  std::vector<std::uint8_t> face_in(disk.faces.size(), 0);
  for (std::size_t k = 0; k < face_in.size(); ++k) {
    const Face& f = disk.faces[k];
    face_in[k] = vertex_in[f[0]] || vertex_in[f[1]] || vertex_in[f[2]] ? 1 : 0;
  }
  return roi_from_faces(disk, uv, face_in, raster);
}

RoiMask roi_from_faces(MeshView disk, std::span<const Vec2> uv, std::span<const std::uint8_t> face_in, std::uint32_t raster) {
  if (uv.size() != disk.positions.size() || face_in.size() != disk.faces.size() || raster == 0)
    throw InvalidInput(fmt::format("region of interest: {} parameter points for {} vertices, {} flags for {} faces (raster {})",
                                   uv.size(), disk.positions.size(), face_in.size(), disk.faces.size(), raster));
  RoiMask m{raster, std::vector<std::uint8_t>(std::size_t{raster} * raster, 0)};
  const auto mark = [&](const Vec2& p) { m.inside[std::size_t{cell_of(p.y(), raster)} * raster + cell_of(p.x(), raster)] = 1; };
  for (std::size_t k = 0; k < disk.faces.size(); ++k) {
    if (!face_in[k]) continue;
    const Face& f = disk.faces[k];
    const Vec2 &a = uv[f[0]], &b = uv[f[1]], &c = uv[f[2]];
    mark(a), mark(b), mark(c), mark((a + b + c) / 3.0);
    const double area = cross2(a, b, c);
    if (!(std::abs(area) > 0.0)) continue;
    const Vec2 lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
    for (std::uint32_t j = cell_of(lo.y(), raster); j <= cell_of(hi.y(), raster); ++j)
      for (std::uint32_t i = cell_of(lo.x(), raster); i <= cell_of(hi.x(), raster); ++i) {
        const Vec2 p((i + 0.5) / raster, (j + 0.5) / raster);
        const double w0 = cross2(b, c, p) / area, w1 = cross2(c, a, p) / area, w2 = cross2(a, b, p) / area;
        if (w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0) m.inside[std::size_t{j} * raster + i] = 1;
      }
  }
  return m;
}

RoiMask roi_from_picture(std::uint32_t width, std::uint32_t height, std::span<const std::uint8_t> inside,
                         std::uint32_t raster) {
  if (width < 2 || height < 2 || inside.size() != std::size_t{width} * height || raster == 0)
    throw InvalidInput(fmt::format("region of interest: a {} × {} picture with {} pixels (at least 2 × 2 needed)",
                                   width, height, inside.size()));
  RoiMask m{raster, std::vector<std::uint8_t>(std::size_t{raster} * raster, 0)};
  for (std::uint32_t j = 0; j < raster; ++j)
    for (std::uint32_t i = 0; i < raster; ++i) {
      const double u = (i + 0.5) / raster, v = (j + 0.5) / raster;
      const auto x = static_cast<std::size_t>(std::lround(u * (width - 1)));
      const auto y = static_cast<std::size_t>(std::lround((1.0 - v) * (height - 1)));
      m.inside[std::size_t{j} * raster + i] = inside[y * width + x] != 0 ? 1 : 0;
    }
  return m;
}

RoiMask roi_auto(const ParametrizedSurface& surface, MeshView disk, std::uint32_t n, double fraction,
                 std::uint32_t raster) {
  if (n < 3 || !(fraction > 0.0 && fraction < 1.0) || raster == 0)
    throw InvalidInput(fmt::format("automatic region of interest: fraction {} is outside (0, 1) or size {} below 3",
                                   fraction, n));
  // The normal image of the uniform grid: each sample takes the normal of the face under it.
  std::vector<Vec3> normal(std::size_t{n} * n);
  for (std::uint32_t j = 0; j < n; ++j)
    for (std::uint32_t i = 0; i < n; ++i) {
      const Face& f = disk.faces[surface.at(Vec2(static_cast<double>(i) / (n - 1), static_cast<double>(j) / (n - 1))).face];
      const Vec3 nn = (disk.positions[f[1]] - disk.positions[f[0]]).cross(disk.positions[f[2]] - disk.positions[f[0]]);
      normal[std::size_t{j} * n + i] = nn.norm() > 0.0 ? Vec3(nn.normalized()) : Vec3::Zero();
    }
  // Summed-area table of the per-point variation.
  std::vector<double> sat(std::size_t{n + 1} * (n + 1), 0.0);
  for (std::uint32_t j = 0; j < n; ++j)
    for (std::uint32_t i = 0; i < n; ++i) {
      const Vec3& a = normal[std::size_t{j} * n + i];
      double v = 0.0;
      if (i > 0) v += 1.0 - a.dot(normal[std::size_t{j} * n + i - 1]);
      if (i + 1 < n) v += 1.0 - a.dot(normal[std::size_t{j} * n + i + 1]);
      if (j > 0) v += 1.0 - a.dot(normal[std::size_t{j - 1} * n + i]);
      if (j + 1 < n) v += 1.0 - a.dot(normal[std::size_t{j + 1} * n + i]);
      sat[std::size_t{j + 1} * (n + 1) + i + 1] =
          v + sat[std::size_t{j} * (n + 1) + i + 1] + sat[std::size_t{j + 1} * (n + 1) + i] - sat[std::size_t{j} * (n + 1) + i];
    }
  const auto k = std::clamp<std::uint32_t>(static_cast<std::uint32_t>(std::lround(std::sqrt(fraction) * (n - 1))) + 1, 2, n);
  double best = -1.0;
  std::uint32_t bi = 0, bj = 0;
  for (std::uint32_t j = 0; j + k <= n; ++j)
    for (std::uint32_t i = 0; i + k <= n; ++i) {
      const double s = sat[std::size_t{j + k} * (n + 1) + i + k] - sat[std::size_t{j} * (n + 1) + i + k] -
                       sat[std::size_t{j + k} * (n + 1) + i] + sat[std::size_t{j} * (n + 1) + i];
      if (s > best) best = s, bi = i, bj = j;
    }
  // The window spans its grid points and half a spacing around them (inside the square).
  const double h = 1.0 / (n - 1);
  const Vec2 lo(bi * h - 0.5 * h, bj * h - 0.5 * h), hi((bi + k - 1) * h + 0.5 * h, (bj + k - 1) * h + 0.5 * h);
  RoiMask m{raster, std::vector<std::uint8_t>(std::size_t{raster} * raster, 0)};
  for (std::uint32_t j = 0; j < raster; ++j)
    for (std::uint32_t i = 0; i < raster; ++i) {
      const Vec2 p((i + 0.5) / raster, (j + 0.5) / raster);
      if (p.x() >= lo.x() && p.x() <= hi.x() && p.y() >= lo.y() && p.y() <= hi.y()) m.inside[std::size_t{j} * raster + i] = 1;
    }
  return m;
}

std::uint64_t samples_in(const RoiMask& roi, std::span<const Vec2> sample_uv) {
  return static_cast<std::uint64_t>(
      std::count_if(sample_uv.begin(), sample_uv.end(), [&](const Vec2& p) { return roi.contains(p); }));
}

RoiEnhanceResult enhance_roi(std::span<const Vec2> disk_uv, std::uint32_t n, std::vector<Vec2> sample_uv,
                             const RoiMask& roi, const RoiEnhanceOptions& options) {
  if (n < 3 || sample_uv.size() != std::size_t{n} * n)
    throw InvalidInput(fmt::format("ROI enhancement: {} samples for a {} × {} grid", sample_uv.size(), n, n));
  if (!(options.gain >= 1.0) || !std::isfinite(options.gain))
    throw InvalidInput(fmt::format("ROI enhancement: gain {} is below 1", options.gain));
  if (roi.size < 2 || roi.inside.size() != std::size_t{roi.size} * roi.size)
    throw InvalidInput(fmt::format("ROI enhancement: a mask of {} cells for {} × {}", roi.inside.size(), roi.size, roi.size));
  if (roi.area_cells() == 0) throw InvalidInput("the region of interest is empty");
  // The weights take the ROI grown by kMargin uniform spacings, so that the dense grid covers all of the ROI
  // and the change of density happens outside it.
  const RoiMask grown = dilated(roi, static_cast<std::uint32_t>(std::ceil(kMargin * roi.size / (n - 1.0))));
  const Regions regions(grown);
  RoiEnhanceResult out;
  out.samples_before = samples_in(roi, sample_uv);
  out.target = static_cast<std::uint64_t>(std::ceil(options.gain * static_cast<double>(std::max<std::uint64_t>(out.samples_before, 1))));
  out.target = std::min<std::uint64_t>(out.target, std::uint64_t{n - 2} * (n - 2));
  // Weights of the four non-ROI regions by their surplus over n_ideal = (n_c / |V|) n².
  std::array<double, 5> vertices{}, samples{};
  for (const Vec2& p : disk_uv) vertices[static_cast<std::size_t>(regions.of(p))] += 1.0;
  for (const Vec2& p : sample_uv) samples[static_cast<std::size_t>(regions.of(p))] += 1.0;
  const double total = std::max<double>(1.0, static_cast<double>(disk_uv.size()));
  std::array<std::size_t, 4> order{0, 1, 2, 3};
  std::array<double, 4> surplus{};
  for (std::size_t r = 0; r < 4; ++r) surplus[r] = samples[r + 1] - vertices[r + 1] / total * n * n;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return surplus[a] > surplus[b]; });
  std::array<double, 5> weight{};
  for (std::size_t rank = 0; rank < 4; ++rank) weight[order[rank] + 1] = static_cast<double>(rank + 1);
  weight[0] = 8.0;
  const double h = 1.0 / (n - 1), shortest = kMinSide * h;
  const auto at = [&](const std::vector<Vec2>& grid, std::uint32_t i, std::uint32_t j) -> const Vec2& {
    return grid[std::size_t{j} * n + i];
  };
  // Every quad sound (grid_quad.h).
  const auto valid = [&](const std::vector<Vec2>& grid) {
    for (std::uint32_t j = 0; j + 1 < n; ++j)
      for (std::uint32_t i = 0; i + 1 < n; ++i) {
        const std::array<Vec2, 4> q{at(grid, i, j), at(grid, i + 1, j), at(grid, i + 1, j + 1), at(grid, i, j + 1)};
        if (!sound_quad(q, shortest)) return false;
      }
    return true;
  };
  // The fixed point of the 1-ring averages for all interior samples at once: each iteration freezes the
  // coefficients c_ij = w(p_j) ‖p_i − p_j‖ and solves Σ_j c_ij (p_i − p_j) = 0 (sparse LU; boundary fixed),
  // then steps kDamping of the way there (the frozen coefficients overshoot: undamped, the grid oscillates),
  // halved until no quad folds. (Sweeps of single moves spread a change of density by one sample per sweep:
  // the depleted band piles up next to the ROI.) The weights w(p) are the regions' blurred over a uniform
  // spacing (WeightField), so a sample crossing a region's edge does not jump.
  WeightField field(grown, regions, weight, std::max<std::uint32_t>(1, static_cast<std::uint32_t>(grown.size / (n - 1.0))));
  field.set_roi_weight(weight[0]);
  const std::uint32_t m = n - 2;  // interior samples per side
  const auto unknown = [m](std::uint32_t i, std::uint32_t j) { return static_cast<int>((j - 1) * m + (i - 1)); };
  const int unknowns = static_cast<int>(m * m);
  Eigen::SparseLU<Eigen::SparseMatrix<double>, Eigen::COLAMDOrdering<int>> solver;
  bool analyzed = false;
  std::vector<Eigen::Triplet<double>> triplets;
  std::uint64_t count = out.samples_before;
  double damping = kDamping, last_moved = std::numeric_limits<double>::infinity();
  std::uint64_t checkpoint = count;
  std::uint32_t since_checkpoint = 0;
  const bool needed = count < out.target;  // a ROI that holds its target already keeps the start grid
  while (needed && out.iterations < options.max_iterations) {
    ++out.iterations;
    triplets.clear();
    Eigen::MatrixX2d rhs = Eigen::MatrixX2d::Zero(unknowns, 2);
    for (std::uint32_t j = 1; j + 1 < n; ++j)
      for (std::uint32_t i = 1; i + 1 < n; ++i) {
        const int row = unknown(i, j);
        const Vec2& p0 = at(sample_uv, i, j);
        double diagonal = 0.0;
        for (int dj = -1; dj <= 1; ++dj)
          for (int di = -1; di <= 1; ++di) {
            if (di == 0 && dj == 0) continue;
            const auto ni = static_cast<std::uint32_t>(static_cast<int>(i) + di);
            const auto nj = static_cast<std::uint32_t>(static_cast<int>(j) + dj);
            const Vec2& q = at(sample_uv, ni, nj);
            const double c = field.at(q) * std::max((q - p0).norm(), 1e-6 * h);
            diagonal += c;
            if (ni == 0 || nj == 0 || ni == n - 1 || nj == n - 1)
              rhs.row(row) += c * q.transpose();
            else
              triplets.emplace_back(row, unknown(ni, nj), -c);
          }
        triplets.emplace_back(row, row, diagonal);
      }
    Eigen::SparseMatrix<double> a(unknowns, unknowns);
    a.setFromTriplets(triplets.begin(), triplets.end());
    a.makeCompressed();
    if (!analyzed) solver.analyzePattern(a), analyzed = true;  // the pattern stays: the grid's 1-rings
    solver.factorize(a);
    if (solver.info() != Eigen::Success) break;
    const Eigen::MatrixX2d solved = solver.solve(rhs);
    if (solver.info() != Eigen::Success || !solved.allFinite()) break;
    std::vector<Vec2> next = sample_uv;
    double moved = 0.0, t = damping;
    for (; t >= 1.0 / 256.0; t *= 0.5) {
      moved = 0.0;
      for (std::uint32_t j = 1; j + 1 < n; ++j)
        for (std::uint32_t i = 1; i + 1 < n; ++i) {
          const std::size_t s = std::size_t{j} * n + i;
          next[s] = sample_uv[s] + t * (Vec2(solved.row(unknown(i, j)).transpose()) - sample_uv[s]);
          moved = std::max(moved, (next[s] - sample_uv[s]).norm());
        }
      if (valid(next)) break;
    }
    if (t < 1.0 / 256.0)
      moved = 0.0;  // no step keeps the grid unfolded: settled where it is
    else
      sample_uv = next;
    count = samples_in(roi, sample_uv);
    // A step longer than the one before: the iteration overshoots, damp it more.
    if (moved > last_moved) damping = std::max(damping * 0.5, 1.0 / 32.0);
    last_moved = moved;
    if (count >= out.target && moved < kSettled * h) break;  // the ROI holds its target, the grid has settled
    // Still moving, and the ROI still gaining: go on.
    const bool stalled = ++since_checkpoint >= kStall &&
                         static_cast<double>(count - std::min(count, checkpoint)) < 0.01 * static_cast<double>(out.target - out.samples_before);
    if (since_checkpoint >= kStall) checkpoint = count, since_checkpoint = 0;
    if (moved >= kSettled * h && !stalled) continue;
    // Settled: done when the ROI holds its target; otherwise it pulls harder.
    if (count >= out.target || weight[0] >= 8.0 * 4096.0) break;
    weight[0] *= 2.0;
    field.set_roi_weight(weight[0]);
    damping = kDamping, last_moved = std::numeric_limits<double>::infinity();
    checkpoint = count, since_checkpoint = 0;
  }
  out.samples_after = count;
  out.roi_weight = weight[0];
  for (std::size_t r = 0; r < 4; ++r) out.region_weights[r] = weight[r + 1];
  out.sample_uv = std::move(sample_uv);
  return out;
}

void glue_flags(std::span<std::uint8_t> flags, std::span<const std::uint32_t> representative) {
  if (flags.size() != representative.size())
    throw InvalidInput(fmt::format("glued flags: {} flags and {} representatives", flags.size(), representative.size()));
  std::vector<std::uint8_t> any(flags.size(), 0);
  for (std::size_t k = 0; k < flags.size(); ++k) {
    if (representative[k] >= flags.size())
      throw InvalidInput(fmt::format("glued flags: representative {} of flag {} is out of range", representative[k], k));
    if (flags[k] != 0) any[representative[k]] = 1;
  }
  for (std::size_t k = 0; k < flags.size(); ++k) flags[k] = any[representative[k]];
}

}  // namespace gimforge
