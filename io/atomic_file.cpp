/// \file atomic_file.cpp
/// Atomic, durable file commits (see atomic_file.h).
#include "io/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <string>
#include <system_error>
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

}  // namespace

std::filesystem::path temporary_path(const std::filesystem::path& path) {
  char host[256] = {};
  if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  std::string suffix = fmt::format(".{}.{}.tmp", host[0] != '\0' ? host : "host", ::getpid());
  std::replace(suffix.begin(), suffix.end(), '/', '_');
  std::filesystem::path tmp = path;
  tmp += suffix;
  return tmp;
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

void sync_file(const std::filesystem::path& path) {
  if (const std::string cause = try_sync(path, 0); !cause.empty())
    throw IoError(fmt::format("{}: cannot sync: {}", path.string(), cause));
}

void sync_directory(const std::filesystem::path& dir) {
  const std::filesystem::path target = dir.empty() ? std::filesystem::path(".") : dir;
  if (const std::string cause = try_sync(target, O_DIRECTORY); !cause.empty())
    throw IoError(fmt::format("{}: cannot sync directory: {}", target.string(), cause));
}

void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& tmp)>& write) {
  const std::filesystem::path dir = path.parent_path();
  if (!dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) throw IoError(fmt::format("{}: cannot create directory: {}", dir.string(), ec.message()));
  }
  const std::filesystem::path tmp = temporary_path(path);
  try {
    write(tmp);
    sync_file(tmp);
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) throw IoError(fmt::format("{}: cannot commit: {}", path.string(), ec.message()));
  } catch (...) {
    std::error_code ignored;  // the original failure is what matters
    std::filesystem::remove(tmp, ignored);
    throw;
  }
  sync_directory(dir);
}

}  // namespace gimforge::io
