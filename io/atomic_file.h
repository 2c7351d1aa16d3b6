#pragma once
/// \file atomic_file.h
/// Files that appear complete or not at all, for jobs that may be killed at any moment (SIGKILL, node
/// loss): a file is written under a temporary name next to its final one, flushed to disk, and renamed
/// into place (rename(2) within one directory is atomic), then the directory entry is flushed too. This
/// is the only place that names temporary files and commits them; every writer goes through
/// write_atomically: the batch shards (io/batch_shard.h), the consolidated batch archive
/// (io/batch_archive.h), the journal (io/journal.h), PLY output (io/mesh_io.h), PNG output
/// (io/png_image.h) and `convert -o` (jobs/gim_store.h). Part of gimforge_io (no HDF5). POSIX only.
#include <cstddef>
#include <filesystem>
#include <functional>
#include <optional>
#include <vector>

#include "kernels/core/errors.h"

namespace gimforge::io {

/// Another process holds the WriterLock of a file (see WriterLock).
class ArchiveInUse : public IoError {
 public:
  using IoError::IoError;
};

/// The temporary name under which this process writes `path` before committing it:
/// "<path>.<host>.<pid>.tmp", in the same directory (so the final rename stays within one file system).
/// It is unique per process, so two processes writing the same path at once (a retried item whose first
/// attempt still runs on another rank) never share a temporary file: both commits are complete and the
/// last rename wins. Leftovers of killed processes end in ".tmp" (see remove_temporary_files and
/// remove_stale_temporaries). The host name's '/' characters are written as '_'.
[[nodiscard]] std::filesystem::path temporary_path(const std::filesystem::path& path);

/// Removes the leftovers of dead writers of `path`: the regular files next to it named
/// "<filename>.<host>.<pid>.tmp" (temporary_path of any process) whose host is this host and whose pid no
/// longer exists (kill(pid, 0) fails with ESRCH). Temporaries of live processes (this one included) are
/// kept, and so is every other file. Temporaries named after another host are kept too, unless
/// `other_hosts_are_dead`: a caller that knows no writer runs anywhere else (a resumed batch job) removes
/// them as well. Safe while other writers are active. Returns the removed files; none when the directory
/// does not exist. Throws IoError "TMP: cannot remove the stale temporary file: CAUSE" or
/// "DIR: cannot list: CAUSE".
std::vector<std::filesystem::path> remove_stale_temporaries(const std::filesystem::path& path,
                                                            bool other_hosts_are_dead = false);

/// Removes every regular file whose name ends in ".tmp" below `dir` (recursively): the leftovers of
/// writers that were killed before their commit. Call it only while no writer is active there (e.g. when
/// a batch resumes). Returns how many files were removed; 0 when `dir` does not exist. Throws IoError
/// "DIR: cannot remove temporary files: CAUSE" when the directory cannot be listed or a file removed.
std::size_t remove_temporary_files(const std::filesystem::path& dir);

/// While alive, names a temporary file that remove_pending_temporaries() deletes: the files a process
/// writes before committing them (write_atomically's, the STL converter's side files) and the lock
/// files of WriterLock must not outlive it
/// when SIGINT, SIGTERM or SIGHUP end it (cli::install_signal_cleanup). At most 16 at once per process
/// (later ones are not removed on a signal, only by remove_stale_temporaries); paths of 4096 bytes or more
/// are not either. Safe to use from several threads.
class RemovedOnSignal {
 public:
  explicit RemovedOnSignal(const std::filesystem::path& path) noexcept;
  ~RemovedOnSignal();
  RemovedOnSignal(const RemovedOnSignal&) = delete;
  RemovedOnSignal& operator=(const RemovedOnSignal&) = delete;

 private:
  int slot_{-1};
};

/// Deletes (unlink(2)) every file a RemovedOnSignal names now. Async-signal-safe: for a signal handler.
void remove_pending_temporaries() noexcept;

/// An exclusive lock on a directory (flock(2) on the directory itself), held from construction to
/// destruction; it blocks until no other process holds it. Writers that read a file, change it and
/// rename the result back (`convert -o EXISTING.h5`) hold it around that sequence, so two of them cannot
/// both start from the same old file and lose one's change. It is released when the process dies. On file
/// systems without flock on directories (some NFS or parallel file systems: EBADF, ENOLCK, EINVAL,
/// EOPNOTSUPP, ENOSYS) it holds nothing (locked() is false). Throws IoError "DIR: cannot lock: CAUSE" when
/// the directory cannot be opened or for other failures.
class DirectoryLock {
 public:
  explicit DirectoryLock(const std::filesystem::path& dir);
  ~DirectoryLock();
  DirectoryLock(const DirectoryLock&) = delete;
  DirectoryLock& operator=(const DirectoryLock&) = delete;
  /// Whether the lock is held (false where the file system cannot lock directories).
  [[nodiscard]] bool locked() const noexcept { return locked_; }

 private:
  int fd_{-1};
  bool locked_{false};
};

/// The exclusive right to write one file (an archive), held from construction to destruction by an
/// advisory lock (flock(2)) on the lock file "<path>.lock" next to it. Writers of one archive (`convert`,
/// `batch`, a `batch --resume`) take it BEFORE their work, so a second writer is refused (or waits) up
/// front instead of losing its result or failing after all its work. The holder writes its pid into the
/// lock file; the lock file is removed on release and when SIGINT, SIGTERM or SIGHUP end the process
/// (RemovedOnSignal; a contender that locked a removed file notices it and locks the new one, so removal
/// never lets two writers in). The lock dies with its process (no stale lock survives a kill; a leftover
/// lock file of a SIGKILLed writer is simply reused). On file systems without
/// flock (ENOLCK, EOPNOTSUPP, ENOSYS, EINVAL) nothing is held (locked() is false).
class WriterLock {
 public:
  enum class Wait {
    kNo,   ///< another holder: throw ArchiveInUse at once
    kYes,  ///< another holder: block until it releases the lock
  };
  /// Throws ArchiveInUse "PATH: archive in use by pid N (another gimforge is writing it); wait with
  /// --wait" when another process holds it and `wait` is kNo; IoError "PATH: cannot lock: CAUSE" when the
  /// lock file cannot be created (e.g. its directory is missing or not writable).
  WriterLock(const std::filesystem::path& path, Wait wait);
  ~WriterLock();
  WriterLock(const WriterLock&) = delete;
  WriterLock& operator=(const WriterLock&) = delete;
  [[nodiscard]] bool locked() const noexcept { return fd_ >= 0 && locked_; }
  /// "<path>.lock".
  [[nodiscard]] static std::filesystem::path lock_path(const std::filesystem::path& path);

 private:
  std::filesystem::path lock_path_;
  int fd_{-1};
  bool locked_{false};
  std::optional<RemovedOnSignal> pending_;  // the lock file, while locked
};

/// Whether `a` and `b` name the same existing file (same st_dev and st_ino after following symbolic
/// links; hard links count as the same file). False when either does not exist.
[[nodiscard]] bool same_file(const std::filesystem::path& a, const std::filesystem::path& b);

/// Throws IoError "PATH: is not a regular file ..." when `path` exists as a device, pipe or socket (after
/// following links): write_atomically would rename its temporary file over it (`-o /dev/null` replaced the
/// device node).
void refuse_special_file(const std::filesystem::path& path);

/// Checks, before any long work, that a file can be created at `path`: its directory ("" = the current
/// one) exists, is a directory and is writable (access(2) W_OK|X_OK), and `path` itself is not a directory
/// nor a device, pipe or socket. Throws IoError "PATH: cannot write here: directory 'DIR' does not exist"
/// (or "... is not a directory", "... is not writable: CAUSE", "PATH: is a directory", "PATH: is not a
/// regular file ...", "the output path is empty").
void check_can_create(const std::filesystem::path& path);

/// Copies the bytes of file `from` into `to` (created or truncated, with the permissions of `from`). Throws
/// IoError "FROM: cannot read: CAUSE", "TO: cannot create: CAUSE" or "TO: cannot write: CAUSE" (a full disk
/// says "No space left on device", where std::filesystem::copy_file's sendfile path says "Input/output
/// error").
void copy_contents(const std::filesystem::path& from, const std::filesystem::path& to);

/// Flushes file `path` (fsync) to stable storage. Throws IoError "PATH: cannot sync: CAUSE".
void sync_file(const std::filesystem::path& path);

/// Flushes directory `dir` (fsync), making created, renamed and removed entries in it durable; "" means
/// the current directory. Throws IoError "DIR: cannot sync directory: CAUSE".
void sync_directory(const std::filesystem::path& dir);

/// What write_atomically does when the directory of `path` does not exist.
enum class ParentDirectory {
  kCreate,     ///< creates it (and its parents); IoError "DIR: cannot create directory: CAUSE"
  kMustExist,  ///< leaves it to `write`, which fails to create the temporary file and says so
};

/// Writes `path` atomically: calls `write(temporary_path(path))`, which must create and close that file,
/// then syncs it, renames it over `path` (replacing an existing file) and syncs the directory. Readers see
/// either the old `path` (or none) or the complete new file, never a partial one; a kill at any moment
/// leaves at most a temporary file that remove_stale_temporaries recognizes. When `write` or the commit
/// throws, the temporary file is removed and the exception propagates, its message naming `path` where
/// it named the temporary file (for FormatError, IoError and LibraryError exactly; other types unchanged); IoError "PATH: cannot
/// commit: CAUSE" when the rename fails, and (before `write`) refuse_special_file's error.
void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& tmp)>& write,
                      ParentDirectory parent = ParentDirectory::kCreate);

}  // namespace gimforge::io
