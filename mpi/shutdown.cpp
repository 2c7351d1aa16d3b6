/// \file shutdown.cpp
/// ShutdownSignals (see shutdown.h).
#include "mpi/shutdown.h"

#include <fmt/format.h>

#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstring>

#include "kernels/core/errors.h"

namespace {

static_assert(std::atomic<bool>::is_always_lock_free, "the signal flag must be lock-free to be set in a handler");
static_assert(std::atomic<int>::is_always_lock_free, "the signal number must be lock-free to be set in a handler");

/// Set by the handler (and request_shutdown_for_testing); read by ShutdownSignals.
std::atomic<bool> g_requested{false};
std::atomic<int> g_signal{0};
/// Whether a ShutdownSignals is alive (one at a time).
std::atomic<bool> g_alive{false};

constexpr std::array<int, 3> kSignals{SIGTERM, SIGUSR1, SIGINT};

void restore(const std::array<struct sigaction, kSignals.size()>& previous, std::size_t count) noexcept {
  for (std::size_t i = 0; i < count; ++i) sigaction(kSignals[i], &previous[i], nullptr);
}

}  // namespace

/// The handler: two stores to lock-free atomics, nothing else (async-signal-safe).
extern "C" {
static void gimforge_shutdown_signal_handler(int sig) {
  g_signal.store(sig);
  g_requested.store(true);
}
}

namespace gimforge::mpi {

ShutdownSignals::ShutdownSignals() {
  if (g_alive.exchange(true)) throw InvalidInput("ShutdownSignals: another instance is already installed");
  g_signal.store(0);
  g_requested.store(false);
  for (std::size_t i = 0; i < kSignals.size(); ++i) {
    struct sigaction action {};
    action.sa_handler = &gimforge_shutdown_signal_handler;
    sigemptyset(&action.sa_mask);
    // SA_RESETHAND is 0x80000000 in glibc: build the flags unsigned, store them as the int field.
    const unsigned flags = SA_RESTART | (kSignals[i] == SIGINT ? unsigned{SA_RESETHAND} : 0U);
    action.sa_flags = static_cast<int>(flags);
    if (sigaction(kSignals[i], &action, &previous_[i]) != 0) {
      const int error = errno;
      restore(previous_, i);
      g_alive.store(false);
      throw LibraryError(
          fmt::format("ShutdownSignals: sigaction({}) failed: {}", strsignal(kSignals[i]), std::strerror(error)));
    }
  }
}

ShutdownSignals::~ShutdownSignals() {
  restore(previous_, kSignals.size());
  g_alive.store(false);
}

bool ShutdownSignals::requested() const noexcept { return g_requested.load(); }

int ShutdownSignals::signal() const noexcept { return g_signal.load(); }

void ShutdownSignals::request_shutdown_for_testing() noexcept {
  g_signal.store(SIGTERM);
  g_requested.store(true);
}

}  // namespace gimforge::mpi
