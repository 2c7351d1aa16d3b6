// bench_scheduler [--items N] [--work-us U] [--in-flight K] [--group-below C] [--max-group G] [--poll-us P]
//                 [--repeat R]
// Per-item overhead of the master / worker scheduler (mpi/scheduler.h). Run it under mpirun with 2 and
// 4 ranks (or alone: then rank 0 runs the items itself). Items have cost id % 100 (so grouping with
// --group-below applies to a share of them) and an 8-byte payload; each one sleeps U microseconds on a
// worker (default 0: empty items, pure scheduling cost). Prints, for the best of R runs:
//   ms/item (wall)     wall time / items: the throughput the master sustains
//   ms/item (worker)   (workers x wall - time spent inside the work function) / items: what each item
//                      costs a worker beyond its own work, i.e. the scheduling overhead per item
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "mpi/comm.h"
#include "mpi/environment.h"
#include "mpi/mpi_comm.h"
#include "mpi/scheduler.h"

namespace {

using Clock = std::chrono::steady_clock;

struct Args {
  std::uint64_t items{20000};
  std::int64_t work_us{0};
  gimforge::mpi::SchedulerOptions options;
  int repeat{3};
};

bool parse_args(int argc, char** argv, Args& args) {
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (i + 1 >= argc) return false;
    const std::string value = argv[++i];
    if (a == "--items") {
      args.items = std::stoull(value);
    } else if (a == "--work-us") {
      args.work_us = std::stoll(value);
    } else if (a == "--in-flight") {
      args.options.in_flight_per_worker = std::stoi(value);
    } else if (a == "--group-below") {
      args.options.group_below_cost = std::stoull(value);
    } else if (a == "--max-group") {
      args.options.max_group = std::stoull(value);
    } else if (a == "--poll-us") {
      args.options.poll_interval = std::chrono::microseconds(std::stoll(value));
    } else if (a == "--repeat") {
      args.repeat = std::stoi(value);
    } else {
      return false;
    }
  }
  return args.items > 0 && args.work_us >= 0 && args.repeat > 0;
}

struct Run {
  double wall = 0;       // seconds, on rank 0
  double work = 0;       // seconds inside the work function, summed over ranks
  std::size_t done = 0;  // results delivered on rank 0
};

Run run_once(const gimforge::mpi::Comm& comm, const Args& args) {
  std::vector<gimforge::mpi::WorkItem> items;
  if (comm.rank() == 0) {
    items.reserve(args.items);
    for (std::uint64_t i = 0; i < args.items; ++i) items.push_back({i, i % 100, "mesh.ply"});
  }
  double work_seconds = 0;
  std::size_t done = 0;
  comm.barrier();
  const auto t0 = Clock::now();
  (void)gimforge::mpi::run_master_worker(
      comm, std::move(items),
      [&](const gimforge::mpi::WorkItem& item) {
        if (args.work_us > 0) {
          const auto w0 = Clock::now();
          std::this_thread::sleep_for(std::chrono::microseconds(args.work_us));
          work_seconds += std::chrono::duration<double>(Clock::now() - w0).count();
        }
        return item.payload;
      },
      [&](const gimforge::mpi::WorkResult&) { ++done; }, args.options);
  const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
  return {wall, comm.allreduce(work_seconds, gimforge::mpi::ReduceOp::kSum), done};
}

}  // namespace

int main(int argc, char** argv) {
  gimforge::mpi::MpiEnvironment mpi(argc, argv);
  Args args;
  try {
    if (!parse_args(argc, argv, args)) {
      fmt::print(stderr,
                 "usage: bench_scheduler [--items N] [--work-us U] [--in-flight K] [--group-below C] "
                 "[--max-group G] [--poll-us P] [--repeat R]\n");
      return 2;
    }
    const gimforge::mpi::Comm comm = gimforge::mpi::mpi_world();
    std::vector<Run> runs;
    for (int r = 0; r < args.repeat; ++r) runs.push_back(run_once(comm, args));
    if (comm.rank() != 0) return 0;
    const Run best =
        *std::min_element(runs.begin(), runs.end(), [](const Run& a, const Run& b) { return a.wall < b.wall; });
    const int workers = std::max(comm.size() - 1, 1);
    const double n = static_cast<double>(args.items);
    fmt::print(
        "ranks: {} (workers: {})  items: {}  work: {} us/item  in-flight: {}  group below cost: {} (max {})  "
        "poll: {} us\n",
        comm.size(), workers, args.items, args.work_us, args.options.in_flight_per_worker,
        args.options.group_below_cost, args.options.max_group, args.options.poll_interval.count());
    fmt::print("best of {}: {:.3f} s, {} results\n", args.repeat, best.wall, best.done);
    fmt::print("ms/item (wall):   {:.4f}\n", 1e3 * best.wall / n);
    fmt::print("ms/item (worker): {:.4f}\n", 1e3 * (static_cast<double>(workers) * best.wall - best.work) / n);
    return best.done == args.items ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_scheduler: error: %s\n", e.what());
    return 1;
  }
}
