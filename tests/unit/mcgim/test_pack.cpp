// Chart packing (Sander et al. 2003, §4.3): gutters, rectangle bounds, scale search, orientations, errors.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <sstream>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

#include "kernels/core/errors.h"
#include "kernels/mcgim/pack.h"

namespace gimforge {
namespace {

struct Pt {
  double x;
  double y;
};
using Polygon = std::vector<Pt>;

/// Distance from (px, py) to the segment a–b.
double segment_distance(double px, double py, Pt a, Pt b) {
  const double dx = b.x - a.x;
  const double dy = b.y - a.y;
  const double len2 = dx * dx + dy * dy;
  const double t = len2 > 0.0 ? std::clamp(((px - a.x) * dx + (py - a.y) * dy) / len2, 0.0, 1.0) : 0.0;
  return std::hypot(px - a.x - t * dx, py - a.y - t * dy);
}

/// Rasterizes `poly` rotated by `angle` and scaled by `scale` like the sampling does: a cell is defined when
/// its centre is inside the polygon (even-odd) or within 0.5 of its boundary. The lowest-left corner of the
/// bounding box sits on a cell centre, so every polygon gets at least one cell. Returns the tight shape.
ChartShape rasterize(const Polygon& poly, double angle, double scale) {
  if (poly.empty()) return {};
  Polygon q;
  q.reserve(poly.size());
  const double c = std::cos(angle);
  const double s = std::sin(angle);
  for (const Pt& p : poly) q.push_back({scale * (c * p.x - s * p.y), scale * (s * p.x + c * p.y)});
  double minx = q[0].x, miny = q[0].y, maxx = q[0].x, maxy = q[0].y;
  for (const Pt& p : q) {
    minx = std::min(minx, p.x), miny = std::min(miny, p.y);
    maxx = std::max(maxx, p.x), maxy = std::max(maxy, p.y);
  }
  for (Pt& p : q) p = {p.x - minx + 1.5, p.y - miny + 1.5};
  const auto gw = static_cast<std::uint32_t>(std::ceil(maxx - minx) + 4);
  const auto gh = static_cast<std::uint32_t>(std::ceil(maxy - miny) + 4);
  std::vector<std::uint8_t> grid(std::size_t{gw} * gh, 0);
  for (std::uint32_t j = 0; j < gh; ++j) {  // interior by scanlines through the cell centres
    const double yc = j + 0.5;
    std::vector<double> xs;
    for (std::size_t e = 0; e < q.size(); ++e) {
      const Pt a = q[e];
      const Pt b = q[(e + 1) % q.size()];
      if ((a.y <= yc) != (b.y <= yc)) xs.push_back(a.x + (yc - a.y) / (b.y - a.y) * (b.x - a.x));
    }
    std::sort(xs.begin(), xs.end());
    for (std::size_t k = 0; k + 1 < xs.size(); k += 2)
      for (std::uint32_t i = 0; i < gw; ++i)
        if (i + 0.5 >= xs[k] && i + 0.5 <= xs[k + 1]) grid[std::size_t{j} * gw + i] = 1;
  }
  for (std::size_t e = 0; e < q.size(); ++e) {  // boundary band of half a cell
    const Pt a = q[e];
    const Pt b = q[(e + 1) % q.size()];
    const auto i0 = static_cast<std::uint32_t>(std::max(0.0, std::floor(std::min(a.x, b.x) - 1)));
    const auto i1 = std::min(gw - 1, static_cast<std::uint32_t>(std::ceil(std::max(a.x, b.x) + 1)));
    const auto j0 = static_cast<std::uint32_t>(std::max(0.0, std::floor(std::min(a.y, b.y) - 1)));
    const auto j1 = std::min(gh - 1, static_cast<std::uint32_t>(std::ceil(std::max(a.y, b.y) + 1)));
    for (std::uint32_t j = j0; j <= j1; ++j)
      for (std::uint32_t i = i0; i <= i1; ++i)
        if (segment_distance(i + 0.5, j + 0.5, a, b) <= 0.5) grid[std::size_t{j} * gw + i] = 1;
  }
  std::uint32_t x0 = gw, y0 = gh, x1 = 0, y1 = 0;
  for (std::uint32_t j = 0; j < gh; ++j)
    for (std::uint32_t i = 0; i < gw; ++i)
      if (grid[std::size_t{j} * gw + i]) x0 = std::min(x0, i), y0 = std::min(y0, j), x1 = std::max(x1, i), y1 = std::max(y1, j);
  ChartShape out;
  if (x0 > x1) return out;
  out.width = x1 - x0 + 1;
  out.height = y1 - y0 + 1;
  out.cells.resize(std::size_t{out.width} * out.height);
  for (std::uint32_t j = 0; j < out.height; ++j)
    for (std::uint32_t i = 0; i < out.width; ++i)
      out.cells[std::size_t{j} * out.width + i] = grid[std::size_t{j + y0} * gw + i + x0];
  return out;
}

Polygon rectangle(double w, double h) { return {{0, 0}, {w, 0}, {w, h}, {0, h}}; }

Polygon ellipse(double rx, double ry, int segments = 48) {
  Polygon p;
  for (int i = 0; i < segments; ++i) {
    const double t = 2.0 * std::numbers::pi * i / segments;
    p.push_back({rx * std::cos(t), ry * std::sin(t)});
  }
  return p;
}

Polygon l_shape(double a, double t) { return {{0, 0}, {a, 0}, {a, t}, {t, t}, {t, a}, {0, a}}; }

/// An annulus (radii r, R) with a notch of `gap` radians cut out: a C-shaped simple polygon.
Polygon notched_ring(double r, double big_r, double gap, int segments = 40) {
  Polygon p;
  const double start = gap / 2;
  const double span = 2.0 * std::numbers::pi - gap;
  for (int i = 0; i <= segments; ++i) {
    const double t = start + span * i / segments;
    p.push_back({big_r * std::cos(t), big_r * std::sin(t)});
  }
  for (int i = segments; i >= 0; --i) {
    const double t = start + span * i / segments;
    p.push_back({r * std::cos(t), r * std::sin(t)});
  }
  return p;
}

/// A bar of length `len` and thickness `t` along the direction `angle`.
Polygon bar(double len, double t, double angle) {
  Polygon p;
  const double c = std::cos(angle), s = std::sin(angle);
  for (const Pt& v : rectangle(len, t)) p.push_back({c * v.x - s * v.y, s * v.x + c * v.y});
  return p;
}

double polygon_area(const Polygon& p) {
  double a = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Pt u = p[i], v = p[(i + 1) % p.size()];
    a += u.x * v.y - v.x * u.y;
  }
  return std::abs(a) / 2.0;
}

/// A ShapeSource rasterizing `charts` rotated by orientation · 2π / orientations.
ShapeSource polygon_source(const std::vector<Polygon>& charts, int orientations) {
  return [charts, orientations](std::size_t chart, int orientation, double scale) {
    return rasterize(charts[chart], 2.0 * std::numbers::pi * orientation / orientations, scale);
  };
}

/// The scale at which the charts' area equals `samples` (the paper's 100 % efficiency start).
double full_efficiency_scale(const std::vector<Polygon>& charts, std::size_t samples) {
  double area = 0.0;
  for (const Polygon& p : charts) area += polygon_area(p);
  return std::sqrt(static_cast<double>(samples) / area);
}

/// Paints every placement into a label image and checks bounds, gutters, the area and aspect bounds and
/// the cell count. Returns the painted cells.
std::size_t expect_valid(const Packing& pk, const ShapeSource& source, std::size_t num_charts, const PackOptions& opt) {
  EXPECT_EQ(pk.placements.size(), num_charts);
  EXPECT_LE(std::size_t{pk.width} * pk.height, opt.max_samples);
  if (pk.width > 0 && pk.height > 0) {
    EXPECT_LT(double(pk.width) / pk.height, opt.max_aspect);
    EXPECT_LT(double(pk.height) / pk.width, opt.max_aspect);
  }
  std::vector<int> label(std::size_t{pk.width} * pk.height, -1);
  std::size_t painted = 0;
  for (std::size_t c = 0; c < pk.placements.size(); ++c) {
    const Placement& pl = pk.placements[c];
    EXPECT_GE(pl.orientation, 0);
    EXPECT_LT(pl.orientation, opt.orientations);
    const ChartShape s = source(c, pl.orientation, pk.scale);
    for (std::uint32_t j = 0; j < s.height; ++j)
      for (std::uint32_t i = 0; i < s.width; ++i) {
        if (!s.at(i, j)) continue;
        const std::uint32_t x = pl.x + i, y = pl.y + j;
        if (x >= pk.width || y >= pk.height) {
          ADD_FAILURE() << "chart " << c << " cell (" << x << ", " << y << ") outside " << pk.width << "x" << pk.height;
          return painted;
        }
        int& l = label[std::size_t{y} * pk.width + x];
        EXPECT_EQ(l, -1) << "charts " << l << " and " << c << " overlap at (" << x << ", " << y << ")";
        l = static_cast<int>(c);
        ++painted;
      }
  }
  for (std::uint32_t y = 0; y + 1 < pk.height; ++y)  // no 2×2 quad holds cells of two charts
    for (std::uint32_t x = 0; x + 1 < pk.width; ++x) {
      int seen = -1;
      for (std::uint32_t k = 0; k < 4; ++k) {
        const int l = label[std::size_t{y + k / 2} * pk.width + x + k % 2];
        if (l < 0) continue;
        if (seen >= 0 && l != seen) {
          ADD_FAILURE() << "charts " << seen << " and " << l << " touch at quad (" << x << ", " << y << ")";
          return painted;
        }
        seen = l;
      }
    }
  EXPECT_EQ(pk.defined_samples, painted);
  if (pk.width > 0) {
    EXPECT_DOUBLE_EQ(pk.efficiency(), double(painted) / (double(pk.width) * pk.height));
  }
  return painted;
}

std::vector<Polygon> mixed_charts() {
  std::vector<Polygon> charts;
  for (int i = 0; i < 5; ++i) charts.push_back(ellipse(1.0 + 0.3 * i, 0.6 + 0.2 * i));
  for (int i = 0; i < 4; ++i) charts.push_back(ellipse(0.8 + 0.25 * i, 0.8 + 0.25 * i));
  for (int i = 0; i < 3; ++i) charts.push_back(l_shape(2.0 + 0.5 * i, 0.7));
  for (int i = 0; i < 3; ++i) charts.push_back(notched_ring(0.8 + 0.2 * i, 1.5 + 0.3 * i, 0.6));
  for (int i = 0; i < 4; ++i) charts.push_back(rectangle(0.5 + 0.4 * i, 2.5 - 0.3 * i));
  return charts;
}

TEST(Pack, MixedShapesKeepGuttersAndBounds) {
  const std::vector<Polygon> charts = mixed_charts();
  PackOptions opt;
  opt.max_samples = 16384;
  const ShapeSource source = polygon_source(charts, opt.orientations);
  const double start = full_efficiency_scale(charts, opt.max_samples);
  const Packing pk = pack_charts(charts.size(), start, source, opt);
  const std::size_t painted = expect_valid(pk, source, charts.size(), opt);
  EXPECT_GT(painted, 0u);
  EXPECT_GT(pk.scale_steps, 0);
  EXPECT_NEAR(pk.scale, start * std::pow(0.99, pk.scale_steps - pk.refined_steps), 1e-9 * start);
  EXPECT_GT(pk.efficiency(), 0.5);
}

TEST(Pack, RefinementRaisesTheScaleWithinTheLastStep) {
  // Bisecting between the answer and the step before it keeps the step search's answer, never lowers the
  // scale, stays below the step that failed, and gives valid packings; on some budget it gains.
  const std::vector<Polygon> charts = mixed_charts();
  int gained = 0;
  for (const std::size_t samples : {6000u, 9000u}) {
    PackOptions plain;
    plain.max_samples = samples;
    plain.refine_levels = 0;
    const ShapeSource source = polygon_source(charts, plain.orientations);
    const double start = full_efficiency_scale(charts, samples);
    const Packing a = pack_charts(charts.size(), start, source, plain);
    EXPECT_EQ(a.refined_steps, 0.0);
    for (const int levels : {1, 2}) {
      PackOptions refined = plain;
      refined.refine_levels = levels;
      const Packing b = pack_charts(charts.size(), start, source, refined);
      expect_valid(b, source, charts.size(), refined);
      EXPECT_EQ(b.scale_steps, a.scale_steps) << samples;
      EXPECT_GE(b.scale, a.scale) << samples;
      EXPECT_LT(b.scale, start * std::pow(0.99, a.scale_steps - 1)) << samples;
      EXPECT_NEAR(b.scale, start * std::pow(0.99, b.scale_steps - b.refined_steps), 1e-9 * start);
      EXPECT_LE(b.width * std::size_t{b.height}, samples);
      if (b.refined_steps > 0.0) ++gained;
    }
  }
  EXPECT_GT(gained, 0);
}

TEST(Pack, OrderRestartsNeverLoseAStepAndStayValid) {
  // The perturbed chart orders only ever move the answer up a step (a larger scale) and give a valid
  // packing; on one of these budgets one of them packs where largest first did not.
  const std::vector<Polygon> charts = mixed_charts();
  int gained = 0;
  for (const std::size_t samples : {6000u, 9000u}) {  // 9000: 28 steps largest first, 26 with restarts
    PackOptions plain;
    plain.max_samples = samples;
    plain.order_restarts = 0;
    PackOptions restarts = plain;
    restarts.order_restarts = 8;
    const ShapeSource source = polygon_source(charts, plain.orientations);
    const double start = full_efficiency_scale(charts, samples);
    const Packing a = pack_charts(charts.size(), start, source, plain);
    const Packing b = pack_charts(charts.size(), start, source, restarts);
    expect_valid(b, source, charts.size(), restarts);
    EXPECT_LE(b.scale_steps, a.scale_steps) << samples;
    if (b.scale_steps < a.scale_steps) ++gained;
  }
  EXPECT_GT(gained, 0);
}

TEST(Pack, FirstStepChangesOnlyTheSearch) {
  // Starting the step search at, above or below the answer gives the same packing (the search assumes
  // monotone packability; these charts have it around the answer) with fewer shapes asked for near it.
  const std::vector<Polygon> charts = mixed_charts();
  PackOptions opt;
  opt.max_samples = 12000;
  opt.order_restarts = 0;
  const ShapeSource inner = polygon_source(charts, opt.orientations);
  int calls = 0;
  double largest = 0.0;  // the largest scale asked for
  const ShapeSource counting = [&](std::size_t c, int o, double scale) {
    ++calls;
    largest = std::max(largest, scale);
    return inner(c, o, scale);
  };
  const double start = full_efficiency_scale(charts, opt.max_samples);
  const Packing from_zero = pack_charts(charts.size(), start, counting, opt);
  const int calls_from_zero = std::exchange(calls, 0);
  ASSERT_GT(from_zero.scale_steps, 4);
  for (const int first : {from_zero.scale_steps, from_zero.scale_steps - 3, from_zero.scale_steps + 9}) {
    opt.first_step = first;
    const Packing p = pack_charts(charts.size(), start, counting, opt);
    EXPECT_EQ(p.scale_steps, from_zero.scale_steps) << first;
    EXPECT_EQ(p.width, from_zero.width) << first;
    EXPECT_EQ(p.height, from_zero.height) << first;
    for (std::size_t c = 0; c < charts.size(); ++c) {
      EXPECT_EQ(p.placements[c].x, from_zero.placements[c].x) << first << " chart " << c;
      EXPECT_EQ(p.placements[c].orientation, from_zero.placements[c].orientation) << first << " chart " << c;
    }
    if (first == from_zero.scale_steps) {
      EXPECT_LT(calls, calls_from_zero);
    }
    calls = 0;
  }
  // The steps below min_step are never rasterized (a caller found a chart too long there); the answer stays
  // while min_step does not exceed it. Beyond max_scale_steps: refused at once, naming the sliver.
  opt.first_step = 0;
  opt.min_step = from_zero.scale_steps - 2;
  largest = 0.0;
  const Packing p = pack_charts(charts.size(), start, counting, opt);
  EXPECT_EQ(p.scale_steps, from_zero.scale_steps);
  EXPECT_EQ(p.width, from_zero.width);
  EXPECT_EQ(p.height, from_zero.height);
  EXPECT_LE(largest, start * std::pow(1.0 - opt.scale_step, opt.min_step) * (1.0 + 1e-12));
  opt.min_step = opt.max_scale_steps + 1;
  try {
    (void)pack_charts(charts.size(), start, counting, opt);
    ADD_FAILURE() << "no exception";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("longer than any rectangle"), std::string::npos) << e.what();
  }
}

TEST(Pack, RepeatedOrientationsAreSkipped) {
  // Charts whose 16 orientations all have the same cells pack exactly as with one orientation: the repeats
  // add no candidates (with them, copies of the best positions would crowd the others out of the
  // touching-perimeter re-ranking).
  const std::vector<Polygon> charts = mixed_charts();
  const ShapeSource one = polygon_source(charts, 1);
  const ShapeSource repeated = [&](std::size_t c, int, double scale) { return one(c, 0, scale); };
  PackOptions opt;
  opt.max_samples = 12000;
  const double start = full_efficiency_scale(charts, opt.max_samples);
  const Packing all = pack_charts(charts.size(), start, repeated, opt);
  opt.orientations = 1;
  const Packing single = pack_charts(charts.size(), start, one, opt);
  EXPECT_EQ(all.scale_steps, single.scale_steps);
  EXPECT_EQ(all.width, single.width);
  EXPECT_EQ(all.height, single.height);
  for (std::size_t c = 0; c < charts.size(); ++c) {
    EXPECT_EQ(all.placements[c].orientation, 0) << c;
    EXPECT_EQ(all.placements[c].x, single.placements[c].x) << c;
    EXPECT_EQ(all.placements[c].y, single.placements[c].y) << c;
  }
}

TEST(Pack, RestartIfSeesThePlainPackingAndCanSkipTheRestarts) {
  // At 9000 samples the restarts gain steps over largest first (OrderRestartsNeverLoseAStepAndStayValid).
  const std::vector<Polygon> charts = mixed_charts();
  PackOptions opt;
  opt.max_samples = 9000;
  const ShapeSource source = polygon_source(charts, opt.orientations);
  const double start = full_efficiency_scale(charts, opt.max_samples);
  const Packing with_restarts = pack_charts(charts.size(), start, source, opt);
  int seen = -1;
  opt.restart_if = [&](const Packing& p) {
    seen = p.scale_steps;
    return false;
  };
  const Packing skipped = pack_charts(charts.size(), start, source, opt);
  EXPECT_EQ(skipped.scale_steps, seen);
  EXPECT_GT(skipped.scale_steps, with_restarts.scale_steps);
  expect_valid(skipped, source, charts.size(), opt);
  opt.restart_if = [&](const Packing& p) { return p.scale_steps == seen; };
  EXPECT_EQ(pack_charts(charts.size(), start, source, opt).scale_steps, with_restarts.scale_steps);
}

TEST(Pack, TwoSquaresExactLayout) {
  // Squares of side ⌊3·scale⌋ in a budget of 21 samples: 3×7 (stacked) and 7×3 tie; the narrower wins.
  const ShapeSource source = [](std::size_t, int, double scale) {
    const auto side = static_cast<std::uint32_t>(std::floor(3.0 * scale + 1e-9));
    return ChartShape{side, side, std::vector<std::uint8_t>(std::size_t{side} * side, 1)};
  };
  PackOptions opt;
  opt.max_samples = 21;
  const Packing pk = pack_charts(2, 1.0, source, opt);
  EXPECT_EQ(pk.scale_steps, 0);
  EXPECT_EQ(pk.width, 3u);
  EXPECT_EQ(pk.height, 7u);
  EXPECT_EQ(pk.placements[0].x, 0u);
  EXPECT_EQ(pk.placements[0].y, 0u);
  EXPECT_EQ(pk.placements[1].x, 0u);
  EXPECT_EQ(pk.placements[1].y, 4u);  // one undefined row between the charts
  EXPECT_EQ(pk.defined_samples, 18u);
  expect_valid(pk, source, 2, opt);
}

TEST(Pack, SmallChartGoesIntoTheHoleUnderAnOverhang) {
  // Chart 0 is a Γ: a 2-wide leg (rows 0–3) under a 9-wide bar (rows 4–5). In a budget of 9 × 6 samples the
  // 2 × 2 chart 1 fits only in the hole under the bar (rows −1..3 of columns 2..8 are free; with the gutter
  // it needs x ≥ 3 and y ≤ 1); a horizon packer would have to put it above the bar (height 9).
  const ShapeSource source = [](std::size_t chart, int, double) {
    if (chart == 1) return ChartShape{2, 2, std::vector<std::uint8_t>(4, 1)};
    ChartShape g{9, 6, std::vector<std::uint8_t>(54, 0)};
    for (std::uint32_t y = 0; y < 6; ++y)
      for (std::uint32_t x = 0; x < 9; ++x) g.cells[std::size_t{y} * 9 + x] = (y >= 4 || x < 2) ? 1 : 0;
    return g;
  };
  PackOptions opt;
  opt.max_samples = 54;
  opt.orientations = 1;
  const Packing pk = pack_charts(2, 1.0, source, opt);
  EXPECT_EQ(pk.scale_steps, 0);
  EXPECT_EQ(pk.width, 9u);
  EXPECT_EQ(pk.height, 6u);
  EXPECT_EQ(pk.placements[0].x, 0u);
  EXPECT_EQ(pk.placements[0].y, 0u);
  EXPECT_GE(pk.placements[1].x, 3u);
  EXPECT_LE(pk.placements[1].y, 1u);
  EXPECT_EQ(pk.defined_samples, 30u);
  expect_valid(pk, source, 2, opt);
}

TEST(Pack, SquareAtFullBudgetNeedsScaleSteps) {
  const std::vector<Polygon> charts{rectangle(1.0, 1.0)};
  PackOptions opt;
  opt.max_samples = 4096;
  const ShapeSource source = polygon_source(charts, opt.orientations);
  const Packing pk = pack_charts(1, full_efficiency_scale(charts, opt.max_samples), source, opt);
  EXPECT_GE(pk.scale_steps, 1);  // the boundary band makes the 64-unit square 65 cells wide at 100 %
  EXPECT_GT(pk.efficiency(), 0.8);
  expect_valid(pk, source, 1, opt);
}

TEST(Pack, ManySmallSquaresPackEfficiently) {
  const std::vector<Polygon> charts(64, rectangle(1.0, 1.0));
  PackOptions opt;
  opt.max_samples = 16384;
  const ShapeSource source = polygon_source(charts, opt.orientations);
  const Packing pk = pack_charts(charts.size(), full_efficiency_scale(charts, opt.max_samples), source, opt);
  EXPECT_GT(pk.efficiency(), 0.6);
  expect_valid(pk, source, charts.size(), opt);
}

TEST(Pack, OrientationsHelpDiagonalBars) {
  const std::vector<Polygon> charts(4, bar(1.0, 0.08, std::numbers::pi / 4));
  PackOptions opt;
  opt.max_samples = 4096;
  const double start = full_efficiency_scale(charts, opt.max_samples);
  opt.orientations = 1;
  const Packing one = pack_charts(charts.size(), start, polygon_source(charts, 1), opt);
  expect_valid(one, polygon_source(charts, 1), charts.size(), opt);
  opt.orientations = 16;
  const Packing sixteen = pack_charts(charts.size(), start, polygon_source(charts, 16), opt);
  expect_valid(sixteen, polygon_source(charts, 16), charts.size(), opt);
  EXPECT_LT(sixteen.scale_steps, one.scale_steps);
  EXPECT_GT(sixteen.scale, one.scale);
  EXPECT_EQ(sixteen.placements[0].orientation % 4, 2);  // 45° + o · 22.5° on an axis: the bar lies flat
}

TEST(Pack, BadOptionsThrow) {
  const std::vector<Polygon> charts{ellipse(1, 1)};
  const ShapeSource source = polygon_source(charts, 16);
  const auto throws = [&](double scale, PackOptions opt) {
    EXPECT_THROW((void)pack_charts(1, scale, source, opt), InvalidInput);
  };
  PackOptions opt;
  opt.max_samples = 0;
  throws(10.0, opt);
  opt = {};
  opt.orientations = 0;
  throws(10.0, opt);
  opt = {};
  opt.max_aspect = 0.5;
  throws(10.0, opt);
  opt.max_aspect = std::nan("");
  throws(10.0, opt);
  opt = {};
  opt.scale_step = 0.0;
  throws(10.0, opt);
  opt.scale_step = 1.0;
  throws(10.0, opt);
  opt = {};
  opt.max_scale_steps = -1;
  throws(10.0, opt);
  opt = {};
  opt.first_step = -1;
  throws(10.0, opt);
  opt = {};
  opt.min_step = -1;
  throws(10.0, opt);
  throws(0.0, {});
  throws(-1.0, {});
  throws(std::numeric_limits<double>::infinity(), {});
  throws(std::nan(""), {});
  EXPECT_THROW((void)pack_charts(1, 1.0, ShapeSource{}, {}), InvalidInput);
}

TEST(Pack, MalformedShapesThrow) {
  const ShapeSource short_cells = [](std::size_t, int, double) { return ChartShape{2, 2, {1, 1, 1}}; };
  EXPECT_THROW((void)pack_charts(1, 1.0, short_cells, {}), InvalidInput);
  const ShapeSource loose = [](std::size_t, int, double) { return ChartShape{2, 2, {1, 0, 0, 0}}; };
  EXPECT_THROW((void)pack_charts(1, 1.0, loose, {}), InvalidInput);
}

TEST(Pack, ImpossibleInputThrows) {
  // A 10×10 block at every scale never fits in 50 samples.
  const ShapeSource block = [](std::size_t, int, double) {
    return ChartShape{10, 10, std::vector<std::uint8_t>(100, 1)};
  };
  PackOptions opt;
  opt.max_samples = 50;
  opt.max_scale_steps = 100;
  try {
    (void)pack_charts(2, 1.0, block, opt);
    ADD_FAILURE() << "no exception";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("chart 0 alone needs 100 samples"), std::string::npos) << e.what();
  }
  // Discs far too large for the budget within 5 steps.
  const std::vector<Polygon> charts(3, ellipse(1, 1));
  opt.max_scale_steps = 5;
  opt.max_samples = 100;
  try {
    (void)pack_charts(charts.size(), 40.0, polygon_source(charts, 16), opt);
    ADD_FAILURE() << "no exception";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("within 5 scale steps"), std::string::npos) << e.what();
  }
}

TEST(Pack, EmptyChartsGetDefaultPlacements) {
  std::vector<Polygon> charts{ellipse(1, 1), ellipse(1.5, 1)};
  const ShapeSource inner = polygon_source(charts, 16);
  const ShapeSource source = [&](std::size_t chart, int o, double scale) {
    return chart == 1 ? ChartShape{} : inner(chart == 2 ? 1 : 0, o, scale);
  };
  PackOptions opt;
  opt.max_samples = 2048;
  const Packing pk = pack_charts(3, 20.0, source, opt);
  expect_valid(pk, source, 3, opt);
  EXPECT_EQ(pk.placements[1].orientation, 0);
  EXPECT_EQ(pk.placements[1].x, 0u);
  EXPECT_EQ(pk.placements[1].y, 0u);
  const ShapeSource nothing = [](std::size_t, int, double) { return ChartShape{}; };
  const Packing none = pack_charts(2, 1.0, nothing, opt);
  EXPECT_EQ(none.defined_samples, 0u);
  EXPECT_EQ(none.placements.size(), 2u);
  EXPECT_EQ(pack_charts(0, 1.0, nothing, opt).placements.size(), 0u);
}

TEST(Pack, ShapesAreRequestedOncePerScale) {
  const std::vector<Polygon> charts = mixed_charts();
  const ShapeSource inner = polygon_source(charts, 16);
  std::map<std::tuple<std::size_t, int, double>, int> calls;
  const ShapeSource counting = [&](std::size_t c, int o, double scale) {
    ++calls[{c, o, scale}];
    return inner(c, o, scale);
  };
  PackOptions opt;
  opt.max_samples = 8192;
  (void)pack_charts(charts.size(), full_efficiency_scale(charts, opt.max_samples), counting, opt);
  std::map<double, int> per_scale;
  for (const auto& [key, n] : calls) {
    EXPECT_EQ(n, 1);
    ++per_scale[std::get<2>(key)];
  }
  for (const auto& [scale, n] : per_scale) EXPECT_EQ(n, static_cast<int>(charts.size()) * 16) << scale;
}

TEST(Pack, ReportsProgressAndCancels) {
  const std::vector<Polygon> charts = mixed_charts();
  const ShapeSource source = polygon_source(charts, 16);
  PackOptions opt;
  opt.max_samples = 8192;
  std::vector<double> fractions;
  opt.progress = [&](std::string_view stage, double f) {
    EXPECT_EQ(stage, "pack");
    fractions.push_back(f);
    return true;
  };
  const double start = full_efficiency_scale(charts, opt.max_samples);
  (void)pack_charts(charts.size(), start, source, opt);
  ASSERT_GE(fractions.size(), 2u);
  EXPECT_TRUE(std::is_sorted(fractions.begin(), fractions.end()));
  EXPECT_GE(fractions.front(), 0.0);
  EXPECT_EQ(fractions.back(), 1.0);
  int calls = 0;
  opt.progress = [&](std::string_view, double) { return ++calls < 3; };
  EXPECT_THROW((void)pack_charts(charts.size(), start, source, opt), Cancelled);
}

/// The same rectangle, scale and placement of every chart.
void expect_same_packing(const Packing& a, const Packing& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.scale, b.scale);
  EXPECT_EQ(a.scale_steps, b.scale_steps);
  EXPECT_EQ(a.refined_steps, b.refined_steps);
  EXPECT_EQ(a.defined_samples, b.defined_samples);
  ASSERT_EQ(a.placements.size(), b.placements.size());
  for (std::size_t c = 0; c < a.placements.size(); ++c) {
    EXPECT_EQ(a.placements[c].orientation, b.placements[c].orientation) << c;
    EXPECT_EQ(a.placements[c].x, b.placements[c].x) << c;
    EXPECT_EQ(a.placements[c].y, b.placements[c].y) << c;
  }
}

TEST(Pack, ReproducibleAtAnyThreadCount) {
  // Twice on one thread, then on more: widths are packed a batch at a time, one per thread (-j); the first
  // that packs in the sequential order, and the least area with its total-order ties, decide.
  const std::vector<Polygon> charts = mixed_charts();
  const ShapeSource source = polygon_source(charts, 16);
  PackOptions opt;
  opt.max_samples = 8192;
  const double start = full_efficiency_scale(charts, opt.max_samples);
  std::vector<Packing> runs;
  for (const std::size_t threads : {std::size_t{1}, std::size_t{1}, std::size_t{2}, std::size_t{3}, std::size_t{8}}) {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    runs.push_back(pack_charts(charts.size(), start, source, opt));
  }
  for (std::size_t k = 1; k < runs.size(); ++k) expect_same_packing(runs[0], runs[k]);
}

TEST(Pack, PlacementsAreThoseOfTheScalarPositionScan) {
  // The position scan runs in vector lanes away from the image's sides (pack_horizon.cpp). The mixed charts
  // plus charts whose shapes have columns without cells (two blocks four columns apart: masked lanes) pack
  // exactly as the scalar scan packed them: this digest was recorded with the scalar scan (commit 85a0ca1).
  std::vector<Polygon> charts = mixed_charts();
  const std::size_t polygons = charts.size();
  const ShapeSource polygons_source = polygon_source(charts, 16);
  const ShapeSource source = [&](std::size_t chart, int orientation, double scale) {
    if (chart < polygons) return polygons_source(chart, orientation, scale);
    const auto a = static_cast<std::uint32_t>(std::max(1.0, std::round(scale * (0.4 + 0.1 * static_cast<double>(chart - polygons)))));
    const std::uint32_t gap = 4;
    ChartShape shape;  // two blocks, a × 2a and a × a, side by side four columns apart (transposed when odd)
    shape.width = 2 * a + gap;
    shape.height = 2 * a;
    shape.cells.assign(std::size_t{shape.width} * shape.height, 0);
    for (std::uint32_t y = 0; y < shape.height; ++y)
      for (std::uint32_t x = 0; x < shape.width; ++x)
        if (x < a || (x >= a + gap && y < a)) shape.cells[std::size_t{y} * shape.width + x] = 1;
    if (orientation % 2 == 1) {
      ChartShape t;
      t.width = shape.height;
      t.height = shape.width;
      t.cells.assign(shape.cells.size(), 0);
      for (std::uint32_t y = 0; y < shape.height; ++y)
        for (std::uint32_t x = 0; x < shape.width; ++x) t.cells[std::size_t{x} * t.width + y] = shape.cells[std::size_t{y} * shape.width + x];
      return t;
    }
    return shape;
  };
  const std::size_t total = polygons + 4;
  for (int k = 0; k < 4; ++k) charts.push_back(ellipse(0.9, 0.9));  // their area, for the start scale only
  PackOptions opt;
  opt.max_samples = 8192;
  const Packing pk = pack_charts(total, full_efficiency_scale(charts, opt.max_samples), source, opt);
  std::ostringstream digest;
  digest << pk.width << "x" << pk.height << " " << pk.scale_steps << "+" << pk.refined_steps << ":";
  for (const Placement& p : pk.placements) digest << " " << p.orientation << "," << p.x << "," << p.y;
  EXPECT_EQ(digest.str(), "119x68 23+0: 5,21,33 5,33,25 3,77,24 0,57,0 4,0,0 0,22,19 0,95,40 0,0,35 0,32,0 12,88,49 0,35,46 "
                          "4,96,33 4,64,45 4,48,19 4,87,0 0,29,47 0,23,0 4,0,56 4,42,53 0,75,20 1,56,47 0,16,55 0,105,58");
}

TEST(Pack, SquareOnlyAspectWorks) {
  const std::vector<Polygon> charts(5, ellipse(1.0, 0.7));
  PackOptions opt;
  opt.max_samples = 4000;
  opt.max_aspect = 1.0;
  const ShapeSource source = polygon_source(charts, 16);
  const Packing pk = pack_charts(charts.size(), full_efficiency_scale(charts, opt.max_samples), source, opt);
  EXPECT_EQ(pk.width, pk.height);
  opt.max_aspect = 1.0 + 1e-12;  // expect_valid checks the strict bound
  expect_valid(pk, source, charts.size(), opt);
}

TEST(Pack, SingleCellChartsFillTheirFootprintBoundExactly) {
  // Eight one-cell charts need every second cell of a row: 15 × 1 (or 1 × 15) is the only rectangle of at
  // most 15 samples that holds them. Their footprints (2 × 2 each, 32 cells) fill (W + 1)(H + 1) exactly: the
  // early-failure bound must let them pack (a bound one cell stricter throws ChartsDoNotFit).
  const ShapeSource one_cell = [](std::size_t, int, double) { return ChartShape{1, 1, {1}}; };
  PackOptions opt;
  opt.max_samples = 15;
  opt.max_aspect = 16.0;
  opt.max_scale_steps = 3;
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);  // charts_placed counts one thread's work
  const Packing pk = pack_charts(8, 1.0, one_cell, opt);
  expect_valid(pk, one_cell, 8, opt);
  EXPECT_EQ(std::size_t{pk.width} * pk.height, 15u);
  EXPECT_EQ(pk.defined_samples, 8u);
  EXPECT_EQ(pk.scale_steps, 0);
  // Of the 15 widths, only 1 × 15 and 15 × 1 hold the footprints: the others end before their first chart
  // (the probe that found 1 × 15, then the least-area pass over all widths: 3 × 8 charts). Without the bound,
  // or with a looser one, 2 × 7 alone places 4 charts before it fails.
  EXPECT_EQ(pk.charts_placed, 24u);
  opt.max_samples = 14;  // no rectangle holds them, and the error says what the gutters need
  try {
    (void)pack_charts(8, 1.0, one_cell, opt);
    ADD_FAILURE() << "packed 8 one-cell charts into 14 samples";
  } catch (const ChartsDoNotFit& e) {
    EXPECT_NE(std::string_view(e.what()).find("do not fit in 14 samples within 3 scale steps"), std::string_view::npos) << e.what();
    EXPECT_NE(std::string_view(e.what()).find("they cover 32 cells, more than the 30 of the largest"), std::string_view::npos)
        << e.what();
  }
}

TEST(Pack, RestartsOfManyChartsTryTheWidthsNearThePlainAnswer) {
  // Beyond full_probe_charts charts the restarts and the refinement try only the widths nearest the plain
  // answer's: less work, a valid packing that does not depend on the thread count, and at 4500 samples still
  // a step above largest first (centred on the narrowest width that packed, as the search leaves its hint,
  // the restarts found nothing there).
  const std::vector<Polygon> charts = mixed_charts();
  PackOptions plain;
  plain.max_samples = 4500;
  plain.order_restarts = 0;
  PackOptions every = plain;  // 19 charts: every width
  every.order_restarts = 8;
  PackOptions focused = every;
  focused.full_probe_charts = 0;  // as if there were many: 8 widths
  const ShapeSource source = polygon_source(charts, plain.orientations);
  const double start = full_efficiency_scale(charts, plain.max_samples);
  Packing a, b, c;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);  // charts_placed counts one thread's work
    a = pack_charts(charts.size(), start, source, plain);
    b = pack_charts(charts.size(), start, source, every);
    c = pack_charts(charts.size(), start, source, focused);
  }
  expect_valid(c, source, charts.size(), focused);
  EXPECT_LT(c.scale_steps, a.scale_steps);
  EXPECT_LT(c.charts_placed, b.charts_placed * 2 / 3) << b.charts_placed;
  const Packing d = pack_charts(charts.size(), start, source, focused);  // every thread
  EXPECT_EQ(std::tie(d.width, d.height, d.scale_steps, d.refined_steps, d.defined_samples),
            std::tie(c.width, c.height, c.scale_steps, c.refined_steps, c.defined_samples));
  for (std::size_t i = 0; i < charts.size(); ++i)
    EXPECT_EQ(std::tie(d.placements[i].x, d.placements[i].y, d.placements[i].orientation),
              std::tie(c.placements[i].x, c.placements[i].y, c.placements[i].orientation));
}

TEST(Pack, ChartsOfOneShapeKeepTheirPositionsAndPackTheSame) {
  // A scan's fragments: 19 distinct charts and 60 copies each of a small ellipse and a small L. The copies
  // of one shape keep the positions evaluated for the last of them (only the columns placements touched
  // since are evaluated again): the same packing, far fewer positions evaluated (6.6 of 31.3 million).
  std::vector<Polygon> charts = mixed_charts();
  for (int i = 0; i < 60; ++i) charts.push_back(ellipse(0.35, 0.2, 12));
  for (int i = 0; i < 60; ++i) charts.push_back(l_shape(0.45, 0.18));
  const ShapeSource source = polygon_source(charts, 16);
  PackOptions opt;
  opt.max_samples = 8192;
  opt.order_restarts = 2;
  const double start = full_efficiency_scale(charts, opt.max_samples);
  const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);  // the counts of one thread
  const Packing kept = pack_charts(charts.size(), start, source, opt);
  opt.shape_classes = false;
  const Packing every = pack_charts(charts.size(), start, source, opt);
  expect_valid(kept, source, charts.size(), opt);
  expect_same_packing(kept, every);
  EXPECT_EQ(kept.charts_placed, every.charts_placed);
  EXPECT_LT(3 * kept.positions_evaluated, every.positions_evaluated)
      << kept.positions_evaluated << " of " << every.positions_evaluated;
}

}  // namespace
}  // namespace gimforge
