#pragma once
// Spawns a program and captures its exit code, stdout and stderr (for end-to-end CLI tests).
#include <filesystem>
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

/// True when the long trials run (`scripts/test.sh --full` sets GIMFORGE_FULL_TESTS=1).
[[nodiscard]] bool full_tests();
/// How many repetitions a randomized trial makes: `quick` in the default suite (enough to prove the
/// property: each trial checks it completely), `full` under scripts/test.sh --full.
[[nodiscard]] int trials(int quick, int full);

/// Runs build/gimforge with the given arguments.
ProcessResult run_gimforge(const std::vector<std::string>& args, double timeout_seconds = 120.0);

/// Runs build/gimforge after the shell commands `setup` (limits, environment: "ulimit -f 32; X=1"), through
/// /bin/sh, which then execs it.
ProcessResult run_gimforge_after(const std::string& setup, const std::vector<std::string>& args,
                                 double timeout_seconds = 120.0);

/// A fresh directory under the system temporary directory (mkdtemp, named `<prefix>-XXXXXX`), removed
/// with its contents on destruction.
class TempDir {
 public:
  explicit TempDir(const std::string& prefix = "gimforge-test");
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  /// Path of `name` inside the directory.
  [[nodiscard]] std::string file(const std::string& name) const { return (path_ / name).string(); }
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace gimforge::test
