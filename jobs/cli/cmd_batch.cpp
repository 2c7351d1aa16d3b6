// `gimforge batch`: a collection of meshes converted by MPI ranks (rank 0 schedules, the others convert)
// into one consolidated archive, resumable after any crash. The run itself is jobs::run_batch
// (jobs/batch_run.h); this file adds the MPI world, signals, logs and threads of the process.
#include <algorithm>
#include <cstdlib>
#include <string_view>
#include <filesystem>
#include <optional>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <tbb/global_control.h>

#include "io/atomic_file.h"
#include "io/printable.h"
#include "io/xdmf.h"
#include "jobs/batch_run.h"
#include "jobs/cli/crash_guard.h"
#include "jobs/cli/commands.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/logging.h"
#include "kernels/core/errors.h"
#include "mpi/agree.h"
#include "mpi/environment.h"
#include "mpi/mpi_comm.h"
#include "mpi/shutdown.h"

namespace gimforge::cli {

namespace {

/// The exit code of a finished run, with its closing line where it stopped early.
int exit_code(const jobs::BatchOutcome& outcome, int signal, const std::string& output) {
  switch (outcome.status) {
    case jobs::BatchStatus::Done:
    case jobs::BatchStatus::AlreadyComplete:
    case jobs::BatchStatus::Worker: return kExitOk;
    case jobs::BatchStatus::Partial: return kExitPartial;
    case jobs::BatchStatus::Error: return kExitError;
    case jobs::BatchStatus::Stopped:
      if (signal != 0)
        fmt::print(stderr, "gimforge batch: stopped by signal {}; ", signal);
      else if (!outcome.lost_workers.empty())
        fmt::print(stderr, "gimforge batch: stopped after giving up on rank(s) {} (--worker-timeout), with items left "
                           "to convert; ", fmt::join(outcome.lost_workers, ", "));
      else
        fmt::print(stderr, "gimforge batch: stopped: a rank did not reach the barrier between rounds within "
                           "--worker-timeout, with items left to convert; ");
      fmt::print(stderr, "{} of {} items are committed in {}.work; run again with --resume to finish\n",
                 outcome.converted, outcome.total, io::printable(output));
      return kExitResumable;
  }
  return kExitError;
}

}  // namespace

int run_batch(const BatchOptions& given) {
  BatchOptions options = given;
  // Shards are files on disk like any other input: on --resume rank 0 reads them in child processes first,
  // while forking is still safe, and redoes those that do not read (crash_guard.h).
  if (options.resume && mpi::may_be_rank_zero()) options.unreadable_shards = probe_shards(options.output + ".work");
  mpi::ShutdownSignals signals;  // a signal during MPI start-up must not kill the job either
  // Alone (no launcher), no MPI is started, as for convert: a singleton start-up failed with a wall of PMIx
  // lines under a small file-size limit, and one process needs no communicator.
  std::optional<mpi::MpiEnvironment> mpi_env;
  mpi::Comm comm = mpi::Comm::serial();
  if (mpi::launched_by_mpi()) {
    mpi_env.emplace();
    comm = mpi::mpi_world();
  }
  try {  // the sidecar's place before any work, on every rank together (no rank left waiting)
    mpi::run_agreed(comm, [&] {
      if (options.xdmf && comm.rank() == 0) io::check_can_create(io::xdmf_sidecar_path(options.output));
    });
  } catch (const mpi::PeerFailed&) {
    return kExitOk;  // the failing rank prints the cause and exits 1 (see cmd_metrics.cpp)
  }
  if (!options.log_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(options.log_dir, ec);
    if (ec && !std::filesystem::is_directory(options.log_dir))  // the cause, not the log file's "No such file"
      throw IoError(fmt::format("{}: cannot create the --log-dir folder: {}", io::printable(options.log_dir), ec.message()));
    jobs::add_log_file((std::filesystem::path(options.log_dir) / fmt::format("rank-{}.log", comm.rank())).string(),
                       comm.rank());
  }
  // One thread per rank unless -j says otherwise: ranks are the parallelism, and results must not depend
  // on thread counts (bit-identical archives for any number of ranks).
  const tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                                    static_cast<std::size_t>(std::max(1, options.threads_per_rank)));
  const jobs::BatchOutcome outcome = jobs::run_batch(comm, options, [&signals] { return signals.requested(); });
  const bool complete = outcome.status == jobs::BatchStatus::Done || outcome.status == jobs::BatchStatus::Partial ||
                        outcome.status == jobs::BatchStatus::AlreadyComplete;
  int code = kExitError;
  try {
    if (options.xdmf && complete && comm.rank() == 0)
      fmt::print("wrote {}\n", io::printable(io::write_xdmf_sidecar(options.output).string()));
    code = exit_code(outcome, signals.signal(), options.output);
  } catch (const std::exception& e) {
    if (outcome.lost_workers.empty() && !outcome.unresponsive) throw;  // main() prints it
    fmt::print(stderr, "gimforge: error: {}\n", e.what());
  }
  if (!outcome.lost_workers.empty() || outcome.unresponsive) {  // the others wait in a collective: end them all
    const std::string why = outcome.unresponsive
                                ? std::string("a rank did not reach the barrier between rounds within --worker-timeout "
                                              "(stopped or hung outside any item)")
                                : fmt::format("rank(s) {} gave no answer within --worker-timeout and cannot be waited for",
                                              fmt::join(outcome.lost_workers, ", "));
    fmt::print(stderr, "gimforge batch: ending every rank with exit code {}: {} (the launcher reports the abort next)\n",
               code, why);
    comm.abort(code);
  }
  return code;
}

}  // namespace gimforge::cli
