#pragma once
/// \file environment.h
/// RAII initialization and finalization of MPI for executables and test mains.

namespace gimforge::mpi {

/// MPI thread support levels, weakest first (MPI_THREAD_SINGLE ... MPI_THREAD_MULTIPLE).
enum class ThreadLevel { kSingle, kFunneled, kSerialized, kMultiple };

/// Initializes MPI with MPI_Init_thread on construction and finalizes it on destruction.
/// - When MPI is already initialized (by a library or an outer environment) it only checks the thread
///   level and leaves finalization to whoever initialized it.
/// - The destructor finalizes only what this object initialized, and not when MPI was finalized already.
/// Create exactly one, first thing in main(); it is neither copyable nor movable.
class MpiEnvironment {
 public:
  /// Initializes MPI with `argc` / `argv` (MPI may remove its own arguments) requesting `required`.
  /// Throws LibraryError when initialization fails or MPI provides a weaker thread level (MPI is then
  /// finalized again if this call initialized it).
  MpiEnvironment(int& argc, char**& argv, ThreadLevel required = ThreadLevel::kFunneled);
  /// Same without command-line arguments.
  explicit MpiEnvironment(ThreadLevel required = ThreadLevel::kFunneled);
  MpiEnvironment(const MpiEnvironment&) = delete;
  MpiEnvironment& operator=(const MpiEnvironment&) = delete;
  /// Finalizes MPI if this object initialized it and it is not finalized yet.
  ~MpiEnvironment();

  /// The thread level MPI provides (>= the required one).
  [[nodiscard]] ThreadLevel provided() const noexcept { return provided_; }
  /// True when this object initialized MPI (and will finalize it).
  [[nodiscard]] bool owns() const noexcept { return owns_; }

 private:
  void init(int* argc, char*** argv, ThreadLevel required);

  ThreadLevel provided_ = ThreadLevel::kSingle;
  bool owns_ = false;
};

/// True when an MPI launcher started this process (Open MPI's mpirun sets OMPI_COMM_WORLD_SIZE, PMIx as
/// `srun --mpi=pmix` starts it PMIX_RANK, PMI-1/2 launchers PMI_SIZE or PMI_RANK): commands that work alone
/// as well (`metrics`) start MPI only then, so a plain run pays nothing for it.
[[nodiscard]] bool launched_by_mpi();

/// False where the launcher says this process is not rank 0 (Open MPI's mpirun, PMIx as srun --mpi=pmix
/// starts it, PMI, Slurm); true otherwise. Known before MPI starts, when no rank is known yet: rank 0 alone
/// reads a batch's shards first, and prints a usage error.
[[nodiscard]] bool may_be_rank_zero();

}  // namespace gimforge::mpi
