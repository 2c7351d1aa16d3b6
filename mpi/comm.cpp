/// \file comm.cpp
/// Comm (argument checks, typed wrappers) and the serial implementation. No MPI here: this target builds
/// and links without MPI.
#include "mpi/comm.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <utility>

#include "kernels/core/errors.h"

namespace gimforge::mpi {
namespace {

[[noreturn]] void throw_no_other_rank() { throw InvalidInput("serial communicator has no other rank"); }

/// The one-rank communicator: collectives are copies or no-ops, point-to-point has nobody to talk to.
class SerialCommImpl final : public CommImpl {
 public:
  [[nodiscard]] int rank() const override { return 0; }
  [[nodiscard]] int size() const override { return 1; }
  void barrier() const override {}
  void allreduce(void*, std::size_t, Datatype, ReduceOp) const override {}
  void broadcast(void*, std::size_t, int) const override {}
  void send(const void*, std::size_t, int, int) const override { throw_no_other_rank(); }
  [[nodiscard]] std::unique_ptr<PendingSend> isend(std::vector<std::byte>, int, int) const override {
    throw_no_other_rank();
  }
  void recv(void*, std::size_t, int, int) const override { throw_no_other_rank(); }
  [[nodiscard]] MessageInfo probe(int, int) const override { throw_no_other_rank(); }
  [[nodiscard]] std::optional<MessageInfo> iprobe(int, int) const override { return std::nullopt; }
  void gather(const void* send, std::size_t bytes, void* recv, int) const override {
    if (bytes > 0) std::memcpy(recv, send, bytes);
  }
  [[nodiscard]] std::unique_ptr<CommImpl> split(int, int) const override { return std::make_unique<SerialCommImpl>(); }
};

/// Throws InvalidInput unless `rank` names a rank of a communicator of `size` (or is a permitted wildcard).
void check_rank(int rank, int size, std::string_view what, bool wildcard_ok) {
  if ((wildcard_ok && rank == kAnySource) || (rank >= 0 && rank < size)) return;
  throw InvalidInput(std::string(what) + ": " + std::to_string(rank) + " is not a rank of a communicator of size " +
                     std::to_string(size));
}

void check_tag(int tag, std::string_view what, bool wildcard_ok) {
  if ((wildcard_ok && tag == kAnyTag) || tag >= 0) return;
  throw InvalidInput(std::string(what) + ": tag " + std::to_string(tag) + " is negative");
}

}  // namespace

Comm::Comm(std::unique_ptr<CommImpl> impl) : impl_(std::move(impl)) {
  if (!impl_) throw InvalidInput("Comm: null implementation");
}

void CommImpl::abort(int exit_code) const {
  std::fflush(nullptr);
  std::_Exit(exit_code);
}

void Comm::abort(int exit_code) const {
  impl_->abort(exit_code);
  std::_Exit(exit_code);  // unreachable: every implementation ends the process
}

Comm Comm::serial() { return Comm(std::make_unique<SerialCommImpl>()); }

Comm::Comm(Comm&&) noexcept = default;
Comm& Comm::operator=(Comm&&) noexcept = default;
Comm::~Comm() = default;

void Comm::allreduce_raw(void* data, std::size_t count, Datatype type, ReduceOp op) const {
  impl_->allreduce(data, count, type, op);
}

void Comm::allreduce_bits(std::vector<std::uint8_t>& bytes, ReduceOp op) const {
  if (op != ReduceOp::kBitOr && op != ReduceOp::kBitXor)
    throw InvalidInput("Comm::allreduce_bits: the operation must be kBitOr or kBitXor");
  impl_->allreduce(bytes.data(), bytes.size(), Datatype::kByte, op);
}

void Comm::gather_raw(const void* send, std::size_t bytes, void* recv, int root) const {
  check_rank(root, size(), "Comm::gather root", false);
  impl_->gather(send, bytes, recv, root);
}

template <class Container>
void Comm::broadcast_container(Container& data, int root) const {
  check_rank(root, size(), "Comm::broadcast root", false);
  std::uint64_t count = data.size();
  impl_->broadcast(&count, sizeof count, root);
  data.resize(static_cast<std::size_t>(count));
  impl_->broadcast(data.data(), data.size() * sizeof(typename Container::value_type), root);
}

void Comm::broadcast(std::vector<std::byte>& data, int root) const { broadcast_container(data, root); }
void Comm::broadcast(std::string& text, int root) const { broadcast_container(text, root); }
void Comm::broadcast(std::vector<double>& values, int root) const { broadcast_container(values, root); }

std::unique_ptr<PendingSend> Comm::isend(std::vector<std::byte> data, int dest, int tag) const {
  check_rank(dest, size(), "Comm::isend destination", false);
  check_tag(tag, "Comm::isend", false);
  return impl_->isend(std::move(data), dest, tag);
}

void Comm::send(std::span<const std::byte> data, int dest, int tag) const {
  check_rank(dest, size(), "Comm::send destination", false);
  check_tag(tag, "Comm::send", false);
  impl_->send(data.data(), data.size(), dest, tag);
}

Message Comm::recv(int source, int tag) const {
  const MessageInfo info = probe(source, tag);
  Message msg{info.source, info.tag, std::vector<std::byte>(info.size)};
  impl_->recv(msg.data.data(), msg.data.size(), info.source, info.tag);
  return msg;
}

MessageInfo Comm::probe(int source, int tag) const {
  check_rank(source, size(), "Comm::probe source", true);
  check_tag(tag, "Comm::probe", true);
  return impl_->probe(source, tag);
}

std::optional<MessageInfo> Comm::iprobe(int source, int tag) const {
  check_rank(source, size(), "Comm::iprobe source", true);
  check_tag(tag, "Comm::iprobe", true);
  return impl_->iprobe(source, tag);
}

Comm Comm::split(int color, int key) const {
  if (color < 0) throw InvalidInput("Comm::split: color " + std::to_string(color) + " is negative");
  return Comm(impl_->split(color, key));
}

}  // namespace gimforge::mpi
