#include "jobs/cli/crash_guard.h"

#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>

#include <fmt/format.h>

#include "io/printable.h"
#include "jobs/cli/exit_codes.h"

namespace gimforge::cli {

int run_guarded(const std::string& archive, const std::function<int()>& work) {
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t child = fork();
  if (child < 0) return work();  // no process to spare: run unguarded rather than not at all
  if (child == 0) {
    int code = kExitError;
    try {
      code = work();  // the command's whole body: it reports its own errors
    } catch (...) {
      std::fputs("gimforge: error: internal error: an exception escaped the command\n", stderr);
    }
    std::fflush(stdout);
    std::fflush(stderr);
    _exit(code);
  }
  // The terminal's Ctrl-C reaches both processes; the parent waits for the child to finish or die.
  int status = 0;
  while (waitpid(child, &status, 0) < 0) {
    if (errno != EINTR) return kExitError;
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) {
    const int sig = WTERMSIG(status);
    if (sig == SIGINT || sig == SIGTERM || sig == SIGKILL || sig == SIGHUP) return 128 + sig;  // stopped, not broken
    fmt::print(stderr, "gimforge: error: {}: the HDF5 library crashed reading the archive (signal {}, {}): it is "
                       "damaged or crafted\n",
               io::printable(archive), sig, sigabbrev_np(sig) != nullptr ? sigabbrev_np(sig) : "?");
  }
  return kExitError;
}

}  // namespace gimforge::cli
