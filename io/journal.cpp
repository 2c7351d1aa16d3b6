/// \file journal.cpp
/// The append-only batch journal (see journal.h).
#include "io/journal.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string_view>

#include <fmt/format.h>

#include "io/atomic_file.h"
#include "kernels/core/errors.h"

namespace gimforge::io {
namespace {

/// IoError "PATH: cannot OP: <errno text>" for the current errno.
[[noreturn]] void throw_errno(const std::filesystem::path& path, std::string_view op) {
  throw IoError(fmt::format("{}: cannot {}: {}", path.string(), op, std::strerror(errno)));
}

/// Reads the whole of `fd` (at most `size` bytes) from offset 0.
std::string read_all(int fd, const std::filesystem::path& path, std::size_t size) {
  std::string text(size, '\0');
  std::size_t got = 0;
  while (got < size) {
    const ssize_t n = ::pread(fd, text.data() + got, size - got, static_cast<off_t>(got));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw_errno(path, "read journal");
    if (n == 0) break;
    got += static_cast<std::size_t>(n);
  }
  text.resize(got);
  return text;
}

/// Size of the open file `fd`.
std::size_t file_size(int fd, const std::filesystem::path& path) {
  struct stat st {};
  if (::fstat(fd, &st) != 0) throw_errno(path, "read journal");
  return static_cast<std::size_t>(st.st_size);
}

/// True when the file `fd` is not empty and its last byte is not a newline (a torn append).
bool ends_torn(int fd, const std::filesystem::path& path) {
  const std::size_t size = file_size(fd, path);
  if (size == 0) return false;
  char last = '\n';
  if (::pread(fd, &last, 1, static_cast<off_t>(size - 1)) != 1) throw_errno(path, "read journal");
  return last != '\n';
}

/// Owns a file descriptor until release(); closes it otherwise (error paths).
class FdGuard {
 public:
  explicit FdGuard(int fd) noexcept : fd_(fd) {}
  FdGuard(const FdGuard&) = delete;
  FdGuard& operator=(const FdGuard&) = delete;
  ~FdGuard() {
    if (fd_ >= 0) ::close(fd_);
  }
  [[nodiscard]] int get() const noexcept { return fd_; }
  int release() noexcept { return std::exchange(fd_, -1); }

 private:
  int fd_;
};

// ---- summarize ---------------------------------------------------------------------------------

/// Reads the fields of one record for summarize(), naming the record in errors.
class RecordReader {
 public:
  RecordReader(const nlohmann::json& record, std::size_t number, std::string_view event)
      : record_(record), number_(number), event_(event) {}

  [[nodiscard]] const nlohmann::json& field(const char* key) const {
    const auto it = record_.find(key);
    if (it == record_.end()) fail(fmt::format("missing '{}'", key));
    return *it;
  }
  [[nodiscard]] std::string string(const char* key) const {
    const nlohmann::json& value = field(key);
    if (!value.is_string()) fail(fmt::format("'{}' is not a string", key));
    return value.get<std::string>();
  }
  [[nodiscard]] JournalKey key() const {
    const nlohmann::json& index = field("index");
    // parsed text gives unsigned for non-negative integers; records built in C++ may hold signed ones
    const bool non_negative = index.is_number_unsigned() || (index.is_number_integer() && index.get<std::int64_t>() >= 0);
    if (!non_negative) fail("'index' is not a non-negative integer");
    return {string("output"), index.get<std::uint64_t>()};
  }
  [[noreturn]] void fail(std::string_view cause) const {
    throw FormatError(fmt::format("journal record {} ({}): {}", number_, event_, cause));
  }

 private:
  const nlohmann::json& record_;
  std::size_t number_;
  std::string_view event_;
};

}  // namespace

Journal Journal::open(const std::filesystem::path& path) {
  std::error_code ec;
  const bool existed = std::filesystem::exists(path, ec);
  FdGuard fd(::open(path.c_str(), O_RDWR | O_CREAT | O_APPEND | O_CLOEXEC, 0644));
  if (fd.get() < 0) throw_errno(path, "open journal");
  if (!existed) {
    sync_directory(path.parent_path());
  } else if (ends_torn(fd.get(), path)) {  // drop the torn last append so records stay one per line
    const std::string text = read_all(fd.get(), path, file_size(fd.get(), path));
    const std::size_t keep = text.rfind('\n') == std::string::npos ? 0 : text.rfind('\n') + 1;
    if (::ftruncate(fd.get(), static_cast<off_t>(keep)) != 0) throw_errno(path, "truncate torn journal line");
    if (::fsync(fd.get()) != 0) throw_errno(path, "sync journal");
  }
  return Journal(path, fd.release());
}

Journal& Journal::operator=(Journal&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    path_ = std::move(other.path_);
    fd_ = std::exchange(other.fd_, -1);
  }
  return *this;
}

Journal::~Journal() {
  if (fd_ >= 0) ::close(fd_);
}

void Journal::append(const nlohmann::json& record) {
  if (!record.is_object())
    throw InvalidInput(fmt::format("{}: a journal record must be a JSON object, got {}", path_.string(),
                                   record.type_name()));
  if (fd_ < 0) throw IoError(fmt::format("{}: cannot append to journal: it is not open", path_.string()));
  std::string line = record.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  line += '\n';
  std::size_t written = 0;
  while (written < line.size()) {  // O_APPEND: a short write continues at the end, i.e. after itself
    const ssize_t n = ::write(fd_, line.data() + written, line.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw_errno(path_, "append to journal");
    written += static_cast<std::size_t>(n);
  }
  if (::fsync(fd_) != 0) throw_errno(path_, "append to journal");
}

std::vector<nlohmann::json> Journal::replay(const std::filesystem::path& path, std::size_t* torn_lines) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw IoError(fmt::format("{}: no such journal", path.string()));
  FdGuard fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (fd.get() < 0) throw_errno(path, "open journal");
  const std::string text = read_all(fd.get(), path, file_size(fd.get(), path));

  std::vector<nlohmann::json> records;
  std::size_t torn = 0, line_number = 0, pos = 0;
  while (pos < text.size()) {
    ++line_number;
    const std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) {  // unterminated: the append was cut short
      torn = 1;
      break;
    }
    const std::string_view line(text.data() + pos, end - pos);
    pos = end + 1;
    if (line.find_first_not_of(" \t\r") == std::string_view::npos) continue;
    nlohmann::json record;
    try {
      record = nlohmann::json::parse(line);
    } catch (const nlohmann::json::parse_error& e) {
      throw FormatError(fmt::format("{}:{}: invalid journal record: not valid JSON (at byte {})", path.string(),
                                    line_number, e.byte));
    } catch (const nlohmann::json::out_of_range&) {  // a number beyond double's range ("1e999"): found by fuzzing
      throw FormatError(fmt::format("{}:{}: invalid journal record: a number out of range", path.string(), line_number));
    }
    if (!record.is_object())
      throw FormatError(fmt::format("{}:{}: invalid journal record: a JSON {}, expected an object", path.string(),
                                    line_number, record.type_name()));
    records.push_back(std::move(record));
  }
  if (torn_lines != nullptr) *torn_lines = torn;
  return records;
}

JournalState summarize(const std::vector<nlohmann::json>& records) {
  JournalState state;
  for (std::size_t i = 0; i < records.size(); ++i) {
    const nlohmann::json& record = records[i];
    const auto event_it = record.find("event");
    if (event_it == record.end() || !event_it->is_string()) continue;
    const std::string event = event_it->get<std::string>();
    const RecordReader reader(record, i + 1, event);
    if (event == "start") {
      state.job = reader.field("job");
      ++state.starts;
    } else if (event == "done") {
      const JournalKey key = reader.key();
      state.done[key] = reader.string("shard");
      state.names[key] = reader.string("name");
    } else if (event == "failed") {
      const JournalKey key = reader.key();
      std::vector<std::string>& reasons = state.failures[key];
      const auto last = state.failure_stamps.find(key);
      if (record.contains("stamp")) {
        const std::string stamp = reader.string("stamp");
        // Attempts at the source as it was before a rewrite are of another input: only this one's count.
        if (last != state.failure_stamps.end() && last->second != stamp) reasons.clear();
        state.failure_stamps[key] = stamp;
      } else if (last != state.failure_stamps.end()) {
        state.failure_stamps.erase(last);  // an earlier gimforge's record: the last attempt's source is unknown
      }
      reasons.push_back(reader.string("reason"));
      state.names[key] = reader.string("name");
    } else if (event == "brick") {
      const JournalKey key = reader.key();
      state.parts[key][reader.string("part")] = reader.string("file");
      state.names[key] = reader.string("name");
    }
  }
  return state;
}

}  // namespace gimforge::io
