#include "kernels/adaptive/strip_sampling.h"

#include <algorithm>
#include <array>
#include <queue>

#include <fmt/format.h>

#include "kernels/adaptive/grid_quad.h"
#include "kernels/core/errors.h"

namespace gimforge {
namespace {

/// One axis: strips of the sorted coordinates `c`, split at their midpoints until there are n − 1.
std::vector<double> equalize_axis(std::vector<double> c, std::uint32_t n) {
  std::sort(c.begin(), c.end());
  const std::uint32_t start = n / 2;
  struct Strip {
    double left, right;
    std::size_t count;
  };
  auto count_in = [&](double left, double right, bool last) {
    const auto lo = std::lower_bound(c.begin(), c.end(), left);
    const auto hi = last ? c.end() : std::lower_bound(c.begin(), c.end(), right);
    return static_cast<std::size_t>(hi - lo);
  };
  std::vector<Strip> strips;
  for (std::uint32_t i = 0; i < start; ++i) {
    const double left = static_cast<double>(i) / start;
    const double right = i + 1 == start ? 1.0 : static_cast<double>(i + 1) / start;
    strips.push_back({left, right, count_in(left, right, i + 1 == start)});
  }
  // The fullest strip is split first, among equals the lowest one: the strips stay sorted by position
  // and a heap of (count, -left) finds the fullest.
  using Entry = std::pair<std::size_t, double>;  // count, -left
  std::priority_queue<Entry> heap;
  for (const Strip& s : strips) heap.push({s.count, -s.left});
  // A strip is not split below a sixteenth of the uniform spacing: vertices that share one coordinate
  // would otherwise draw strips of zero width.
  const double narrowest = 1.0 / (16.0 * (n - 1));
  while (strips.size() < n - 1 && !heap.empty()) {
    const Entry top = heap.top();
    heap.pop();
    const double left = -top.second;
    auto it = std::lower_bound(strips.begin(), strips.end(), left, [](const Strip& s, double x) { return s.left < x; });
    const Strip s = *it;
    if (s.right - s.left < 2.0 * narrowest) continue;
    const bool last = s.right >= 1.0;
    const double mid = 0.5 * (s.left + s.right);
    const Strip a{s.left, mid, count_in(s.left, mid, false)};
    const Strip b{mid, s.right, count_in(mid, s.right, last)};
    *it = a;
    strips.insert(it + 1, b);
    heap.push({a.count, -a.left});
    heap.push({b.count, -b.left});
  }
  std::vector<double> lines;
  lines.reserve(n);
  for (const Strip& s : strips) lines.push_back(s.left);
  lines.push_back(1.0);
  return lines;
}

}  // namespace

StripLines equalized_strips(std::span<const Vec2> points, std::uint32_t n) {
  if (n < 3) throw InvalidInput(fmt::format("strip sampling: size {} is below 3", n));
  // Points on a side of the square (a boundary vertex on x = 0 has no place among the x-strips: it
  // would pull them all to the side, where the samples stay on the uniform perimeter grid anyway).
  std::vector<double> xs, ys;
  for (const Vec2& p : points) {
    if (p.x() > 0.0 && p.x() < 1.0) xs.push_back(p.x());
    if (p.y() > 0.0 && p.y() < 1.0) ys.push_back(p.y());
  }
  return {equalize_axis(std::move(xs), n), equalize_axis(std::move(ys), n)};
}

std::vector<Vec2> strip_sample_grid(const StripLines& lines) {
  const std::size_t n = lines.x.size();
  if (n < 2 || lines.y.size() != n)
    throw InvalidInput(fmt::format("strip sampling: {} x-lines and {} y-lines", lines.x.size(), lines.y.size()));
  const double step = 1.0 / static_cast<double>(n - 1);
  const double band = std::max(2.0, static_cast<double>(n - 1) / 8.0);
  std::vector<double> weight(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double t = std::min(1.0, static_cast<double>(std::min(k, n - 1 - k)) / band);
    weight[k] = t * t * (3.0 - 2.0 * t);  // smoothstep
  }
  // The blend shears the quads of the band; where strips are very uneven next to a side, a quad could
  // turn non-convex. The strips' pull is then scaled down (halved until every quad is sound, grid_quad.h;
  // at 0 the grid is the uniform one).
  std::vector<Vec2> grid(n * n);
  for (double pull = 1.0;; pull *= 0.5) {
    if (pull < 1e-3) pull = 0.0;
    for (std::size_t j = 0; j < n; ++j)
      for (std::size_t i = 0; i < n; ++i) {
        const double u = static_cast<double>(i) * step, v = static_cast<double>(j) * step;
        grid[j * n + i] = Vec2(u + pull * weight[j] * (lines.x[i] - u), v + pull * weight[i] * (lines.y[j] - v));
      }
    bool convex = true;
    for (std::size_t j = 0; j + 1 < n && convex; ++j)
      for (std::size_t i = 0; i + 1 < n && convex; ++i) {
        const std::array<Vec2, 4> q{grid[j * n + i], grid[j * n + i + 1], grid[(j + 1) * n + i + 1], grid[(j + 1) * n + i]};
        convex = sound_quad(q, 0.0);
      }
    if (convex || pull == 0.0) return grid;
  }
}

}  // namespace gimforge
