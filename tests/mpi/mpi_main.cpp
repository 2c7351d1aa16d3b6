// GoogleTest main for the MPI tests (run with mpiexec -n N): MPI is initialized and finalized by
// mpi::MpiEnvironment; rank 0 prints the usual report, other ranks print only their failures, prefixed
// "[rank N]"; the result is reduced with MPI_MAX, so a failure on any rank makes every rank (and so
// mpiexec) exit non-zero.
//
// Tests must keep collectives matched on all ranks: use EXPECT_* (not ASSERT_*) before a collective call,
// or a failing rank would leave the others waiting (ctest's TIMEOUT then ends the run).
#include <gtest/gtest.h>
#include <mpi.h>

#include <cstdio>
#include <sstream>
#include <string>

#include "mpi/environment.h"

namespace {

/// Prints failed assertions and failed tests of a non-zero rank, every line prefixed "[rank N]".
class RankFailurePrinter : public ::testing::EmptyTestEventListener {
 public:
  explicit RankFailurePrinter(int rank) : prefix_("[rank " + std::to_string(rank) + "] ") {}

  void OnTestPartResult(const ::testing::TestPartResult& result) override {
    if (!result.failed()) return;
    std::ostringstream text;
    text << (result.file_name() != nullptr ? result.file_name() : "unknown file") << ":" << result.line_number()
         << ": Failure\n"
         << result.message();
    print(text.str());
  }
  void OnTestEnd(const ::testing::TestInfo& info) override {
    if (info.result()->Failed()) print(std::string("FAILED ") + info.test_suite_name() + "." + info.name());
  }

 private:
  void print(const std::string& text) const {
    std::istringstream lines(text);
    std::string out;
    for (std::string line; std::getline(lines, line);) out += prefix_ + line + "\n";
    std::fputs(out.c_str(), stderr);
    std::fflush(stderr);
  }

  std::string prefix_;
};

}  // namespace

int main(int argc, char** argv) {
  gimforge::mpi::MpiEnvironment mpi_env(argc, argv);
  ::testing::InitGoogleTest(&argc, argv);
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  if (rank != 0) {
    auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
    delete listeners.Release(listeners.default_result_printer());
    listeners.Append(new RankFailurePrinter(rank));
  }
  const int local = RUN_ALL_TESTS();
  int global = local;
  if (MPI_Allreduce(&local, &global, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD) != MPI_SUCCESS) global = 1;
  if (rank == 0 && global != local) std::fputs("[rank 0] tests failed on other ranks (see [rank N] lines)\n", stderr);
  return global;
}
