// Tests of the serial communicator (mpi/comm.h): size 1, identity reductions, copying collectives, and
// point-to-point operations that refuse with InvalidInput.
#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "kernels/core/errors.h"
#include "mpi/agree.h"
#include "mpi/comm.h"

using namespace gimforge;
using mpi::Comm;
using mpi::ReduceOp;

namespace {

TEST(SerialComm, HasOneRank) {
  const Comm comm = Comm::serial();
  EXPECT_EQ(comm.rank(), 0);
  EXPECT_EQ(comm.size(), 1);
  comm.barrier();
}

TEST(SerialComm, ScalarReductionsReturnTheirInput) {
  const Comm comm = Comm::serial();
  for (const ReduceOp op : {ReduceOp::kSum, ReduceOp::kMin, ReduceOp::kMax}) {
    EXPECT_EQ(comm.allreduce(std::int64_t{-7}, op), -7);
    EXPECT_EQ(comm.allreduce(std::numeric_limits<std::uint64_t>::max(), op), std::numeric_limits<std::uint64_t>::max());
    EXPECT_EQ(comm.allreduce(2.5, op), 2.5);
  }
}

TEST(SerialComm, VectorReductionsReturnTheirInput) {
  const Comm comm = Comm::serial();
  EXPECT_EQ(comm.allreduce(std::vector<double>{1.5, -2.0}, ReduceOp::kSum), (std::vector<double>{1.5, -2.0}));
  EXPECT_EQ(comm.allreduce(std::vector<std::int64_t>{3, 1}, ReduceOp::kMax), (std::vector<std::int64_t>{3, 1}));
  EXPECT_TRUE(comm.allreduce(std::vector<std::uint64_t>{}, ReduceOp::kMin).empty());
}

TEST(SerialComm, BroadcastFromRankZeroKeepsTheData) {
  const Comm comm = Comm::serial();
  std::string text = "hello";
  comm.broadcast(text, 0);
  EXPECT_EQ(text, "hello");
  std::vector<double> values{1, 2, 3};
  comm.broadcast(values, 0);
  EXPECT_EQ(values, (std::vector<double>{1, 2, 3}));
  std::vector<std::byte> bytes{std::byte{1}, std::byte{255}};
  comm.broadcast(bytes, 0);
  EXPECT_EQ(bytes, (std::vector<std::byte>{std::byte{1}, std::byte{255}}));
}

TEST(SerialComm, BroadcastFromAMissingRootThrows) {
  const Comm comm = Comm::serial();
  std::string text;
  EXPECT_THROW(comm.broadcast(text, 1), InvalidInput);
  EXPECT_THROW(comm.broadcast(text, -1), InvalidInput);
}

TEST(SerialComm, GatherReturnsTheOwnValueAtTheRoot) {
  struct Sample {
    int rank;
    double value;
  };
  const Comm comm = Comm::serial();
  const auto gathered = comm.gather(Sample{0, 4.5}, 0);
  ASSERT_EQ(gathered.size(), 1u);
  EXPECT_EQ(gathered[0].rank, 0);
  EXPECT_EQ(gathered[0].value, 4.5);
  EXPECT_THROW((void)comm.gather(1.0, 2), InvalidInput);
}

TEST(SerialComm, PointToPointThrowsNoOtherRank) {
  const Comm comm = Comm::serial();
  const std::vector<std::byte> payload(4);
  try {
    comm.send(payload, 0, 1);
    FAIL() << "send did not throw";
  } catch (const InvalidInput& e) {
    EXPECT_STREQ(e.what(), "serial communicator has no other rank");
  }
  EXPECT_THROW((void)comm.recv(0, 1), InvalidInput);
  EXPECT_THROW((void)comm.recv(), InvalidInput);
  EXPECT_THROW((void)comm.probe(), InvalidInput);
  EXPECT_FALSE(comm.iprobe().has_value());
  EXPECT_FALSE(comm.iprobe(0, 3).has_value());
}

TEST(SerialComm, BadRanksAndTagsAreInvalidInput) {
  const Comm comm = Comm::serial();
  const std::vector<std::byte> payload(1);
  EXPECT_THROW(comm.send(payload, 1, 0), InvalidInput);
  EXPECT_THROW(comm.send(payload, 0, -5), InvalidInput);
  EXPECT_THROW((void)comm.probe(3, mpi::kAnyTag), InvalidInput);
  EXPECT_THROW((void)comm.iprobe(mpi::kAnySource, -2), InvalidInput);
}

TEST(SerialComm, SplitGivesAnotherSerialCommunicator) {
  const Comm comm = Comm::serial();
  const Comm sub = comm.split(3, 10);
  EXPECT_EQ(sub.rank(), 0);
  EXPECT_EQ(sub.size(), 1);
  EXPECT_EQ(sub.allreduce(std::int64_t{5}, ReduceOp::kSum), 5);
  EXPECT_THROW((void)comm.split(-1), InvalidInput);
}

TEST(SerialComm, IsAMovableValue) {
  Comm a = Comm::serial();
  Comm b = std::move(a);
  EXPECT_EQ(b.size(), 1);
  a = Comm::serial();
  EXPECT_EQ(a.size(), 1);
  EXPECT_THROW(Comm(nullptr), InvalidInput);
}

}  // namespace

TEST(SerialComm, RunAgreedRethrowsTheOnlyRanksError) {
  const Comm comm = Comm::serial();
  int ran = 0;
  EXPECT_NO_THROW(mpi::run_agreed(comm, [&] { ++ran; }));
  EXPECT_EQ(ran, 1);
  EXPECT_THROW(mpi::run_agreed(comm, [] { throw InvalidInput("cause"); }), InvalidInput);
  EXPECT_THROW(mpi::run_agreed(comm, [] { throw std::runtime_error("cause"); }), std::runtime_error);
}
