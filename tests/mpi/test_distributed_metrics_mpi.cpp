// The fidelity metric over MPI (jobs/distributed_metrics.h) for any number of ranks >= 2 (ctest runs 2 and
// 4): equal bit for bit to one process, rank counts that leave some ranks without a block, and a failure
// on one rank fails every rank without a hang (mpi/agree.h).
// Collectives stay matched on all ranks even when an expectation fails (EXPECT, not ASSERT).
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "jobs/distributed_metrics.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "mpi/agree.h"
#include "mpi/mpi_comm.h"
#include "tests/mpi/expect_metrics.h"

using namespace gimforge;

using gimforge::test::expect_same;

TEST(DistributedMetrics, EqualsOneProcessBitForBit) {
  const mpi::Comm world = mpi::mpi_world();
  const EmbreeDevice device;
  const TriMesh a = make_icosphere(1.0, 4);
  TriMesh b = make_torus(1.0, 0.4, 40, 20);
  for (Vec3& p : b.positions) p *= 1.02;
  // 50,000 samples: 25 blocks of distances for 2 or 4 ranks; 700: one block, so all ranks but one get none.
  for (const std::size_t samples : {50'000u, 700u}) {
    HausdorffOptions o;
    o.samples = samples;
    const HausdorffResult serial = symmetric_hausdorff(device, a, b, o);
    const HausdorffResult dist = jobs::distributed_hausdorff(world, device, a, b, o);
    expect_same(dist, serial);
  }
}

TEST(DistributedMetrics, FailureOnOneRankFailsEveryRank) {
  const mpi::Comm world = mpi::mpi_world();
  const int failing = world.size() - 1;
  bool own = false, peer = false;
  try {
    mpi::run_agreed(world, [&] {
      if (world.rank() == failing) throw InvalidInput("rank-local cause");
    });
  } catch (const mpi::PeerFailed&) {
    peer = true;
  } catch (const InvalidInput& e) {
    own = std::string(e.what()) == "rank-local cause";
  }
  EXPECT_EQ(own, world.rank() == failing);
  EXPECT_EQ(peer, world.rank() != failing);
  // Two ranks fail: only the lowest reports its own error. And a run without failures returns normally.
  own = peer = false;
  try {
    mpi::run_agreed(world, [&] {
      if (world.rank() >= 1) throw std::runtime_error("not a gimforge error");
    });
  } catch (const mpi::PeerFailed&) {
    peer = true;
  } catch (const std::runtime_error&) {
    own = true;
  }
  EXPECT_EQ(own, world.rank() == 1);
  EXPECT_EQ(peer, world.rank() != 1);
  EXPECT_NO_THROW(mpi::run_agreed(world, [] {}));
}
