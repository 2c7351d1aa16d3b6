#pragma once
/// \file shutdown.h
/// Graceful-shutdown signals for batch runs (issue #5): SIGTERM, SIGUSR1 and SIGINT only raise a flag;
/// the master polls it (SchedulerOptions::stop_requested = [&] { return signals.requested(); }),
/// stops dispatching, lets the items in flight finish up to the drain deadline, and the caller commits,
/// flushes its journal and exits "resumable" (exit code 4).
///
/// How the signal reaches the ranks:
/// - Slurm (srun / sbatch): at the time limit Slurm sends SIGTERM to every task, then SIGKILL after
///   KillWait; `sbatch --signal=USR1@300` (or `scancel --signal=USR1`) sends SIGUSR1 ahead of time.
///   Either reaches every rank.
/// - Open MPI's mpirun forwards SIGUSR1 (and SIGUSR2) to every rank, but answers SIGTERM and SIGINT by
///   killing the whole job itself (SIGTERM, then SIGKILL a few seconds later). Under mpirun, ask for a
///   graceful stop with `kill -USR1 <mpirun pid>`.
/// - A single process (no mpirun) honours all three directly.
/// Every rank installs the handlers (so a signal does not kill a worker mid-item), but only rank 0's flag
/// drives scheduling: workers finish the items they hold and return when the master tells them to.
#include <signal.h>

#include <array>

namespace gimforge::mpi {

/// RAII installation of the shutdown handlers for SIGTERM, SIGUSR1 and SIGINT. The handler is
/// async-signal-safe: it only stores to two static lock-free atomics (the signal number, then the
/// flag). SIGINT is installed with SA_RESETHAND, so a second Ctrl-C ends the process at once; all three
/// use SA_RESTART, so system calls in flight (file writes, MPI) resume instead of failing with EINTR.
/// At most one instance may be alive at a time.
class ShutdownSignals {
 public:
  /// Clears the flag and installs the handlers, remembering the previous ones.
  /// Throws InvalidInput when another ShutdownSignals is alive, LibraryError when sigaction fails (the
  /// handlers already installed are restored first).
  ShutdownSignals();
  ShutdownSignals(const ShutdownSignals&) = delete;
  ShutdownSignals& operator=(const ShutdownSignals&) = delete;
  /// Restores the previous handlers. The flag keeps its value.
  ~ShutdownSignals();

  /// True once one of the signals arrived (or request_shutdown_for_testing was called).
  [[nodiscard]] bool requested() const noexcept;
  /// The signal that arrived last (SIGTERM, SIGUSR1 or SIGINT), 0 while none has.
  [[nodiscard]] int signal() const noexcept;
  /// Sets the flag as if SIGTERM had arrived (for tests and for callers that stop for other reasons).
  void request_shutdown_for_testing() noexcept;

 private:
  /// The handlers in place before construction, for SIGTERM, SIGUSR1 and SIGINT in that order.
  std::array<struct sigaction, 3> previous_{};
};

}  // namespace gimforge::mpi
