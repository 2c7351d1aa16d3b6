#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "jobs/cli/commands.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/load_mesh.h"
#include "jobs/progress.h"
#include "jobs/reports.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/hausdorff.h"

namespace gimforge::cli {

int run_metrics(const MetricsOptions& options) {
  const jobs::LoadPolicy policy{.repair = true, .warn = true};
  jobs::LoadedMesh a = jobs::load_mesh(options.a, policy);
  jobs::LoadedMesh b = jobs::load_mesh(options.b, policy);
  // One common frame, A's local one, before Embree's float BVH sees them: distances do not depend on
  // where the meshes lie (scans in georeferenced coordinates).
  const Vec3 origin = jobs::local_frame_origin(a.mesh);
  jobs::to_local_frame(a.mesh, origin);
  jobs::to_local_frame(b.mesh, origin);
  const EmbreeDevice device;
  jobs::TerminalProgress progress("metrics", options.progress);
  HausdorffOptions hopt;
  hopt.samples = options.samples;
  hopt.seed = options.seed;
  hopt.include_vertices = options.include_vertices;
  hopt.progress = progress.callback();
  const HausdorffResult r = symmetric_hausdorff(device, a.mesh, b.mesh, hopt);
  progress.finish();
  if (options.json)
    fmt::print("{}\n", jobs::metrics_json(r).dump(2));
  else
    fmt::print("{}", jobs::metrics_text(r, options.a, options.b));
  return kExitOk;
}

}  // namespace gimforge::cli
