#pragma once
/// \file input_file.h
/// Opening what users name as input without hanging: a named pipe (FIFO) or a device given where a mesh,
/// archive or list is expected must give one clear line, never a process blocked in open() waiting for a
/// writer that will not come (where no signal handler can reach it: the handlers restart system calls).
#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace gimforge::io {

/// Throws IoError "SHOWN: file does not exist (No such file)", "SHOWN: is a directory, not a file" or
/// "SHOWN: is not a regular file (a pipe, device or socket)" unless `path` is a regular file (links
/// followed). Uses stat() only, so it never blocks.
void require_regular_file(const std::filesystem::path& path, const std::string& shown);

/// The whole contents of a text input (a batch list or job file, at most `max_bytes`). Pipes are allowed,
/// since `--list <(find ...)` is one, but the open does not wait for a writer: a named pipe nobody writes to
/// reads as empty. Throws IoError naming `path` when it is missing, a directory, unreadable or too long.
[[nodiscard]] std::string read_text_input(const std::filesystem::path& path, std::size_t max_bytes);

/// Size and modification time (ns) of the file at `path` (links followed): what tells a file rewritten since
/// (not the inode, which some network file systems do not keep stable). nullopt when it cannot be stat'ed.
[[nodiscard]] std::optional<std::array<std::uint64_t, 2>> file_identity(const std::filesystem::path& path);

/// file_identity as text, "SIZE:MTIME_NS" (a batch shard's source_stamp); empty when it cannot be stat'ed.
[[nodiscard]] std::string file_stamp(const std::filesystem::path& path);

}  // namespace gimforge::io
