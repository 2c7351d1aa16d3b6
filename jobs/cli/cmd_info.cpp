#include <cstdio>

#include <fmt/format.h>

#include "jobs/cli/commands.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/load_mesh.h"
#include "jobs/reports.h"
#include "kernels/core/topology.h"

namespace gimforge::cli {

int run_info(const InfoOptions& options) {
  // info reports what the file holds: topological defects are described, not refused.
  const jobs::LoadedMesh m = jobs::load_mesh(options.mesh, {.repair = true, .warn = !options.json});
  const TopologyReport topology = analyze_topology(m.mesh);
  if (options.json)
    fmt::print("{}\n", jobs::info_json(m, topology).dump(2, ' ', false, nlohmann::json::error_handler_t::replace));
  else
    fmt::print("{}", jobs::info_text(m, topology));
  return kExitOk;
}

}  // namespace gimforge::cli
