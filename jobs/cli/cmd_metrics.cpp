#include <memory>
#include <optional>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>

#include "jobs/cli/commands.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/brick_metrics.h"
#include "jobs/distributed_metrics.h"
#include "jobs/load_mesh.h"
#include "jobs/memory_budget.h"
#include "jobs/progress.h"
#include "jobs/reports.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "mpi/agree.h"
#include "mpi/environment.h"
#include "mpi/mpi_comm.h"

namespace gimforge::cli {

int run_metrics(const MetricsOptions& options) {
  // Under an MPI launcher the ranks split the queries (jobs/distributed_metrics.h) and rank 0 prints; alone,
  // no MPI is started.
  std::optional<mpi::MpiEnvironment> mpi_env;
  mpi::Comm comm = mpi::Comm::serial();
  if (mpi::launched_by_mpi()) {
    mpi_env.emplace();
    comm = mpi::mpi_world();
  }
  // One thread per rank unless -j says otherwise (ranks are the parallelism, as in batch).
  std::unique_ptr<tbb::global_control> one_thread;
  if (comm.size() > 1 && options.threads == 0)
    one_thread = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, 1);
  try {
    const EmbreeDevice device;
    jobs::TerminalProgress progress("metrics", options.progress && comm.rank() == 0);
    HausdorffOptions hopt;
    hopt.samples = options.samples;
    hopt.seed = options.seed;
    hopt.include_vertices = options.include_vertices;
    hopt.progress = progress.callback();
    const auto print = [&](const HausdorffResult& r) {
      progress.finish();
      if (comm.rank() != 0) return kExitOk;
      if (options.json)
        fmt::print("{}\n", jobs::metrics_json(r).dump(2, ' ', false, nlohmann::json::error_handler_t::replace));
      else
        fmt::print("{}", jobs::metrics_text(r, options.a, options.b));
      return kExitOk;
    };
    // Both ways hold the samples of a direction in each rank: refused up front, with the file named (by bricks it
    // ended as an unattributed "out of memory" on every rank).
    mpi::run_agreed(comm, [&] {
      jobs::check_memory(options.a, jobs::metric_bytes(options.samples), fmt::format("--samples {}", options.samples),
                         "lower --samples");
    });
    // Two binary PLY triangle files under mpirun: no rank reads either mesh whole (jobs/brick_metrics.h).
    bool bricks = false;
    if (comm.size() > 1) mpi::run_agreed(comm, [&] { bricks = jobs::readable_in_bricks(options.a, options.b); });
    if (bricks) return print(jobs::brick_hausdorff(comm, device, options.a, options.b, hopt));
    const jobs::LoadPolicy policy{.repair = true, .warn = comm.rank() == 0, .topology = false};
    jobs::LoadedMesh a, b;
    mpi::run_agreed(comm, [&] {
      a = jobs::load_mesh(options.a, policy);
      b = jobs::load_mesh(options.b, policy);
      for (const jobs::LoadedMesh* m : {&a, &b})
        if (!(surface_area(m->mesh) > 0.0))
          throw InvalidInput(fmt::format("{}: the surface has no area (the metric samples it by area)", m->path.string()));
      // One common frame, A's local one, before Embree's float BVH sees them: distances do not depend on
      // where the meshes lie (scans in georeferenced coordinates).
      const Vec3 origin = jobs::local_frame_origin(a.mesh);
      jobs::to_local_frame(a.mesh, origin);
      jobs::to_local_frame(b.mesh, origin);
    });
    try {
      return print(jobs::distributed_hausdorff(comm, device, a.mesh, b.mesh, hopt));
    } catch (const NumericalError& e) {  // "distance A->B: ...": name the files
      throw NumericalError(fmt::format("A = {}, B = {}: {}", options.a, options.b, e.what()));
    }
  } catch (const mpi::PeerFailed&) {
    // The failing rank prints the cause and exits 1, which makes the job's status 1. Exiting 1 here too
    // would let the launcher tear the job down before that line is out (seen with 3-4 ranks).
    return kExitOk;
  }
}

}  // namespace gimforge::cli
