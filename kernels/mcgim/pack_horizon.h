#pragma once
/// \file pack_horizon.h
/// The horizon packer's one packing of charts into a rectangle (kernels/mcgim/pack.cpp's notes: gutter,
/// holes, wasted space, touching perimeter), apart from the search over scales and widths in pack.cpp, which
/// runs several of them at once. Internal to pack.cpp.
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "kernels/mcgim/pack.h"

namespace gimforge::pack_detail {

using Row = std::int32_t;
constexpr Row kEmpty = std::numeric_limits<Row>::max() / 4;  // an envelope entry of a column without cells
constexpr std::uint64_t kMaxSide = (std::uint64_t{1} << 30) - 1;  // sides stay in int32 arithmetic
constexpr std::size_t kRerank = 64;       // least-waste candidates re-ranked by their touching perimeter
constexpr double kContactWeight = 5.0;    // wasted cells one touching rim cell is worth

/// A position of a chart: (orientation o, column x, row y), its wasted space and its top row.
struct Candidate {
  std::int64_t waste{0};
  std::int32_t top{0};
  std::int32_t x{0};
  std::int32_t y{0};
  int o{0};
};

/// Orders candidates by waste, then by top.
inline bool less_waste(const Candidate& a, const Candidate& b) { return a.waste != b.waste ? a.waste < b.waste : a.top < b.top; }

/// One chart in one orientation at one scale, reduced to what the horizon packer needs.
struct Prepared {
  std::uint32_t width{0};
  std::uint32_t height{0};
  std::size_t cells{0};
  /// Cells of the shape grown by one cell to the right and one up (each cell c becomes the 2×2 block at c).
  /// Charts never come closer than Chebyshev distance 2, so the grown shapes of packed charts never overlap.
  std::size_t footprint{0};
  std::int64_t hollow{0};  ///< undefined cells between each column's lowest and highest defined cell
  std::vector<Row> low;    ///< width + 2 entries: lowest row of the dilated shape in column j − 1 (or kEmpty)
  std::vector<Row> top;    ///< width + 2 entries: highest row of the dilated shape in column j − 1 (or −kEmpty)
  std::vector<Row> plain_low;  ///< width entries: lowest defined row of the plain shape per column (or kEmpty)
  std::vector<Row> high;   ///< width entries: highest defined row of the plain shape per column (or kEmpty)
  std::vector<std::pair<Row, Row>> rim;  ///< cells 4-adjacent to the dilated shape, outside it (x, y offsets)
  std::int64_t low_sum{0};  ///< Σ of low over the dilated columns that have cells (all width + 2 of them)
  Row columns{0};           ///< how many of the width + 2 dilated columns have cells
  bool repeat{false};      ///< the same cells as an earlier orientation of the chart: its positions are skipped
};

/// A run of free rows [lo, hi] below a column's horizon (a hole left under a packed chart).
struct Span {
  Row lo{0};
  Row hi{0};
};

/// The holes of one image column, bottom first. At most kMaxHoles are kept: when a placement would make
/// more, the shortest is treated as taken (the packing stays valid, it only forgoes that hole).
constexpr int kMaxHoles = 4;
struct Holes {
  int count{0};
  Span run[kMaxHoles];
};

/// An order in which the charts are placed.
struct ChartOrder {
  std::vector<std::size_t> charts;  ///< charts with cells, in placement order
  std::vector<std::uint64_t> rest;  ///< rest[i]: Σ of the fewest cells over orientations of charts[i..]
  std::vector<std::uint64_t> rest_footprint;  ///< rest_footprint[i]: the same for the footprints
};

/// All shapes at one scale, plus bounds derived from them.
struct ScaleShapes {
  double scale{0.0};
  std::vector<Prepared> shapes;    ///< chart · orientations + orientation
  /// orders[0]: most cells first (ties: lower index); orders[r], r ≥ 1: the perturbed orders of the
  /// restarts (most cells · (1 + kOrderJitter · u), u ∈ [0, 1) a hash of chart and r)
  std::vector<ChartOrder> orders;
  /// Per chart, its shape class: charts whose positions are evaluated alike in every orientation (the same
  /// sizes, envelopes and hollow cells: a scan's thousands of two- and three-cell fragments fall into a few
  /// classes) share one, whose positions RectPacker keeps between its charts; kNoClass for the others.
  std::vector<std::uint32_t> shape_class;
  std::vector<std::size_t> class_first;  ///< per class, its first chart (whose shapes stand for the class)
  std::uint64_t min_cells{0};      ///< Σ over charts of their fewest cells over orientations
  std::uint64_t width_bound{0};    ///< Σ over charts of (widest orientation + 1): a wider image never helps
  std::uint64_t min_width{0};      ///< max over charts of their narrowest orientation
};

constexpr std::uint32_t kNoClass = std::numeric_limits<std::uint32_t>::max();
constexpr std::size_t kMinClassCharts = 16;  // a class keeps its positions when it has this many charts
constexpr std::size_t kMaxClasses = 32;      // the largest classes that do (each a W × orientations table)

/// Sets s.shape_class and s.class_first from s.shapes (`orientations` per chart).
void assign_shape_classes(ScaleShapes& s, std::size_t charts, std::size_t orientations);

/// A usable rectangle width with its height bound and the least height its aspect bound allows.
struct WidthChoice {
  std::uint32_t width{0};
  std::uint32_t max_height{0};
  std::uint32_t min_height{0};
};

/// The outcome of one horizon packing into a W × H rectangle.
struct RectPacking {
  std::uint32_t width{0};
  std::uint32_t height{0};  ///< packed height, raised to the aspect bound's minimum
  std::vector<Placement> placements;
  std::size_t cells{0};
};

/// The two positions of a shape at one column: resting on the horizon, and lower inside the holes under it.
struct ColumnPositions {
  std::int64_t waste_horizon{0};
  std::int64_t waste_hole{0};
  Row y_horizon{0};
  Row y_hole{0};
  bool horizon{false};  ///< the horizon position lies within the height bound
  bool hole{false};     ///< a hole position exists, lower than the horizon's and within the bound
};

/// One horizon packing at a time (Packer runs several at once, one RectPacker each): the horizon, holes and
/// occupancy of the rectangle being packed.
class RectPacker {
 public:
  RectPacker(std::size_t num_charts, int orientations) : charts_(num_charts), orientations_(orientations) {}

  /// Packs the charts of `s` into the rectangle `wc` with the horizon packer. Returns false when some chart
  /// has no position within the height bound, or when the rectangle's area would exceed `area_limit`.
  bool pack_rectangle(const ScaleShapes& s, const ChartOrder& order, const WidthChoice& wc, std::uint64_t area_limit,
                      RectPacking& out);

  /// Charts placed by every pack_rectangle so far.
  [[nodiscard]] std::uint64_t placements() const { return placements_; }
  /// Positions (orientation, column) evaluated by every pack_rectangle so far.
  [[nodiscard]] std::uint64_t evaluations() const { return evaluations_; }

 private:
  /// The positions of `p` at column x of the W × H rectangle being packed. They depend only on the image
  /// columns x − 1 .. x + width (which place() changes only where a chart goes): a class's table of them
  /// stays valid for every column range no placement has touched since.
  void evaluate(const Prepared& p, Row x, Row W, Row H, ColumnPositions& out) const;

  /// Marks stale, in every class table in use, the columns whose positions a chart placed over image
  /// columns [x, x + width) changed.
  void invalidate(const ScaleShapes& s, Row x, Row width, Row W);

  /// The lowest row y in [lower, below) at which every dilated column j ∈ [jb, je) of `p` placed at column x
  /// lies in one run of free rows of its image column (a hole or above the horizon), if there is one.
  /// On success `gap` is Σ over those columns of the free rows between the column's run floor and the shape.
  bool fit_in_holes(const Prepared& p, Row x, Row jb, Row je, Row binding, Row lower, Row below, Row& y_out,
                    std::int64_t& gap) const;

  /// Marks the plain columns of `p` at (x, y) as taken: above the horizon the rows skipped become a hole,
  /// inside a hole the hole is split. Runs too short for any dilated column (< 3 rows) are dropped.
  void place(const Prepared& p, Row x, Row y);

  std::size_t charts_;
  int orientations_;
  std::uint64_t placements_{0};
  std::uint64_t evaluations_{0};
  std::vector<Row> horizon_;
  std::vector<Candidate> near_;
  std::vector<std::uint8_t> occ_;             ///< W × H: 1 where a packed chart's column range lies
  std::vector<Holes> holes_;               ///< per column, the free runs under its horizon, bottom first
  Row height_{0};                          ///< the rectangle's height bound H while packing
  std::vector<std::int64_t> col_free_;     ///< per column, its free rows in [0, H) (holes and above the horizon)
  std::int64_t free_cells_{0};             ///< Σ col_free_
  std::vector<Row> tallest_hole_;          ///< per column, the rows of its tallest hole (0: none)
  std::vector<Row> lowest_free_;           ///< per column, the lowest free row (a hole's floor or the horizon)
  /// Per shape class (ScaleShapes::shape_class) in use in this packing: its positions per orientation and
  /// column (orientations × W), and which of them are stale.
  struct ClassTable {
    bool used{false};
    std::vector<ColumnPositions> positions;
    std::vector<std::uint8_t> stale;
  };
  std::vector<ClassTable> tables_;
};

}  // namespace gimforge::pack_detail
