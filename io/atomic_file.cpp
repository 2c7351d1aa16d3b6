/// \file atomic_file.cpp
/// Atomic, durable file commits (see atomic_file.h).
#include "io/atomic_file.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <string>
#include <system_error>
#include <typeinfo>
#include <vector>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge::io {
namespace {

/// Opens `path` read-only with `flags` added, fsyncs it and closes it; the errno text on failure.
std::string try_sync(const std::filesystem::path& path, int flags) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | flags);
  if (fd < 0) return std::strerror(errno);
  std::string cause;
  if (::fsync(fd) != 0) cause = std::strerror(errno);
  ::close(fd);
  return cause;
}

/// This host's name as temporary names carry it ('/' written as '_').
std::string this_host() {
  char host[256] = {};
  if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  std::string name = host[0] != '\0' ? host : "host";
  std::replace(name.begin(), name.end(), '/', '_');
  return name;
}

/// The writer that a temporary name of `filename` ("<filename>.<host>.<pid>.tmp") names; pid 0 when
/// `name` is not such a name.
struct Writer {
  std::string host;
  pid_t pid{0};
};
Writer writer_of(std::string_view name, std::string_view filename) {
  constexpr std::string_view kTmp = ".tmp";
  if (name.size() <= filename.size() + 1 + kTmp.size() || !name.starts_with(filename) ||
      name[filename.size()] != '.' || !name.ends_with(kTmp))
    return {};
  const std::string_view middle = name.substr(filename.size() + 1, name.size() - filename.size() - 1 - kTmp.size());
  const std::size_t dot = middle.rfind('.');
  if (dot == std::string_view::npos || dot == 0) return {};
  const std::string_view digits = middle.substr(dot + 1);
  Writer w;
  const auto [end, err] = std::from_chars(digits.data(), digits.data() + digits.size(), w.pid);
  if (err != std::errc() || end != digits.data() + digits.size() || w.pid <= 0) return {};
  w.host = std::string(middle.substr(0, dot));
  return w;
}

/// True when no process `pid` exists (kill(pid, 0) fails with ESRCH; EPERM means it exists).
bool is_dead(pid_t pid) { return ::kill(pid, 0) != 0 && errno == ESRCH; }

}  // namespace

std::filesystem::path temporary_path(const std::filesystem::path& path) {
  std::filesystem::path tmp = path;
  tmp += fmt::format(".{}.{}.tmp", this_host(), ::getpid());
  return tmp;
}

std::vector<std::filesystem::path> remove_stale_temporaries(const std::filesystem::path& path,
                                                            bool other_hosts_are_dead) {
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  const std::string filename = path.filename().string();
  const std::string host = this_host();
  std::error_code ec;
  std::vector<std::filesystem::path> removed;
  if (!std::filesystem::is_directory(dir, ec)) return removed;
  for (auto it = std::filesystem::directory_iterator(dir, ec); !ec && it != std::filesystem::directory_iterator();
       it.increment(ec)) {
    const Writer w = writer_of(it->path().filename().string(), filename);
    std::error_code type;
    if (w.pid == 0 || !it->is_regular_file(type)) continue;
    if (w.host == host ? !is_dead(w.pid) : !other_hosts_are_dead) continue;
    std::error_code rm;
    if (!std::filesystem::remove(it->path(), rm) && rm)
      throw IoError(fmt::format("{}: cannot remove the stale temporary file: {}", it->path().string(), rm.message()));
    removed.push_back(it->path());
  }
  if (ec) throw IoError(fmt::format("{}: cannot list: {}", dir.string(), ec.message()));
  return removed;
}

std::size_t remove_temporary_files(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!std::filesystem::exists(dir, ec)) return 0;
  std::vector<std::filesystem::path> leftovers;
  for (auto it = std::filesystem::recursive_directory_iterator(dir, ec); !ec && it != std::filesystem::end(it);
       it.increment(ec))
    if (it->is_regular_file(ec) && it->path().extension() == ".tmp") leftovers.push_back(it->path());
  for (const auto& file : leftovers)
    if (!ec) std::filesystem::remove(file, ec);
  if (ec) throw IoError(fmt::format("{}: cannot remove temporary files: {}", dir.string(), ec.message()));
  return leftovers.size();
}

DirectoryLock::DirectoryLock(const std::filesystem::path& dir) {
  const std::filesystem::path target = dir.empty() ? std::filesystem::path(".") : dir;
  fd_ = ::open(target.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd_ < 0) throw IoError(fmt::format("{}: cannot lock: {}", target.string(), std::strerror(errno)));
  int rc = 0;
  while ((rc = ::flock(fd_, LOCK_EX)) != 0 && errno == EINTR) {
  }
  if (rc == 0) {
    locked_ = true;
    return;
  }
  const int err = errno;
  if (err == EBADF || err == ENOLCK || err == EINVAL || err == EOPNOTSUPP || err == ENOSYS) return;
  ::close(fd_);
  fd_ = -1;
  throw IoError(fmt::format("{}: cannot lock: {}", target.string(), std::strerror(err)));
}

DirectoryLock::~DirectoryLock() {
  if (fd_ >= 0) ::close(fd_);  // closing the only descriptor releases the flock
}

std::filesystem::path WriterLock::lock_path(const std::filesystem::path& path) {
  std::filesystem::path lock = path;
  lock += ".lock";
  return lock;
}

namespace {

/// The pid a holder wrote into lock file `fd` (0 when it has not written it yet).
long holder_pid(int fd) {
  char text[32] = {};
  const ssize_t n = ::pread(fd, text, sizeof text - 1, 0);
  if (n <= 0) return 0;
  long pid = 0;
  const auto [end, err] = std::from_chars(text, text + n, pid);
  return err == std::errc() ? pid : 0;
}

/// Whether descriptor `fd` still refers to the file named `path` (not removed or replaced since it was opened).
bool still_named(int fd, const std::filesystem::path& path) {
  struct stat by_fd {}, by_name {};
  return ::fstat(fd, &by_fd) == 0 && ::stat(path.c_str(), &by_name) == 0 && by_fd.st_dev == by_name.st_dev &&
         by_fd.st_ino == by_name.st_ino;
}

bool no_flock_here(int err) { return err == ENOLCK || err == EOPNOTSUPP || err == ENOSYS || err == EINVAL; }

}  // namespace

WriterLock::WriterLock(const std::filesystem::path& path, Wait wait) : lock_path_(lock_path(path)) {
  const std::string shown = path.string();
  for (;;) {
    // O_NOFOLLOW: a link planted as the lock file must not make us truncate and write the file it names.
    fd_ = ::open(lock_path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
    if (fd_ < 0) {
      const int err = errno;
      throw IoError(err == ELOOP ? fmt::format("{}: cannot lock: {} is a symbolic link (remove it)", shown,
                                               lock_path_.string())
                                 : fmt::format("{}: cannot lock: {}: {}", shown, lock_path_.string(), std::strerror(err)));
    }
    if (struct stat st {}; ::fstat(fd_, &st) == 0 && !S_ISREG(st.st_mode)) {
      ::close(fd_);
      fd_ = -1;
      throw IoError(fmt::format("{}: cannot lock: {} is not a regular file", shown, lock_path_.string()));
    }
    int rc = 0;
    while ((rc = ::flock(fd_, LOCK_EX | LOCK_NB)) != 0 && errno == EINTR) {
    }
    if (rc != 0 && errno == EWOULDBLOCK) {
      if (wait == Wait::kNo) {
        const long pid = holder_pid(fd_);
        ::close(fd_);
        fd_ = -1;
        throw ArchiveInUse(fmt::format("{}: archive in use by {} (another gimforge is writing it); wait with --wait",
                                       shown, pid > 0 ? fmt::format("pid {}", pid) : std::string("another process")));
      }
      while ((rc = ::flock(fd_, LOCK_EX)) != 0 && errno == EINTR) {
      }
    }
    if (rc != 0) {
      const int err = errno;
      if (no_flock_here(err)) return;  // held open, not locked: as good as this file system allows
      ::close(fd_);
      fd_ = -1;
      throw IoError(fmt::format("{}: cannot lock: {}: {}", shown, lock_path_.string(), std::strerror(err)));
    }
    if (still_named(fd_, lock_path_)) break;
    ::close(fd_);  // the previous holder removed the file we locked: lock the one that has the name now
    fd_ = -1;
  }
  locked_ = true;
  pending_.emplace(lock_path_);
  const std::string pid = std::to_string(::getpid());
  if (::ftruncate(fd_, 0) == 0) {
    [[maybe_unused]] const ssize_t n = ::pwrite(fd_, pid.data(), pid.size(), 0);
  }
}

WriterLock::~WriterLock() {
  if (fd_ < 0) return;
  pending_.reset();  // first: a signal after the unlink must not remove a contender's new lock file
  // Removed while still locked, so that a contender that opened it notices (still_named) and retries.
  if (locked_) ::unlink(lock_path_.c_str());
  ::close(fd_);
}

bool same_file(const std::filesystem::path& a, const std::filesystem::path& b) {
  struct stat sa {}, sb {};
  return ::stat(a.c_str(), &sa) == 0 && ::stat(b.c_str(), &sb) == 0 && sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

void refuse_special_file(const std::filesystem::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode))
    throw IoError(fmt::format("{}: is not a regular file (a device, pipe or socket); the output is written to a "
                              "temporary file and renamed, which would replace it: give a file name", path.string()));
}

void check_can_create(const std::filesystem::path& path) {
  const std::string shown = path.string();
  if (path.empty()) throw IoError("the output path is empty (give a file name)");
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode))
    throw IoError(fmt::format("{}: is a directory (give a file name)", shown));
  refuse_special_file(path);
  const std::filesystem::path dir = path.parent_path().empty() ? std::filesystem::path(".") : path.parent_path();
  if (::stat(dir.c_str(), &st) != 0) {
    const int err = errno;
    if (err == ENOENT || err == ENOTDIR)
      throw IoError(fmt::format("{}: cannot write here: directory '{}' does not exist", shown, dir.string()));
    throw IoError(fmt::format("{}: cannot write here: directory '{}': {}", shown, dir.string(), std::strerror(err)));
  }
  if (!S_ISDIR(st.st_mode))
    throw IoError(fmt::format("{}: cannot write here: '{}' is not a directory", shown, dir.string()));
  if (::access(dir.c_str(), W_OK | X_OK) != 0)
    throw IoError(fmt::format("{}: cannot write here: directory '{}' is not writable: {}", shown, dir.string(),
                              std::strerror(errno)));
}

void copy_contents(const std::filesystem::path& from, const std::filesystem::path& to) {
  const auto fail = [](const std::filesystem::path& which, std::string_view op, int err) {
    throw IoError(fmt::format("{}: cannot {}: {}", which.string(), op, std::strerror(err)));
  };
  const int in = ::open(from.c_str(), O_RDONLY | O_CLOEXEC);
  if (in < 0) fail(from, "read", errno);
  const int out = ::open(to.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (out < 0) {
    const int err = errno;
    ::close(in);
    fail(to, "create", err);
  }
  // The copy replaces the original: it keeps its permissions (a private archive stays private, a read-only
  // one stays read-only and cannot be opened for writing), as std::filesystem::copy_file did.
  if (struct stat st {}; ::fstat(in, &st) != 0 || ::fchmod(out, st.st_mode & 07777) != 0) {
    const int err = errno;
    ::close(in);
    ::close(out);
    fail(to, "create", err);
  }
  std::vector<char> buffer(std::size_t{1} << 20);
  int err = 0;
  bool reading = true;
  for (ssize_t n; err == 0 && (n = ::read(in, buffer.data(), buffer.size())) != 0;) {
    if (n < 0) {
      if (errno != EINTR) err = errno;
      continue;
    }
    for (ssize_t at = 0; at < n && err == 0;) {
      const ssize_t w = ::write(out, buffer.data() + at, static_cast<std::size_t>(n - at));
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) {
        err = w < 0 ? errno : EIO;
        reading = false;
      } else {
        at += w;
      }
    }
  }
  ::close(in);
  if (::close(out) != 0 && err == 0) {
    err = errno;
    reading = false;
  }
  if (err != 0) fail(reading ? from : to, reading ? "read" : "write", err);
}

void sync_file(const std::filesystem::path& path) {
  if (const std::string cause = try_sync(path, 0); !cause.empty())
    throw IoError(fmt::format("{}: cannot sync: {}", path.string(), cause));
}

void sync_directory(const std::filesystem::path& dir) {
  const std::filesystem::path target = dir.empty() ? std::filesystem::path(".") : dir;
  if (const std::string cause = try_sync(target, O_DIRECTORY); !cause.empty())
    throw IoError(fmt::format("{}: cannot sync directory: {}", target.string(), cause));
}

namespace {

/// RemovedOnSignal's slots: a slot is free (0), being filled (1) or names a file (2). The signal handler
/// reads only slots in state 2, whose path is complete (written before the release store).
constexpr std::size_t kSignalSlots = 16;
constexpr std::size_t kSignalPathMax = 4096;
struct SignalSlot {
  std::atomic<int> state{0};
  std::atomic<std::uint64_t> generation{0};  ///< raised each time the slot names a new file
  char path[kSignalPathMax] = {};
};
static_assert(std::atomic<int>::is_always_lock_free, "a signal handler reads the slot states");
static_assert(std::atomic<std::uint64_t>::is_always_lock_free, "a signal handler reads the slot generations");
SignalSlot signal_slots[kSignalSlots];

}  // namespace

RemovedOnSignal::RemovedOnSignal(const std::filesystem::path& path) noexcept {
  const std::string& text = path.native();
  if (text.empty() || text.size() >= kSignalPathMax) return;
  for (std::size_t i = 0; i < kSignalSlots; ++i) {
    int expected = 0;
    if (!signal_slots[i].state.compare_exchange_strong(expected, 1)) continue;
    std::memcpy(signal_slots[i].path, text.c_str(), text.size() + 1);
    signal_slots[i].generation.fetch_add(1);
    signal_slots[i].state.store(2, std::memory_order_release);
    slot_ = static_cast<int>(i);
    return;
  }
}

RemovedOnSignal::~RemovedOnSignal() {
  if (slot_ >= 0) signal_slots[static_cast<std::size_t>(slot_)].state.store(0);
}

void remove_pending_temporaries() noexcept {
  // Another thread may free a slot and fill it again meanwhile: the path is copied, and used only when the
  // slot still names the same file afterwards.
  char path[kSignalPathMax];
  for (SignalSlot& slot : signal_slots) {
    const std::uint64_t generation = slot.generation.load(std::memory_order_acquire);
    if (slot.state.load(std::memory_order_acquire) != 2) continue;
    std::memcpy(path, slot.path, kSignalPathMax);
    path[kSignalPathMax - 1] = '\0';
    if (slot.state.load(std::memory_order_acquire) == 2 && slot.generation.load(std::memory_order_acquire) == generation)
      ::unlink(path);
  }
}

namespace {

/// An error while writing the temporary file names the file the user asked for ("out.h5: cannot flush
/// file: file write failed: No space left on device"), not "out.h5.host.123.tmp", which is gone by then.
std::string named_as_output(std::string message, const std::filesystem::path& tmp, const std::filesystem::path& path) {
  const std::string from = tmp.string(), to = path.string();
  for (std::size_t at = 0; (at = message.find(from, at)) != std::string::npos; at += to.size())
    message.replace(at, from.size(), to);
  return message;
}

}  // namespace

void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& tmp)>& write, ParentDirectory parent) {
  refuse_special_file(path);
  const std::filesystem::path dir = path.parent_path();
  if (!dir.empty() && parent == ParentDirectory::kCreate) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) throw IoError(fmt::format("{}: cannot create directory: {}", dir.string(), ec.message()));
  }
  const std::filesystem::path tmp = temporary_path(path);
  const RemovedOnSignal pending(tmp);
  const auto remove_tmp = [&] {
    std::error_code ignored;  // the original failure is what matters
    std::filesystem::remove(tmp, ignored);
  };
  try {
    write(tmp);
    sync_file(tmp);
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) throw IoError(fmt::format("{}: cannot commit: {}", path.string(), ec.message()));
  } catch (const Error& e) {
    remove_tmp();
    // These three exactly (a subclass such as ArchiveInUse keeps its type and its words).
    const std::type_info& type = typeid(e);
    if (type == typeid(FormatError)) throw FormatError(named_as_output(e.what(), tmp, path));
    if (type == typeid(IoError)) throw IoError(named_as_output(e.what(), tmp, path));
    if (type == typeid(LibraryError)) throw LibraryError(named_as_output(e.what(), tmp, path));
    throw;
  } catch (...) {
    remove_tmp();
    throw;
  }
  sync_directory(dir);
}

}  // namespace gimforge::io
