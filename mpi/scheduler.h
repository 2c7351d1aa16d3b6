#pragma once
/// \file scheduler.h
/// Master / worker scheduling of independent work items over a mpi::Comm (issue #5, batch conversion):
/// rank 0 is the master, every other rank a worker that runs items and sends their results back.
///
/// - Order: items are dispatched by cost descending, ties by id ascending (largest first, so the long
///   ones do not end the run alone).
/// - Pull: each worker holds at most `in_flight_per_worker` messages; the master sends the next one
///   when a result comes back, so a worker rarely waits for the master.
/// - Grouping: items with cost < `group_below_cost` (all at the tail of the order) travel
///   several to a message, at most `max_group` and no more than an even share of what is left, so that
///   tiny items cost one message per group instead of one each and the tail still balances.
/// - No busy-waiting: the master polls with iprobe and sleeps between empty polls, an idle worker
///   likewise; the sleeps start at 1/16 of `poll_interval` after a message and double up to it.
/// - Stop: once `stop_requested` returns true the master dispatches nothing more, waits up to
///   `drain_deadline` for the items the workers already hold (their results still reach `on_result`),
///   tells every worker to stop and returns; the ids never completed are listed in the report. The
///   caller then commits, flushes its journal and exits "resumable" (see shutdown.h for the signals).
/// - Follow-ups: items may make others ready (the next stage of a multi-step item, e.g. a huge scan's
///   bricks in `batch`): `follow_ups` is asked after each result, and what it returns joins the items not
///   yet dispatched, in the same order. While results are outstanding an idle worker is then kept (not
///   told to stop), since a result may bring work for it.
/// - One process (size() == 1, serial Comm or `mpirun -n 1`): rank 0 runs the items itself, in the
///   same order, and checks `stop_requested` between items.
///
/// The call is collective over `comm`. It works on a private duplicate of `comm` (Comm::split), so its
/// messages never mix with the caller's. Messages are a small tagged binary protocol (little-endian
/// integers, length-prefixed strings). The master sends batches and stops without blocking (a blocking
/// send of even a few bytes to a worker busy with an item may wait for that item to end), and a worker
/// sends its results with a blocking send (the master is always polling). Payloads should still be short
/// (paths, not mesh data).
///
/// When the drain deadline expires, workers still inside an item are abandoned: rank 0 tells them to
/// stop, takes results already on their way for at most 100 ms and returns; such a worker returns when
/// its current item ends, dropping that item's result and anything it had not started (its own report
/// lists them in not_done). Rank 0 then keeps its private communicator until the process ends, so that
/// a result sent just as the master gave up can never reach a later communicator. The same happens when
/// on_result throws. Since MPI_Finalize waits for every rank, a caller that must exit right away after
/// a stop calls MPI_Abort with its exit code once its journal is safe.
///
/// Lost workers: an item may carry a `patience`. When a worker holds a batch longer than its items'
/// patience together (counted from when the worker could start it: the batch's dispatch, or the result of
/// the batch before it), the master declares the worker lost (hung, stopped, or gone with its node): the
/// batch's items are delivered as failed results saying so, the batches queued behind it go back to the
/// others, the worker is sent an abandoning stop and is never waited for again (it drops whatever it still
/// holds should it ever wake). The run goes on with the other workers; the report lists the lost ranks.
/// A collective over `comm` after such a run would wait for the lost rank forever, and so would
/// MPI_Finalize: the caller ends the job with MPI_Abort once its results are safe.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "mpi/comm.h"

namespace gimforge::mpi {

/// One unit of work: an id chosen by the caller (reported back with the result), a cost estimate
/// (any unit, only compared: larger is dispatched first) and an opaque payload (e.g. a path).
struct WorkItem {
  std::uint64_t id{0};
  std::uint64_t cost{0};
  std::string payload;
  /// Rank 0 only (not sent): how long the master waits for this item's result once its worker could
  /// start it before declaring the worker lost (see the file comment). Zero: as long as it takes.
  std::chrono::milliseconds patience{0};
};

/// The outcome of one item, as delivered to the ResultHandler on the master.
struct WorkResult {
  std::uint64_t id{0};  ///< the item's id
  int worker{0};        ///< rank that ran it (0 when size() == 1)
  bool ok{true};        ///< false when the work function threw
  std::string payload;  ///< the work function's return value, or the exception's what() when !ok
};

/// Tuning and control of run_master_worker. Every rank passes its own copy; `poll_interval` matters on
/// every rank, the rest on rank 0 only.
struct SchedulerOptions {
  /// Messages (single items or groups) sent to a worker before its first result comes back (>= 1).
  int in_flight_per_worker{2};
  /// Items with cost < this are sent in groups (0: never group) ...
  std::uint64_t group_below_cost{0};
  /// ... of at most this many items per message (>= 1).
  std::size_t max_group{16};
  /// Longest sleep between empty iprobe polls, of the master and of an idle worker (>= 0; 0 yields
  /// instead). Right after a message the sleeps are 1/16 of this, doubling while nothing arrives.
  std::chrono::microseconds poll_interval{500};
  /// Polled by the master (between messages; by the single process between items); once it returns
  /// true, no new item is dispatched. Empty: never stop.
  std::function<bool()> stop_requested{};
  /// After a stop: how long the master waits for the results of items already dispatched (>= 0).
  std::chrono::milliseconds drain_deadline{std::chrono::minutes(5)};
  /// Called on the master after each result (after the ResultHandler): done = completed + failed so far,
  /// total = number of items. Empty: no progress.
  std::function<void(std::size_t done, std::size_t total)> progress{};
  /// Called on the master after each result (after the ResultHandler and progress): the items that result
  /// made ready, dispatched with the rest by cost (they count in the report's total). Empty: the items
  /// are those passed in. After a stop, what it returns is not dispatched (it is listed in not_done).
  std::function<std::vector<WorkItem>()> follow_ups{};
  /// Called on the master when it gives up on a worker (see the file comment), before that worker's items
  /// reach the ResultHandler: a caller learns of it even when the run then ends in an exception.
  std::function<void(int rank)> on_worker_lost{};
};

/// What a rank saw. On rank 0: the whole run, with total == completed + failed + not_done.size() (total
/// includes the follow-ups).
/// On a worker: the items it received, ran (completed / failed) and dropped (not_done, only when the
/// master abandoned it after the drain deadline or an exception).
struct SchedulerReport {
  std::size_t total{0};
  std::size_t completed{0};  ///< results with ok
  std::size_t failed{0};     ///< results with !ok (the work function threw)
  /// Rank 0: a stop was requested before every item was done (not_done may still be empty when the
  /// items in flight were the last ones). A worker: the master had stopped early when it told this
  /// worker to stop (false for a worker released earlier because no item was left for it).
  bool stopped{false};
  /// Ids never completed (not dispatched after a stop, or still running at the drain deadline), in
  /// dispatch order.
  std::vector<std::uint64_t> not_done;
  /// Rank 0: workers declared lost (an item outlasted its patience), in the order they were lost. Their
  /// batch's items count as failed; no collective over the communicator may follow (see the file comment).
  std::vector<int> lost_workers;
  double seconds{0};  ///< wall time of the call on this rank
};

/// Runs on workers (or on rank 0 when size() == 1); may throw (the item is then reported as failed with
/// the exception's what()). Returns the result payload.
using WorkFunction = std::function<std::string(const WorkItem&)>;

/// Runs on the master only, once per result, in completion order. An exception it throws ends the run:
/// workers are told to stop first, then the exception propagates from run_master_worker on rank 0.
using ResultHandler = std::function<void(const WorkResult&)>;

/// Distributes `items` over the ranks of `comm` (master / worker, see the file comment) and delivers
/// every result to `on_result` on rank 0. Collective over `comm`: every rank calls it with its own
/// `work` and `options`; `items` matter on rank 0 only (other ranks pass {}). Dispatch order: cost
/// descending, then id ascending. Ids need not be unique (results are matched by position).
///
/// Rank 0 returns the report after every worker has been told to stop; workers return a report with
/// their own counts. Throws InvalidInput on every rank when any rank's arguments are invalid (`work`
/// empty, in_flight_per_worker < 1, max_group < 1, a negative interval or deadline) before any item
/// moves; LibraryError when MPI fails or a scheduler message is malformed; on rank 0, whatever
/// `on_result` or `progress` throws (after the workers were told to stop).
SchedulerReport run_master_worker(const Comm& comm, std::vector<WorkItem> items, const WorkFunction& work,
                                  const ResultHandler& on_result, const SchedulerOptions& options = {});

}  // namespace gimforge::mpi
