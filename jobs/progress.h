#pragma once
/// \file progress.h
/// Progress of long work on stderr: a line drawn in place on a terminal, otherwise (a log file, a Slurm job)
/// a log line now and then.
#include <chrono>
#include <mutex>
#include <string>

#include "kernels/core/progress.h"

namespace gimforge::jobs {

/// Draws "label: stage 42%" in place on stderr (rate-limited to 10 updates per second) and clears it on
/// finish. When stderr is not a terminal it logs "label: stage 42% after N s" (info level) once the work has
/// run `first_line` and then at most every `every`, so a long conversion in a log is not silent; quick work
/// prints nothing. With `enabled` false it prints nothing at all. Thread-safe.
class TerminalProgress {
 public:
  TerminalProgress(std::string label, bool enabled, std::chrono::milliseconds first_line = std::chrono::seconds(10),
                   std::chrono::milliseconds every = std::chrono::seconds(30));
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
  bool terminal_;
  std::chrono::milliseconds first_line_;
  std::chrono::milliseconds every_;
  bool drawn_{false};
  std::mutex mutex_;
  std::chrono::steady_clock::time_point start_{std::chrono::steady_clock::now()};
  std::chrono::steady_clock::time_point last_{};
  bool logged_{false};
};

}  // namespace gimforge::jobs
