#pragma once
/// \file progress.h
/// A progress line on stderr for long work, drawn only when stderr is a terminal.
#include <chrono>
#include <mutex>
#include <string>

#include "kernels/core/progress.h"

namespace gimforge::jobs {

/// Draws "label: stage 42%" in place on stderr (rate-limited to 10 updates per second) and clears it on
/// finish. When stderr is not a terminal, or `enabled` is false, it prints nothing. Thread-safe.
class TerminalProgress {
 public:
  TerminalProgress(std::string label, bool enabled);
  ~TerminalProgress();
  TerminalProgress(const TerminalProgress&) = delete;
  TerminalProgress& operator=(const TerminalProgress&) = delete;

  /// A callback for kernels; never cancels.
  [[nodiscard]] ProgressCallback callback();
  /// Erases the progress line.
  void finish();

 private:
  void update(std::string_view stage, double fraction);

  std::string label_;
  bool enabled_;
  bool drawn_{false};
  std::mutex mutex_;
  std::chrono::steady_clock::time_point last_{};
};

}  // namespace gimforge::jobs
