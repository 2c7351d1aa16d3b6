#pragma once
/// \file pack.h
/// Chart packing of multi-chart geometry images (Sander et al. 2003, §4.3): the "Tetris" horizon packer of
/// Lévy et al. 2002 extended to 16 orientations per chart, with the wasted-space rule of the paper's Fig. 3
/// (the gap between the atlas's upper horizon and the chart's lower horizon, plus the unused space inside the
/// chart's own upper and lower envelopes), into an arbitrary rectangle of at most `max_samples` samples with
/// aspect ratio below `max_aspect`. The chart scale starts at the value the caller gives (100 % packing
/// efficiency) and is reduced by 1 % steps until a packing succeeds; the last step is then refined (the scale
/// halfway between the last failing and the first packing step is tried too).
///
/// The packer knows charts only through their discrete shapes (ShapeSource), so it packs exactly what the
/// sampling will rasterize. Charts never touch: between samples of two charts there is at least one
/// undefined sample in each of the 8 directions (no 2×2 quad of the image holds samples of two charts).
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "kernels/core/errors.h"
#include "kernels/core/progress.h"

namespace gimforge {

/// A chart's discrete shape in one orientation at one scale: `width` × `height` cells, row-major, row 0 at
/// the bottom (y grows upward), 1 where the chart defines a sample. The shape is tight: its first and last
/// row and column each hold at least one defined cell. An empty shape (0 × 0) means the chart has no sample.
struct ChartShape {
  std::uint32_t width{0};
  std::uint32_t height{0};
  std::vector<std::uint8_t> cells;
  [[nodiscard]] bool at(std::uint32_t x, std::uint32_t y) const { return cells[std::size_t{y} * width + x] != 0; }
};

/// Rasterizes chart `chart` rotated by orientation · 2π / orientations and scaled by `scale` (samples per
/// parameter unit). Called many times (it may be costly: the packer keeps what it needs per scale).
using ShapeSource = std::function<ChartShape(std::size_t chart, int orientation, double scale)>;

/// Where one chart went: its shape (orientation at Packing::scale) has its cell (0, 0) at image sample
/// (x, y) (column x, row y of the rectangle, row 0 at the bottom).
struct Placement {
  int orientation{0};
  std::uint32_t x{0};
  std::uint32_t y{0};
};

struct Packing {
  std::uint32_t width{0};              ///< rectangle W
  std::uint32_t height{0};             ///< rectangle H (the packed height)
  double scale{0.0};                   ///< the scale the shapes were made at
  int scale_steps{0};                  ///< 1 % reductions from the initial scale: the step search's answer
  /// The part of the step before scale_steps regained by the refinement (0, or 0.5, 0.25, … : the scale is
  /// initial · (1 − scale_step)^(scale_steps − refined_steps)).
  double refined_steps{0.0};
  std::vector<Placement> placements;   ///< one per chart, in chart order
  std::size_t defined_samples{0};      ///< cells of all placed shapes
  /// The packer's work: charts placed over every packing it tried (with several threads this includes widths
  /// packed beside the one that decided a probe, so it depends on the thread count; the packing does not).
  std::uint64_t charts_placed{0};
  std::uint64_t positions_evaluated{0};  ///< (orientation, column) positions evaluated, the same way
  [[nodiscard]] double efficiency() const {  ///< defined samples / rectangle area (the paper's packing efficiency)
    return width == 0 || height == 0 ? 0.0 : static_cast<double>(defined_samples) / (double(width) * height);
  }
};

struct PackOptions {
  std::size_t max_samples{65536};  ///< upper bound of the rectangle's area W·H
  double max_aspect{4.0};          ///< W/H and H/W stay below this
  int orientations{16};            ///< rotations tried per chart, evenly spaced
  double scale_step{0.01};         ///< the scale is multiplied by (1 − scale_step) until the charts fit
  int max_scale_steps{2000};       ///< bound on the steps (InvalidInput beyond it: the charts cannot be packed)
  /// Perturbed chart orders tried at the steps above the search's answer (ours, pack.cpp); 0: none.
  int order_restarts{8};
  /// Refinement of the answer: the interval between the step before it (which failed) and the answer is
  /// halved this many times, each midpoint tried with the plain and the restarts' chart orders, the interval
  /// kept on the side that packs (ours, pack.cpp). 0: none.
  int refine_levels{1};
  /// Up to this many charts (with cells) the restarts and the refinement try every width the search does;
  /// beyond, 32 · full_probe_charts / charts of them (at least 8), those nearest the plain answer's width.
  std::size_t full_probe_charts{256};
  /// Charts of one shape (every orientation alike: a scan's small fragments) keep the positions evaluated
  /// for the last of them, and only the columns a placement touched since are evaluated again. Exact: the
  /// same packing; false evaluates every position for every chart (the reference the tests compare with).
  bool shape_classes{true};
  /// Where the step search starts (a caller that packed similar charts before passes that answer: the
  /// search then probes around it instead of from step 0). Only the number of trials depends on it, as long
  /// as packability is monotone in the step.
  int first_step{0};
  /// Steps below this one are known not to pack (the caller found a chart longer, in every orientation, than
  /// the longest side of any allowed rectangle there) and are never tried: their shapes are not rasterized.
  /// Above max_scale_steps: InvalidInput at once.
  int min_step{0};
  /// Called with the step search's packing before the order restarts; returning false skips them (a caller
  /// that will change the charts and pack again). pack_charts then returns that packing.
  std::function<bool(const Packing&)> restart_if{};
  ProgressCallback progress{};     ///< stage "pack"
};

/// What pack_charts throws when the charts do not fit the budget at any allowed scale (a larger budget helps),
/// as opposed to bad options or shapes (InvalidInput).
class ChartsDoNotFit : public InvalidInput {
 public:
  using InvalidInput::InvalidInput;
};

/// Packs `num_charts` charts. Charts are placed largest first (by defined cells); each in the orientation and
/// column that waste the least space, resting on the horizon or inside a hole left under packed charts, the
/// least-waste candidates re-ranked by how much of their outline touches packed charts (pack.cpp). Among the rectangles tried at the first scale where one succeeds, the
/// one of least area W·H wins. Throws InvalidInput when nothing fits even after max_scale_steps (or a shape
/// is larger than any allowed rectangle at every scale: ChartsDoNotFit), Cancelled via progress.
/// The least step count is found by exponential and binary search (assuming that charts that pack at a
/// scale also pack at every smaller one), then the few steps below it are re-checked, and the steps above
/// the answer get `order_restarts` perturbed chart orders; with many usable widths only an even spread of
/// them, refined around the best, is tried; last the scale between the answer and the step before it is tried
/// (refine_levels; details in pack.cpp). With more than full_probe_charts charts the restarts and the
/// refinement try fewer widths, those nearest the plain answer's (down to 8). A packing gives up once the charts
/// left cannot fit in the free rows by their cells or by their footprints (pack.cpp). The widths of a probe are
/// packed in parallel, as many at once as TBB may run threads (-j); the result does not depend on that number.
[[nodiscard]] Packing pack_charts(std::size_t num_charts, double initial_scale, const ShapeSource& shape,
                                  const PackOptions& options = {});

}  // namespace gimforge
