/// \file mpi_comm.cpp
/// The MPI communicator implementation (see mpi_comm.h): every MPI call goes through check_mpi().
#include "mpi/mpi_comm.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <thread>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "kernels/core/errors.h"

namespace gimforge::mpi {
namespace {

/// MPI counts are int: throws InvalidInput for larger buffers.
int to_count(std::size_t n, std::string_view what) {
  if (n > static_cast<std::size_t>(INT_MAX))
    throw InvalidInput(fmt::format("MPI {}: {} elements exceed the MPI count limit", what, n));
  return static_cast<int>(n);
}

MPI_Datatype mpi_type(Datatype type) {
  switch (type) {
    case Datatype::kByte: return MPI_BYTE;
    case Datatype::kInt64: return MPI_INT64_T;
    case Datatype::kUInt64: return MPI_UINT64_T;
    case Datatype::kDouble: return MPI_DOUBLE;
  }
  return MPI_DATATYPE_NULL;
}

MPI_Op mpi_op(ReduceOp op) {
  switch (op) {
    case ReduceOp::kSum: return MPI_SUM;
    case ReduceOp::kMin: return MPI_MIN;
    case ReduceOp::kMax: return MPI_MAX;
    case ReduceOp::kBitOr: return MPI_BOR;
    case ReduceOp::kBitXor: return MPI_BXOR;
  }
  return MPI_OP_NULL;
}

int mpi_source(int source) { return source == kAnySource ? MPI_ANY_SOURCE : source; }
int mpi_tag(int tag) { return tag == kAnyTag ? MPI_ANY_TAG : tag; }

MessageInfo envelope(const MPI_Status& status) {
  int count = 0;
  check_mpi(MPI_Get_count(&status, MPI_BYTE, &count), "Get_count");
  return {status.MPI_SOURCE, status.MPI_TAG, static_cast<std::size_t>(count)};
}

/// Owns one MPI communicator (a duplicate or a split result) with MPI_ERRORS_RETURN set.
/// An MPI_Isend and the bytes it sends.
class MpiPendingSend final : public PendingSend {
 public:
  MpiPendingSend(std::vector<std::byte> data, int dest, int tag, MPI_Comm comm) : data_(std::move(data)) {
    check_mpi(MPI_Isend(data_.data(), to_count(data_.size(), "Isend"), MPI_BYTE, dest, tag, comm, &request_), "Isend");
  }
  ~MpiPendingSend() override {
    if (request_ == MPI_REQUEST_NULL) return;
    int finalized = 0;
    MPI_Finalized(&finalized);
    if (finalized != 0) return;
    // Unfinished: MPI completes it on its own, and its bytes must outlive it.
    MPI_Request_free(&request_);
    new std::vector<std::byte>(std::move(data_));  // NOLINT: deliberately never freed
  }
  bool done() override {
    if (request_ == MPI_REQUEST_NULL) return true;
    int flag = 0;
    check_mpi(MPI_Test(&request_, &flag, MPI_STATUS_IGNORE), "Test");
    return flag != 0;
  }

 private:
  std::vector<std::byte> data_;
  MPI_Request request_ = MPI_REQUEST_NULL;
};

class MpiCommImpl final : public CommImpl {
 public:
  /// Takes ownership of `comm` and makes its errors return codes.
  explicit MpiCommImpl(MPI_Comm comm) : comm_(comm) {
    check_mpi(MPI_Comm_set_errhandler(comm_, MPI_ERRORS_RETURN), "Comm_set_errhandler");
    check_mpi(MPI_Comm_rank(comm_, &rank_), "Comm_rank");
    check_mpi(MPI_Comm_size(comm_, &size_), "Comm_size");
  }
  ~MpiCommImpl() override {
    int finalized = 0;
    MPI_Finalized(&finalized);
    if (finalized == 0) MPI_Comm_free(&comm_);
  }

  [[nodiscard]] MPI_Comm native() const noexcept { return comm_; }

  [[nodiscard]] int rank() const override { return rank_; }
  [[nodiscard]] int size() const override { return size_; }
  void barrier() const override { check_mpi(MPI_Barrier(comm_), "Barrier"); }

  [[nodiscard]] bool barrier_within(std::chrono::milliseconds limit) const override {
    MPI_Request request = MPI_REQUEST_NULL;
    check_mpi(MPI_Ibarrier(comm_, &request), "Ibarrier");
    const auto end = limit >= std::chrono::hours(24 * 365 * 100) ? std::chrono::steady_clock::time_point::max()
                                                                  : std::chrono::steady_clock::now() + limit;
    for (auto pause = std::chrono::microseconds(50);; pause = std::min(2 * pause, std::chrono::microseconds(20000))) {
      int done = 0;
      check_mpi(MPI_Test(&request, &done, MPI_STATUS_IGNORE), "Test");
      if (done != 0) return true;
      if (std::chrono::steady_clock::now() >= end) return false;  // left pending: only an abort follows
      std::this_thread::sleep_for(pause);
    }
  }

  void allreduce(void* data, std::size_t count, Datatype type, ReduceOp op) const override {
    check_mpi(MPI_Allreduce(MPI_IN_PLACE, data, to_count(count, "Allreduce"), mpi_type(type), mpi_op(op), comm_),
              "Allreduce");
  }
  void broadcast(void* data, std::size_t bytes, int root) const override {
    check_mpi(MPI_Bcast(data, to_count(bytes, "Bcast"), MPI_BYTE, root, comm_), "Bcast");
  }
  void send(const void* data, std::size_t bytes, int dest, int tag) const override {
    check_mpi(MPI_Send(data, to_count(bytes, "Send"), MPI_BYTE, dest, tag, comm_), "Send");
  }
  [[nodiscard]] std::unique_ptr<PendingSend> isend(std::vector<std::byte> data, int dest, int tag) const override {
    return std::make_unique<MpiPendingSend>(std::move(data), dest, tag, comm_);
  }
  void recv(void* data, std::size_t bytes, int source, int tag) const override {
    check_mpi(MPI_Recv(data, to_count(bytes, "Recv"), MPI_BYTE, source, tag, comm_, MPI_STATUS_IGNORE), "Recv");
  }
  [[nodiscard]] MessageInfo probe(int source, int tag) const override {
    MPI_Status status;
    check_mpi(MPI_Probe(mpi_source(source), mpi_tag(tag), comm_, &status), "Probe");
    return envelope(status);
  }
  [[nodiscard]] std::optional<MessageInfo> iprobe(int source, int tag) const override {
    MPI_Status status;
    int found = 0;
    check_mpi(MPI_Iprobe(mpi_source(source), mpi_tag(tag), comm_, &found, &status), "Iprobe");
    if (found == 0) return std::nullopt;
    return envelope(status);
  }
  void gather(const void* send, std::size_t bytes, void* recv, int root) const override {
    const int count = to_count(bytes, "Gather");
    check_mpi(MPI_Gather(send, count, MPI_BYTE, recv, count, MPI_BYTE, root, comm_), "Gather");
  }
  [[noreturn]] void abort(int exit_code) const override {
    std::fflush(nullptr);
    MPI_Abort(comm_, exit_code);
    std::_Exit(exit_code);  // MPI_Abort does not return; should it, end this process at least
  }

  [[nodiscard]] std::unique_ptr<CommImpl> split(int color, int key) const override {
    MPI_Comm sub = MPI_COMM_NULL;
    check_mpi(MPI_Comm_split(comm_, color, key, &sub), "Comm_split");
    return owning(sub);
  }

  /// Wraps a new communicator, freeing it if the wrapper cannot be built.
  static std::unique_ptr<CommImpl> owning(MPI_Comm comm) {
    try {
      return std::make_unique<MpiCommImpl>(comm);
    } catch (...) {
      MPI_Comm_free(&comm);
      throw;
    }
  }

 private:
  MPI_Comm comm_;
  int rank_ = 0;
  int size_ = 0;
};

}  // namespace

void check_mpi(int rc, std::string_view what) {
  if (rc == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING] = {};
  int len = 0;
  if (MPI_Error_string(rc, text, &len) != MPI_SUCCESS || len <= 0)
    throw LibraryError(fmt::format("MPI {} failed: error code {}", what, rc));
  throw LibraryError(fmt::format("MPI {} failed: {}", what, std::string(text, static_cast<std::size_t>(len))));
}

Comm from_mpi(MPI_Comm comm) {
  if (comm == MPI_COMM_NULL) throw InvalidInput("mpi::from_mpi: MPI_COMM_NULL is not a communicator");
  int initialized = 0, finalized = 0;
  check_mpi(MPI_Initialized(&initialized), "Initialized");
  check_mpi(MPI_Finalized(&finalized), "Finalized");
  if (initialized == 0 || finalized != 0)
    throw LibraryError("mpi::from_mpi: MPI is not initialized (create a mpi::MpiEnvironment first)");
  MPI_Comm dup = MPI_COMM_NULL;
  check_mpi(MPI_Comm_dup(comm, &dup), "Comm_dup");
  return Comm(MpiCommImpl::owning(dup));
}

Comm mpi_world() { return from_mpi(MPI_COMM_WORLD); }

bool is_mpi(const Comm& comm) noexcept { return dynamic_cast<const MpiCommImpl*>(&comm.impl()) != nullptr; }

MPI_Comm native(const Comm& comm) {
  const auto* impl = dynamic_cast<const MpiCommImpl*>(&comm.impl());
  if (impl == nullptr) throw InvalidInput("mpi::native: the communicator is not MPI-backed (serial)");
  return impl->native();
}

}  // namespace gimforge::mpi
