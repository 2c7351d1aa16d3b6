// Tests of the MPI communicator (mpi/mpi_comm.h) for any number of ranks (ctest runs 2 and 4).
// Collectives stay matched on all ranks even when an expectation fails (EXPECT, not ASSERT).
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <optional>
#include <string>
#include <vector>

#include "kernels/core/errors.h"
#include "mpi/comm.h"
#include "mpi/mpi_comm.h"

using namespace gimforge;
using mpi::Comm;
using mpi::ReduceOp;

namespace {

std::vector<std::byte> bytes_of(const std::string& text) {
  std::vector<std::byte> out(text.size());
  std::transform(text.begin(), text.end(), out.begin(), [](char c) { return static_cast<std::byte>(c); });
  return out;
}

std::string text_of(const std::vector<std::byte>& data) {
  std::string out(data.size(), '\0');
  std::transform(data.begin(), data.end(), out.begin(), [](std::byte b) { return static_cast<char>(b); });
  return out;
}

TEST(MpiComm, RankAndSizeMatchMpiCommWorld) {
  const Comm comm = mpi::mpi_world();
  int rank = -1, size = -1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  EXPECT_EQ(comm.rank(), rank);
  EXPECT_EQ(comm.size(), size);
  EXPECT_TRUE(mpi::is_mpi(comm));
  comm.barrier();
}

TEST(MpiComm, NativeIsADuplicateOfTheWorld) {
  const Comm comm = mpi::mpi_world();
  int result = MPI_UNEQUAL;
  MPI_Comm_compare(mpi::native(comm), MPI_COMM_WORLD, &result);
  EXPECT_EQ(result, MPI_CONGRUENT);
  EXPECT_THROW((void)mpi::native(Comm::serial()), InvalidInput);
  EXPECT_FALSE(mpi::is_mpi(Comm::serial()));
  EXPECT_THROW((void)mpi::from_mpi(MPI_COMM_NULL), InvalidInput);
}

TEST(MpiComm, ScalarReductions) {
  const Comm comm = mpi::mpi_world();
  const auto r = static_cast<std::int64_t>(comm.rank());
  const auto n = static_cast<std::int64_t>(comm.size());
  EXPECT_EQ(comm.allreduce(r, ReduceOp::kSum), n * (n - 1) / 2);
  EXPECT_EQ(comm.allreduce(r - 5, ReduceOp::kMin), -5);
  EXPECT_EQ(comm.allreduce(r, ReduceOp::kMax), n - 1);
  EXPECT_EQ(comm.allreduce(0.5 * static_cast<double>(r), ReduceOp::kSum), 0.25 * static_cast<double>(n * (n - 1)));
  const std::uint64_t big = (std::uint64_t{1} << 63) + static_cast<std::uint64_t>(r);  // above INT64_MAX
  EXPECT_EQ(comm.allreduce(big, ReduceOp::kMax), (std::uint64_t{1} << 63) + static_cast<std::uint64_t>(n - 1));
  EXPECT_EQ(comm.allreduce(big, ReduceOp::kMin), std::uint64_t{1} << 63);
}

TEST(MpiComm, VectorReductionsAreElementWise) {
  const Comm comm = mpi::mpi_world();
  const auto r = static_cast<std::int64_t>(comm.rank());
  const auto n = static_cast<std::int64_t>(comm.size());
  EXPECT_EQ(comm.allreduce(std::vector<std::int64_t>{r, -r, 1}, ReduceOp::kSum),
            (std::vector<std::int64_t>{n * (n - 1) / 2, -n * (n - 1) / 2, n}));
  EXPECT_EQ(comm.allreduce(std::vector<double>{static_cast<double>(r), -static_cast<double>(r)}, ReduceOp::kMax),
            (std::vector<double>{static_cast<double>(n - 1), 0.0}));
  EXPECT_TRUE(comm.allreduce(std::vector<double>{}, ReduceOp::kSum).empty());
}

TEST(MpiComm, BroadcastFromEveryRoot) {
  const Comm comm = mpi::mpi_world();
  for (int root = 0; root < comm.size(); ++root) {
    const std::string expected = "from rank " + std::to_string(root) + std::string(static_cast<std::size_t>(root), '!');
    std::string text = comm.rank() == root ? expected : std::string(7, 'x');
    comm.broadcast(text, root);
    EXPECT_EQ(text, expected);

    std::vector<double> values(static_cast<std::size_t>(comm.rank() + 1), -1.0);
    if (comm.rank() == root) values = {1.5, 2.5, static_cast<double>(root)};
    comm.broadcast(values, root);
    EXPECT_EQ(values, (std::vector<double>{1.5, 2.5, static_cast<double>(root)}));

    std::vector<std::byte> bytes = comm.rank() == root ? bytes_of(expected) : std::vector<std::byte>{};
    comm.broadcast(bytes, root);
    EXPECT_EQ(text_of(bytes), expected);
  }
  std::string text;
  EXPECT_THROW(comm.broadcast(text, comm.size()), InvalidInput);  // checked before any communication
}

TEST(MpiComm, SendAndRecvAroundARing) {
  const Comm comm = mpi::mpi_world();
  const int next = (comm.rank() + 1) % comm.size();
  const int prev = (comm.rank() + comm.size() - 1) % comm.size();
  const std::vector<std::byte> payload = bytes_of("hello from " + std::to_string(comm.rank()));
  auto receive = [&] {
    const mpi::Message msg = comm.recv(prev, 7);
    EXPECT_EQ(msg.source, prev);
    EXPECT_EQ(msg.tag, 7);
    EXPECT_EQ(text_of(msg.data), "hello from " + std::to_string(prev));
  };
  if (comm.rank() % 2 == 0) {
    comm.send(payload, next, 7);
    receive();
  } else {
    receive();
    comm.send(payload, next, 7);
  }
  EXPECT_THROW(comm.send(payload, comm.size(), 0), InvalidInput);
  EXPECT_THROW(comm.send(payload, next, -3), InvalidInput);
}

TEST(MpiComm, ProbeReportsSourceTagAndSize) {
  const Comm comm = mpi::mpi_world();
  if (comm.rank() != 0) {
    const std::vector<std::byte> payload(static_cast<std::size_t>(comm.rank()) * 10, std::byte{0x5a});
    comm.send(payload, 0, 100 + comm.rank());
  } else {
    std::vector<int> seen;
    for (int i = 1; i < comm.size(); ++i) {
      const mpi::MessageInfo info = comm.probe(mpi::kAnySource, mpi::kAnyTag);
      EXPECT_EQ(info.tag, 100 + info.source);
      EXPECT_EQ(info.size, static_cast<std::size_t>(info.source) * 10);
      const mpi::Message msg = comm.recv(info.source, info.tag);
      EXPECT_EQ(msg.data.size(), info.size);
      seen.push_back(info.source);
    }
    std::sort(seen.begin(), seen.end());
    std::vector<int> expected(static_cast<std::size_t>(comm.size() - 1));
    std::iota(expected.begin(), expected.end(), 1);
    EXPECT_EQ(seen, expected);
    EXPECT_FALSE(comm.iprobe().has_value());  // everything was received
  }
  comm.barrier();
}

TEST(MpiComm, IprobeEventuallySeesAPendingMessage) {
  const Comm comm = mpi::mpi_world();
  const int to = comm.size() - 1;
  if (comm.rank() == 0) comm.send(bytes_of("ping"), to, 3);
  if (comm.rank() == to) {
    std::optional<mpi::MessageInfo> info;
    while (!(info = comm.iprobe(0, 3))) {
    }
    EXPECT_EQ(info->source, 0);
    EXPECT_EQ(info->size, 4u);
    EXPECT_EQ(text_of(comm.recv(0, 3).data), "ping");
  }
  comm.barrier();
}

TEST(MpiComm, GatherCollectsOneValuePerRankInRankOrder) {
  struct Sample {
    int rank;
    double value;
  };
  const Comm comm = mpi::mpi_world();
  for (int root = 0; root < comm.size(); ++root) {
    const auto gathered = comm.gather(Sample{comm.rank(), 0.5 * comm.rank()}, root);
    if (comm.rank() != root) {
      EXPECT_TRUE(gathered.empty());
      continue;
    }
    EXPECT_EQ(gathered.size(), static_cast<std::size_t>(comm.size()));
    for (std::size_t i = 0; i < gathered.size(); ++i) {
      EXPECT_EQ(gathered[i].rank, static_cast<int>(i));
      EXPECT_EQ(gathered[i].value, 0.5 * static_cast<double>(i));
    }
  }
}

TEST(MpiComm, SplitGroupsByColorAndOrdersByKey) {
  const Comm comm = mpi::mpi_world();
  const int color = comm.rank() % 2;
  const Comm sub = comm.split(color, -comm.rank());  // reverse order inside each color
  int same = 0, above = 0;
  for (int r = 0; r < comm.size(); ++r) {
    same += r % 2 == color;
    above += r % 2 == color && r > comm.rank();
  }
  EXPECT_EQ(sub.size(), same);
  EXPECT_EQ(sub.rank(), above);
  std::int64_t expected_sum = 0;
  for (int r = color; r < comm.size(); r += 2) expected_sum += r;
  EXPECT_EQ(sub.allreduce(static_cast<std::int64_t>(comm.rank()), ReduceOp::kSum), expected_sum);
  const Comm single = sub.split(sub.rank());  // one rank each
  EXPECT_EQ(single.size(), 1);
  EXPECT_THROW((void)comm.split(-1), InvalidInput);
}

}  // namespace
