#pragma once
/// \file journal.h
/// The batch journal: an append-only text file with one JSON object per line (JSON Lines). The batch
/// master appends a record after each event it must survive a kill (an item's shard committed, an attempt
/// failed, a job started) and `--resume` replays the file to learn what is already done.
///
/// A record counts once its line, newline included, is on disk: append() writes the whole line with one
/// write(2) and fsyncs. A job killed in the middle of an append leaves at most one unterminated last line
/// (a *torn* line); replay() ignores it and counts it, and open() cuts it off before appending, so the next
/// record starts on a line of its own. Anything else that is not a JSON object is damage, not a torn write:
/// replay() rejects it with FormatError naming the file and the line.
///
/// Records the batch writes (docs/archive.md, "Journal"); the journal itself accepts any JSON object:
///   {"event":"start","job":{...}}
///   {"event":"done","output":"gim_257","name":"chair/0001","index":12,"shard":"shards/gim_257/12.h5"}
///   {"event":"failed","output":"gim_257","name":"chair/0002","index":13,"attempt":1,"reason":"..."}
///   {"event":"brick","output":"gim_513","name":"scan","index":3,"part":"plan","file":"bricks/gim_513/3/plan.bin"}
///   (a huge item's brick tasks, jobs/brick_tasks.h: part "plan", then one per brick: "0", "1", ...)
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace gimforge::io {

/// An open journal, appending. Move-only; the file closes with the object.
class Journal {
 public:
  /// Opens the journal at `path` for appending, creating it (and syncing its directory) when missing.
  /// A torn last line (no newline; see the file comment) is cut off first. Throws IoError "PATH: cannot
  /// open journal: CAUSE" (or another operation) when the file cannot be opened, read or truncated.
  [[nodiscard]] static Journal open(const std::filesystem::path& path);

  /// Appends `record` as one line of compact JSON and makes it durable (write + fsync) before returning.
  /// Invalid UTF-8 in strings is replaced by U+FFFD rather than refused (reasons quote file names).
  /// Throws InvalidInput when `record` is not a JSON object, IoError "PATH: cannot append to journal:
  /// CAUSE" when writing or syncing fails.
  void append(const nlohmann::json& record);

  /// The path the journal was opened with.
  [[nodiscard]] const std::filesystem::path& path() const noexcept { return path_; }

  /// Reads every complete record of the journal at `path`, in file order. Blank lines are skipped. An
  /// unterminated last line is a torn append: it is ignored and, when `torn_lines` is given, counted there
  /// (0 or 1). Throws IoError "PATH: no such journal" when the file is missing, IoError when it cannot be
  /// read, FormatError "PATH:LINE: invalid journal record: CAUSE" for a complete line that is not a JSON
  /// object.
  [[nodiscard]] static std::vector<nlohmann::json> replay(const std::filesystem::path& path,
                                                          std::size_t* torn_lines = nullptr);

  Journal(Journal&& other) noexcept : path_(std::move(other.path_)), fd_(std::exchange(other.fd_, -1)) {}
  Journal& operator=(Journal&& other) noexcept;
  Journal(const Journal&) = delete;
  Journal& operator=(const Journal&) = delete;
  /// Closes the file (every record is already durable).
  ~Journal();

 private:
  Journal(std::filesystem::path path, int fd) noexcept : path_(std::move(path)), fd_(fd) {}

  std::filesystem::path path_;
  int fd_ = -1;
};

/// Identifies one item of one output in the journal: (output, index).
using JournalKey = std::pair<std::string, std::uint64_t>;

/// What a replayed journal says about the batch.
struct JournalState {
  /// The `job` of the last "start" record (the configuration of the latest run), if any.
  std::optional<nlohmann::json> job{};
  /// Number of "start" records (runs begun, the first included).
  std::size_t starts = 0;
  /// Committed items: (output, index) -> the shard path recorded (as written, typically relative to the
  /// job directory). When an item was redone, the last record wins.
  std::map<JournalKey, std::string> done{};
  /// Failed attempts: (output, index) -> their reasons in journal order (size() = attempts so far), those at
  /// the source as its last stamped attempt found it (failure_stamps). An item may be both here and in `done`
  /// when a retry succeeded; `done` is what counts.
  std::map<JournalKey, std::vector<std::string>> failures{};
  /// The `stamp` of each item's last failed attempt, where the record has one: its source's file_stamp
  /// (io/input_file.h) when the attempt was sent. A source stamped otherwise now was rewritten since.
  std::map<JournalKey, std::string> failure_stamps{};
  /// Brick tasks done: (output, index) -> part ("plan", or a brick number) -> the file recorded. The last
  /// record of a part wins.
  std::map<JournalKey, std::map<std::string, std::string>> parts{};
  /// Names of the items seen in "done", "failed" or "brick" records.
  std::map<JournalKey, std::string> names{};
};

/// Folds replayed records into a JournalState. Records with another or no `event` are ignored (the
/// journal is generic). Throws FormatError "journal record N (EVENT): CAUSE" (N counts from 1) when a
/// "start", "done", "failed" or "brick" record lacks a field of the layout in the file comment or has it with
/// the wrong type (`index` must be a non-negative integer).
[[nodiscard]] JournalState summarize(const std::vector<nlohmann::json>& records);

}  // namespace gimforge::io
