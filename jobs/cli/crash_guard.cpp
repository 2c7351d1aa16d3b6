#include "jobs/cli/crash_guard.h"

#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <csignal>
#include <cstdio>
#include <cstring>

#include <cstdlib>
#include <memory>
#include <new>
#include <string_view>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>

#include "io/atomic_file.h"
#include "io/batch_shard.h"
#include "io/gim_archive.h"
#include "io/hdf5.h"
#include "io/printable.h"
#include "io/relief_archive.h"
#include "io/sphere_archive.h"
#include "jobs/archive_listing.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/logging.h"
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

/// Writes all of `text` to `fd` (retrying short writes and EINTR); false when the descriptor fails.
bool write_all(int fd, std::string_view text) {
  for (std::size_t at = 0; at < text.size();) {
    const ssize_t n = write(fd, text.data() + at, text.size() - at);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    at += static_cast<std::size_t>(n);
  }
  return true;
}

/// Everything a child writes to the pipe `fd` until it closes it (at most `limit` bytes kept); closes `fd`.
std::string read_all(int fd, std::size_t limit) {
  std::string text;
  char buffer[4096];
  for (ssize_t n; (n = read(fd, buffer, sizeof buffer)) != 0;) {
    if (n < 0) {
      if (errno == EINTR) continue;
      break;
    }
    if (text.size() < limit) text.append(buffer, static_cast<std::size_t>(n));
  }
  close(fd);
  return text;
}

/// A child process with a pipe to its parent: returns its pid (0 in the child, where `fd` is the pipe's
/// write end; in the parent `fd` is its read end), or -1 when none can be made (nothing left open).
pid_t fork_with_pipe(int& fd) {
  int fds[2];
  if (pipe(fds) != 0) return -1;
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t parent = getpid();
  const pid_t child = fork();
  if (child < 0) {
    close(fds[0]);
    close(fds[1]);
    return -1;
  }
  if (child == 0) {  // dies with the parent, even one killed with SIGKILL; or already dead before this line
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() != parent) _exit(kExitError);
  }
  close(child == 0 ? fds[0] : fds[1]);
  fd = child == 0 ? fds[1] : fds[0];
  return child;
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

/// The run_guarded child while it runs (0 otherwise): a signal that ends the parent goes to it too.
std::atomic<pid_t> guarded_child{0};
static_assert(std::atomic<pid_t>::is_always_lock_free, "a signal handler reads the child's pid");

}  // namespace

extern "C" {
static void gimforge_cleanup_signal_handler(int sig) {
  io::remove_pending_temporaries();
  if (const pid_t child = guarded_child.load(); child > 0) kill(child, sig);
  signal(sig, SIG_DFL);
  raise(sig);  // delivered when the handler returns: the process ends as the signal would have ended it
}
}

void install_signal_cleanup() {
  for (const int sig : {SIGINT, SIGTERM, SIGHUP}) {
    struct sigaction previous {};
    if (sigaction(sig, nullptr, &previous) != 0 || previous.sa_handler == SIG_IGN) continue;
    struct sigaction action {};
    action.sa_handler = &gimforge_cleanup_signal_handler;
    sigemptyset(&action.sa_mask);
    sigaction(sig, &action, nullptr);
  }
}

int run_command(const std::string& archive, const std::string& subject, const GlobalOptions& global,
                const std::function<int()>& dispatch) {
  const auto run = [&]() -> int {
    try {
      jobs::setup_logging(global.verbose ? "debug" : global.quiet ? "error" : global.log_level);
      std::unique_ptr<tbb::global_control> threads;
      if (global.threads > 0)
        threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                        static_cast<std::size_t>(global.threads));
      return dispatch();
    } catch (const Error& e) {
      spdlog::error("{}", e.what());
    } catch (const std::bad_alloc&) {
      if (subject.empty())
        spdlog::error("out of memory");
      else
        spdlog::error("{}: out of memory (what it holds needs more than this machine can give)", io::printable(subject));
    } catch (const std::exception& e) {
      spdlog::error("internal error: {}", e.what());
    }
    return kExitError;
  };
  install_signal_cleanup();
  const int code = archive.empty() ? run() : run_guarded(archive, run);
  if (h5::file_close_failed()) {  // HDF5's own clean-up at exit would crash (h5::file_close_failed)
    std::fflush(nullptr);
    std::_Exit(code);
  }
  return code;
}

void probe_archive(const std::string& archive) {
  int fd = -1;
  const pid_t child = fork_with_pipe(fd);
  if (child < 0) return read_everything(archive);  // no process to spare: read it here rather than not at all
  if (child == 0) {
    enter_child();
    std::string message;
    try {
      read_everything(archive);
    } catch (const std::exception& e) {
      message = e.what();
    }
    if (!message.empty()) {
      [[maybe_unused]] const ssize_t n = write(fd, message.data(), message.size());
    }
    close(fd);
    _exit(message.empty() ? 0 : 1);
  }
  const std::string message = read_all(fd, 65536);
  int status = 0;
  while (waitpid(child, &status, 0) < 0)
    if (errno != EINTR) return;
  if (WIFSIGNALED(status)) throw FormatError(crash_message(archive, WTERMSIG(status)));
  if (WIFEXITED(status) && WEXITSTATUS(status) != 0)
    throw FormatError(message.empty() ? io::printable(archive) + ": cannot be read" : message);
}

namespace {

/// One child of probe_shards: reads shards[first..] and reports on `fd` a line "S i" before shard i and
/// "E i MESSAGE" when it does not read.
[[noreturn]] void probe_shards_child(const std::vector<std::filesystem::path>& shards, std::size_t first, int fd) {
  enter_child();
  const auto say = [fd](const std::string& line) {
    if (!write_all(fd, line)) _exit(2);
  };
  for (std::size_t i = first; i < shards.size(); ++i) {
    say(fmt::format("S {}\n", i));
    try {
      io::read_shard_fully(shards[i]);
    } catch (const std::exception& e) {
      std::string message = e.what();
      std::replace(message.begin(), message.end(), '\n', ' ');
      say(fmt::format("E {} {}\n", i, message));
    }
  }
  close(fd);
  _exit(0);
}

}  // namespace

std::map<std::string, std::string> probe_shards(const std::filesystem::path& work_dir) {
  namespace fs = std::filesystem;
  std::vector<fs::path> shards;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(work_dir / "shards", ec), end; !ec && it != end; it.increment(ec))
    if (it->is_regular_file(ec) && it->path().extension() == ".h5") shards.push_back(it->path());
  std::sort(shards.begin(), shards.end());
  std::map<std::string, std::string> bad;
  const auto relative = [&](std::size_t i) { return shards[i].lexically_relative(work_dir).generic_string(); };
  for (std::size_t first = 0; first < shards.size();) {
    int fd = -1;
    const pid_t child = fork_with_pipe(fd);
    if (child < 0) break;  // no process to spare: the batch reads the shards itself, as before
    if (child == 0) probe_shards_child(shards, first, fd);
    const std::string text = read_all(fd, std::size_t{1} << 26);
    int status = 0;
    while (waitpid(child, &status, 0) < 0)
      if (errno != EINTR) break;
    std::size_t started = first;
    bool any_started = false;
    for (std::size_t at = 0; at < text.size();) {
      const std::size_t eol = std::min(text.find('\n', at), text.size());
      const std::string line = text.substr(at, eol - at);
      at = eol + 1;
      std::size_t index = 0;
      const auto [ptr, err] = std::from_chars(line.data() + std::min<std::size_t>(2, line.size()),
                                              line.data() + line.size(), index);
      if (line.size() < 3 || err != std::errc{} || index >= shards.size()) continue;
      if (line[0] == 'S') {
        started = index;
        any_started = true;
      } else if (line[0] == 'E' && *ptr == ' ') {
        bad[relative(index)] = std::string(ptr + 1, line.data() + line.size());
      }
    }
    const int sig = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
    if (sig != 0 && any_started && sig != SIGINT && sig != SIGTERM && sig != SIGKILL && sig != SIGHUP) {
      bad[relative(started)] = crash_message(shards[started].string(), sig);
      first = started + 1;  // a new child goes on after the shard that killed this one
      continue;
    }
    break;
  }
  return bad;
}

namespace {

void write_stderr(std::string_view text) { (void)write_all(STDERR_FILENO, text); }

/// Relays what a guarded child writes to its stderr (the pipe `fd`) until it closes it, one line behind:
/// returns the last complete line (and any unterminated rest) unwritten, so that the caller can drop it
/// when the child dies of a signal — glibc's "malloc(): corrupted ..." before an abort inside HDF5 — and
/// the user sees one line. Text without a newline that redraws a progress bar ('\r') passes at once.
std::string relay_stderr(int fd) {
  std::string pending, held;
  char buffer[4096];
  for (ssize_t n; (n = read(fd, buffer, sizeof buffer)) != 0;) {
    if (n < 0) {
      if (errno == EINTR) continue;
      break;
    }
    pending.append(buffer, static_cast<std::size_t>(n));
    for (std::size_t eol; (eol = pending.find('\n')) != std::string::npos;) {
      write_stderr(held);
      held = pending.substr(0, eol + 1);
      pending.erase(0, eol + 1);
    }
    if (!pending.empty() && pending.find('\r') != std::string::npos) {
      write_stderr(held);
      held.clear();
      write_stderr(pending);
      pending.clear();
    }
  }
  close(fd);
  return held + pending;
}

}  // namespace

int run_guarded(const std::string& archive, const std::function<int()>& work) {
  const bool terminal = jobs::stderr_is_terminal();
  int fd = -1;
  const pid_t child = fork_with_pipe(fd);
  if (child < 0) return work();  // no process to spare: run unguarded rather than not at all
  if (child == 0) {
    // stderr through the parent (relay_stderr); glibc's fatal messages there too, not on /dev/tty.
    dup2(fd, STDERR_FILENO);
    close(fd);
    setenv("LIBC_FATAL_STDERR_", "1", 1);
    jobs::set_stderr_is_terminal(terminal);
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
  guarded_child.store(child);
  const std::string last = relay_stderr(fd);
  // The terminal's Ctrl-C reaches both processes; the parent waits for the child to finish or die.
  int status = 0;
  while (waitpid(child, &status, 0) < 0) {
    if (errno != EINTR) {
      guarded_child.store(0);
      write_stderr(last);
      return kExitError;
    }
  }
  guarded_child.store(0);
  const int sig = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
  // SIGPIPE: the reader of our stdout went away (`gimforge ls A.h5 | head`), which says nothing of the archive.
  const bool stopped = sig == SIGINT || sig == SIGTERM || sig == SIGKILL || sig == SIGHUP || sig == SIGPIPE;
  // A log line of ours (on a terminal it starts by clearing the progress line: jobs/logging.cpp).
  const bool ours = last.starts_with("gimforge") || last.starts_with("\r\033[Kgimforge");
  if (sig == 0 || stopped || ours) write_stderr(last);
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (stopped) return 128 + sig;  // stopped, not broken
  if (sig != 0) fmt::print(stderr, "gimforge: error: {}\n", crash_message(archive, sig));
  return kExitError;
}

}  // namespace gimforge::cli
