#include "jobs/cli/crash_guard.h"

#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>

#include <cstdlib>
#include <string_view>

#include <fmt/format.h>

#include "io/gim_archive.h"
#include "io/hdf5.h"
#include "io/printable.h"
#include "io/relief_archive.h"
#include "io/sphere_archive.h"
#include "jobs/archive_listing.h"
#include "jobs/cli/exit_codes.h"
#include "kernels/core/errors.h"

namespace gimforge::cli {
namespace {

/// Seconds one HDF5 metadata call may take in a guarded child (h5::set_call_deadline): 30, or
/// GIMFORGE_HDF5_CALL_SECONDS (1..3600; tests shorten it).
unsigned call_seconds() {
  const char* env = std::getenv("GIMFORGE_HDF5_CALL_SECONDS");
  if (env != nullptr) {
    char* end = nullptr;
    const unsigned long v = std::strtoul(env, &end, 10);
    if (end != env && *end == '\0' && v >= 1 && v <= 3600) return static_cast<unsigned>(v);
  }
  return 30;
}

/// What a guarded child runs first: a hostile archive can make HDF5 loop, and the child must not hang.
void enter_child() { h5::set_call_deadline(call_seconds()); }

std::string crash_message(const std::string& archive, int sig) {
  if (sig == SIGALRM)
    return fmt::format("{}: the HDF5 library did not return within {} s reading the archive: it is damaged or crafted",
                       io::printable(archive), call_seconds());
  const char* name = sigabbrev_np(sig);
  return fmt::format("{}: the HDF5 library crashed reading the archive (signal {}, {}): it is damaged or crafted",
                     io::printable(archive), sig, name != nullptr ? name : "?");
}

/// What probe_archive's child does: every read the commands make of an archive.
void read_everything(const std::string& path) {
  const io::Archive archive = io::Archive::open(path);
  for (const jobs::ListedItem& item : jobs::list_archive(archive).items) {
    if (!item.problem.empty()) throw FormatError(item.problem);
    if (item.group == "gim") (void)io::read_geometry_image(archive, item.name);
    if (item.group == "spherical") (void)io::read_spherical_image(archive, item.name);
    if (item.group == "relief") (void)io::read_relief_map(archive, item.name);
  }
}

}  // namespace

void probe_archive(const std::string& archive) {
  int fds[2];
  if (pipe(fds) != 0) return read_everything(archive);
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t child = fork();
  if (child < 0) {
    close(fds[0]);
    close(fds[1]);
    return read_everything(archive);
  }
  if (child == 0) {
    close(fds[0]);
    enter_child();
    std::string message;
    try {
      read_everything(archive);
    } catch (const std::exception& e) {
      message = e.what();
    }
    if (!message.empty()) {
      [[maybe_unused]] const ssize_t n = write(fds[1], message.data(), message.size());
    }
    close(fds[1]);
    _exit(message.empty() ? 0 : 1);
  }
  close(fds[1]);
  std::string message;
  char buffer[4096];
  for (ssize_t n; (n = read(fds[0], buffer, sizeof buffer)) != 0;) {
    if (n < 0) {
      if (errno == EINTR) continue;
      break;
    }
    if (message.size() < 65536) message.append(buffer, static_cast<std::size_t>(n));
  }
  close(fds[0]);
  int status = 0;
  while (waitpid(child, &status, 0) < 0)
    if (errno != EINTR) return;
  if (WIFSIGNALED(status)) throw FormatError(crash_message(archive, WTERMSIG(status)));
  if (WIFEXITED(status) && WEXITSTATUS(status) != 0)
    throw FormatError(message.empty() ? io::printable(archive) + ": cannot be read" : message);
}

int run_guarded(const std::string& archive, const std::function<int()>& work) {
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t child = fork();
  if (child < 0) return work();  // no process to spare: run unguarded rather than not at all
  if (child == 0) {
    enter_child();
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
    fmt::print(stderr, "gimforge: error: {}\n", crash_message(archive, sig));
  }
  return kExitError;
}

}  // namespace gimforge::cli
