// `gimforge convert --method mcgim`: the summary of a multi-chart geometry image (Sander et al. 2003; the
// conversion itself is jobs::convert_mesh).
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "io/printable.h"
#include "jobs/cli/convert_common.h"

namespace gimforge::cli {

void print_mcgim_summary(const ConvertSummary& s) {
  const McgimResult& result = s.conversion.mcgim.value();
  const McgimStats& st = result.stats;
  const MultiChartImage& image = result.image;
  fmt::print("{} -> {}:/mcgim/{}\n", io::printable(s.options.mesh), io::printable(s.options.output), io::printable(s.name));
  fmt::print("  image            {} wide x {} high = {} samples (bound {}), {} defined, {} unique vertices\n",
             image.width, image.height, image.samples(), s.options.method.samples, st.defined_samples, st.unique_vertices);
  std::string chosen;
  if (!st.auto_tried.empty()) {
    std::vector<std::string> tried;
    for (std::size_t i = 0; i < st.auto_tried.size(); ++i)
      tried.push_back(i < st.auto_same_as.size() && st.auto_same_as[i] != 0
                          ? fmt::format("{}: the charts of {}", st.auto_tried[i], st.auto_same_as[i])
                          : fmt::format("{}: rms {:.3g}{}", st.auto_tried[i], st.auto_rms[i],
                                        st.auto_tried[i] == st.auto_kept ? ", kept" : ""));
    chosen = fmt::format(" (--charts auto tried {}{})", fmt::join(tried, ", "),
                         st.charts != st.auto_kept ? "; seeds are added where a chart would not be a disk" : "");
  }
  fmt::print("  charts           {}{}; chartification {} after {} rounds{}\n", st.charts, chosen,
             st.chartify_converged ? "converged" : (st.chartify_cycle ? "stopped at a cycle" : "stopped at the bound"),
             st.chartify_iterations, st.extra_seeds > 0 ? fmt::format(", {} seeds added for disk charts", st.extra_seeds) : "");
  // Charts without surface area have no stretch (NaN): the range is over the others.
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (double e : st.chart_efficiency)
    if (std::isfinite(e)) lo = std::min(lo, e), hi = std::max(hi, e);
  fmt::print("  stretch eff.     {:.4f} in total (charts {:.4f} .. {:.4f}){}{}\n", st.stretch.efficiency, lo, hi,
             st.optimizer_fallbacks > 0 ? fmt::format(", {} charts kept Floater's map", st.optimizer_fallbacks) : "",
             st.boundary_folds > 0 ? fmt::format(", {} boundary folds narrower than a sample kept", st.boundary_folds) : "");
  std::vector<std::string> cut;  // what cutting the input into an oriented 2-manifold changed
  if (st.cut_nonmanifold_edges > 0) cut.push_back(fmt::format("{} non-manifold edges made boundaries", st.cut_nonmanifold_edges));
  if (st.cut_orientation_edges > 0)
    cut.push_back(fmt::format("{} edges whose faces could not agree made boundaries", st.cut_orientation_edges));
  if (st.flipped_faces > 0) cut.push_back(fmt::format("{} faces reversed", st.flipped_faces));
  if (st.split_vertices > 0) cut.push_back(fmt::format("{} vertices split into fans", st.split_vertices));
  if (st.arealess_faces > 0) cut.push_back(fmt::format("{} faces of pieces without area left out", st.arealess_faces));
  if (!cut.empty()) fmt::print("  input cut        {}\n", fmt::join(cut, ", "));
  fmt::print("  packing eff.     {:.4f} ({:g} scale steps of 1 %)\n", st.packing_efficiency, st.scale_steps);
  fmt::print("  zipper           {} cut-nodes, {} cut-paths, {} samples unified\n", st.zipper.cut_nodes,
             st.zipper.cut_paths, st.zipper.unified_samples);
  if (s.options.method.optimize)
    fmt::print("  optimization     energy {:.4g} -> {:.4g}\n", st.fit_energy_before, st.fit_energy_after);
  print_fidelity(s.conversion);
  std::string stages = fmt::format("chartify {:.2f} s, parametrize {:.2f} s, pack {:.2f} s, sample {:.2f} s, zipper {:.2f} s",
                                   st.seconds_chartify, st.seconds_parametrize, st.seconds_pack, st.seconds_sample,
                                   st.seconds_zipper);
  if (s.options.method.optimize) stages += fmt::format(", optimize {:.2f} s", st.seconds_optimize);
  print_times(s, stages);
}

nlohmann::json mcgim_json_fields(const ConvertSummary& s) {
  const McgimResult& r = s.conversion.mcgim.value();
  nlohmann::json j = {{"width", r.image.width},
                      {"height", r.image.height},
                      {"chart_efficiency", r.stats.chart_efficiency},
                      {"input_faces", s.conversion.input_faces},
                      {"input_vertices", s.conversion.input_vertices}};
  if (!r.stats.auto_tried.empty())
    j["charts_tried"] = {{"charts", r.stats.auto_tried}, {"rms", r.stats.auto_rms}, {"same_as", r.stats.auto_same_as}};
  return j;
}

}  // namespace gimforge::cli
