#pragma once
// A three-stage job for the scheduler's follow-ups (mpi/scheduler.h), shared by the serial and the MPI
// tests: `jobs` roots (id 100·j, cost 10); each root's result makes `parts` parts ready (id 100·j + 1 + p,
// cost 5); the last part of a job to finish makes its finish item ready (id 100·j + 99, cost 8); and one
// plain item (id 1000, cost 1) is passed in from the start. Every result is checked against what must
// already be done before it.
#include <gtest/gtest.h>

#include <cstdint>
#include <map>
#include <set>
#include <utility>
#include <string>
#include <vector>

#include "mpi/scheduler.h"

namespace gimforge::test {

class StagedItems {
 public:
  StagedItems(std::uint64_t jobs, std::uint64_t parts) : jobs_(jobs), parts_(parts) {}

  [[nodiscard]] std::vector<mpi::WorkItem> initial() const {
    std::vector<mpi::WorkItem> items;
    for (std::uint64_t j = 0; j < jobs_; ++j) items.push_back({100 * j, 10, "root"});
    items.push_back({1000, 1, "plain"});
    return items;
  }
  [[nodiscard]] std::uint64_t total() const { return jobs_ * (parts_ + 2) + 1; }

  /// The master's result handler.
  void on_result(const mpi::WorkResult& r) {
    EXPECT_TRUE(r.ok) << r.payload;
    EXPECT_TRUE(seen_.insert(r.id).second) << "item " << r.id << " ran twice";
    order_.push_back(r.id);
    if (r.id == 1000) return;
    const std::uint64_t job = r.id / 100, within = r.id % 100;
    if (within == 0) {
      for (std::uint64_t p = 0; p < parts_; ++p) ready_.push_back({100 * job + 1 + p, 5, "part"});
    } else if (within == 99) {
      EXPECT_EQ(parts_done_[job], parts_) << "job " << job << " finished before its parts";
    } else {
      EXPECT_TRUE(seen_.contains(100 * job)) << "a part ran before its root";
      if (++parts_done_[job] == parts_) ready_.push_back({100 * job + 99, 8, "finish"});
    }
  }

  /// The scheduler's follow_ups.
  [[nodiscard]] std::vector<mpi::WorkItem> follow_ups() { return std::exchange(ready_, {}); }

  [[nodiscard]] const std::vector<std::uint64_t>& order() const { return order_; }
  [[nodiscard]] std::size_t seen() const { return seen_.size(); }

 private:
  std::uint64_t jobs_, parts_;
  std::set<std::uint64_t> seen_;
  std::vector<std::uint64_t> order_;
  std::map<std::uint64_t, std::uint64_t> parts_done_;
  std::vector<mpi::WorkItem> ready_;
};

}  // namespace gimforge::test
