#pragma once
/// \file atomic_file.h
/// Files that appear complete or not at all, for jobs that may be killed at any moment (SIGKILL, node
/// loss): a file is written under a temporary name next to its final one, flushed to disk, and renamed
/// into place (rename(2) within one directory is atomic), then the directory entry is flushed too. Used
/// by the batch shards (io/batch_shard.h), the consolidated batch archive (io/batch_archive.h) and the
/// journal (io/journal.h). POSIX only.
#include <cstddef>
#include <filesystem>
#include <functional>

namespace gimforge::io {

/// The temporary name under which this process writes `path` before committing it:
/// "<path>.<host>.<pid>.tmp", in the same directory (so the final rename stays within one file system).
/// It is unique per process, so two processes writing the same path at once (a retried item whose first
/// attempt still runs on another rank) never share a temporary file: both commits are complete and the
/// last rename wins. Leftovers of killed processes end in ".tmp" (see remove_temporary_files).
[[nodiscard]] std::filesystem::path temporary_path(const std::filesystem::path& path);

/// Removes every regular file whose name ends in ".tmp" below `dir` (recursively): the leftovers of
/// writers that were killed before their commit. Call it only while no writer is active there (e.g. when
/// a batch resumes). Returns how many files were removed; 0 when `dir` does not exist. Throws IoError
/// "DIR: cannot remove temporary files: CAUSE" when the directory cannot be listed or a file removed.
std::size_t remove_temporary_files(const std::filesystem::path& dir);

/// Flushes file `path` (fsync) to stable storage. Throws IoError "PATH: cannot sync: CAUSE".
void sync_file(const std::filesystem::path& path);

/// Flushes directory `dir` (fsync), making created, renamed and removed entries in it durable; "" means
/// the current directory. Throws IoError "DIR: cannot sync directory: CAUSE".
void sync_directory(const std::filesystem::path& dir);

/// Writes `path` atomically: creates its parent directories, calls `write(temporary_path(path))`, which
/// must create and close that file, then syncs it, renames it over `path` (replacing an existing file) and
/// syncs the directory. Readers see either the old `path` (or none) or the complete new file, never a
/// partial one. When `write` or the commit throws, the temporary file is removed and the exception
/// propagates unchanged; IoError "PATH: cannot commit: CAUSE" when the rename fails.
void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& tmp)>& write);

}  // namespace gimforge::io
