#include "io/input_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <system_error>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge::io {
namespace {

std::string errno_text(int err) { return std::generic_category().message(err); }

}  // namespace

void require_regular_file(const std::filesystem::path& path, const std::string& shown) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int err = errno;
    if (err == ENOENT) throw IoError(fmt::format("{}: file does not exist (No such file)", shown));
    throw IoError(fmt::format("{}: cannot access the file: {}", shown, errno_text(err)));
  }
  if (S_ISDIR(st.st_mode)) throw IoError(fmt::format("{}: is a directory, not a file", shown));
  if (!S_ISREG(st.st_mode)) throw IoError(fmt::format("{}: is not a regular file (a pipe, device or socket)", shown));
}

std::string read_text_input(const std::filesystem::path& path, std::size_t max_bytes) {
  const std::string shown = path.string();
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode))
    throw IoError(fmt::format("{}: is a directory, not a file", shown));
  // O_NONBLOCK: opening a FIFO for reading does not wait for a writer. Then blocking reads again: a pipe
  // with a writer is read to its end, one without any reads as end of file at once.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    if (err == ENOENT) throw IoError(fmt::format("{}: file does not exist (No such file)", shown));
    throw IoError(fmt::format("{}: cannot open: {}", shown, errno_text(err)));
  }
  std::string text;
  try {
    const int flags = ::fcntl(fd, F_GETFL);
    if (flags < 0 || ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK) != 0)
      throw IoError(fmt::format("{}: cannot read: {}", shown, errno_text(errno)));
    char buffer[1 << 14];
    for (;;) {
      const ssize_t n = ::read(fd, buffer, sizeof buffer);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) throw IoError(fmt::format("{}: cannot read: {}", shown, errno_text(errno)));
      if (n == 0) break;
      if (text.size() + static_cast<std::size_t>(n) > max_bytes)
        throw IoError(fmt::format("{}: longer than {} bytes", shown, max_bytes));
      text.append(buffer, static_cast<std::size_t>(n));
    }
  } catch (...) {
    ::close(fd);
    throw;
  }
  ::close(fd);
  return text;
}

std::optional<std::array<std::uint64_t, 2>> file_identity(const std::filesystem::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return std::nullopt;
  const auto ns = static_cast<std::uint64_t>(st.st_mtim.tv_sec) * 1'000'000'000u + static_cast<std::uint64_t>(st.st_mtim.tv_nsec);
  return std::array<std::uint64_t, 2>{static_cast<std::uint64_t>(st.st_size), ns};
}

std::string file_stamp(const std::filesystem::path& path) {
  const auto id = file_identity(path);
  return id ? fmt::format("{}:{}", (*id)[0], (*id)[1]) : std::string();
}

}  // namespace gimforge::io
