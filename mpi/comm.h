#pragma once
/// \file comm.h
/// The communicator value type (after ADIOS2's helper/adiosComm.h): a Comm owns one implementation,
/// either the serial one made by Comm::serial() (this target, no MPI needed) or an MPI one made by
/// mpi/mpi_comm.h. Kernels and most of the pipeline take a `const Comm&` and run unchanged without mpirun.
///
/// Semantics follow MPI: collective operations (barrier, allreduce, broadcast, gather, split) must be
/// called by every rank in the same order; ranks are 0..size()-1. Arguments are validated before any
/// communication (InvalidInput), and a failure reported by MPI becomes LibraryError with MPI's text.
///
/// The serial implementation has size 1: reductions return their input, broadcast and gather copy, split
/// returns another serial communicator, iprobe finds nothing, and send / recv / probe throw InvalidInput
/// "serial communicator has no other rank" (a message to oneself could never be received in order).
#include <chrono>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

namespace gimforge::mpi {

/// Reduction operators; kBitOr and kBitXor for integers and bytes only.
enum class ReduceOp { kSum, kMin, kMax, kBitOr, kBitXor };

/// Element types the implementations transfer.
enum class Datatype { kByte, kInt64, kUInt64, kDouble };

/// Types allreduce accepts (pass std::int64_t{n}, not a plain int).
template <class T>
concept Reducible = std::same_as<T, std::int64_t> || std::same_as<T, std::uint64_t> || std::same_as<T, double>;

/// The Datatype of a Reducible C++ type.
template <Reducible T>
inline constexpr Datatype kDatatypeOf = std::same_as<T, std::int64_t>    ? Datatype::kInt64
                                        : std::same_as<T, std::uint64_t> ? Datatype::kUInt64
                                                                         : Datatype::kDouble;

/// Wildcard source for recv / probe / iprobe (MPI_ANY_SOURCE).
inline constexpr int kAnySource = -1;
/// Wildcard tag for recv / probe / iprobe (MPI_ANY_TAG).
inline constexpr int kAnyTag = -1;

/// Envelope of a pending message: who sent it, with which tag, and how many bytes it holds.
struct MessageInfo {
  int source = 0;
  int tag = 0;
  std::size_t size = 0;
};

/// A received message.
struct Message {
  int source = 0;
  int tag = 0;
  std::vector<std::byte> data;
};

/// A send in flight (Comm::isend): it owns its bytes until the message has left this process.
class PendingSend {
 public:
  PendingSend() = default;
  PendingSend(const PendingSend&) = delete;
  PendingSend& operator=(const PendingSend&) = delete;
  /// An unfinished send is left to MPI (its bytes are then never freed): destroy only finished ones, or
  /// on the way out.
  virtual ~PendingSend() = default;
  /// Whether the send has finished; makes progress. Throws LibraryError when MPI fails.
  [[nodiscard]] virtual bool done() = 0;
};

/// Interface of a communicator implementation (serial in comm.cpp, MPI in mpi_comm.cpp).
/// Comm validates ranks, roots, tags and colors before calling it; buffers are raw bytes or `count`
/// elements of `type`.
class CommImpl {
 public:
  CommImpl() = default;
  CommImpl(const CommImpl&) = delete;
  CommImpl& operator=(const CommImpl&) = delete;
  virtual ~CommImpl() = default;

  /// This process's rank.
  [[nodiscard]] virtual int rank() const = 0;
  /// Number of ranks.
  [[nodiscard]] virtual int size() const = 0;
  /// Blocks until every rank has called it.
  virtual void barrier() const = 0;
  /// A barrier that waits at most `limit` (see Comm::barrier_within). This default waits as long as it takes.
  [[nodiscard]] virtual bool barrier_within(std::chrono::milliseconds /*limit*/) const {
    barrier();
    return true;
  }
  /// Reduces `count` elements of `type` in place over all ranks.
  virtual void allreduce(void* data, std::size_t count, Datatype type, ReduceOp op) const = 0;
  /// Copies `bytes` bytes from `root`'s buffer into every other rank's buffer.
  virtual void broadcast(void* data, std::size_t bytes, int root) const = 0;
  /// Sends `bytes` bytes to rank `dest` with `tag` (blocking).
  virtual void send(const void* data, std::size_t bytes, int dest, int tag) const = 0;
  /// Starts sending `data` to rank `dest` with `tag` without waiting for it to leave.
  [[nodiscard]] virtual std::unique_ptr<PendingSend> isend(std::vector<std::byte> data, int dest, int tag) const = 0;
  /// Receives exactly `bytes` bytes from `source` with `tag` (concrete values from a probe).
  virtual void recv(void* data, std::size_t bytes, int source, int tag) const = 0;
  /// Waits for a message matching `source` / `tag` (wildcards allowed) and returns its envelope.
  [[nodiscard]] virtual MessageInfo probe(int source, int tag) const = 0;
  /// Like probe, but returns std::nullopt at once when no matching message is pending.
  [[nodiscard]] virtual std::optional<MessageInfo> iprobe(int source, int tag) const = 0;
  /// Gathers `bytes` bytes from every rank into `recv` on `root` (size() * bytes, in rank order).
  virtual void gather(const void* send, std::size_t bytes, void* recv, int root) const = 0;
  /// Splits into sub-communicators of equal `color` (>= 0), ranked by (`key`, old rank).
  [[nodiscard]] virtual std::unique_ptr<CommImpl> split(int color, int key) const = 0;
  /// Ends every process of the job with `exit_code`, stdout and stderr flushed. This default (one
  /// process) ends this process; the MPI one calls MPI_Abort.
  [[noreturn]] virtual void abort(int exit_code) const;
};

/// A communicator: a move-only value owning its implementation. All operations are const (they do not
/// change which group of processes the Comm names). A moved-from Comm may only be assigned or destroyed.
class Comm {
 public:
  /// Wraps an implementation. Throws InvalidInput when `impl` is null.
  explicit Comm(std::unique_ptr<CommImpl> impl);
  /// The serial communicator: one rank, no MPI.
  [[nodiscard]] static Comm serial();

  Comm(Comm&&) noexcept;
  Comm& operator=(Comm&&) noexcept;
  ~Comm();

  /// This process's rank, 0..size()-1.
  [[nodiscard]] int rank() const { return impl_->rank(); }
  /// Number of ranks (>= 1).
  [[nodiscard]] int size() const { return impl_->size(); }
  /// Blocks until every rank has called it. Collective.
  void barrier() const { impl_->barrier(); }
  /// A barrier (MPI_Ibarrier; every rank must call this, not barrier()) that gives up after `limit`: false
  /// when some rank has not arrived by then. The barrier then stays pending, so nothing collective may follow
  /// on this communicator: the caller ends the job (abort). Collective.
  [[nodiscard]] bool barrier_within(std::chrono::milliseconds limit) const { return impl_->barrier_within(limit); }

  /// Reduces one value over all ranks; every rank gets the result. Collective.
  template <Reducible T>
  [[nodiscard]] T allreduce(T value, ReduceOp op) const {
    allreduce_raw(&value, 1, kDatatypeOf<T>, op);
    return value;
  }
  /// Reduces element-wise over all ranks (every rank passes the same length); returns the result.
  /// Collective.
  template <Reducible T>
  [[nodiscard]] std::vector<T> allreduce(std::vector<T> values, ReduceOp op) const {
    allreduce_raw(values.data(), values.size(), kDatatypeOf<T>, op);
    return values;
  }

  /// Element-wise bitwise reduction of bytes in place (op kBitOr or kBitXor), e.g. bit sets every rank fills.
  void allreduce_bits(std::vector<std::uint8_t>& bytes, ReduceOp op) const;
  /// Replaces `data` on every rank with `root`'s (other ranks' sizes do not matter). Collective.
  /// Throws InvalidInput when `root` is not a rank.
  void broadcast(std::vector<std::byte>& data, int root) const;
  /// Replaces `text` on every rank with `root`'s. Collective.
  void broadcast(std::string& text, int root) const;
  /// Replaces `values` on every rank with `root`'s. Collective.
  void broadcast(std::vector<double>& values, int root) const;

  /// Sends `data` to rank `dest` with `tag` (>= 0); blocks until the buffer may be reused.
  /// Throws InvalidInput for a bad rank or tag, and on the serial communicator.
  void send(std::span<const std::byte> data, int dest, int tag) const;
  /// Starts sending `data` to `dest` with `tag` and returns at once: a blocking send of even a few bytes
  /// may wait until the receiver next calls MPI (Open MPI's shared-memory transport completes a send
  /// when the receiver has taken it), which a rank that must stay responsive cannot afford. Poll done()
  /// until true. Throws as send.
  [[nodiscard]] std::unique_ptr<PendingSend> isend(std::vector<std::byte> data, int dest, int tag) const;
  /// Receives the next message matching `source` / `tag` (wildcards kAnySource / kAnyTag), whatever
  /// its size. Throws InvalidInput for a bad rank or tag, and on the serial communicator.
  [[nodiscard]] Message recv(int source = kAnySource, int tag = kAnyTag) const;
  /// Waits for a matching message and returns its envelope without receiving it.
  /// Throws InvalidInput for a bad rank or tag, and on the serial communicator (it would wait forever).
  [[nodiscard]] MessageInfo probe(int source = kAnySource, int tag = kAnyTag) const;
  /// Returns the envelope of a pending matching message, or std::nullopt (always on the serial one).
  [[nodiscard]] std::optional<MessageInfo> iprobe(int source = kAnySource, int tag = kAnyTag) const;

  /// Gathers one trivially copyable value per rank at `root`: there a vector of size() values in rank
  /// order, elsewhere an empty vector. Collective. Throws InvalidInput when `root` is not a rank.
  template <class T>
  requires std::is_trivially_copyable_v<T>
  [[nodiscard]] std::vector<T> gather(const T& value, int root) const {
    std::vector<T> out(rank() == root ? static_cast<std::size_t>(size()) : 0);
    gather_raw(&value, sizeof(T), out.data(), root);
    return out;
  }

  /// Splits into disjoint communicators, one per `color` (>= 0, else InvalidInput); ranks in each are
  /// ordered by `key`, ties by old rank. Collective.
  [[nodiscard]] Comm split(int color, int key = 0) const;

  /// Ends every process of the job with `exit_code` after flushing stdout and stderr (MPI_Abort; the
  /// serial communicator ends this process). For a rank that cannot finalize because a rank it gave up
  /// on will never take part again (mpi/scheduler.h, lost workers); the launcher prints its own notice.
  [[noreturn]] void abort(int exit_code) const;

  /// The implementation (for implementation-specific access such as mpi::native in mpi_comm.h).
  [[nodiscard]] const CommImpl& impl() const noexcept { return *impl_; }

 private:
  void allreduce_raw(void* data, std::size_t count, Datatype type, ReduceOp op) const;
  void gather_raw(const void* send, std::size_t bytes, void* recv, int root) const;
  template <class Container>
  void broadcast_container(Container& data, int root) const;

  std::unique_ptr<CommImpl> impl_;
};

}  // namespace gimforge::mpi
