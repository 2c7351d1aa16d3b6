#include "mpi/agree.h"

#include <cstdint>
#include <exception>
#include <string>

namespace gimforge::mpi {

void run_agreed(const Comm& comm, const std::function<void()>& local) {
  std::exception_ptr failure;
  try {
    local();
  } catch (...) {
    failure = std::current_exception();
  }
  const auto size = static_cast<std::int64_t>(comm.size());
  const std::int64_t first = comm.allreduce(failure ? static_cast<std::int64_t>(comm.rank()) : size, ReduceOp::kMin);
  if (first == size) return;
  if (first == comm.rank()) std::rethrow_exception(failure);
  throw PeerFailed("rank " + std::to_string(first) + " failed");
}

}  // namespace gimforge::mpi
