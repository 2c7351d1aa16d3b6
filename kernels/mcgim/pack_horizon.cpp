/// \file pack_horizon.cpp
/// RectPacker (pack_horizon.h): one horizon packing.
#include "kernels/mcgim/pack_horizon.h"

#include <algorithm>
#include <limits>
#include <map>
#include <vector>

namespace gimforge::pack_detail {
namespace {

/// What a position of a shape at an interior column needs, over its n = width + 2 dilated columns (hz and
/// fl start at the image column under dilated column 0): max_j (hz[j] − low[j]), max_j (fl[j] − low[j]) and
/// Σ hz[j] over the columns with cells (low[j] ≠ kEmpty, which keeps the maxima out of reach: hz, fl ≥ −1).
/// Branch-free, so that it runs in vector lanes; cloned for AVX2 and picked at run time.
struct ColumnSums {
  Row rise;      ///< max_j (hz[j] − low[j])
  Row floor;     ///< max_j (fl[j] − low[j])
  std::int64_t horizon;  ///< Σ hz[j] over the columns with cells
};

#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target_clones("avx2", "default")))
#endif
ColumnSums column_sums(const Row* hz, const Row* fl, const Row* low, Row n) {
  Row rise = std::numeric_limits<Row>::min();
  Row floor = std::numeric_limits<Row>::min();
  std::int64_t horizon = 0;
  for (Row j = 0; j < n; ++j) {
    rise = std::max(rise, hz[j] - low[j]);
    floor = std::max(floor, fl[j] - low[j]);
    horizon += low[j] != kEmpty ? hz[j] : 0;
  }
  return {rise, floor, horizon};
}

}  // namespace

bool RectPacker::pack_rectangle(const ScaleShapes& s, const ChartOrder& order, const WidthChoice& wc,
                                std::uint64_t area_limit, RectPacking& out) {
  const auto n = static_cast<std::size_t>(orientations_);
  const auto W = static_cast<Row>(wc.width);
  const auto H = static_cast<Row>(wc.max_height);
  for (std::size_t c : order.charts) {  // quick rejection: every chart needs an orientation that fits
    bool fits = false;
    for (std::size_t o = 0; o < n && !fits; ++o) {
      const Prepared& p = s.shapes[c * n + o];
      fits = p.cells > 0 && p.width <= wc.width && p.height <= wc.max_height;
    }
    if (!fits) return false;
  }
  horizon_.assign(wc.width, -1);
  height_ = static_cast<Row>(wc.max_height);
  holes_.assign(wc.width, Holes{});
  lowest_free_.assign(wc.width, -1);
  tallest_hole_.assign(wc.width, 0);
  occ_.assign(std::size_t{wc.width} * wc.max_height, 0);
  out.width = wc.width;
  out.placements.assign(charts_, Placement{});
  out.cells = 0;
  out.height = wc.min_height;
  Row packed_top = 0;
  col_free_.assign(wc.width, static_cast<std::int64_t>(wc.max_height));
  tables_.resize(s.class_first.size());
  for (ClassTable& t : tables_) t.used = false;
  free_cells_ = std::int64_t{wc.width} * wc.max_height;
  for (std::size_t i = 0; i < order.charts.size(); ++i) {
    // Give up early when the charts left cannot fit in the free rows: neither their cells nor their
    // footprints (pack_horizon.h; these lie in free runs, or in row H or column W just outside, disjoint).
    const auto free = static_cast<std::uint64_t>(free_cells_);
    if (order.rest[i] > free || order.rest_footprint[i] > free + std::uint64_t{wc.width} + wc.max_height + 1) return false;
    const std::size_t c = order.charts[i];
    near_.clear();  // the kRerank least-waste candidates, least first
    const auto consider = [&](std::int64_t waste, Row top, Row x, Row y, int o) {
      const Candidate cd{waste, top, x, y, o};
      if (near_.size() < kRerank || less_waste(cd, near_.back())) {
        near_.insert(std::upper_bound(near_.begin(), near_.end(), cd, less_waste), cd);
        if (near_.size() > kRerank) near_.pop_back();
      }
    };
    // A chart of a shape class reads and refreshes its class's table: only the stale columns are evaluated
    // again (the same candidates, in the same order); any other chart evaluates every column.
    const std::uint32_t k = s.shape_class.empty() ? kNoClass : s.shape_class[c];
    ClassTable* table = k == kNoClass ? nullptr : &tables_[k];
    if (table != nullptr && !table->used) {
      table->used = true;
      table->positions.resize(n * wc.width);
      table->stale.assign(n * wc.width, 1);
    }
    ColumnPositions scratch;
    for (std::size_t o = 0; o < n; ++o) {
      const Prepared& p = s.shapes[c * n + o];
      if (p.cells == 0 || p.repeat || p.width > wc.width || p.height > wc.max_height) continue;
      const auto h = static_cast<Row>(p.height);
      for (Row x = 0; x + static_cast<Row>(p.width) <= W; ++x) {
        const std::size_t at = o * wc.width + static_cast<std::size_t>(x);
        ColumnPositions& e = table != nullptr ? table->positions[at] : scratch;
        if (table == nullptr || table->stale[at] != 0) {
          evaluate(p, x, W, H, e);
          ++evaluations_;
          if (table != nullptr) table->stale[at] = 0;
        }
        if (e.horizon) consider(e.waste_horizon, e.y_horizon + h, x, e.y_horizon, static_cast<int>(o));
        if (e.hole) consider(e.waste_hole, e.y_hole + h, x, e.y_hole, static_cast<int>(o));
      }
    }
    if (near_.empty()) return false;
    // Touching perimeter: of the least-waste candidates, the one that best hugs the packed charts and the
    // image border (waste − kContactWeight · contact) wins; lateral gaps become slivers no chart can use.
    double best_score = std::numeric_limits<double>::max();
    Candidate best;
    for (const Candidate& cd : near_) {
      const Prepared& q = s.shapes[c * n + static_cast<std::size_t>(cd.o)];
      std::int64_t contact = 0;
      for (const auto& [rx, ry] : q.rim) {
        const Row gx = cd.x + rx, gy = cd.y + ry;
        if (gx < 0 || gy < 0 || gx >= W) ++contact;
        else if (gy < H && occ_[static_cast<std::size_t>(gy) * wc.width + static_cast<std::size_t>(gx)] != 0) ++contact;
      }
      const double score = static_cast<double>(cd.waste) - kContactWeight * static_cast<double>(contact);
      if (score < best_score) {
        best_score = score;
        best = cd;
      }
    }
    const Prepared& p = s.shapes[c * n + static_cast<std::size_t>(best.o)];
    place(p, best.x, best.y);
    invalidate(s, best.x, static_cast<Row>(p.width), W);
    out.placements[c] = {best.o, static_cast<std::uint32_t>(best.x), static_cast<std::uint32_t>(best.y)};
    out.cells += p.cells;
    ++placements_;
    packed_top = std::max(packed_top, best.top);
    out.height = std::max(static_cast<std::uint32_t>(packed_top), wc.min_height);
    if (std::uint64_t{out.height} * wc.width > area_limit) return false;
  }
  return true;
}

void RectPacker::evaluate(const Prepared& p, Row x, Row W, Row H, ColumnPositions& out) const {
  const auto w = static_cast<Row>(p.width);
  const auto h = static_cast<Row>(p.height);
  const Row* low = p.low.data();
  const Row jb = x == 0 ? 1 : 0;            // dilated column −1 lies outside the image
  const Row je = x + w == W ? w + 1 : w + 2;  // dilated column w lies outside the image
  const Row* hz = horizon_.data() + x;       // hz[j − 1] is the horizon under dilated column j
  const Row* fl = lowest_free_.data() + x;   // fl[j − 1]: the lowest free row of its column
  Row y = 0;
  Row lower = 0;  // no position of this column range is below it
  Row binding = jb;  // a column that sets y: below y it must lie in a hole
  std::int64_t sum_gap = 0;
  Row columns = 0;
  if (jb == 0 && je == w + 2) {  // every dilated column inside the image: the vector pass
    const ColumnSums sums = column_sums(hz - 1, fl - 1, low, je);
    if (sums.rise > 0) {
      y = sums.rise;
      while (hz[binding - 1] - low[binding] != y) ++binding;  // the first column that sets y
    }
    lower = std::max(lower, sums.floor);
    sum_gap = p.low_sum - sums.horizon;
    columns = p.columns;
  } else {
    for (Row j = jb; j < je; ++j) {
      const Row l = low[j];
      if (l == kEmpty) continue;
      const Row hh = hz[j - 1];
      if (hh - l > y) {
        y = hh - l;
        binding = j;
      }
      lower = std::max(lower, fl[j - 1] - l);
      sum_gap += l - hh;
      ++columns;
    }
  }
  out.horizon = y + h <= H;
  out.waste_horizon = sum_gap + std::int64_t{columns} * y + p.hollow;
  out.y_horizon = y;
  // A lower position inside the holes under the horizon, when the columns have any.
  Row yh = 0;
  std::int64_t gap = 0;
  const Row binding_rows = p.top[static_cast<std::size_t>(binding)] - low[binding] + 1;
  out.hole = lower < y && tallest_hole_[static_cast<std::size_t>(x + binding - 1)] >= binding_rows &&
             fit_in_holes(p, x, jb, je, binding, lower, y, yh, gap) && yh + h <= H;
  out.waste_hole = gap + p.hollow;
  out.y_hole = yh;
}

void RectPacker::invalidate(const ScaleShapes& s, Row x, Row width, Row W) {
  const std::size_t n = static_cast<std::size_t>(orientations_);
  for (std::size_t k = 0; k < tables_.size(); ++k) {
    ClassTable& t = tables_[k];
    if (!t.used) continue;
    for (std::size_t o = 0; o < n; ++o) {
      // Column x' reads image columns x' − 1 .. x' + w: it changed when those meet [x, x + width).
      const auto w = static_cast<Row>(s.shapes[s.class_first[k] * n + o].width);
      const Row from = std::max<Row>(0, x - w), to = std::min<Row>(W - 1, x + width);
      if (from <= to)
        std::fill(t.stale.begin() + static_cast<std::ptrdiff_t>(o * static_cast<std::size_t>(W) + static_cast<std::size_t>(from)),
                  t.stale.begin() + static_cast<std::ptrdiff_t>(o * static_cast<std::size_t>(W) + static_cast<std::size_t>(to) + 1),
                  std::uint8_t{1});
    }
  }
}

void assign_shape_classes(ScaleShapes& s, std::size_t charts, std::size_t orientations) {
  s.shape_class.assign(charts, kNoClass);
  s.class_first.clear();
  // Everything evaluate() reads of a chart's shapes, per orientation (rims, cells and plain columns are
  // the chart's own: contact and placement read them from the chart itself).
  std::map<std::vector<Row>, std::vector<std::size_t>> groups;
  for (std::size_t c = 0; c < charts; ++c) {
    std::vector<Row> key;
    for (std::size_t o = 0; o < orientations; ++o) {
      const Prepared& p = s.shapes[c * orientations + o];
      key.insert(key.end(), {static_cast<Row>(p.width), static_cast<Row>(p.height), p.cells == 0 ? 0 : 1,
                             p.repeat ? 1 : 0, static_cast<Row>(p.hollow), p.columns});
      key.insert(key.end(), p.low.begin(), p.low.end());
      key.insert(key.end(), p.top.begin(), p.top.end());
    }
    groups[std::move(key)].push_back(c);
  }
  std::vector<const std::vector<std::size_t>*> large;
  for (const auto& [key, members] : groups)
    if (members.size() >= kMinClassCharts) large.push_back(&members);
  // The largest classes, ties by their first chart: the same classes whatever the map's order.
  std::sort(large.begin(), large.end(), [](const auto* a, const auto* b) {
    return a->size() != b->size() ? a->size() > b->size() : a->front() < b->front();
  });
  if (large.size() > kMaxClasses) large.resize(kMaxClasses);
  for (const std::vector<std::size_t>* members : large) {
    for (const std::size_t c : *members) s.shape_class[c] = static_cast<std::uint32_t>(s.class_first.size());
    s.class_first.push_back(members->front());
  }
}

bool RectPacker::fit_in_holes(const Prepared& p, Row x, Row jb, Row je, Row binding, Row lower, Row below,
                              Row& y_out, std::int64_t& gap) const {
  const Row* low = p.low.data();
  const Row* top = p.top.data();
  // The first y' ≥ y at which dilated column j lies in one free run of its image column.
  const auto need = [&](Row j, Row y) {
    const auto col = static_cast<std::size_t>(x + j - 1);
    if (horizon_[col] <= y + low[j]) return y;  // above the horizon, and every hole lies below it
    const Holes& hs = holes_[col];
    for (int i = 0; i < hs.count; ++i) {
      const Row cand = std::max(y, hs.run[i].lo - low[j]);
      if (cand + top[j] <= hs.run[i].hi) return cand;
    }
    return std::max(y, horizon_[col] - low[j]);
  };
  Row y = need(binding, lower);  // the column that set the horizon position fails first, if any does
  if (y >= below) return false;
  for (bool moved = true; moved;) {  // raise y to the first row that every column allows
    moved = false;
    for (Row j = jb; j < je; ++j) {
      if (low[j] == kEmpty) continue;
      const Row n = need(j, y);
      if (n >= below) return false;  // the horizon position is as low: nothing gained
      if (n > y) {
        y = n;
        moved = true;
      }
    }
  }
  gap = 0;
  for (Row j = jb; j < je; ++j) {
    if (low[j] == kEmpty) continue;
    const auto col = static_cast<std::size_t>(x + j - 1);
    Row floor = horizon_[col];
    const Holes& hs = holes_[col];
    for (int i = 0; i < hs.count; ++i)
      if (hs.run[i].lo <= y + low[j] && y + low[j] <= hs.run[i].hi) floor = hs.run[i].lo;
    gap += y + low[j] - floor;
  }
  y_out = y;
  return true;
}

void RectPacker::place(const Prepared& p, Row x, Row y) {
  constexpr Row kMinRun = 3;
  for (std::size_t j = 0; j < p.width; ++j) {
    if (p.high[j] == kEmpty) continue;
    const std::size_t col = static_cast<std::size_t>(x) + j;
    const Row lo = y + p.plain_low[j];
    const Row hi = y + p.high[j];
    for (Row r = lo; r <= hi; ++r) occ_[static_cast<std::size_t>(r) * holes_.size() + col] = 1;
    Holes& hs = holes_[col];
    Span add[2];
    int adds = 0;
    if (lo >= horizon_[col]) {
      if (lo - horizon_[col] >= kMinRun) add[adds++] = {horizon_[col], lo - 1};
      horizon_[col] = hi + 1;
    } else {
      for (int i = 0; i < hs.count; ++i) {
        if (!(hs.run[i].lo <= lo && hi <= hs.run[i].hi)) continue;
        const Span whole = hs.run[i];
        std::copy(hs.run + i + 1, hs.run + hs.count, hs.run + i);
        --hs.count;
        if (lo - whole.lo >= kMinRun) add[adds++] = {whole.lo, lo - 1};
        if (whole.hi - hi >= kMinRun) add[adds++] = {hi + 1, whole.hi};
        break;
      }
    }
    for (int a = 0; a < adds; ++a) {
      Span r = add[a];
      if (hs.count == kMaxHoles) {  // keep the longer runs
        Span* shortest = std::min_element(hs.run, hs.run + hs.count, [](const Span& u, const Span& v) { return u.hi - u.lo < v.hi - v.lo; });
        if (shortest->hi - shortest->lo >= r.hi - r.lo) continue;
        std::copy(shortest + 1, hs.run + hs.count, shortest);
        --hs.count;
      }
      Span* at = std::find_if(hs.run, hs.run + hs.count, [&](const Span& u) { return u.lo > r.lo; });
      std::copy_backward(at, hs.run + hs.count, hs.run + hs.count + 1);
      *at = r;
      ++hs.count;
    }
  }
  for (std::size_t j = 0; j < p.width; ++j) {
    const std::size_t col = static_cast<std::size_t>(x) + j;
    const Holes& hs = holes_[col];
    lowest_free_[col] = hs.count == 0 ? horizon_[col] : hs.run[0].lo;
    std::int64_t free = std::max<std::int64_t>(0, height_ - std::max(horizon_[col], 0));
    for (int i = 0; i < hs.count; ++i) free += std::max(0, std::min(hs.run[i].hi, height_ - 1) - std::max(hs.run[i].lo, 0) + 1);
    free_cells_ += free - col_free_[col];
    col_free_[col] = free;
    tallest_hole_[col] = 0;
    for (int i = 0; i < hs.count; ++i) tallest_hole_[col] = std::max(tallest_hole_[col], hs.run[i].hi - hs.run[i].lo + 1);
  }
}

}  // namespace gimforge::pack_detail
