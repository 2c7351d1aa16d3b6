/// \file mcgim_fuse.cpp
/// Fusing the zipper of a decoded multi-chart geometry image (see mcgim_fuse.h).
#include "kernels/mcgim/mcgim_fuse.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include <Eigen/Dense>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge {
namespace {

void check_sizes(const MultiChartImage& image, std::size_t displacements, const char* what) {
  const std::size_t n = image.samples();
  if (image.positions.size() != 3 * n || image.mask.size() != n || image.unified.size() != n || image.chart.size() != n ||
      (displacements != 0 && displacements != n))
    throw InvalidInput(fmt::format("{}: the image's arrays do not match its {} × {} samples", what, image.width, image.height));
}

Vec3 at(const std::vector<float>& xyz, std::size_t s) { return {xyz[3 * s], xyz[3 * s + 1], xyz[3 * s + 2]}; }

}  // namespace

ZipperFuseStats fuse_zipper(MultiChartImage& image, std::vector<Vec3>& displacement) {
  check_sizes(image, 0, "fusing the zipper");
  const std::size_t n = image.samples();
  std::vector<Vec3> sum(n, Vec3::Zero());
  std::vector<std::uint32_t> count(n, 0);
  for (std::size_t s = 0; s < n; ++s) {
    if (image.mask[s] == 0) continue;
    const std::uint32_t r = image.unified[s];
    if (r >= n || image.mask[r] == 0)
      throw InvalidInput(fmt::format("fusing the zipper: sample {} names representative {}, not a defined sample", s, r));
    sum[r] += at(image.positions, s);
    ++count[r];
  }
  displacement.assign(n, Vec3::Zero());
  ZipperFuseStats stats;
  for (std::size_t s = 0; s < n; ++s) {
    if (image.mask[s] == 0) continue;
    const std::uint32_t r = image.unified[s];
    if (count[r] < 2) continue;
    if (r == s) ++stats.clusters;
    const Vec3 mean = sum[r] / static_cast<double>(count[r]);
    const Vec3 stored(static_cast<float>(mean.x()), static_cast<float>(mean.y()), static_cast<float>(mean.z()));
    displacement[s] = stored - at(image.positions, s);
    for (Eigen::Index c = 0; c < 3; ++c) image.positions[3 * s + static_cast<std::size_t>(c)] = static_cast<float>(stored[c]);
    stats.max_displacement = std::max(stats.max_displacement, displacement[s].norm());
  }
  return stats;
}

namespace {

/// The basis of a chart's map at (column, row) relative to the chart's centre: 1, x, y, x², xy, y².
constexpr std::size_t kBasis = 6;
Eigen::Matrix<double, kBasis, 1> basis(double x, double y) {
  Eigen::Matrix<double, kBasis, 1> u;
  u << 1.0, x, y, x * x, x * y, y * y;
  return u;
}

}  // namespace

std::vector<float> chart_planes(const MultiChartImage& image, std::uint32_t charts) {
  check_sizes(image, 0, "chart planes");
  using Normal = Eigen::Matrix<double, kBasis, kBasis>;
  using Right = Eigen::Matrix<double, kBasis, 3>;
  std::vector<Normal> ata(charts, Normal::Zero());
  std::vector<Right> atb(charts, Right::Zero());
  std::vector<Eigen::Vector2d> centre(charts, Eigen::Vector2d::Zero());
  std::vector<double> count(charts, 0.0);
  for (std::size_t s = 0; s < image.samples(); ++s) {
    if (!image.mask[s]) continue;
    const std::uint32_t c = image.chart[s];
    if (c >= charts) throw InvalidInput(fmt::format("chart planes: sample {} is in chart {} of {}", s, c, charts));
    centre[c] += Eigen::Vector2d(static_cast<double>(s % image.width), static_cast<double>(s / image.width));
    count[c] += 1.0;
  }
  for (std::uint32_t c = 0; c < charts; ++c)
    if (count[c] > 0.0) centre[c] = (centre[c] / count[c]).array().round();  // integral: exact differences below
  for (std::size_t s = 0; s < image.samples(); ++s) {
    if (!image.mask[s]) continue;
    const std::uint32_t c = image.chart[s];
    const auto u = basis(static_cast<double>(s % image.width) - centre[c].x(), static_cast<double>(s / image.width) - centre[c].y());
    ata[c] += u * u.transpose();
    atb[c] += u * at(image.positions, s).transpose();
  }
  // Per chart: centre (x, y), then the kBasis coefficients of each axis.
  std::vector<float> planes(kPlaneFloats * std::size_t{charts}, 0.0f);
  for (std::uint32_t c = 0; c < charts; ++c) {
    if (count[c] == 0.0) continue;
    Right coef = Right::Zero();
    const Eigen::LDLT<Normal> ldlt(ata[c]);
    const Right solved = ldlt.solve(atb[c]);
    const bool fitted = count[c] >= 2.0 * kBasis && ldlt.info() == Eigen::Success && ldlt.isPositive() &&
                        solved.allFinite() && (ata[c] * solved - atb[c]).norm() <= 1e-6 * (atb[c].norm() + 1e-30);
    if (fitted)
      coef = solved;
    else
      coef.row(0) = atb[c].row(0) / count[c];  // the mean
    float* out = &planes[kPlaneFloats * std::size_t{c}];
    out[0] = static_cast<float>(centre[c].x());
    out[1] = static_cast<float>(centre[c].y());
    for (Eigen::Index a = 0; a < 3; ++a)
      for (Eigen::Index k = 0; k < static_cast<Eigen::Index>(kBasis); ++k)
        out[2 + static_cast<std::size_t>(a) * kBasis + static_cast<std::size_t>(k)] = static_cast<float>(coef(k, a));
  }
  return planes;
}

void apply_chart_planes(std::vector<float>& positions, const MultiChartImage& image, const std::vector<float>& planes,
                        int sign) {
  const std::size_t n = image.samples();
  if (positions.size() != 3 * n || image.mask.size() != n || image.chart.size() != n || planes.size() % kPlaneFloats != 0)
    throw InvalidInput(fmt::format("chart planes: arrays that do not match {} × {} samples", image.width, image.height));
  const std::size_t charts = planes.size() / kPlaneFloats;
  for (std::size_t s = 0; s < n; ++s) {
    if (!image.mask[s]) continue;
    const std::size_t c = image.chart[s];
    if (c >= charts) throw InvalidInput(fmt::format("chart planes: sample {} is in chart {} of {}", s, c, charts));
    const float* p = &planes[kPlaneFloats * c];
    const auto u = basis(static_cast<double>(s % image.width) - double{p[0]}, static_cast<double>(s / image.width) - double{p[1]});
    for (std::size_t a = 0; a < 3; ++a) {
      double value = 0.0;
      for (std::size_t k = 0; k < kBasis; ++k) value += double{p[2 + a * kBasis + k]} * u[static_cast<Eigen::Index>(k)];
      const double sum = double{positions[3 * s + a]} + sign * value;
      if (std::abs(sum) > double{std::numeric_limits<float>::max()})
        throw InvalidInput(fmt::format("chart planes: sample {} of chart {} leaves float32 ({:g})", s, c, sum));
      positions[3 * s + a] = static_cast<float>(sum);
    }
  }
}

void restore_decoded_multichart(MultiChartImage& image, const std::vector<float>& planes) {
  check_sizes(image, 0, "decoded multi-chart image");
  for (std::size_t s = 0; s < image.samples(); ++s)
    if (image.mask[s] == 0)
      image.positions[3 * s] = image.positions[3 * s + 1] = image.positions[3 * s + 2] = std::numeric_limits<float>::quiet_NaN();
  apply_chart_planes(image.positions, image, planes, +1);
  std::vector<Vec3> displacement;
  (void)fuse_zipper(image, displacement);
  diffuse_zipper_fusing(image, displacement);
}

void diffuse_zipper_fusing(MultiChartImage& image, const std::vector<Vec3>& displacement, std::uint32_t band) {
  check_sizes(image, displacement.size(), "error diffusion");
  const std::size_t n = image.samples();
  if (displacement.empty()) return;
  // Which samples are clustered (more than one member): they keep their fused values.
  std::vector<std::uint32_t> members(n, 0);
  for (std::size_t s = 0; s < n; ++s) {
    if (!image.mask[s]) continue;
    if (image.unified[s] >= n) throw InvalidInput(fmt::format("error diffusion: sample {} names no representative", s));
    ++members[image.unified[s]];
  }
  const auto clustered = [&](std::size_t s) { return image.mask[s] != 0 && members[image.unified[s]] > 1; };
  if (band == 0) {
    std::set<std::uint32_t> charts;
    std::size_t defined = 0;
    for (std::size_t s = 0; s < n; ++s)
      if (image.mask[s]) ++defined, charts.insert(image.chart[s]);
    const double side = charts.empty() ? 0.0 : std::sqrt(static_cast<double>(defined) / static_cast<double>(charts.size()));
    band = std::max<std::uint32_t>(2, static_cast<std::uint32_t>(std::lround(side / 8.0)));
  }
  band = std::min<std::uint32_t>(band, 64);
  // One breadth-first walk from all fused samples at once, inside their charts, over unclustered samples:
  // every sample within band − 1 steps takes the displacement of the fused sample that reaches it first (the
  // nearest), weighted (1 − d/band)². Linear in the samples whatever the zipper holds.
  constexpr std::uint32_t kUnreached = 0xffffffffu;
  std::vector<std::uint32_t> source(n, kUnreached);
  std::vector<std::uint32_t> frontier, next;
  for (std::size_t s = 0; s < n; ++s)
    if (clustered(s) && !displacement[s].isZero(0.0)) {
      source[s] = static_cast<std::uint32_t>(s);
      frontier.push_back(static_cast<std::uint32_t>(s));
    }
  const std::int64_t w = image.width, h = image.height;
  for (std::uint32_t d = 1; d < band && !frontier.empty(); ++d) {
    const double t = 1.0 - static_cast<double>(d) / band, weight = t * t;
    next.clear();
    for (const std::uint32_t s : frontier) {
      const std::int64_t x = s % image.width, y = s / image.width;
      const std::int64_t around[4][2] = {{x - 1, y}, {x + 1, y}, {x, y - 1}, {x, y + 1}};
      for (const auto& q : around) {
        if (q[0] < 0 || q[1] < 0 || q[0] >= w || q[1] >= h) continue;
        const auto u = static_cast<std::size_t>(q[1] * w + q[0]);
        if (source[u] != kUnreached || image.mask[u] == 0 || image.chart[u] != image.chart[s] || clustered(u)) continue;
        source[u] = source[s];
        for (Eigen::Index c = 0; c < 3; ++c) {
          float& v = image.positions[3 * u + static_cast<std::size_t>(c)];
          v = static_cast<float>(double{v} + weight * displacement[source[s]][c]);
        }
        next.push_back(static_cast<std::uint32_t>(u));
      }
    }
    frontier.swap(next);
  }
}

}  // namespace gimforge
