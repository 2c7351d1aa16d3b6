#include "jobs/cli/convert_common.h"

#include <fmt/format.h>

namespace gimforge::cli {

void print_fidelity(const jobs::Conversion& c) {
  if (!c.fidelity) {
    fmt::print("  fidelity         not measured (--no-metric)\n");
    return;
  }
  const HausdorffResult& h = *c.fidelity;
  fmt::print("  fidelity         PSNR {:.2f} dB (rms {:.4e}, max {:.4e}, diag {:.6g})\n", h.psnr, h.rms, h.max, h.diag);
}

void print_adaptive(const jobs::Conversion& c) {
  const auto& n = c.numbers;
  if (!n.contains("adapt_max_before")) return;
  fmt::print("  adaptive         max {:.4g} -> {:.4g}, rms {:.4g} -> {:.4g} (local Hausdorff), {} moves in {} "
             "round(s), {:.2f} s\n",
             n.at("adapt_max_before"), n.at("adapt_max_after"), n.at("adapt_rms_before"), n.at("adapt_rms_after"),
             n.at("adapt_moves"), n.at("adapt_rounds_run"), n.at("seconds_adapt"));
  if (!n.contains("roi_samples_before")) return;
  fmt::print("  roi              {} -> {} samples; ROI -> input max {:.4g} -> {:.4g}, rms {:.4g} -> {:.4g}{}\n",
             n.at("roi_samples_before"), n.at("roi_samples_after"), n.at("roi_max_d2_before"), n.at("roi_max_d2_after"),
             n.at("roi_rms_d2_before"), n.at("roi_rms_d2_after"),
             n.contains("roi_kept_start") && n.at("roi_kept_start") != 0.0 ? " (start grid kept)" : "");
  fmt::print("  outside roi      max {:.4g} -> {:.4g}, rms {:.4g} -> {:.4g}\n", n.at("outside_max_d2_before"),
             n.at("outside_max_d2_after"), n.at("outside_rms_d2_before"), n.at("outside_rms_d2_after"));
}

void print_times(const ConvertSummary& s, const std::string& stages) {
  const jobs::Conversion& c = s.conversion;
  fmt::print("  time             {}; construction {:.2f} s, metric {:.2f} s, total {:.2f} s (loading and writing "
             "included)\n",
             stages, c.seconds_construct, c.seconds_metric, s.seconds_command);
}

}  // namespace gimforge::cli
