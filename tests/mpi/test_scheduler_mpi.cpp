// Tests of the master / worker scheduler (mpi/scheduler.h) over MPI, for any number of ranks >= 2
// (ctest runs 2 and 4): every item exactly once, failures reported, results equal to a one-process run,
// stop with drain, an expired drain deadline, grouping of tiny items, the in-flight limit (counted on
// the wire by a communicator that wraps the MPI one).
// Collectives stay matched on all ranks even when an expectation fails (EXPECT, not ASSERT).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "kernels/core/errors.h"
#include "mpi/comm.h"
#include "mpi/mpi_comm.h"
#include "mpi/scheduler.h"
#include "tests/unit/mpi/staged_items.h"

using namespace gimforge;
using mpi::Comm;
using mpi::ReduceOp;
using mpi::SchedulerOptions;
using mpi::SchedulerReport;
using mpi::WorkItem;
using mpi::WorkResult;
using Clock = std::chrono::steady_clock;

namespace {

/// Point-to-point traffic seen by one rank through CountingComm.
struct Traffic {
  std::map<int, std::int64_t> sent;      // messages sent to each peer
  std::map<int, std::int64_t> received;  // messages received from each peer
  std::int64_t max_outstanding = 0;      // max over peers and time of sent - received
};

/// A communicator implementation that forwards to another Comm and counts sends and receives per peer
/// (splits are wrapped too, so the scheduler's private communicator is counted).
class CountingCommImpl final : public mpi::CommImpl {
 public:
  CountingCommImpl(Comm inner, std::shared_ptr<Traffic> traffic)
      : inner_(std::move(inner)), traffic_(std::move(traffic)) {}

  [[nodiscard]] int rank() const override { return inner_.impl().rank(); }
  [[nodiscard]] int size() const override { return inner_.impl().size(); }
  void barrier() const override { inner_.impl().barrier(); }
  void allreduce(void* data, std::size_t count, mpi::Datatype type, ReduceOp op) const override {
    inner_.impl().allreduce(data, count, type, op);
  }
  void broadcast(void* data, std::size_t bytes, int root) const override { inner_.impl().broadcast(data, bytes, root); }
  void send(const void* data, std::size_t bytes, int dest, int tag) const override {
    inner_.impl().send(data, bytes, dest, tag);
    const std::int64_t outstanding = ++traffic_->sent[dest] - traffic_->received[dest];
    traffic_->max_outstanding = std::max(traffic_->max_outstanding, outstanding);
  }
  [[nodiscard]] std::unique_ptr<mpi::PendingSend> isend(std::vector<std::byte> data, int dest, int tag) const override {
    auto pending = inner_.impl().isend(std::move(data), dest, tag);
    const std::int64_t outstanding = ++traffic_->sent[dest] - traffic_->received[dest];
    traffic_->max_outstanding = std::max(traffic_->max_outstanding, outstanding);
    return pending;
  }
  void recv(void* data, std::size_t bytes, int source, int tag) const override {
    inner_.impl().recv(data, bytes, source, tag);
    ++traffic_->received[source];
  }
  [[nodiscard]] mpi::MessageInfo probe(int source, int tag) const override { return inner_.impl().probe(source, tag); }
  [[nodiscard]] std::optional<mpi::MessageInfo> iprobe(int source, int tag) const override {
    return inner_.impl().iprobe(source, tag);
  }
  void gather(const void* send_data, std::size_t bytes, void* recv_data, int root) const override {
    inner_.impl().gather(send_data, bytes, recv_data, root);
  }
  [[nodiscard]] std::unique_ptr<mpi::CommImpl> split(int color, int key) const override {
    return std::make_unique<CountingCommImpl>(Comm(inner_.impl().split(color, key)), traffic_);
  }

 private:
  Comm inner_;
  std::shared_ptr<Traffic> traffic_;
};

Comm counting_world(const std::shared_ptr<Traffic>& traffic) {
  return Comm(std::make_unique<CountingCommImpl>(mpi::mpi_world(), traffic));
}

/// `n` items with costs spread over 0..97 (many ties) and payload "p<id>".
std::vector<WorkItem> make_items(std::uint64_t n) {
  std::vector<WorkItem> items;
  for (std::uint64_t i = 0; i < n; ++i) {
    std::string payload = "p";  // (not "p" + ...: GCC 12 reports a false -Wrestrict there)
    payload += std::to_string(i);
    items.push_back({i, (i * 37) % 98, std::move(payload)});
  }
  return items;
}

/// A deterministic work function: fails for ids divisible by 7, else returns a digest of the item.
std::string deterministic_work(const WorkItem& item) {
  if (item.id % 7 == 0) throw InvalidInput("item " + std::to_string(item.id) + " is unusable");
  return item.payload + "/" + std::to_string(item.cost * 1000003 + item.id);
}

/// Sum over all ranks of `value`.
std::int64_t sum(const Comm& comm, std::size_t value) {
  return comm.allreduce(static_cast<std::int64_t>(value), ReduceOp::kSum);
}

void sleep_ms(int ms) { std::this_thread::sleep_for(std::chrono::milliseconds(ms)); }

TEST(SchedulerMpi, EveryItemExactlyOnceWithFailuresReported) {
  const Comm comm = mpi::mpi_world();
  const std::uint64_t n = 300;
  std::map<std::uint64_t, int> seen;
  std::vector<std::uint64_t> costs_here;  // costs of the items this rank ran, in order
  std::size_t progress_calls = 0;
  SchedulerOptions options;
  options.progress = [&](std::size_t done, std::size_t total) {
    EXPECT_EQ(done, ++progress_calls);
    EXPECT_EQ(total, n);
  };
  const SchedulerReport report = mpi::run_master_worker(
      comm, comm.rank() == 0 ? make_items(n) : std::vector<WorkItem>{},
      [&](const WorkItem& item) {
        costs_here.push_back(item.cost);
        return deterministic_work(item);
      },
      [&](const WorkResult& result) {
        ++seen[result.id];
        EXPECT_GE(result.worker, 1);
        EXPECT_LT(result.worker, comm.size());
        EXPECT_EQ(result.ok, result.id % 7 != 0);
        if (!result.ok) {
          EXPECT_EQ(result.payload, "item " + std::to_string(result.id) + " is unusable");
        }
      },
      options);
  // Each worker receives its items in dispatch order: costs never increase.
  EXPECT_TRUE(std::is_sorted(costs_here.rbegin(), costs_here.rend()));
  const std::uint64_t failures = (n + 6) / 7;
  if (comm.rank() == 0) {
    EXPECT_TRUE(costs_here.empty());  // the master does not work when there are workers
    EXPECT_EQ(seen.size(), n);
    EXPECT_TRUE(std::all_of(seen.begin(), seen.end(), [](const auto& entry) { return entry.second == 1; }));
    EXPECT_EQ(report.total, n);
    EXPECT_EQ(report.completed, n - failures);
    EXPECT_EQ(report.failed, failures);
    EXPECT_EQ(progress_calls, n);
    EXPECT_FALSE(report.stopped);
    EXPECT_TRUE(report.not_done.empty());
  } else {
    EXPECT_EQ(report.total, costs_here.size());
    EXPECT_EQ(report.completed + report.failed, report.total);
    EXPECT_TRUE(report.not_done.empty());
    EXPECT_FALSE(report.stopped);
  }
  // The workers' counts add up to the master's.
  EXPECT_EQ(sum(comm, comm.rank() == 0 ? 0 : report.completed), static_cast<std::int64_t>(n - failures));
  EXPECT_EQ(sum(comm, comm.rank() == 0 ? 0 : report.failed), static_cast<std::int64_t>(failures));
}

TEST(SchedulerMpi, ResultsEqualAOneProcessRun) {
  const Comm comm = mpi::mpi_world();
  const std::vector<WorkItem> items = make_items(120);
  std::map<std::uint64_t, std::pair<bool, std::string>> parallel;
  SchedulerOptions options;
  options.group_below_cost = 30;  // a mix of single items and groups
  options.max_group = 5;
  (void)mpi::run_master_worker(
      comm, comm.rank() == 0 ? items : std::vector<WorkItem>{}, deterministic_work,
      [&](const WorkResult& result) {
        parallel[result.id] = {result.ok, result.payload};
      },
      options);
  if (comm.rank() == 0) {
    std::map<std::uint64_t, std::pair<bool, std::string>> serial;
    std::vector<std::uint64_t> serial_order;
    const SchedulerReport report =
        mpi::run_master_worker(Comm::serial(), items, deterministic_work, [&](const WorkResult& r) {
          serial[r.id] = {r.ok, r.payload};
          serial_order.push_back(r.id);
          EXPECT_EQ(r.worker, 0);
        });
    EXPECT_EQ(report.completed + report.failed, items.size());
    EXPECT_EQ(parallel, serial);
    // The one-process run follows the dispatch order exactly.
    std::vector<WorkItem> sorted = items;
    std::stable_sort(sorted.begin(), sorted.end(), [](const WorkItem& a, const WorkItem& b) {
      return a.cost != b.cost ? a.cost > b.cost : a.id < b.id;
    });
    std::vector<std::uint64_t> expected;
    for (const WorkItem& item : sorted) expected.push_back(item.id);
    EXPECT_EQ(serial_order, expected);
  } else {
    EXPECT_TRUE(parallel.empty());  // results reach the master only
  }
}

TEST(SchedulerMpi, StopMidwayDrainsTheItemsInFlight) {
  const Comm comm = mpi::mpi_world();
  const std::uint64_t n = 100;
  const int workers = comm.size() - 1;
  std::vector<std::uint64_t> delivered;
  SchedulerOptions options;
  options.in_flight_per_worker = 2;
  options.poll_interval = std::chrono::microseconds(200);
  options.stop_requested = [&] { return delivered.size() >= 10; };
  const SchedulerReport report = mpi::run_master_worker(
      comm, comm.rank() == 0 ? make_items(n) : std::vector<WorkItem>{},
      [](const WorkItem& item) {
        sleep_ms(2);
        return item.payload;
      },
      [&](const WorkResult& result) { delivered.push_back(result.id); }, options);
  EXPECT_TRUE(report.stopped);
  if (comm.rank() == 0) {
    // Everything dispatched before the stop came back: at most one full pipeline beyond the 10th result.
    EXPECT_GE(report.completed, 10u);
    EXPECT_LE(report.completed, 10u + 2u * static_cast<std::size_t>(workers));
    EXPECT_EQ(report.completed, delivered.size());
    EXPECT_FALSE(report.not_done.empty());
    EXPECT_EQ(report.total, report.completed + report.failed + report.not_done.size());
    std::vector<std::uint64_t> all = delivered;
    all.insert(all.end(), report.not_done.begin(), report.not_done.end());
    std::sort(all.begin(), all.end());
    std::vector<std::uint64_t> ids(n);
    for (std::uint64_t i = 0; i < n; ++i) ids[i] = i;
    EXPECT_EQ(all, ids);  // each id either delivered or not done, exactly once
  } else {
    EXPECT_TRUE(report.not_done.empty());  // the drain let every held item finish and report
    EXPECT_EQ(report.completed, report.total);
  }
  EXPECT_EQ(sum(comm, comm.rank() == 0 ? 0 : report.completed),
            comm.allreduce(static_cast<std::int64_t>(comm.rank() == 0 ? report.completed : 0), ReduceOp::kSum));
}

TEST(SchedulerMpi, StopBeforeTheFirstItemDispatchesNothing) {
  const Comm comm = mpi::mpi_world();
  SchedulerOptions options;
  options.stop_requested = [] { return true; };
  int ran = 0;
  const SchedulerReport report = mpi::run_master_worker(
      comm, comm.rank() == 0 ? make_items(10) : std::vector<WorkItem>{},
      [&](const WorkItem& item) {
        ++ran;
        return item.payload;
      },
      {}, options);
  EXPECT_EQ(ran, 0);
  EXPECT_TRUE(report.stopped);
  EXPECT_EQ(report.not_done.size(), comm.rank() == 0 ? 10u : 0u);
}

TEST(SchedulerMpi, AnExpiredDrainDeadlineAbandonsABusyWorker) {
  const Comm comm = mpi::mpi_world();
  // Item 0 (largest, so first to worker 1) takes 800 ms; the stop comes 100 ms after the master's
  // first poll (just before it dispatches), the deadline 100 ms later: the master returns without
  // item 0, and worker 1 drops it and what it holds behind it.
  std::vector<WorkItem> items{{0, 1000, "slow"}};
  for (std::uint64_t i = 1; i <= 20; ++i) items.push_back({i, 1, "fast"});
  std::optional<Clock::time_point> first_poll;
  SchedulerOptions options;
  options.drain_deadline = std::chrono::milliseconds(100);
  options.stop_requested = [&] {
    const auto now = Clock::now();
    if (!first_poll) first_poll = now;
    return now - *first_poll > std::chrono::milliseconds(100);
  };
  const SchedulerReport report = mpi::run_master_worker(
      comm, comm.rank() == 0 ? items : std::vector<WorkItem>{},
      [](const WorkItem& item) {
        if (item.id == 0) sleep_ms(800);
        return item.payload;
      },
      {}, options);
  const auto not_done = [&](std::uint64_t id) {
    return std::find(report.not_done.begin(), report.not_done.end(), id) != report.not_done.end();
  };
  if (comm.rank() == 0) {
    EXPECT_TRUE(report.stopped);
    EXPECT_LT(report.seconds, 0.6);  // 100 ms + 100 ms + the 100 ms grace, not the 800 ms item
    EXPECT_EQ(report.total, report.completed + report.failed + report.not_done.size());
    EXPECT_TRUE(not_done(0));
    EXPECT_TRUE(not_done(1));  // queued behind item 0 on worker 1
  } else if (comm.rank() == 1) {
    // Worker 1 got items 0 and 1 first (the initial fill serves rank 1 first), ran item 0 to the end,
    // then found the master gone: both results dropped.
    EXPECT_TRUE(report.stopped);
    EXPECT_GE(report.seconds, 0.79);
    EXPECT_EQ(report.total, 2u);
    EXPECT_EQ(report.completed, 0u);
    EXPECT_EQ(report.not_done, (std::vector<std::uint64_t>{0, 1}));
  } else {
    EXPECT_TRUE(report.not_done.empty());  // the other workers were never abandoned
  }
  comm.barrier();
}

TEST(SchedulerMpi, AWorkerThatOutlastsItsPatienceIsLostAndTheRunGoesOn) {
  const Comm comm = mpi::mpi_world();
  // Item 0 (largest, so first to worker 1, with item 1 queued behind it) may take 200 ms and takes
  // 1.5 s, as a hung or stopped worker would: the master fails it and gives up on worker 1 after about
  // 200 ms, item 1 goes to another worker, and the run ends without waiting for worker 1. With no other
  // worker (2 ranks) the rest is left undone.
  std::vector<WorkItem> items{{0, 1000, "slow", std::chrono::milliseconds(200)}};
  for (std::uint64_t i = 1; i <= 20; ++i) items.push_back({i, 1, "fast"});
  std::vector<WorkResult> failures;
  const SchedulerReport report = mpi::run_master_worker(
      comm, comm.rank() == 0 ? items : std::vector<WorkItem>{},
      [](const WorkItem& item) {
        if (item.id == 0) sleep_ms(1500);
        return item.payload;
      },
      [&](const WorkResult& r) {
        if (!r.ok) failures.push_back(r);
      });
  if (comm.rank() == 0) {
    EXPECT_EQ(report.lost_workers, std::vector<int>{1});
    EXPECT_LT(report.seconds, 1.2);  // about 200 ms, not the 1.5 s item
    ASSERT_EQ(failures.size(), 1u);
    EXPECT_EQ(failures[0].id, 0u);
    EXPECT_EQ(failures[0].worker, 1);
    EXPECT_NE(failures[0].payload.find("rank 1 gave no answer"), std::string::npos) << failures[0].payload;
    EXPECT_EQ(report.failed, 1u);
    EXPECT_EQ(report.total, report.completed + report.failed + report.not_done.size());
    if (comm.size() > 2) {
      EXPECT_EQ(report.completed, 20u);  // item 1, queued on worker 1, ran elsewhere
      EXPECT_TRUE(report.not_done.empty());
    } else {
      EXPECT_EQ(report.completed, 0u);
      EXPECT_EQ(report.not_done.size(), 20u);  // each listed once, item 1 included
    }
  } else if (comm.rank() == 1) {
    // It ran item 0 to its end, then found the abandoning stop: both items it held are dropped.
    EXPECT_TRUE(report.stopped);
    EXPECT_EQ(report.completed, 0u);
    EXPECT_EQ(report.not_done, (std::vector<std::uint64_t>{0, 1}));
  }
  comm.barrier();  // worker 1 arrives after its 1.5 s item
}

TEST(SchedulerMpi, ALostWorkersGroupComesBackOneItemAtATime) {
  const Comm comm = mpi::mpi_world();
  // Twenty tiny items travel in groups (each allowed 300 ms; a group of 4 to 10 items, 1.2 to 3 s); item 0
  // (in rank 1's first group) hangs for 4 s. Which item of a
  // group hung is unknown, so the group costs no item an attempt: its items come back alone, and only item 0
  // fails, on the worker that takes it next (lost too). With one worker, nothing is charged.
  std::vector<WorkItem> items;
  for (std::uint64_t i = 0; i < 20; ++i) items.push_back({i, 1, "tiny", std::chrono::milliseconds(300)});
  SchedulerOptions options;
  options.group_below_cost = 2;
  std::vector<WorkResult> failures;
  const SchedulerReport report = mpi::run_master_worker(
      comm, comm.rank() == 0 ? items : std::vector<WorkItem>{},
      [](const WorkItem& item) {
        if (item.id == 0) sleep_ms(4000);
        return item.payload;
      },
      [&](const WorkResult& r) {
        if (!r.ok) failures.push_back(r);
      },
      options);
  if (comm.rank() == 0) {
    EXPECT_EQ(report.total, report.completed + report.failed + report.not_done.size());
    if (comm.size() > 3) {
      EXPECT_EQ(report.lost_workers.size(), 2u);
      ASSERT_EQ(failures.size(), 1u);
      EXPECT_EQ(failures[0].id, 0u);
      EXPECT_EQ(report.completed, 19u);
      EXPECT_TRUE(report.not_done.empty());
    } else if (comm.size() == 2) {
      EXPECT_EQ(report.lost_workers, std::vector<int>{1});
      EXPECT_TRUE(failures.empty());
      EXPECT_EQ(report.not_done.size(), 20u);
    }
  }
  comm.barrier();
}

TEST(SchedulerMpi, AResultHandlerExceptionStopsTheWorkersThenPropagates) {
  const Comm comm = mpi::mpi_world();
  std::size_t delivered = 0;
  const auto run = [&] {
    return mpi::run_master_worker(
        comm, comm.rank() == 0 ? make_items(50) : std::vector<WorkItem>{},
        [](const WorkItem& item) { return item.payload; },
        [&](const WorkResult&) {
          if (++delivered == 3) throw IoError("journal.h5: disk full");
        });
  };
  if (comm.rank() == 0) {
    EXPECT_THROW((void)run(), IoError);
    EXPECT_EQ(delivered, 3u);
  } else {
    SchedulerReport report;
    EXPECT_NO_THROW(report = run());
    EXPECT_TRUE(report.stopped);
    EXPECT_EQ(report.total, report.completed + report.failed + report.not_done.size());
  }
  comm.barrier();  // nobody hangs
}

TEST(SchedulerMpi, ManyTinyItemsTravelInGroups) {
  const auto traffic = std::make_shared<Traffic>();
  const Comm comm = counting_world(traffic);
  const std::uint64_t n = 3000;
  std::vector<WorkItem> items;
  for (std::uint64_t i = 0; i < n; ++i) items.push_back({i, i < 10 ? 500 + i : i % 5, std::to_string(i)});
  SchedulerOptions options;
  options.group_below_cost = 5;
  options.max_group = 16;
  std::map<std::uint64_t, int> seen;
  const SchedulerReport report = mpi::run_master_worker(
      comm, comm.rank() == 0 ? items : std::vector<WorkItem>{}, [](const WorkItem& item) { return item.payload; },
      [&](const WorkResult& result) {
        ++seen[result.id];
        EXPECT_EQ(result.payload, std::to_string(result.id));
      },
      options);
  if (comm.rank() == 0) {
    EXPECT_EQ(seen.size(), n);
    EXPECT_TRUE(std::all_of(seen.begin(), seen.end(), [](const auto& entry) { return entry.second == 1; }));
    EXPECT_EQ(report.completed, n);
    std::int64_t messages = 0;
    for (const auto& [peer, count] : traffic->sent) messages += count;
    // 10 single items, the rest in groups of up to 16 (smaller only at the tail), one stop per worker.
    EXPECT_LT(messages, 10 + static_cast<std::int64_t>(n) / 16 + 150);
    EXPECT_GT(messages, static_cast<std::int64_t>(n) / 16);
  } else {
    // One results message per batch received.
    EXPECT_EQ(traffic->sent[0] + 1, traffic->received[0]);
  }
}

TEST(SchedulerMpi, TheInFlightLimitIsRespectedAndReached) {
  for (const int limit : {1, 3}) {
    const auto traffic = std::make_shared<Traffic>();
    const Comm comm = counting_world(traffic);
    SchedulerOptions options;
    options.in_flight_per_worker = limit;
    std::size_t delivered = 0;
    const SchedulerReport report = mpi::run_master_worker(
        comm, comm.rank() == 0 ? make_items(60) : std::vector<WorkItem>{},
        [](const WorkItem& item) {
          std::this_thread::sleep_for(std::chrono::microseconds(300));
          return item.payload;
        },
        [&](const WorkResult&) { ++delivered; }, options);
    if (comm.rank() == 0) {
      EXPECT_EQ(traffic->max_outstanding, limit) << "in_flight_per_worker " << limit;
      EXPECT_EQ(delivered, 60u);
      EXPECT_EQ(report.completed, 60u);
    }
  }
}

TEST(SchedulerMpi, InvalidArgumentsOnOneRankThrowOnEveryRank) {
  const Comm comm = mpi::mpi_world();
  SchedulerOptions options;
  if (comm.rank() == comm.size() - 1) options.poll_interval = std::chrono::microseconds(-5);
  EXPECT_THROW((void)mpi::run_master_worker(comm, comm.rank() == 0 ? make_items(5) : std::vector<WorkItem>{},
                                            deterministic_work, {}, options),
               InvalidInput);
  comm.barrier();
}

TEST(SchedulerMpi, NoItemsReturnsAtOnceEverywhere) {
  const Comm comm = mpi::mpi_world();
  const SchedulerReport report = mpi::run_master_worker(comm, {}, deterministic_work, {});
  EXPECT_EQ(report.total, 0u);
  EXPECT_FALSE(report.stopped);
}

TEST(SchedulerMpi, MoreWorkersThanItems) {
  const Comm comm = mpi::mpi_world();
  std::size_t delivered = 0;
  const SchedulerReport report = mpi::run_master_worker(
      comm, comm.rank() == 0 ? make_items(1) : std::vector<WorkItem>{},
      [](const WorkItem& item) { return item.payload; }, [&](const WorkResult&) { ++delivered; });
  EXPECT_EQ(sum(comm, comm.rank() == 0 ? 0 : report.total), 1);
  if (comm.rank() == 0) {
    EXPECT_EQ(delivered, 1u);
  }
}

TEST(SchedulerMpi, FollowUpsRunAfterTheirCauseOnEveryWorker) {
  const Comm comm = mpi::mpi_world();
  test::StagedItems staged(3, 6);
  SchedulerOptions options;
  options.follow_ups = [&] { return staged.follow_ups(); };
  std::set<int> workers;
  const SchedulerReport report = mpi::run_master_worker(
      comm, comm.rank() == 0 ? staged.initial() : std::vector<WorkItem>{},
      [](const WorkItem& item) {
        sleep_ms(item.payload == "part" ? 20 : 5);
        return item.payload;
      },
      [&](const WorkResult& r) {
        workers.insert(r.worker);
        staged.on_result(r);
      },
      options);
  if (comm.rank() == 0) {
    EXPECT_EQ(staged.seen(), staged.total());
    EXPECT_EQ(report.total, staged.total());
    EXPECT_EQ(report.completed, staged.total());
    EXPECT_TRUE(report.not_done.empty());
    // The parts (18 of them, 20 ms each) spread over every worker, none left idle until the end.
    EXPECT_EQ(workers.size(), static_cast<std::size_t>(comm.size() - 1));
  } else {
    EXPECT_TRUE(report.not_done.empty());
  }
  EXPECT_EQ(sum(comm, comm.rank() == 0 ? 0 : report.completed), static_cast<std::int64_t>(staged.total()));
}

TEST(SchedulerMpi, FollowUpsGoToIdleWorkersAtOnce) {
  const Comm comm = mpi::mpi_world();
  // Worker 1 takes the root (id 0) and a slow item (id 1, 2 s); the root's four quick follow-ups must not
  // wait for the slow item: idle workers take them at once.
  std::vector<WorkItem> ready;
  std::vector<std::uint64_t> order;  // results as the master sees them
  SchedulerOptions options;
  options.follow_ups = [&] { return std::exchange(ready, {}); };
  (void)mpi::run_master_worker(
      comm, comm.rank() == 0 ? std::vector<WorkItem>{{0, 10, "root"}, {1, 5, "slow"}} : std::vector<WorkItem>{},
      [](const WorkItem& item) {
        sleep_ms(item.payload == "slow" ? 2000 : 50);
        return item.payload;
      },
      [&](const WorkResult& r) {
        order.push_back(r.id);
        if (r.id == 0)
          for (std::uint64_t k = 0; k < 4; ++k) ready.push_back({10 + k, 1, "quick"});
      },
      options);
  if (comm.rank() == 0 && comm.size() > 2) {
    ASSERT_EQ(order.size(), 6u);
    // At most one quick item queues behind the slow one on worker 1 (two messages in flight per worker).
    const auto slow = std::find(order.begin(), order.end(), 1u);
    EXPECT_GE(slow - order.begin(), 4) << "the quick follow-ups waited for the slow item";
  }
}

}  // namespace
