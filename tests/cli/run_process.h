#pragma once
// Spawns a program and captures its exit code, stdout and stderr (for end-to-end CLI tests).
#include <string>
#include <vector>

namespace gimforge::test {

struct ProcessResult {
  int exit_code{-1};      ///< exit status, or 128+signal if killed by a signal
  std::string out;
  std::string err;
  /// Non-empty lines of stderr.
  [[nodiscard]] std::vector<std::string> err_lines() const;
};

/// Runs `argv[0]` with the arguments (no shell), stdin from /dev/null, in a process group of its own, with
/// a wall-clock limit after which the child, its process group and all its descendants are killed with
/// SIGKILL (exit_code then 128+SIGKILL): everything it started dies at once, e.g. mpirun and its ranks.
ProcessResult run_process(const std::vector<std::string>& argv, double timeout_seconds = 120.0);

/// Runs build/gimforge with the given arguments.
ProcessResult run_gimforge(const std::vector<std::string>& args, double timeout_seconds = 120.0);

}  // namespace gimforge::test
