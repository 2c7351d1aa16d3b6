#pragma once
/// \file batch_run.h
/// A batch run over any communicator (mpi/comm.h): rank 0 discovers the collection, opens or resumes the
/// journal and schedules (largest meshes first), every rank converts items through the one pipeline
/// (jobs/batch_item.h) and commits one shard each, and rank 0 finally merges the shards into the
/// consolidated archive. With the serial communicator the same code runs in one process (tests use it);
/// `gimforge batch` runs it over MPI (jobs/cli/cmd_batch.cpp). docs/cli.md "batch" describes the behaviour,
/// docs/archive.md "Batch archives" the layout.
#include <cstddef>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "jobs/method.h"
#include "mpi/comm.h"

namespace gimforge::jobs {

/// `gimforge batch (--input DIR | --list FILE | --job JOB.toml) -o ARCHIVE.h5 [--method M ...] [--resume]
/// [--max-retries N] [--item-timeout S] [--worker-timeout S]`.
struct BatchOptions {
  std::string input;                ///< directory searched recursively for meshes
  std::string list;                 ///< file with one mesh path per line
  std::string job;                  ///< TOML job file (collections and outputs)
  std::string output;               ///< the consolidated archive to write
  MethodOptions method{};           ///< without --job: the single output's method and options
  std::string label{"folder"};      ///< without --job: "folder", "none" or a fixed label
  bool resume{false};
  bool wait{false};                 ///< another writer holds the archive's lock: wait for it (else refuse)
  int max_retries{1};               ///< extra attempts of a failed item
  double item_timeout{0.0};         ///< seconds per item and attempt (0: none)
  /// Seconds rank 0 waits for a worker's answer on one item before it declares the worker lost (hung,
  /// stopped, gone with its node): the item fails, the run goes on without that rank, and the job ends
  /// with MPI_Abort once the results are safe. Negative: default_worker_timeout(item_timeout) for
  /// conversions, none for brick planning and decimation (which --item-timeout does not bound); 0: none.
  double worker_timeout{-1.0};
  std::size_t metric_samples{200'000};
  bool metric_samples_set{false};   ///< --metric-samples given (overrides the job file)
  bool no_metric{false};            ///< --no-metric: no fidelity report per item (overrides the job file)
  bool xdmf{false};                 ///< --xdmf: the CLI writes ARCHIVE.xmf (io/xdmf.h) once the archive is complete
  int threads_per_rank{1};          ///< TBB threads of each rank (-j)
  std::string log_dir;              ///< non-empty: every rank also logs to LOG_DIR/rank-<r>.log
  bool progress{true};
  std::string command_line;         ///< recorded as the archive's creator
  /// --resume: shards found unreadable before the run (the CLI's probe_shards, jobs/cli/crash_guard.h:
  /// damaged, or crashing or hanging HDF5 in a child process), path relative to the work directory →
  /// reason. Their items are redone; the run never opens them itself.
  std::map<std::string, std::string> unreadable_shards;
};

/// How a run ended, on this rank.
enum class BatchStatus {
  Done,             ///< rank 0: every item converted and merged
  Partial,          ///< rank 0: merged, some items failed (listed in the archive)
  Stopped,          ///< rank 0: stop_requested() before the end; resumable with --resume
  AlreadyComplete,  ///< --resume found the archive finished: nothing to do
  Worker,           ///< a rank other than 0 finished its part
  Error,            ///< a rank other than 0 learned that rank 0 refused the job (rank 0 throws instead)
};

/// The worker timeout implied by `item_timeout` (seconds; 0: none): twice it plus a minute, room for a
/// cancellation that comes late (the item is cancelled at its next progress step) and for writing the shard.
[[nodiscard]] inline double default_worker_timeout(double item_timeout) {
  return item_timeout > 0.0 ? 2.0 * item_timeout + 60.0 : 0.0;
}

/// The worker timeout in effect for conversions (seconds; 0: none): --worker-timeout, or its default.
[[nodiscard]] inline double worker_timeout_in_effect(const BatchOptions& options) {
  return options.worker_timeout >= 0.0 ? options.worker_timeout : default_worker_timeout(options.item_timeout);
}

/// Why --worker-timeout cannot go with --item-timeout (it must leave 10 s over it for the cancellation,
/// which comes at the item's next progress step, and for writing the shard), or "" when it can.
[[nodiscard]] std::string worker_timeout_problem(const BatchOptions& options);

struct BatchOutcome {
  BatchStatus status{BatchStatus::Done};
  std::size_t converted{0};  ///< rank 0: items in the archive (Stopped: committed so far, of `total`)
  std::size_t total{0};      ///< rank 0: items × outputs of the job
  std::size_t failed{0};     ///< rank 0: items that failed all their attempts
  /// Rank 0: workers declared lost (--worker-timeout). The other ranks wait for them in a collective:
  /// the caller ends the job with Comm::abort once it has reported the outcome.
  std::vector<int> lost_workers{};
  /// Rank 0: some rank did not arrive at a barrier between rounds within the worker timeout (stopped or
  /// hung outside any item). As with lost workers, the caller ends the job with Comm::abort.
  bool unresponsive{false};
};

/// Runs the batch described by `options` on every rank of `comm` (collective). `stop_requested` is polled
/// by rank 0 (e.g. SIGTERM / SIGUSR1): running items finish, nothing new starts, the journal stays
/// resumable. Rank 0 throws InvalidInput for a job it refuses (bad collection, existing archive without
/// --resume, a journal of another job) and the io errors of the journal and the merge.
[[nodiscard]] BatchOutcome run_batch(const mpi::Comm& comm, const BatchOptions& options,
                                     const std::function<bool()>& stop_requested = {});

}  // namespace gimforge::jobs
