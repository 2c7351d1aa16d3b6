#include "kernels/mcgim/pack.h"

#include <algorithm>
#include <functional>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include "kernels/core/errors.h"
#include "kernels/core/hash.h"
#include "kernels/mcgim/pack_horizon.h"

// Implementation notes (Sander et al. 2003, §4.3, on the "Tetris" packer of Lévy et al. 2002).
//
// Gutter. The horizon holds, per column, the first free row above every cell packed in that column; the floor
// is row −1 (the image border needs no gutter). A new chart is tested with its shape dilated by one cell in
// the 8-neighbourhood: every dilated cell must lie on a free row of its column. So every cell of the new
// chart is at Chebyshev distance ≥ 2 from every packed cell (no 2×2 quad holds two charts). Dilated columns
// outside the image are ignored (the border is a free gutter).
//
// Holes (a deviation from the plain horizon packer). The rows a chart leaves free under itself in a column
// are kept as that column's holes (at most kMaxHoles runs of ≥ 3 rows per column). Besides the horizon
// position, a candidate (orientation, column x) also gets the lowest position where every dilated column lies
// in one free run (a hole or above the horizon): small charts go into the space under overhangs. On the
// shared meshes at 32 charts that left 13–16 % of the rectangle, under the horizon, unused.
//
// Wasted space of a candidate, paper Fig. 3: Σ over the dilated columns inside the image of (dilated lower
// envelope − the floor of its free run: the horizon or the hole's bottom), plus the "hollow" of the plain
// shape (per column, undefined cells between its lowest and highest defined cell). Only candidates whose top
// stays within the rectangle's height are considered.
//
// Touching perimeter (a deviation too). Of the kRerank least-waste candidates (ties: lower top, then
// orientation and column order), the one of least waste − kContactWeight · contact wins, contact = the cells
// 4-adjacent to the dilated shape that are packed (or the image's sides and floor). The waste rule alone only
// looks down, so a chart can rest beside a neighbour with a lateral gap that becomes a sliver. Both
// deviations together raised the packing efficiency of eight shared meshes at 32 charts from 0.686 to 0.713
// on average (every mesh gained 0.5–7.7 points) for about 1.7× the packing time (BENCHMARKS.md).
//
// Rectangles. For a width W the height bound is H(W) = min(⌊max_samples / W⌋, tallest h with h/W < aspect);
// W is usable when H(W) ≥ the least h with W/h < aspect (a square always counts, so max_aspect = 1 works).
// For W in [√(S/a), √(S·a)] this is exactly H = ⌊S/W⌋; narrower widths get an aspect-capped H (the paper's
// nested loops over W and H). Widths are further limited to those that can hold every chart and the charts'
// total cells, and to at most Σ (widest orientation + 1) over the charts (wider never helps). The reported height is the packed height, raised to the least height the aspect
// bound allows when a wide rectangle packs lower than that (so the reported rectangle obeys the bound).
//
// Cost. One packing costs Σ_charts orientations · W · (shape width + 2) (an orientation whose cells repeat an
// earlier orientation's is skipped: a scan's tiny fragments have many). The paper loops over every width;
// with up to ~400 usable widths per scale (S = 65536, aspect 4) and ~10 scales per search that is too slow,
// so when more than kAllWidthsUpTo widths are usable we try kCoarseWidths widths spread evenly over them and
// then, at the final scale only, every width between the best coarse width's two neighbours. A packing that
// already exceeds the best area found is abandoned early (a pure prune: it cannot change the answer). The
// scan of a shape's positions, two maxima and a sum over its columns at every image column, runs branch-free
// in vector lanes (AVX2 where the processor has it) away from the image's side columns (pack_horizon.cpp):
// the same positions, a third less packing time on the shared meshes (BENCHMARKS.md).
//
// Scale. The paper lowers the scale by 1 % until a packing succeeds. We find the least k (scale =
// initial · (1 − step)^k) for which some coarse width packs by exponential then binary search, ASSUMING that
// packability is monotone in k (smaller charts pack at least as easily). The greedy packer does not
// guarantee this, so afterwards the kVerifyBelow values below the answer are tried as well (a success there
// lowers the answer and the check repeats below it). One step: on eight shared meshes three steps never
// found more than one did, and each infeasible step costs a packing per width.
//
// Restarts (ours). The greedy packer's success at a scale depends on the order of the charts, and no order
// rule was better than largest first on the shared meshes (by thickness, by length: no change). So after the
// search, the step above the answer is also tried with order_restarts perturbed largest-first orders (each
// chart's cell count times 1 + kOrderJitter · u, u a hash of chart and restart in [0, 1)); while one packs,
// the answer moves up a step and the next step is tried. At 32 charts on eight shared meshes, 3 restarts
// raised the packing efficiency on five (+1.1 to +1.9 points), 8 also on the camel (+2.8). With more than
// full_probe_charts charts a restart tries fewer widths, those nearest the answer's (probe_widths): its probes
// mostly fail, and a failing probe packs nearly every chart into every width (a kitten with 1000 scan
// fragments, 2006 charts: the restarts and the refinement were three quarters of the packing time).
//
// Refinement (ours). The answer's scale is at most 1 % below one that did not pack, so the packing efficiency
// can lose up to 2 % to the step alone. The interval between the two is bisected refine_levels times (in steps:
// scale · (1 − step)^−½, then ^−¼ or ^−¾), each midpoint tried with every chart order and kept where one packs.
// Only the answer's neighbourhood is probed, so the step search and the charts are those of 1 % steps. One
// level raised hand, cow and buddha by 0.5–0.7 points at their default chart counts (the camel's half step
// does not pack) for 0.2–8 s more packing (BENCHMARKS.md); a global 0.5 % step moved the search's path
// instead. Its probes try the restarts' widths (all, or with many charts those nearest the answer's).
//
// Early failure. A packing also gives up as soon as the charts left need more cells (their fewest over the
// orientations) than the free rows of the rectangle hold, or more footprint: grow every cell of a chart to the
// 2×2 block at it and two charts' grown shapes never overlap (their cells are ≥ 2 apart in both axes or one);
// a chart's grown shape lies in the free runs its dilated columns take, or in the row above the rectangle or
// the column right of it, so the footprints left must fit in the free rows + W + H + 1. Infeasible steps end
// sooner, results are unchanged. Small charts' gutters are a large part of their footprint: on the kitten with
// 1000 fragments the search's probes at steps 15 and 31 now fail before placing a chart (footprints 81,806
// and 67,484 cells against the largest rectangle's 66,170) instead of after ~1,600 charts per width.

namespace gimforge {
namespace {

using namespace pack_detail;

constexpr std::size_t kAllWidthsUpTo = 48;                         // try every width when this few are usable
constexpr std::size_t kCoarseWidths = 32;                          // widths tried per scale otherwise
constexpr std::size_t kFocusWidths = 8;        // the fewest widths a restart or refinement probe tries
constexpr std::size_t kCachedSteps = 4;        // steps whose shapes the packer keeps
constexpr int kVerifyBelow = 1;                                     // steps re-checked below the search's answer
constexpr double kOrderJitter = 0.3;      // relative perturbation of the cell counts in a restart's order

/// Least h ≥ 1 with w / h < aspect (or h = w: a square is always allowed).
std::uint64_t least_height(std::uint64_t w, double aspect) {
  const auto wd = static_cast<double>(w);
  if (wd < aspect) return 1;
  auto h = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::floor(wd / aspect)));
  while (h > 1 && wd < aspect * static_cast<double>(h - 1)) --h;
  while (!(wd < aspect * static_cast<double>(h))) ++h;
  return std::min(h, w);
}

/// Greatest h with h / w < aspect (or h = w), capped at `cap`.
std::uint64_t greatest_height(std::uint64_t w, double aspect, std::uint64_t cap) {
  const double bound = aspect * static_cast<double>(w);
  if (!(bound < static_cast<double>(cap))) return cap;
  auto h = static_cast<std::uint64_t>(std::ceil(bound));
  while (h > 0 && !(static_cast<double>(h) < bound)) --h;
  return std::min(std::max(h, w), cap);
}

/// Checks a shape from the ShapeSource and extracts its envelopes. Throws InvalidInput when the shape's
/// cells do not match its size or the shape is not tight.
Prepared prepare_shape(const ChartShape& s, std::size_t chart, int orientation, double scale) {
  const auto where = [&] {
    return "pack_charts: shape of chart " + std::to_string(chart) + " (orientation " + std::to_string(orientation) +
           ", scale " + std::to_string(scale) + ", " + std::to_string(s.width) + "x" + std::to_string(s.height) + ")";
  };
  if ((s.width == 0) != (s.height == 0) || s.width > kMaxSide || s.height > kMaxSide)
    throw InvalidInput(where() + " has an invalid size");
  if (s.cells.size() != std::size_t{s.width} * s.height)
    throw InvalidInput(where() + " has " + std::to_string(s.cells.size()) + " cells");
  Prepared p;
  p.width = s.width;
  p.height = s.height;
  if (s.width == 0) return p;
  const auto w = static_cast<std::size_t>(s.width);
  std::vector<Row> low_plain(w, kEmpty);
  p.high.assign(w, kEmpty);
  Row lowest = kEmpty;
  Row highest = -1;
  for (std::uint32_t x = 0; x < s.width; ++x) {
    std::int64_t count = 0;
    for (std::uint32_t y = 0; y < s.height; ++y) {
      if (!s.at(x, y)) continue;
      ++count;
      if (low_plain[x] == kEmpty) low_plain[x] = static_cast<Row>(y);
      p.high[x] = static_cast<Row>(y);
    }
    if (count == 0) continue;
    p.cells += static_cast<std::size_t>(count);
    p.hollow += p.high[x] - low_plain[x] + 1 - count;
    lowest = std::min(lowest, low_plain[x]);
    highest = std::max(highest, p.high[x]);
  }
  if (low_plain.front() == kEmpty || low_plain.back() == kEmpty || lowest != 0 ||
      highest != static_cast<Row>(s.height) - 1)
    throw InvalidInput(where() + " is not tight (an empty first or last row or column)");
  p.low.assign(w + 2, kEmpty);
  p.top.assign(w + 2, -kEmpty);
  for (std::size_t j = 0; j < w + 2; ++j)  // dilated column j − 1 covers plain columns j − 2 .. j
    for (std::size_t c = j < 2 ? 0 : j - 2; c <= j && c < w; ++c)
      if (low_plain[c] != kEmpty) {
        p.low[j] = std::min(p.low[j], low_plain[c] - 1);
        p.top[j] = std::max(p.top[j], p.high[c] + 1);
      }
  p.plain_low = std::move(low_plain);
  for (const Row l : p.low)
    if (l != kEmpty) {
      p.low_sum += l;
      ++p.columns;
    }
  {  // the footprint: every cell grown to the 2×2 block at it
    const std::size_t fw = w + 1;
    std::vector<std::uint8_t> f(fw * (std::size_t{s.height} + 1), 0);
    for (std::uint32_t y = 0; y < s.height; ++y)
      for (std::uint32_t x = 0; x < s.width; ++x)
        if (s.at(x, y))
          for (std::size_t dy = 0; dy < 2; ++dy)
            for (std::size_t dx = 0; dx < 2; ++dx) f[(y + dy) * fw + x + dx] = 1;
    p.footprint = static_cast<std::size_t>(std::count(f.begin(), f.end(), std::uint8_t{1}));
  }
  {
    const Row dw = static_cast<Row>(w) + 2, dh = static_cast<Row>(s.height) + 2;
    std::vector<std::uint8_t> d(static_cast<std::size_t>(dw * dh), 0);
    for (std::uint32_t y = 0; y < s.height; ++y)
      for (std::uint32_t x = 0; x < s.width; ++x)
        if (s.at(x, y))
          for (Row dy = 0; dy < 3; ++dy)
            for (Row dx = 0; dx < 3; ++dx) d[static_cast<std::size_t>((static_cast<Row>(y) + dy) * dw + static_cast<Row>(x) + dx)] = 1;
    const auto in = [&](Row x, Row y) { return x >= 0 && y >= 0 && x < dw && y < dh && d[static_cast<std::size_t>(y * dw + x)] != 0; };
    for (Row y = -1; y <= dh; ++y)
      for (Row x = -1; x <= dw; ++x)
        if (!in(x, y) && (in(x - 1, y) || in(x + 1, y) || in(x, y - 1) || in(x, y + 1))) p.rim.emplace_back(x - 1, y - 1);
  }
  return p;
}

/// The horizon packer of one scale: loads and caches the shapes, packs rectangles, searches the scale.
class Packer {
 public:
  Packer(std::size_t num_charts, double initial_scale, const ShapeSource& source, const PackOptions& options)
      : charts_(num_charts), initial_scale_(initial_scale), source_(source), options_(options) {}

  /// The scale after k reductions.
  [[nodiscard]] double scale_at(int k) const {
    return initial_scale_ * std::pow(1.0 - options_.scale_step, static_cast<double>(k));
  }

  /// The shapes at step k, asking the ShapeSource once per chart and orientation. The kCachedSteps steps used
  /// last are kept (a reference stays valid until the next call): a search that runs to thousands of steps
  /// kept every step's shapes (a scan of 8000 fragments: 0.86 GB), and rasterizing again costs little.
  const ScaleShapes& shapes_at(int k) {
    std::erase(recent_, k);
    recent_.push_back(k);
    auto it = cache_.find(k);
    if (it != cache_.end()) return it->second;
    if (recent_.size() > kCachedSteps) {
      cache_.erase(recent_.front());
      recent_.erase(recent_.begin());
    }
    const auto n = static_cast<std::size_t>(options_.orientations);
    ScaleShapes s;
    s.scale = scale_at(k);
    s.shapes.reserve(charts_ * n);
    std::vector<std::size_t> most(charts_, 0);
    std::vector<std::uint64_t> fewest_cells(charts_, 0);
    std::vector<std::uint64_t> fewest_footprint(charts_, 0);
    std::vector<std::size_t> with_cells;
    for (std::size_t c = 0; c < charts_; ++c) {
      std::size_t fewest = std::numeric_limits<std::size_t>::max();
      std::size_t least_footprint = std::numeric_limits<std::size_t>::max();
      std::uint64_t narrowest = std::numeric_limits<std::uint64_t>::max();
      std::uint64_t widest = 0;
      std::vector<ChartShape> seen;  // this chart's distinct shapes so far
      for (int o = 0; o < options_.orientations; ++o) {
        ChartShape shape = source_(c, o, s.scale);
        s.shapes.push_back(prepare_shape(shape, c, o, s.scale));
        Prepared& p = s.shapes.back();
        const auto same = [&](const ChartShape& q) { return q.width == shape.width && q.height == shape.height && q.cells == shape.cells; };
        p.repeat = std::any_of(seen.begin(), seen.end(), same);
        if (!p.repeat) seen.push_back(std::move(shape));
        most[c] = std::max(most[c], p.cells);
        if (p.cells == 0) continue;
        fewest = std::min(fewest, p.cells);
        least_footprint = std::min(least_footprint, p.footprint);
        narrowest = std::min<std::uint64_t>(narrowest, p.width);
        widest = std::max<std::uint64_t>(widest, p.width);
      }
      if (most[c] == 0) continue;
      fewest_cells[c] = fewest;
      fewest_footprint[c] = least_footprint;
      with_cells.push_back(c);
      s.min_cells += fewest;
      s.width_bound += widest + 1;
      s.min_width = std::max(s.min_width, narrowest);
    }
    if (options_.shape_classes) assign_shape_classes(s, charts_, n);
    std::vector<double> key(charts_, 0.0);
    for (int r = 0; r <= std::max(0, options_.order_restarts); ++r) {
      ChartOrder ord;
      ord.charts = with_cells;
      for (std::size_t c : with_cells) {
        const std::uint64_t h = splitmix64(std::uint64_t{c} * std::uint64_t{0x9e3779b97f4a7c15} + static_cast<std::uint64_t>(r));
        const double u = r == 0 ? 0.0 : static_cast<double>(h >> 11) * 0x1p-53;
        key[c] = static_cast<double>(most[c]) * (1.0 + kOrderJitter * u);
      }
      std::stable_sort(ord.charts.begin(), ord.charts.end(), [&](std::size_t a, std::size_t b) { return key[a] > key[b]; });
      ord.rest.assign(ord.charts.size() + 1, 0);
      ord.rest_footprint.assign(ord.charts.size() + 1, 0);
      for (std::size_t i = ord.charts.size(); i-- > 0;) {
        ord.rest[i] = ord.rest[i + 1] + fewest_cells[ord.charts[i]];
        ord.rest_footprint[i] = ord.rest_footprint[i + 1] + fewest_footprint[ord.charts[i]];
      }
      s.orders.push_back(std::move(ord));
    }
    return cache_.emplace(k, std::move(s)).first->second;
  }

  /// The usable widths at these shapes (see the notes at the top), in increasing order.
  [[nodiscard]] std::vector<WidthChoice> widths_for(const ScaleShapes& s) const {
    std::vector<WidthChoice> out;
    const std::uint64_t budget = options_.max_samples;
    const std::uint64_t last = std::min({s.width_bound, kMaxSide, budget});
    for (std::uint64_t w = std::max<std::uint64_t>(1, s.min_width); w <= last; ++w) {
      const std::uint64_t hmin = least_height(w, options_.max_aspect);
      if (hmin * w > budget) break;  // w · least_height(w) grows with w
      const std::uint64_t hmax = std::min(budget / w, greatest_height(w, options_.max_aspect, kMaxSide));
      if (hmax < hmin || hmax * w < s.min_cells) continue;
      out.push_back({static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(hmax), static_cast<std::uint32_t>(hmin)});
    }
    return out;
  }

  /// True when some coarse width packs at step k with chart order r; a success's width is tried first next
  /// time. The widths are packed a batch at a time, in parallel; the first that packs in the sequential
  /// order decides, so the answer does not depend on the thread count.
  bool feasible(int k, int r = 0) {
    auto known = feasible_.find({k, r});
    if (known != feasible_.end()) return known->second;
    const ScaleShapes& s = shapes_at(k);
    const std::vector<WidthChoice> widths = widths_for(s);
    std::vector<std::size_t> tries = coarse(widths.size());
    if (const std::size_t most = probe_widths(s);
        (r > 0 || focused_) && hint_width_ != 0 && tries.size() > most) {
      // Many charts: a restart's order or the refinement's scale is tried at the widths nearest the answer's.
      const auto distance = [&](std::size_t i) { return std::abs(std::int64_t{widths[i].width} - std::int64_t{hint_width_}); };
      std::stable_sort(tries.begin(), tries.end(), [&](std::size_t a, std::size_t b) { return distance(a) < distance(b); });
      tries.resize(most);
    } else if (auto hint = std::find_if(tries.begin(), tries.end(), [&](std::size_t i) { return widths[i].width == hint_width_; });
               hint != tries.end()) {
      std::rotate(tries.begin(), hint, hint + 1);
    }
    bool ok = false;
    for (std::size_t at = 0; at < tries.size() && !ok;) {
      report(search_fraction());
      const std::span<const std::size_t> batch(tries.data() + at, std::min(batch_size(s, widths), tries.size() - at));
      pack_batch(s, s.orders[static_cast<std::size_t>(r)], widths, batch, [] { return std::numeric_limits<std::uint64_t>::max(); });
      for (std::size_t t = 0; t < batch.size() && !ok; ++t)
        if (packed_[t] != 0) {
          hint_width_ = widths[batch[t]].width;
          ok = true;
        }
      at += batch.size();
    }
    ++probes_;
    feasible_.emplace(std::make_pair(k, r), ok);
    return ok;
  }

  /// From now on every probe is limited to probe_widths() widths around `width`, as the main packer's restarts
  /// are: for the refinement's packers, which probe around an answer of that width.
  void focus(std::uint32_t width) {
    focused_ = true;
    hint_width_ = width;
  }

  /// True when the restarts at step k may try fewer widths than a probe of the search (many charts).
  [[nodiscard]] bool focused_restarts(int k) { return probe_widths(shapes_at(k)) != std::numeric_limits<std::size_t>::max(); }

  /// Charts placed by every packing this packer ran (the work done; with several threads it includes
  /// the widths packed beside the one that decided a probe).
  [[nodiscard]] std::uint64_t placements() const { return sum_over_slots(&RectPacker::placements); }
  /// Positions evaluated by every packing this packer ran (the same way).
  [[nodiscard]] std::uint64_t evaluations() const { return sum_over_slots(&RectPacker::evaluations); }

  /// The least-area packing at step k with chart order r over the coarse widths and every width around the
  /// best of them. Precondition: feasible(k, r). Packed a batch of widths at a time, in parallel: each run
  /// is abandoned once it exceeds the best area known when it started (a pure prune), and the least area
  /// wins, ties to the squarer rectangle and then the narrower one (a total order: the answer does not
  /// depend on the thread count).
  Packing best_at(int k, int r) {
    const ScaleShapes& s = shapes_at(k);
    const std::vector<WidthChoice> widths = widths_for(s);
    const std::vector<std::size_t> tries = coarse(widths.size());
    const ChartOrder& order = s.orders[static_cast<std::size_t>(r)];
    RectPacking best;
    std::uint64_t best_area = std::numeric_limits<std::uint64_t>::max();
    std::size_t best_width = widths.size();  // index into widths of the best packing
    // Packs widths[i] for every i of `indices`, a batch at a time; `fraction(done)` is the progress.
    const auto pack_all = [&](const std::vector<std::size_t>& indices, const std::function<double(std::size_t)>& fraction) {
      for (std::size_t at = 0; at < indices.size();) {
        report(fraction(at));
        const std::span<const std::size_t> batch(indices.data() + at, std::min(batch_size(s, widths), indices.size() - at));
        pack_batch(s, order, widths, batch, [&] { return best_area; });
        for (std::size_t t = 0; t < batch.size(); ++t) {
          if (packed_[t] == 0) continue;
          const RectPacking& trial = results_[t];
          const std::uint64_t area = std::uint64_t{trial.width} * trial.height;
          if (area < best_area || (area == best_area && squarer(trial, best))) {
            best_area = area;
            best = trial;
            best_width = batch[t];
          }
        }
        at += batch.size();
      }
    };
    pack_all(tries, [&](std::size_t done) { return 0.8 + 0.1 * static_cast<double>(done) / static_cast<double>(tries.size()); });
    const auto best_slot = static_cast<std::size_t>(std::find(tries.begin(), tries.end(), best_width) - tries.begin());
    if (best_slot == tries.size())
      throw Error("pack_charts: internal error: no packing at a scale found packable");
    const std::size_t from = best_slot == 0 ? tries[0] : tries[best_slot - 1] + 1;
    const std::size_t to = best_slot + 1 == tries.size() ? tries.back() : tries[best_slot + 1] - 1;
    std::vector<std::size_t> around;
    for (std::size_t i = from; i <= to; ++i)
      if (i != tries[best_slot]) around.push_back(i);
    pack_all(around, [&](std::size_t done) { return 0.9 + 0.1 * static_cast<double>(done) / static_cast<double>(around.size() + 1); });
    Packing result;
    result.width = best.width;
    result.height = best.height;
    result.scale = s.scale;
    result.scale_steps = k;
    result.placements = std::move(best.placements);
    result.defined_samples = best.cells;
    return result;
  }

  /// Reports progress as stage "pack", never going backwards.
  void report(double fraction) {
    reported_ = std::max(reported_, std::min(fraction, 1.0));
    report_progress(options_.progress, "pack", reported_);
  }

  /// A fraction in [0, 0.8) that grows with the probes of the scale search.
  [[nodiscard]] double search_fraction() const {
    const auto p = static_cast<double>(probes_);
    return 0.8 * p / (p + 8.0);
  }

 private:
  /// How many widths are packed at once: the threads this process may use (-j), as long as their occupancy
  /// grids (a byte per sample of the budget each) and their shape-class tables (pack_horizon.h: classes ×
  /// orientations × the widest width, 33 bytes each) stay within 256 MiB.
  [[nodiscard]] std::size_t batch_size(const ScaleShapes& s, const std::vector<WidthChoice>& widths) const {
    const std::size_t threads = tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
    const std::size_t widest = widths.empty() ? 0 : widths.back().width;
    const std::size_t per_slot = options_.max_samples + s.class_first.size() * static_cast<std::size_t>(options_.orientations) *
                                                            widest * (sizeof(ColumnPositions) + 1);
    const std::size_t by_memory = (std::size_t{1} << 28) / std::max<std::size_t>(1, per_slot);
    return std::max<std::size_t>(1, std::min(threads, by_memory));
  }

  /// Packs widths[batch[t]] with order into results_[t] for every t at once, one RectPacker each;
  /// packed_[t] says whether it packed. `limit()` is a run's area bound, read when it starts.
  void pack_batch(const ScaleShapes& s, const ChartOrder& order, const std::vector<WidthChoice>& widths,
                  std::span<const std::size_t> batch, const std::function<std::uint64_t()>& limit) {
    while (slots_.size() < batch.size()) slots_.emplace_back(charts_, options_.orientations);
    results_.resize(std::max(results_.size(), batch.size()));
    packed_.assign(batch.size(), 0);
    const std::uint64_t bound = limit();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, batch.size(), 1), [&](const tbb::blocked_range<std::size_t>& range) {
      for (std::size_t t = range.begin(); t != range.end(); ++t)
        packed_[t] = slots_[t].pack_rectangle(s, order, widths[batch[t]], bound, results_[t]) ? 1 : 0;
    });
  }

  [[nodiscard]] std::uint64_t sum_over_slots(std::uint64_t (RectPacker::*count)() const) const {
    std::uint64_t n = 0;
    for (const RectPacker& slot : slots_) n += (slot.*count)();
    return n;
  }

  /// How many widths a restart or refinement probe tries (those nearest the answer's width): every coarse width
  /// up to full_probe_charts charts with cells; beyond, fewer in proportion, down to kFocusWidths. Such probes
  /// mostly fail, and a failing probe packs nearly every chart into every width it tries (a scan's thousand
  /// fragments: three quarters of the packing time).
  [[nodiscard]] std::size_t probe_widths(const ScaleShapes& s) const {
    const std::size_t charts = s.orders[0].charts.size();
    if (charts <= options_.full_probe_charts) return std::numeric_limits<std::size_t>::max();
    return std::max(kFocusWidths, kCoarseWidths * options_.full_probe_charts / charts);
  }

  /// Indices into a list of `count` widths to try: all of them, or kCoarseWidths spread evenly.
  static std::vector<std::size_t> coarse(std::size_t count) {
    std::vector<std::size_t> out;
    if (count <= kAllWidthsUpTo) {
      for (std::size_t i = 0; i < count; ++i) out.push_back(i);
      return out;
    }
    for (std::size_t t = 0; t < kCoarseWidths; ++t) out.push_back(t * (count - 1) / (kCoarseWidths - 1));
    return out;
  }

  /// Tie-break of equal areas: the rectangle closer to a square, then the narrower one.
  static bool squarer(const RectPacking& a, const RectPacking& b) {
    const auto ratio = [](const RectPacking& r) {
      const double lo = std::min(r.width, r.height);
      const double hi = std::max(r.width, r.height);
      return hi / lo;
    };
    if (ratio(a) != ratio(b)) return ratio(a) < ratio(b);
    return a.width < b.width;
  }

  std::size_t charts_;
  double initial_scale_;
  const ShapeSource& source_;
  const PackOptions& options_;
  std::map<int, ScaleShapes> cache_;
  std::vector<int> recent_;  ///< the steps of cache_, least recently used first
  std::map<std::pair<int, int>, bool> feasible_;  ///< (step, order) → packs
  std::vector<RectPacker> slots_;          ///< one per packing run at once
  std::vector<RectPacking> results_;       ///< the runs' packings (pack_batch)
  std::vector<std::uint8_t> packed_;       ///< whether each run packed
  std::uint32_t hint_width_{0};
  bool focused_{false};
  int probes_{0};
  double reported_{0.0};
};

/// Throws InvalidInput saying why nothing packed even at step max_scale_steps: a chart larger than the whole
/// budget at that scale if there is one, otherwise the charts together.
[[noreturn]] void throw_unpackable(Packer& packer, std::size_t num_charts, const PackOptions& options) {
  const int k = options.max_scale_steps;
  const ScaleShapes& s = packer.shapes_at(k);
  const auto n = static_cast<std::size_t>(options.orientations);
  const std::string where = fmt::format(" within {} scale steps (scale {:.3g})", k, s.scale);
  for (std::size_t c = 0; c < num_charts; ++c) {
    std::size_t fewest = std::numeric_limits<std::size_t>::max();
    for (std::size_t o = 0; o < n; ++o)
      if (s.shapes[c * n + o].cells > 0) fewest = std::min(fewest, s.shapes[c * n + o].cells);
    if (fewest != std::numeric_limits<std::size_t>::max() && fewest > options.max_samples)
      throw ChartsDoNotFit("pack_charts: chart " + std::to_string(c) + " alone needs " + std::to_string(fewest) +
                         " samples, more than max_samples " + std::to_string(options.max_samples) + where);
  }
  // Many small charts: the gutters between them alone need the room (pack_horizon.h, Prepared::footprint).
  const std::uint64_t footprint = s.orders.empty() ? 0 : s.orders[0].rest_footprint[0];
  std::uint64_t room = 0;  // the most footprint any allowed rectangle holds: (W + 1)(H + 1)
  for (const WidthChoice& wc : packer.widths_for(s)) room = std::max(room, (wc.width + std::uint64_t{1}) * (wc.max_height + 1));
  if (room > 0 && footprint > room)
    throw ChartsDoNotFit(fmt::format("pack_charts: the {} charts do not fit in {} samples{}: with the undefined sample "
                                     "that separates charts they cover {} cells, more than the {} of the largest "
                                     "allowed rectangle with its border row and column",
                                     num_charts, options.max_samples, where, footprint, room));
  throw ChartsDoNotFit("pack_charts: the " + std::to_string(num_charts) + " charts do not fit in " +
                     std::to_string(options.max_samples) + " samples" + where);
}

/// Throws InvalidInput for options out of range.
void check_options(double initial_scale, const ShapeSource& shape, const PackOptions& o) {
  if (!shape) throw InvalidInput("pack_charts: no shape source");
  if (!std::isfinite(initial_scale) || initial_scale <= 0.0)
    throw InvalidInput("pack_charts: initial_scale " + std::to_string(initial_scale) + " is not a positive number");
  if (o.max_samples == 0) throw InvalidInput("pack_charts: max_samples is 0");
  if (!(o.max_aspect >= 1.0))
    throw InvalidInput("pack_charts: max_aspect " + std::to_string(o.max_aspect) + " is below 1");
  if (o.orientations < 1)
    throw InvalidInput("pack_charts: orientations " + std::to_string(o.orientations) + " is below 1");
  if (!(o.scale_step > 0.0 && o.scale_step < 1.0))
    throw InvalidInput("pack_charts: scale_step " + std::to_string(o.scale_step) + " is not in (0, 1)");
  if (o.max_scale_steps < 0)
    throw InvalidInput("pack_charts: max_scale_steps " + std::to_string(o.max_scale_steps) + " is negative");
  if (o.first_step < 0) throw InvalidInput("pack_charts: first_step " + std::to_string(o.first_step) + " is negative");
  if (o.min_step < 0) throw InvalidInput("pack_charts: min_step " + std::to_string(o.min_step) + " is negative");
  if (o.min_step > o.max_scale_steps)
    throw InvalidInput("pack_charts: a chart is longer than any rectangle of " + std::to_string(o.max_samples) +
                       " samples allows until scale step " + std::to_string(o.min_step) + ", beyond the " +
                       std::to_string(o.max_scale_steps) + " steps allowed (a sliver chart: too thin to sample)");
}

/// Binary search between a failing step `bad` and a packing step `good` > bad for the least packing step.
void bisect(Packer& packer, int bad, int& good) {
  while (good - bad > 1) {
    const int mid = bad + (good - bad) / 2;
    (packer.feasible(mid) ? good : bad) = mid;
  }
}

}  // namespace

Packing pack_charts(std::size_t num_charts, double initial_scale, const ShapeSource& shape,
                    const PackOptions& options) {
  check_options(initial_scale, shape, options);
  Packer packer(num_charts, initial_scale, shape, options);
  packer.report(0.0);
  const int least = options.min_step;
  if (packer.shapes_at(least).orders[0].charts.empty()) {  // nothing to place: an empty rectangle
    Packing empty;
    empty.scale = initial_scale;
    empty.placements.assign(num_charts, Placement{});
    packer.report(1.0);
    return empty;
  }
  // Exponential search from the first step (g, g + 1, g + 3, g + 7, …, capped at max_scale_steps; or, when g
  // packs, g − 1, g − 3, … down to step 0), then binary search between the last failure and the first success,
  // assuming packability is monotone in k.
  const int first = std::clamp(options.first_step, least, options.max_scale_steps);
  int good = first;
  if (!packer.feasible(first)) {
    int bad = first;
    for (int step = 1;; step *= 2) {
      const int k = static_cast<int>(std::min<std::int64_t>(std::int64_t{bad} + step, options.max_scale_steps));
      if (k <= bad || (!packer.feasible(k) && k == options.max_scale_steps))
        throw_unpackable(packer, num_charts, options);
      if (packer.feasible(k)) {
        good = k;
        break;
      }
      bad = k;
    }
    bisect(packer, bad, good);
  } else if (first > least) {
    int bad = least - 1;  // a virtual failure below the least step
    for (int step = 1; good > least; step *= 2) {
      const int k = std::max(least, good - step);
      if (!packer.feasible(k)) {
        bad = k;
        break;
      }
      good = k;
    }
    bisect(packer, bad, good);
  }
  // Monotonicity is not guaranteed by the greedy packer: re-check a few steps below the answer.
  for (int k = good - 1; k >= least && k >= good - kVerifyBelow; --k)
    if (packer.feasible(k)) good = k;
  // Restarts: the steps above the answer get the perturbed chart orders too, while one of them packs.
  // With many charts they try the widths nearest the plain answer's (Packer::probe_widths).
  std::optional<Packing> plain;
  std::uint64_t fine_placements = 0, fine_evaluations = 0;  // of the refinement's packers
  const auto done = [&](Packing p) {
    p.charts_placed = packer.placements() + fine_placements;
    p.positions_evaluated = packer.evaluations() + fine_evaluations;
    packer.report(1.0);
    return p;
  };
  if (options.restart_if || (options.order_restarts > 0 && good > least && packer.focused_restarts(good))) {
    plain = packer.best_at(good, 0);
    packer.focus(plain->width);
    if (options.restart_if && !options.restart_if(*plain)) return done(*std::move(plain));
  }
  int order = 0;
  for (int k = good - 1; k >= least; --k) {
    int won = -1;
    for (int r = 1; r <= options.order_restarts && won < 0; ++r)
      if (packer.feasible(k, r)) won = r;
    if (won < 0) break;
    good = k;
    order = won;
  }
  Packing result = order == 0 && plain ? *std::move(plain) : packer.best_at(good, order);
  // Refinement: bisect (in steps) between the failing step good − 1 and the answer.
  if (good > least) {
    double packs = 0.0, fails = 1.0;  // steps regained: 0 packs (the answer), 1 (step good − 1) does not
    PackOptions at_one_scale = options;
    double reached = 0.95;  // the fine packers' probes report this through `packer` (which never goes backwards)
    at_one_scale.progress = [&](std::string_view, double) {
      packer.report(reached);
      return true;
    };
    for (int level = 0; level < options.refine_levels; ++level) {
      reached = 0.95 + 0.05 * level / options.refine_levels;
      packer.report(reached);
      const double mid = 0.5 * (packs + fails);
      Packer fine(num_charts, packer.scale_at(good) * std::pow(1.0 - options.scale_step, -mid), shape, at_one_scale);
      fine.focus(result.width);
      int won = -1;
      for (int r = 0; r <= options.order_restarts && won < 0; ++r)
        if (fine.feasible(0, r)) won = r;
      (won < 0 ? fails : packs) = mid;
      if (won >= 0) {
        result = fine.best_at(0, won);
        result.scale_steps = good;
        result.refined_steps = mid;
      }
      fine_placements += fine.placements();
      fine_evaluations += fine.evaluations();
    }
  }
  return done(std::move(result));
}

}  // namespace gimforge
