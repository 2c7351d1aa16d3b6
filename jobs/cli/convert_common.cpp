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

void print_times(const ConvertSummary& s, const std::string& stages) {
  const jobs::Conversion& c = s.conversion;
  fmt::print("  time             {}; construction {:.2f} s, metric {:.2f} s, total {:.2f} s (loading and writing "
             "included)\n",
             stages, c.seconds_construct, c.seconds_metric, s.seconds_command);
}

}  // namespace gimforge::cli
