/// \file scheduler.cpp
/// run_master_worker (see scheduler.h): the wire protocol, the master, the worker and the one-process
/// path. Only mpi::Comm is used, so this builds without MPI.
///
/// Protocol (on a private split of the caller's Comm; integers little-endian, strings as u64 length +
/// bytes):
///   kTagBatch   master -> worker  u64 count, then count x (u64 id, u64 cost, string payload)
///   kTagResults worker -> master  u64 count, then count x (u64 id, u8 ok, string payload): the results
///                                 of the oldest batch the worker has not answered, in batch order
///   kTagStop    master -> worker  u8 flags (kStopEarly, kStopAbandon); the master's last message to it
/// A worker answers every batch with exactly one results message, so the master matches results to
/// items by position (a FIFO of batches per worker) and ids need not be unique. The master sends a
/// plain stop only to a worker with nothing in flight; a stop with kStopAbandon may overtake batches the
/// worker has not taken yet (it probes for the stop tag between items), and those batches are then
/// received and dropped.
#include "mpi/scheduler.h"

#include <fmt/format.h>

#include <algorithm>
#include <deque>
#include <exception>
#include <mutex>
#include <optional>
#include <set>
#include <string_view>
#include <thread>
#include <utility>

#include "kernels/core/errors.h"

namespace gimforge::mpi {
namespace {

using Clock = std::chrono::steady_clock;

constexpr int kTagBatch = 1;
constexpr int kTagResults = 2;
constexpr int kTagStop = 3;

/// Stop flags: the run ended before every item was done; the master no longer waits for results.
constexpr std::uint8_t kStopEarly = 1;
constexpr std::uint8_t kStopAbandon = 2;

/// After abandoning workers, the master still takes results for this long: a worker may have checked
/// for the stop just before it arrived and be sending a result (which, above the eager limit, would
/// otherwise wait for a receive that never comes).
constexpr auto kAbandonGrace = std::chrono::milliseconds(100);

/// A pause of the master's own loop longer than this (stopped, descheduled, a slow on_result) is not
/// counted against the workers' patience.
constexpr auto kOwnStall = std::chrono::milliseconds(500);

/// A batch without a patience: its worker is waited for as long as it takes.
constexpr auto kForever = std::chrono::milliseconds::max();

/// Smallest encoded item / result, to bound the element count a message may claim.
constexpr std::size_t kMinItemBytes = 24;
constexpr std::size_t kMinResultBytes = 17;

// ---- encoding -------------------------------------------------------------------------------------

/// Appends little-endian integers and length-prefixed strings to a byte buffer.
class Writer {
 public:
  void u8(std::uint8_t value) { out_.push_back(std::byte{value}); }
  void u64(std::uint64_t value) {
    for (int i = 0; i < 8; ++i) out_.push_back(static_cast<std::byte>((value >> (8 * i)) & 0xffU));
  }
  void str(std::string_view text) {
    u64(text.size());
    for (const char c : text) out_.push_back(static_cast<std::byte>(c));
  }
  [[nodiscard]] std::vector<std::byte> take() { return std::move(out_); }

 private:
  std::vector<std::byte> out_;
};

/// Reads what Writer wrote; any overrun or leftover byte is a LibraryError naming the sender and tag.
class Reader {
 public:
  explicit Reader(const Message& msg) : msg_(msg) {}

  [[nodiscard]] std::uint8_t u8() {
    need(1);
    return std::to_integer<std::uint8_t>(msg_.data[pos_++]);
  }
  [[nodiscard]] std::uint64_t u64() {
    need(8);
    std::uint64_t value = 0;
    for (int i = 0; i < 8; ++i) value |= std::to_integer<std::uint64_t>(msg_.data[pos_++]) << (8 * i);
    return value;
  }
  [[nodiscard]] std::string str() {
    const std::uint64_t length = u64();
    if (length > remaining()) fail(fmt::format("string of {} bytes exceeds the {} bytes left", length, remaining()));
    std::string text(static_cast<std::size_t>(length), '\0');
    for (char& c : text) c = static_cast<char>(msg_.data[pos_++]);
    return text;
  }
  /// Reads an element count; each element takes at least `min_bytes` bytes.
  [[nodiscard]] std::size_t count(std::size_t min_bytes) {
    const std::uint64_t n = u64();
    if (n > remaining() / min_bytes) fail(fmt::format("{} elements cannot fit in {} bytes", n, remaining()));
    return static_cast<std::size_t>(n);
  }
  void finish() const {
    if (remaining() != 0) fail(fmt::format("{} trailing bytes", remaining()));
  }
  [[noreturn]] void fail(std::string_view what) const {
    throw LibraryError(
        fmt::format("scheduler: malformed message (tag {}) from rank {}: {}", msg_.tag, msg_.source, what));
  }

 private:
  [[nodiscard]] std::size_t remaining() const { return msg_.data.size() - pos_; }
  void need(std::size_t n) const {
    if (remaining() < n) fail("truncated");
  }

  const Message& msg_;
  std::size_t pos_ = 0;
};

std::vector<std::byte> encode_batch(const std::vector<WorkItem>& items, const std::vector<std::size_t>& batch) {
  Writer w;
  w.u64(batch.size());
  for (const std::size_t i : batch) {
    w.u64(items[i].id);
    w.u64(items[i].cost);
    w.str(items[i].payload);
  }
  return w.take();
}

std::vector<WorkItem> decode_batch(const Message& msg) {
  Reader r(msg);
  std::vector<WorkItem> batch(r.count(kMinItemBytes));
  for (WorkItem& item : batch) {
    item.id = r.u64();
    item.cost = r.u64();
    item.payload = r.str();
  }
  r.finish();
  return batch;
}

std::vector<std::byte> encode_results(const std::vector<WorkResult>& results) {
  Writer w;
  w.u64(results.size());
  for (const WorkResult& result : results) {
    w.u64(result.id);
    w.u8(result.ok ? 1 : 0);
    w.str(result.payload);
  }
  return w.take();
}

std::vector<WorkResult> decode_results(const Message& msg) {
  Reader r(msg);
  std::vector<WorkResult> results(r.count(kMinResultBytes));
  for (WorkResult& result : results) {
    result.id = r.u64();
    const std::uint8_t ok = r.u8();
    if (ok > 1) r.fail(fmt::format("ok flag {} is neither 0 nor 1", ok));
    result.ok = ok == 1;
    result.payload = r.str();
    result.worker = msg.source;
  }
  r.finish();
  return results;
}

std::uint8_t decode_stop(const Message& msg) {
  Reader r(msg);
  const std::uint8_t flags = r.u8();
  r.finish();
  return flags;
}

// ---- shared helpers -------------------------------------------------------------------------------

/// The sleeps between empty polls: short right after a message (1/16 of the poll interval), doubling
/// up to the poll interval while nothing comes, so a quick answer is picked up quickly and a long wait
/// costs a wake-up per poll interval. A zero interval yields instead of sleeping.
class Backoff {
 public:
  explicit Backoff(std::chrono::microseconds longest)
      : longest_(longest), shortest_(std::max(longest / 16, std::chrono::microseconds(1))), next_(shortest_) {}

  /// After a message: the next sleep is short again.
  void reset() { next_ = shortest_; }

  /// Sleeps (or yields) once and lengthens the next sleep.
  void pause() {
    if (longest_.count() <= 0) {
      std::this_thread::yield();
      return;
    }
    std::this_thread::sleep_for(std::min(next_, longest_));
    next_ = std::min(next_ * 2, longest_);
  }

 private:
  std::chrono::microseconds longest_;
  std::chrono::microseconds shortest_;
  std::chrono::microseconds next_;
};

/// iprobe that also sees what arrived while this rank was busy or asleep: Open MPI's iprobe matches
/// what it has already pulled in and only then makes progress, so the first probe after a pause can
/// miss a message that is there; a second probe finds it.
std::optional<MessageInfo> poll(const Comm& comm, int source, int tag) {
  if (auto info = comm.iprobe(source, tag)) return info;
  return comm.iprobe(source, tag);
}

double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

/// Keeps `comm` until the process ends. Rank 0 parks here the private communicator of a run that
/// abandoned workers with items in flight: their late results then stay queued on it, whereas on a
/// freed communicator MPI would hand them to the next one created with the same context id.
void keep_until_exit(Comm comm) {
  static std::mutex mutex;
  static std::vector<Comm> parked;  // destroyed after MPI_Finalize: the MPI Comm then frees nothing
  const std::lock_guard lock(mutex);
  parked.push_back(std::move(comm));
}

/// Runs one item, turning an exception into a failed result.
WorkResult run_item(const WorkFunction& work, const WorkItem& item, int rank) {
  WorkResult result{item.id, rank, true, {}};
  try {
    result.payload = work(item);
  } catch (const std::exception& e) {
    result.ok = false;
    result.payload = e.what();
  } catch (...) {
    result.ok = false;
    result.payload = "unknown exception (not derived from std::exception)";
  }
  return result;
}

/// Indices of `items` in dispatch order: cost descending, then id ascending, then input order.
std::vector<std::size_t> dispatch_order(const std::vector<WorkItem>& items) {
  std::vector<std::size_t> order(items.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (items[a].cost != items[b].cost) return items[a].cost > items[b].cost;
    return items[a].id < items[b].id;
  });
  return order;
}

/// Appends `more` to `items` and merges them into the part of `order` from `from` on (the items not yet
/// dispatched), keeping it in dispatch order.
void add_follow_ups(std::vector<WorkItem>& items, std::vector<std::size_t>& order, std::size_t from,
                    std::vector<WorkItem> more) {
  if (more.empty()) return;
  for (WorkItem& item : more) {
    order.push_back(items.size());
    items.push_back(std::move(item));
  }
  std::stable_sort(order.begin() + static_cast<std::ptrdiff_t>(from), order.end(), [&](std::size_t a, std::size_t b) {
    if (items[a].cost != items[b].cost) return items[a].cost > items[b].cost;
    return items[a].id < items[b].id;
  });
}

/// An empty string when this rank's arguments are valid, else the reason.
std::string check_arguments(const WorkFunction& work, const SchedulerOptions& options) {
  if (!work) return "run_master_worker: the work function is empty";
  if (options.in_flight_per_worker < 1)
    return fmt::format("run_master_worker: in_flight_per_worker is {} (must be >= 1)", options.in_flight_per_worker);
  if (options.max_group < 1) return "run_master_worker: max_group is 0 (must be >= 1)";
  if (options.poll_interval.count() < 0)
    return fmt::format("run_master_worker: poll_interval is {} us (must be >= 0)", options.poll_interval.count());
  if (options.drain_deadline.count() < 0)
    return fmt::format("run_master_worker: drain_deadline is {} ms (must be >= 0)", options.drain_deadline.count());
  return {};
}

// ---- one process ------------------------------------------------------------------------------------

SchedulerReport run_alone(std::vector<WorkItem> items, const WorkFunction& work, const ResultHandler& on_result,
                          const SchedulerOptions& options, Clock::time_point start) {
  SchedulerReport report;
  report.total = items.size();
  std::vector<std::size_t> order = dispatch_order(items);
  for (std::size_t k = 0; k < order.size(); ++k) {
    if (options.stop_requested && options.stop_requested()) {
      report.stopped = true;
      for (std::size_t j = k; j < order.size(); ++j) report.not_done.push_back(items[order[j]].id);
      break;
    }
    const WorkResult result = run_item(work, items[order[k]], 0);
    ++(result.ok ? report.completed : report.failed);
    if (on_result) on_result(result);
    if (options.progress) options.progress(report.completed + report.failed, report.total);
    if (options.follow_ups) {
      const std::size_t before = items.size();
      add_follow_ups(items, order, k + 1, options.follow_ups());
      report.total += items.size() - before;
    }
  }
  report.seconds = seconds_since(start);
  return report;
}

// ---- master -----------------------------------------------------------------------------------------

/// Rank 0 of a communicator with at least two ranks: dispatches, collects, stops.
class Master {
 public:
  Master(const Comm& comm, std::vector<WorkItem> items, const ResultHandler& on_result, const SchedulerOptions& options)
      : comm_(comm),
        items_(std::move(items)),
        order_(dispatch_order(items_)),
        done_(items_.size(), false),
        on_result_(on_result),
        options_(options),
        workers_(static_cast<std::size_t>(comm.size())),
        slots_(static_cast<std::size_t>(comm.size() - 1) * static_cast<std::size_t>(options.in_flight_per_worker)) {}

  /// True when workers were abandoned with results still to come, or lost (after run returned or threw).
  [[nodiscard]] bool left_results_behind() const { return outstanding() || !report_.lost_workers.empty(); }

  SchedulerReport run(Clock::time_point start) {
    report_.total = items_.size();
    active_ = comm_.size() - 1;
    try {
      check_stop();
      fill_all();
      retire_idle();
      while (active_ > 0) {
        discount_own_stall();
        check_stop();
        if (stopping_ && Clock::now() >= deadline_) {
          abandon(true);
          break;
        }
        if (const auto info = poll(comm_, kAnySource, kTagResults)) {
          const int w = info->source;
          std::vector<WorkResult> results = receive(*info);
          if (options_.follow_ups) {
            // The results first: they may bring the work for this worker and for the idle ones.
            deliver(results);
            add_more();
            fill_all();
            retire_idle();
          } else {
            if (!stopping_) fill(w);
            retire_idle();  // w, or one kept for a requeue
            deliver(results);
          }
          reap_sends();
          backoff_.reset();
          continue;
        }
        reap_sends();
        // Only after an empty poll: every result that has arrived is taken, so none is overdue unseen.
        if (lose_overdue_workers()) continue;
        backoff_.pause();
      }
      // Every worker was stopped with nothing in flight: it is waiting, and takes its stop at once.
      if (!outstanding())
        while (!reap_sends()) backoff_.pause();
    } catch (...) {
      abandon_quietly();
      throw;
    }
    std::vector<bool> listed(items_.size(), false);  // a lost worker's queued batches appear twice in order_
    for (const std::size_t i : order_)
      if (!done_[i] && !listed[i]) {
        listed[i] = true;
        report_.not_done.push_back(items_[i].id);
      }
    report_.seconds = seconds_since(start);
    return report_;
  }

 private:
  struct Worker {
    std::deque<std::vector<std::size_t>> in_flight;  // item indices of each unanswered batch, oldest first
    Clock::time_point since{};                       // when it could start the oldest (dispatch or last result)
    bool retired = false;                            // has been sent its stop
    bool lost = false;                               // outlasted its batch's patience: never waited for again
  };

  /// A send not yet finished, and its destination.
  struct Send {
    int rank;
    std::unique_ptr<PendingSend> request;
  };

  /// Forgets the sends that have left; true when none is left in flight.
  bool reap_sends() {
    std::erase_if(sends_, [](const Send& s) { return s.request->done(); });
    return sends_.empty();
  }

  /// The patience of a batch: its items' together, kForever when one has none.
  [[nodiscard]] std::chrono::milliseconds batch_patience(const std::vector<std::size_t>& batch) const {
    std::chrono::milliseconds patience{0};
    for (const std::size_t i : batch) {
      if (items_[i].patience.count() <= 0) return kForever;
      patience += items_[i].patience;
    }
    return patience;
  }

  /// Time this master did not poll (it was stopped, descheduled, or busy in on_result) does not count
  /// against the workers: their results may be waiting unread. Every worker's clock moves on by it.
  void discount_own_stall() {
    const auto now = Clock::now();
    if (now - last_turn_ > kOwnStall)
      for (Worker& w : workers_) w.since += now - last_turn_;
    last_turn_ = now;
  }

  /// Declares lost every worker whose oldest batch has outlasted its patience; true when one was.
  bool lose_overdue_workers() {
    bool any = false;
    const auto now = Clock::now();
    for (int w = 1; w < comm_.size(); ++w) {
      const Worker& worker = workers_[static_cast<std::size_t>(w)];
      if (worker.retired || worker.in_flight.empty()) continue;
      const std::chrono::milliseconds patience = batch_patience(worker.in_flight.front());
      const double waited = std::chrono::duration<double>(now - worker.since).count();
      const double allowed = std::chrono::duration<double>(patience).count();  // in double: no overflow
      if (patience == kForever || waited <= allowed) continue;
      lose(w, waited, allowed);
      any = true;
    }
    return any;
  }

  /// Gives up on worker `w`: it gets an abandoning stop (its sends are never awaited), and the batches
  /// queued behind its oldest (never started) go back to the front of the order for the others. The oldest
  /// fails when it is one item; a group goes back too, its items to travel alone from now on, since which
  /// of them hung is unknown (the one that did then fails alone on the next worker).
  void lose(int w, double waited, double allowed) {
    Worker& worker = workers_[static_cast<std::size_t>(w)];
    std::vector<std::size_t> running = std::move(worker.in_flight.front());
    worker.in_flight.pop_front();
    if (running.size() > 1) {
      worker.in_flight.push_front(std::move(running));
      running.clear();
    }
    for (auto queued = worker.in_flight.rbegin(); queued != worker.in_flight.rend(); ++queued) {
      order_.insert(order_.begin() + static_cast<std::ptrdiff_t>(next_), queued->begin(), queued->end());
      for (const std::size_t i : *queued) solo_.insert(i);
    }
    worker.in_flight.clear();
    send_stop(w, kStopEarly | kStopAbandon);
    worker.lost = true;
    report_.lost_workers.push_back(w);
    if (options_.on_worker_lost) options_.on_worker_lost(w);
    for (Send& s : sends_)
      if (s.rank == w) lost_sends_.push_back(std::move(s.request));
    std::erase_if(sends_, [](const Send& s) { return !s.request; });
    std::vector<WorkResult> failures;
    for (const std::size_t i : running) {
      done_[i] = true;
      failures.push_back({items_[i].id, w, false,
                          fmt::format("rank {} gave no answer for {:.1f} s (its item was allowed {:g} s): the "
                                      "worker is hung, stopped, or gone with its node",
                                      w, waited, allowed)});
    }
    deliver(failures);
    if (options_.follow_ups) add_more();
    fill_all();
    retire_idle();
  }

  /// Polls stop_requested (until it first returns true) and starts the drain.
  void check_stop() {
    if (stopping_ || !options_.stop_requested || !options_.stop_requested()) return;
    stopping_ = true;
    report_.stopped = true;
    deadline_ = Clock::now() + options_.drain_deadline;
    retire_idle();
  }

  /// Fills every worker (unless stopping).
  void fill_all() {
    if (stopping_) return;
    for (int w = 1; w < comm_.size(); ++w) fill(w);
  }

  /// Sends batches to worker `w` until it holds in_flight_per_worker of them or no item is left.
  void fill(int w) {
    Worker& worker = workers_[static_cast<std::size_t>(w)];
    if (worker.retired) return;
    while (worker.in_flight.size() < static_cast<std::size_t>(options_.in_flight_per_worker) && next_ < order_.size()) {
      std::vector<std::size_t> batch = take_batch();
      sends_.push_back({w, comm_.isend(encode_batch(items_, batch), w, kTagBatch)});
      if (worker.in_flight.empty()) worker.since = Clock::now();
      worker.in_flight.push_back(std::move(batch));
    }
  }

  /// The next batch: one item, or, from the first item cheaper than group_below_cost on (the rest of
  /// the order, all cheaper), a group of at most max_group items and at most an even share of what is
  /// left over all in-flight slots (so the tail still spreads over every worker).
  std::vector<std::size_t> take_batch() {
    std::size_t count = 1;
    if (items_[order_[next_]].cost < options_.group_below_cost && !solo_.contains(order_[next_])) {
      const std::size_t left = order_.size() - next_;
      count = std::clamp((left + slots_ - 1) / slots_, std::size_t{1}, options_.max_group);
      for (std::size_t k = 1; k < count; ++k)  // a lost worker's group comes back one item at a time
        if (solo_.contains(order_[next_ + k])) count = k;
    }
    std::vector<std::size_t> batch(order_.begin() + static_cast<std::ptrdiff_t>(next_),
                                   order_.begin() + static_cast<std::ptrdiff_t>(next_ + count));
    next_ += count;
    return batch;
  }

  /// The follow-ups of the results just delivered.
  void add_more() {
    std::vector<WorkItem> more = options_.follow_ups();
    report_.total += more.size();
    done_.resize(done_.size() + more.size(), false);
    add_follow_ups(items_, order_, next_, std::move(more));
  }

  /// Sends its stop to every worker that has nothing in flight and will get nothing more (with follow-ups:
  /// once no result is outstanding either; with patience: once no batch waits behind one that may yet
  /// make its worker lost, and so come back).
  void retire_idle() {  // the condition once per call: may_come_back looks at every worker
    if (!stopping_ && (next_ < order_.size() || (options_.follow_ups && outstanding()) || may_come_back())) return;
    for (int w = 1; w < comm_.size(); ++w) {
      const Worker& worker = workers_[static_cast<std::size_t>(w)];
      if (!worker.retired && worker.in_flight.empty()) send_stop(w, stopping_ ? kStopEarly : std::uint8_t{0});
    }
  }

  /// True when some worker holds a batch queued behind one with a patience (which may yet make it lost).
  [[nodiscard]] bool may_come_back() const {
    return std::any_of(workers_.begin(), workers_.end(), [this](const Worker& w) {
      return w.in_flight.size() > 1 && batch_patience(w.in_flight.front()) != kForever;
    });
  }

  void send_stop(int w, std::uint8_t flags) {
    Writer out;
    out.u8(flags);
    sends_.push_back({w, comm_.isend(out.take(), w, kTagStop)});
    workers_[static_cast<std::size_t>(w)].retired = true;
    --active_;
  }

  /// Receives the results message `info` announces and matches it to the sender's oldest batch.
  std::vector<WorkResult> receive(const MessageInfo& info) {
    const Message msg = comm_.recv(info.source, kTagResults);
    Worker& worker = workers_[static_cast<std::size_t>(msg.source)];
    if (worker.lost) return {};  // its items were failed when it was lost
    std::vector<WorkResult> results = decode_results(msg);
    if (worker.in_flight.empty())
      throw LibraryError(fmt::format("scheduler: rank {} sent results for no batch", msg.source));
    const std::vector<std::size_t> batch = std::move(worker.in_flight.front());
    worker.in_flight.pop_front();
    if (results.size() != batch.size())
      throw LibraryError(fmt::format("scheduler: rank {} sent {} results for a batch of {} items", msg.source,
                                     results.size(), batch.size()));
    for (std::size_t k = 0; k < batch.size(); ++k) {
      if (results[k].id != items_[batch[k]].id)
        throw LibraryError(fmt::format("scheduler: rank {} sent a result for id {} where id {} was expected",
                                       msg.source, results[k].id, items_[batch[k]].id));
      done_[batch[k]] = true;
    }
    worker.since = Clock::now();  // it starts its next batch now
    return results;
  }

  /// Counts the results and hands them to on_result and progress.
  void deliver(const std::vector<WorkResult>& results) {
    for (const WorkResult& result : results) {
      ++(result.ok ? report_.completed : report_.failed);
      if (on_result_) on_result_(result);
      if (options_.progress) options_.progress(report_.completed + report_.failed, report_.total);
    }
  }

  /// Stops every worker not yet stopped, whatever it holds, then takes results for kAbandonGrace (or
  /// until none is outstanding), delivering them when `deliver_late` is set, else dropping them.
  /// Results still outstanding after that make left_results_behind() true.
  void abandon(bool deliver_late) {
    for (int w = 1; w < comm_.size(); ++w)
      if (!workers_[static_cast<std::size_t>(w)].retired) send_stop(w, kStopEarly | kStopAbandon);
    const auto grace_end = Clock::now() + kAbandonGrace;
    backoff_.reset();
    while (outstanding() && Clock::now() < grace_end) {
      if (const auto info = poll(comm_, kAnySource, kTagResults)) {
        const std::vector<WorkResult> results = receive(*info);
        if (deliver_late) deliver(results);
        continue;
      }
      backoff_.pause();
    }
  }

  /// On the way out with an exception: stop the workers so none waits forever; errors here are dropped
  /// in favour of the one already propagating.
  void abandon_quietly() noexcept {
    try {
      abandon(false);
    } catch (...) {
    }
  }

  [[nodiscard]] bool outstanding() const {
    return std::any_of(workers_.begin(), workers_.end(), [](const Worker& w) { return !w.in_flight.empty(); });
  }

  const Comm& comm_;
  std::vector<WorkItem> items_;
  std::vector<std::size_t> order_;
  std::vector<bool> done_;
  std::set<std::size_t> solo_;  // items of a lost worker's group: never grouped again
  Clock::time_point last_turn_{Clock::now()};  // the master's last pass through its loop
  const ResultHandler& on_result_;
  const SchedulerOptions& options_;
  std::vector<Worker> workers_;  // indexed by rank; [0] unused
  std::size_t slots_;            // workers x in_flight_per_worker
  std::size_t next_ = 0;         // position in order_ of the next item to dispatch
  int active_ = 0;               // workers not yet sent their stop
  bool stopping_ = false;
  Clock::time_point deadline_{};
  Backoff backoff_{options_.poll_interval};
  SchedulerReport report_;
  // Batches and stops are sent without blocking (Comm::isend): a blocking send to a worker busy with an
  // item can wait until that item ends (Open MPI's shared-memory transport), and the master would hold
  // every other worker's results and work meanwhile. Sends to one worker still arrive in order.
  std::vector<Send> sends_;
  // Sends to lost workers: never awaited (a stopped process may never take them); their requests are freed
  // with the Master, their buffers left to MPI (PendingSend).
  std::vector<std::unique_ptr<PendingSend>> lost_sends_;
};

// ---- worker -----------------------------------------------------------------------------------------

/// Waits for a message from rank 0 without spinning: iprobe, then sleep.
MessageInfo wait_for_master(const Comm& comm, std::chrono::microseconds poll_interval) {
  Backoff backoff(poll_interval);
  for (;;) {
    if (const auto info = poll(comm, 0, kAnyTag)) return *info;
    backoff.pause();
  }
}

/// A rank other than 0: runs batches until the master's stop.
class WorkerLoop {
 public:
  WorkerLoop(const Comm& comm, const WorkFunction& work, const SchedulerOptions& options)
      : comm_(comm), work_(work), options_(options) {}

  SchedulerReport run(Clock::time_point start) {
    for (;;) {
      const MessageInfo info = wait_for_master(comm_, options_.poll_interval);
      const Message msg = comm_.recv(0, info.tag);
      if (msg.tag == kTagStop) {
        stop(decode_stop(msg));
        break;
      }
      if (msg.tag != kTagBatch) throw LibraryError(fmt::format("scheduler: unexpected tag {} from rank 0", msg.tag));
      if (!run_batch(decode_batch(msg))) break;
    }
    report_.seconds = seconds_since(start);
    return report_;
  }

 private:
  /// Runs a batch and sends its results; false when the master abandoned this worker meanwhile.
  bool run_batch(const std::vector<WorkItem>& batch) {
    report_.total += batch.size();
    std::vector<WorkResult> results;
    results.reserve(batch.size());
    for (const WorkItem& item : batch) {
      if (abandoned()) return drop(batch);
      results.push_back(run_item(work_, item, comm_.rank()));
    }
    if (abandoned()) return drop(batch);
    comm_.send(encode_results(results), 0, kTagResults);
    for (const WorkResult& result : results) ++(result.ok ? report_.completed : report_.failed);
    return true;
  }

  /// True when the master's stop is pending: it was sent while this worker still held items, so the
  /// master has given up on them.
  [[nodiscard]] bool abandoned() const { return poll(comm_, 0, kTagStop).has_value(); }

  /// Drops `batch` and every batch still queued before the stop, then takes the stop.
  bool drop(const std::vector<WorkItem>& batch) {
    for (const WorkItem& item : batch) report_.not_done.push_back(item.id);
    for (;;) {
      const Message msg = comm_.recv(0, kAnyTag);
      if (msg.tag == kTagStop) {
        stop(decode_stop(msg));
        return false;
      }
      if (msg.tag != kTagBatch) throw LibraryError(fmt::format("scheduler: unexpected tag {} from rank 0", msg.tag));
      const std::vector<WorkItem> queued = decode_batch(msg);
      report_.total += queued.size();
      for (const WorkItem& item : queued) report_.not_done.push_back(item.id);
    }
  }

  void stop(std::uint8_t flags) { report_.stopped = (flags & kStopEarly) != 0; }

  const Comm& comm_;
  const WorkFunction& work_;
  const SchedulerOptions& options_;
  SchedulerReport report_;
};

}  // namespace

SchedulerReport run_master_worker(const Comm& comm, std::vector<WorkItem> items, const WorkFunction& work,
                                  const ResultHandler& on_result, const SchedulerOptions& options) {
  const auto start = Clock::now();
  std::string problem = check_arguments(work, options);
  if (comm.size() == 1) {
    if (!problem.empty()) throw InvalidInput(problem);
    return run_alone(std::move(items), work, on_result, options, start);
  }
  // A private communicator for the protocol; its creation also agrees on the arguments' validity.
  Comm own = comm.split(0, comm.rank());
  const auto invalid = own.allreduce(std::int64_t{problem.empty() ? 0 : 1}, ReduceOp::kMax);
  if (invalid != 0) {
    if (problem.empty()) problem = "run_master_worker: the arguments of another rank are invalid";
    throw InvalidInput(problem);
  }
  if (own.rank() != 0) return WorkerLoop(own, work, options).run(start);
  Master master(own, std::move(items), on_result, options);
  SchedulerReport report;
  try {
    report = master.run(start);
  } catch (...) {
    if (master.left_results_behind()) keep_until_exit(std::move(own));
    throw;
  }
  if (master.left_results_behind()) keep_until_exit(std::move(own));
  return report;
}

}  // namespace gimforge::mpi
