// Tests of the master / worker scheduler (mpi/scheduler.h) on one process (the serial communicator: the
// master runs every item itself) and of the shutdown-signal flag (mpi/shutdown.h).
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <cstdint>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "kernels/core/errors.h"
#include "mpi/comm.h"
#include "mpi/scheduler.h"
#include "mpi/shutdown.h"
#include "tests/unit/mpi/staged_items.h"

using namespace gimforge;
using mpi::Comm;
using mpi::SchedulerOptions;
using mpi::SchedulerReport;
using mpi::WorkItem;
using mpi::WorkResult;

namespace {

/// Items with the given costs; id i has cost costs[i] and payload "item i".
std::vector<WorkItem> items_with_costs(const std::vector<std::uint64_t>& costs) {
  std::vector<WorkItem> items;
  for (std::size_t i = 0; i < costs.size(); ++i) items.push_back({i, costs[i], "item " + std::to_string(i)});
  return items;
}

std::string echo(const WorkItem& item) { return "done " + item.payload; }

TEST(SchedulerSerial, RunsLargestCostFirstThenSmallestId) {
  const Comm comm = Comm::serial();
  // ids 0..7; equal costs are ordered by id.
  const std::vector<WorkItem> items = items_with_costs({5, 9, 1, 9, 0, 5, 7, 1});
  std::vector<std::uint64_t> ran, delivered;
  const SchedulerReport report = mpi::run_master_worker(
      comm, items,
      [&](const WorkItem& item) {
        ran.push_back(item.id);
        return echo(item);
      },
      [&](const WorkResult& result) {
        delivered.push_back(result.id);
        EXPECT_TRUE(result.ok);
        EXPECT_EQ(result.worker, 0);
        EXPECT_EQ(result.payload, "done item " + std::to_string(result.id));
      });
  const std::vector<std::uint64_t> expected{1, 3, 6, 0, 5, 2, 7, 4};
  EXPECT_EQ(ran, expected);
  EXPECT_EQ(delivered, expected);
  EXPECT_EQ(report.total, 8u);
  EXPECT_EQ(report.completed, 8u);
  EXPECT_EQ(report.failed, 0u);
  EXPECT_FALSE(report.stopped);
  EXPECT_TRUE(report.not_done.empty());
  EXPECT_GE(report.seconds, 0.0);
}

TEST(SchedulerSerial, DuplicateIdsAndPayloadsArriveIntact) {
  const Comm comm = Comm::serial();
  const std::string binary("a\0b\xff", 4);
  const std::vector<WorkItem> items{{7, 1, binary}, {7, 2, ""}, {3, 2, std::string(10000, 'x')}};
  std::vector<std::pair<std::uint64_t, std::string>> seen;
  const auto report = mpi::run_master_worker(
      comm, items, [](const WorkItem& item) { return item.payload; },
      [&](const WorkResult& result) { seen.emplace_back(result.id, result.payload); });
  ASSERT_EQ(seen.size(), 3u);
  EXPECT_EQ(seen[0], (std::pair<std::uint64_t, std::string>{3, std::string(10000, 'x')}));
  EXPECT_EQ(seen[1], (std::pair<std::uint64_t, std::string>{7, ""}));
  EXPECT_EQ(seen[2], (std::pair<std::uint64_t, std::string>{7, binary}));
  EXPECT_EQ(report.completed, 3u);
}

TEST(SchedulerSerial, ExceptionsBecomeFailedResults) {
  const Comm comm = Comm::serial();
  const std::vector<WorkItem> items = items_with_costs({1, 1, 1, 1, 1, 1});
  std::map<std::uint64_t, WorkResult> results;
  const auto report = mpi::run_master_worker(
      comm, items,
      [](const WorkItem& item) -> std::string {
        if (item.id == 1) throw IoError("mesh.ply: truncated");
        if (item.id == 3) throw std::runtime_error("plain runtime error");
        if (item.id == 5) throw 42;  // not a std::exception
        return echo(item);
      },
      [&](const WorkResult& result) { results[result.id] = result; });
  ASSERT_EQ(results.size(), 6u);
  EXPECT_FALSE(results[1].ok);
  EXPECT_EQ(results[1].payload, "mesh.ply: truncated");
  EXPECT_FALSE(results[3].ok);
  EXPECT_EQ(results[3].payload, "plain runtime error");
  EXPECT_FALSE(results[5].ok);
  EXPECT_NE(results[5].payload.find("unknown exception"), std::string::npos);
  for (const std::uint64_t id : {0U, 2U, 4U}) {
    EXPECT_TRUE(results[id].ok);
    EXPECT_EQ(results[id].payload, "done item " + std::to_string(id));
  }
  EXPECT_EQ(report.completed, 3u);
  EXPECT_EQ(report.failed, 3u);
  EXPECT_TRUE(report.not_done.empty());
}

TEST(SchedulerSerial, StopRequestedMidwayListsTheRestAsNotDone) {
  const Comm comm = Comm::serial();
  const std::vector<WorkItem> items = items_with_costs({10, 20, 30, 40, 50, 60, 70});  // order: 6 5 4 3 2 1 0
  std::vector<std::uint64_t> delivered;
  SchedulerOptions options;
  options.stop_requested = [&] { return delivered.size() >= 3; };
  const auto report = mpi::run_master_worker(
      comm, items, echo, [&](const WorkResult& result) { delivered.push_back(result.id); }, options);
  EXPECT_EQ(delivered, (std::vector<std::uint64_t>{6, 5, 4}));
  EXPECT_TRUE(report.stopped);
  EXPECT_EQ(report.total, 7u);
  EXPECT_EQ(report.completed, 3u);
  EXPECT_EQ(report.not_done, (std::vector<std::uint64_t>{3, 2, 1, 0}));
  EXPECT_EQ(report.total, report.completed + report.failed + report.not_done.size());
}

TEST(SchedulerSerial, StopBeforeTheFirstItemRunsNothing) {
  const Comm comm = Comm::serial();
  SchedulerOptions options;
  options.stop_requested = [] { return true; };
  int ran = 0;
  const auto report = mpi::run_master_worker(
      comm, items_with_costs({1, 2, 3}),
      [&](const WorkItem& item) {
        ++ran;
        return echo(item);
      },
      {}, options);
  EXPECT_EQ(ran, 0);
  EXPECT_TRUE(report.stopped);
  EXPECT_EQ(report.not_done, (std::vector<std::uint64_t>{2, 1, 0}));
}

TEST(SchedulerSerial, StopAfterTheLastItemIsNoStop) {
  const Comm comm = Comm::serial();
  std::size_t delivered = 0;
  SchedulerOptions options;
  options.stop_requested = [&] { return delivered == 3; };
  const auto report = mpi::run_master_worker(
      comm, items_with_costs({1, 2, 3}), echo, [&](const WorkResult&) { ++delivered; }, options);
  EXPECT_FALSE(report.stopped);
  EXPECT_EQ(report.completed, 3u);
  EXPECT_TRUE(report.not_done.empty());
}

TEST(SchedulerSerial, GroupingOptionsNeitherLoseNorDuplicateItems) {
  const Comm comm = Comm::serial();
  std::vector<WorkItem> items;
  for (std::uint64_t i = 0; i < 1000; ++i) items.push_back({i, i % 3 == 0 ? 100 + i : i % 5, std::to_string(i)});
  SchedulerOptions options;
  options.group_below_cost = 10;
  options.max_group = 7;
  std::map<std::uint64_t, int> seen;
  std::vector<std::uint64_t> costs;
  const auto report = mpi::run_master_worker(
      comm, items,
      [&](const WorkItem& item) {
        costs.push_back(item.cost);
        return item.payload;
      },
      [&](const WorkResult& result) {
        ++seen[result.id];
        EXPECT_EQ(result.payload, std::to_string(result.id));
      },
      options);
  EXPECT_EQ(seen.size(), 1000u);
  EXPECT_TRUE(std::all_of(seen.begin(), seen.end(), [](const auto& entry) { return entry.second == 1; }));
  EXPECT_TRUE(std::is_sorted(costs.rbegin(), costs.rend()));
  EXPECT_EQ(report.completed, 1000u);
}

TEST(SchedulerSerial, ProgressCountsDoneOverTotal) {
  const Comm comm = Comm::serial();
  std::vector<std::pair<std::size_t, std::size_t>> calls;
  SchedulerOptions options;
  options.progress = [&](std::size_t done, std::size_t total) { calls.emplace_back(done, total); };
  const auto report = mpi::run_master_worker(
      comm, items_with_costs({3, 2, 1}),
      [](const WorkItem& item) -> std::string {
        if (item.id == 1) throw InvalidInput("bad");
        return {};
      },
      {}, options);
  EXPECT_EQ(calls, (std::vector<std::pair<std::size_t, std::size_t>>{{1, 3}, {2, 3}, {3, 3}}));
  EXPECT_EQ(report.failed, 1u);
}

TEST(SchedulerSerial, ResultHandlerExceptionsPropagate) {
  const Comm comm = Comm::serial();
  int ran = 0;
  EXPECT_THROW((void)mpi::run_master_worker(
                   comm, items_with_costs({3, 2, 1}),
                   [&](const WorkItem& item) {
                     ++ran;
                     return echo(item);
                   },
                   [](const WorkResult&) { throw IoError("journal.h5: disk full"); }),
               IoError);
  EXPECT_EQ(ran, 1);
}

TEST(SchedulerSerial, NoItemsIsAnEmptyReport) {
  const auto report = mpi::run_master_worker(Comm::serial(), {}, echo, {});
  EXPECT_EQ(report.total, 0u);
  EXPECT_EQ(report.completed, 0u);
  EXPECT_FALSE(report.stopped);
}

TEST(SchedulerSerial, InvalidArgumentsThrowInvalidInput) {
  const Comm comm = Comm::serial();
  const auto items = items_with_costs({1});
  EXPECT_THROW((void)mpi::run_master_worker(comm, items, mpi::WorkFunction{}, {}), InvalidInput);
  SchedulerOptions options;
  options.in_flight_per_worker = 0;
  EXPECT_THROW((void)mpi::run_master_worker(comm, items, echo, {}, options), InvalidInput);
  options = {};
  options.max_group = 0;
  EXPECT_THROW((void)mpi::run_master_worker(comm, items, echo, {}, options), InvalidInput);
  options = {};
  options.poll_interval = std::chrono::microseconds(-1);
  EXPECT_THROW((void)mpi::run_master_worker(comm, items, echo, {}, options), InvalidInput);
  options = {};
  options.drain_deadline = std::chrono::milliseconds(-1);
  EXPECT_THROW((void)mpi::run_master_worker(comm, items, echo, {}, options), InvalidInput);
}

// ---- shutdown signals -----------------------------------------------------------------------------

int g_previous_handler_calls = 0;
extern "C" void count_previous_handler(int) { ++g_previous_handler_calls; }

/// The handler currently installed for `sig`.
void (*current_handler(int sig))(int) {
  struct sigaction action {};
  sigaction(sig, nullptr, &action);
  return action.sa_handler;
}

TEST(ShutdownSignals, SignalsSetTheFlagAndRecordWhichOne) {
  for (const int sig : {SIGTERM, SIGUSR1, SIGINT}) {
    const mpi::ShutdownSignals signals;
    EXPECT_FALSE(signals.requested());
    EXPECT_EQ(signals.signal(), 0);
    ASSERT_EQ(raise(sig), 0);  // would end the test program without the handler
    EXPECT_TRUE(signals.requested());
    EXPECT_EQ(signals.signal(), sig);
  }
}

TEST(ShutdownSignals, ASecondSigintGetsTheDefaultAction) {
  const mpi::ShutdownSignals signals;
  EXPECT_NE(current_handler(SIGINT), SIG_DFL);
  ASSERT_EQ(raise(SIGINT), 0);
  EXPECT_TRUE(signals.requested());
  EXPECT_EQ(current_handler(SIGINT), SIG_DFL);   // a second Ctrl-C would end the process
  EXPECT_NE(current_handler(SIGTERM), SIG_DFL);  // SIGTERM and SIGUSR1 stay caught
  EXPECT_NE(current_handler(SIGUSR1), SIG_DFL);
}

TEST(ShutdownSignals, RestoresThePreviousHandlers) {
  struct sigaction previous {};
  previous.sa_handler = &count_previous_handler;
  sigemptyset(&previous.sa_mask);
  struct sigaction saved {};
  ASSERT_EQ(sigaction(SIGUSR1, &previous, &saved), 0);
  {
    const mpi::ShutdownSignals signals;
    EXPECT_NE(current_handler(SIGUSR1), &count_previous_handler);
    ASSERT_EQ(raise(SIGUSR1), 0);
    EXPECT_EQ(g_previous_handler_calls, 0);
  }
  EXPECT_EQ(current_handler(SIGUSR1), &count_previous_handler);
  ASSERT_EQ(raise(SIGUSR1), 0);
  EXPECT_EQ(g_previous_handler_calls, 1);
  sigaction(SIGUSR1, &saved, nullptr);
}

TEST(ShutdownSignals, OneInstanceAtATime) {
  mpi::ShutdownSignals signals;
  EXPECT_THROW(mpi::ShutdownSignals{}, InvalidInput);
  signals.request_shutdown_for_testing();
  EXPECT_TRUE(signals.requested());
  EXPECT_EQ(signals.signal(), SIGTERM);
}

TEST(ShutdownSignals, ASignalStopsTheSchedulerBetweenItems) {
  const Comm comm = Comm::serial();
  const mpi::ShutdownSignals signals;
  SchedulerOptions options;
  options.stop_requested = [&] { return signals.requested(); };
  const auto report = mpi::run_master_worker(
      comm, items_with_costs({5, 4, 3, 2, 1}),
      [](const WorkItem& item) {
        if (item.id == 1) raise(SIGUSR1);  // arrives while the second item runs
        return echo(item);
      },
      {}, options);
  EXPECT_TRUE(report.stopped);
  EXPECT_EQ(report.completed, 2u);
  EXPECT_EQ(report.not_done, (std::vector<std::uint64_t>{2, 3, 4}));
  EXPECT_EQ(signals.signal(), SIGUSR1);
}

TEST(SchedulerSerial, FollowUpsJoinTheOrderByCost) {
  test::StagedItems staged(2, 3);
  SchedulerOptions options;
  options.follow_ups = [&] { return staged.follow_ups(); };
  std::size_t last_total = 0;
  options.progress = [&](std::size_t, std::size_t total) { last_total = total; };
  const SchedulerReport report = mpi::run_master_worker(
      Comm::serial(), staged.initial(), [](const WorkItem& item) { return item.payload; },
      [&](const WorkResult& r) { staged.on_result(r); }, options);
  // Roots (cost 10) first; the first root's parts (5) wait behind the second root; each finish (8) goes
  // before the parts of the next job still waiting; the plain item (1) last.
  const std::vector<std::uint64_t> expected{0, 100, 1, 2, 3, 99, 101, 102, 103, 199, 1000};
  EXPECT_EQ(staged.order(), expected);
  EXPECT_EQ(report.total, staged.total());
  EXPECT_EQ(report.completed, staged.total());
  EXPECT_EQ(last_total, staged.total());
}

TEST(SchedulerSerial, FollowUpsOfAStoppedRunAreNotDone) {
  test::StagedItems staged(1, 4);
  SchedulerOptions options;
  options.follow_ups = [&] { return staged.follow_ups(); };
  std::size_t results = 0;
  options.stop_requested = [&] { return results == 2; };  // the root and one part
  const SchedulerReport report = mpi::run_master_worker(
      Comm::serial(), staged.initial(), [](const WorkItem& item) { return item.payload; },
      [&](const WorkResult& r) {
        ++results;
        staged.on_result(r);
      },
      options);
  EXPECT_TRUE(report.stopped);
  EXPECT_EQ(report.completed, 2u);
  EXPECT_EQ(report.total, 6u);  // the root, its four parts and the plain item; no finish yet
  const std::vector<std::uint64_t> not_done{2, 3, 4, 1000};
  EXPECT_EQ(report.not_done, not_done);
}

}  // namespace
