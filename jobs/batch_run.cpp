#include "jobs/batch_run.h"

#include <array>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <string_view>
#include <algorithm>
#include <new>
#include <optional>
#include <utility>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "io/archive.h"
#include "io/atomic_file.h"
#include "io/batch_archive.h"
#include "io/batch_shard.h"
#include "io/input_file.h"
#include "io/printable.h"
#include "io/journal.h"
#include "io/mesh_header.h"
#include "jobs/batch_item.h"
#include "jobs/batch_job.h"
#include "jobs/brick_tasks.h"
#include "jobs/gim_store.h"
#include "jobs/memory_budget.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "mpi/scheduler.h"

namespace gimforge::jobs {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using nlohmann::json;

/// The working directory of a batch writing ARCHIVE: ARCHIVE.work/ with journal.jsonl and shards/.
struct WorkDir {
  fs::path root;
  [[nodiscard]] fs::path journal() const { return root / "journal.jsonl"; }
  [[nodiscard]] std::string shard(const std::string& output, std::uint64_t index) const {
    return fmt::format("shards/{}/{}.h5", output, index);
  }
  /// The directory of a huge item's brick tasks (jobs/brick_tasks.h), relative to root.
  [[nodiscard]] std::string bricks(const std::string& output, std::uint64_t index) const {
    return fmt::format("bricks/{}/{}", output, index);
  }
};

/// What a work item asks a worker to do: convert an item whole, or one of a huge item's brick tasks.
enum class TaskKind { Whole, Plan, Piece, Finish };

constexpr std::array<std::string_view, 4> kTaskNames{"whole", "plan", "piece", "finish"};

struct Task {
  TaskKind kind{TaskKind::Whole};
  std::size_t output{0};
  std::uint64_t index{0};
  std::size_t brick{0};  ///< TaskKind::Piece
  std::uint64_t generation{0};  ///< brick tasks: the item's plan generation when made (results of older ones are void)
  std::string stamp{};  ///< the source's io::file_stamp when the task was made, journaled with a failure
};

/// How often a run plans an item again because its plan or pieces were unusable, before that counts as a
/// failed attempt (a source rewritten again and again).
constexpr int kMaxReplans = 2;

/// A huge item's brick tasks so far.
struct Staged {
  std::optional<std::vector<std::uint64_t>> brick_faces;  ///< after its plan: faces per brick (empty: whole)
  std::set<std::size_t> pieces;                           ///< bricks decimated
};

bool is_final(const std::string& reason) { return reason.ends_with(kNotRetried); }

/// Whether an output's items are representation groups (relief maps and multi-chart images differ in size,
/// compressed images carry their own payload) rather than images.
bool stores_groups(const MethodOptions& m) {
  return m.method == Method::Relief || m.method == Method::Mcgim || !m.codec.empty();
}

/// Progress line of the master: items done / total, failures, rate and ETA, at most every 2 s (and at the
/// end), on stderr.
class BatchProgress {
 public:
  BatchProgress(bool enabled, std::size_t already_done, std::size_t total)
      : enabled_(enabled), base_(already_done), total_(total) {}
  void update(std::size_t done_now, std::size_t failed, bool force = false) {
    if (!enabled_) return;
    const auto now = Clock::now();
    if (!force && now - last_ < std::chrono::seconds(2)) return;
    last_ = now;
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    const double rate = elapsed > 0.0 ? static_cast<double>(done_now) / elapsed : 0.0;
    const std::size_t done = base_ + done_now;
    const double eta = rate > 0.0 ? static_cast<double>(total_ - std::min(done, total_)) / rate : 0.0;
    fmt::print(stderr, "gimforge batch: {}/{} done, {} failed, {:.2f} items/s, ETA {:.0f} s\n", done, total_, failed,
               rate, eta);
  }

 private:
  bool enabled_;
  std::size_t base_, total_;
  Clock::time_point start_{Clock::now()}, last_{};
};

/// What rank 0 decided before the scheduling starts; broadcast to the workers as JSON.
struct Plan {
  std::string error;     ///< non-empty: every rank stops with this error
  bool nothing_to_do{false};
  std::string work_root;
};

/// Removes the "<archive>.<host>.<pid>.tmp" files (io/atomic_file.h) that a merge killed before its rename
/// left next to the archive. A resumed job has no other writer anywhere, so temporaries named after other
/// hosts (a requeued job that ran elsewhere) go too; those of live processes on this host stay.
void remove_unfinished_archives(const fs::path& archive) {
  for (const fs::path& file : io::remove_stale_temporaries(archive, /*other_hosts_are_dead=*/true))
    spdlog::info("resume: removed the unfinished archive {}", file.string());
}

/// Seconds as whole milliseconds, rounded up (a patience of 0.4 ms is 1 ms, not "none").
std::chrono::milliseconds milliseconds_up(double seconds) {
  return std::chrono::milliseconds(static_cast<std::int64_t>(std::ceil(seconds * 1000.0)));
}

/// Rank 0's bookkeeping of one run: the journal, the items done and failed, the merge.
class BatchCoordinator {
 public:
  BatchCoordinator(const BatchOptions& o, BatchJob job, WorkDir dir) : o_(o), job_(std::move(job)), dir_(std::move(dir)) {}

  /// Opens or resumes the journal; returns the work items still to do.
  std::vector<mpi::WorkItem> prepare() {
    std::error_code ec;
    const bool exists = fs::exists(dir_.journal(), ec);
    if (exists && !o_.resume)
      throw InvalidInput(fmt::format("{}: a previous batch for {} was interrupted; run again with --resume to "
                                     "finish it, or remove {} to start over",
                                     dir_.root.string(), o_.output, dir_.root.string()));
    if (fs::exists(o_.output, ec)) {
      if (!o_.resume)
        throw InvalidInput(fmt::format("{}: exists; choose another output (a batch writes a new archive)", o_.output));
      // The archive is renamed into place whole, so an existing one of this job means the merge finished:
      // a requeued job, or one stopped before it removed its work directory. Nothing is left to redo.
      if (!written_by_this_job())
        throw InvalidInput(fmt::format("{}: exists and is not this job's archive (another batch's, or one that "
                                       "convert wrote); choose another output, or move that archive away",
                                       o_.output));
      fs::remove_all(dir_.root, ec);
      if (ec) spdlog::warn("{}: could not remove the work directory: {}", dir_.root.string(), ec.message());
      complete_ = true;
      return {};
    }
    fs::create_directories(dir_.root, ec);
    if (ec) throw IoError(fmt::format("{}: cannot create: {}", dir_.root.string(), ec.message()));
    const auto own_shard_dirs = [&] {
      for (const OutputSpec& output : job_.outputs) own_dir(fs::path("shards") / output.name);
    };
    const json identity = job_json(job_);
    if (exists) {
      std::size_t torn = 0;
      io::JournalState state;
      try {
        state = io::summarize(io::Journal::replay(dir_.journal(), &torn));
      } catch (const FormatError& e) {
        throw FormatError(fmt::format("{} (the journal is damaged: remove {} to start over; every item is then "
                                      "converted again)", e.what(), dir_.root.string()));
      }
      if (!state.job && (!state.done.empty() || !state.failures.empty() || !state.parts.empty()))  // whose items?
        throw FormatError(fmt::format("{}: records of items but none of their job (the journal is damaged: remove {} "
                                      "to start over; every item is then converted again)", dir_.journal().string(), dir_.root.string()));
      bool legacy_labels = false;
      if (state.job) {
        if (const std::string why = job_difference(*state.job, identity, &legacy_labels); !why.empty())
          throw InvalidInput(fmt::format("{}: --resume with a different job: {}; run it as it was started, or remove "
                                         "{} to start over (every item is then converted again)",
                                         dir_.journal().string(), why, dir_.root.string()));
      }
      if (legacy_labels) {
        // Labels of an earlier gimforge's rule for --list: the job keeps the journal's, which its committed
        // shards carry.
        const json& stored = (*state.job)["items"];
        for (std::size_t i = 0; i < job_.items.size(); ++i) job_.items[i].label = stored[i][2].get<std::string>();
        spdlog::info("resume: the journal's item labels are kept (its batch was started by an earlier gimforge)");
      }
      own_shard_dirs();  // once the job is this one: a refused --resume left a folder of the other options behind
      for (const auto& [key, reasons] : state.failures) {
        // A source rewritten since its last failed attempt is another input: its failures are forgotten (a
        // failure "not retried" would otherwise outlive the fix), as a converted item's shard is redone.
        const auto stamp = state.failure_stamps.find(key);
        if (stamp != state.failure_stamps.end() && key.second < job_.items.size() &&
            io::file_stamp(job_.items[key.second].source) != stamp->second) {
          spdlog::info("resume: {} changed since it failed: converted again", io::printable(job_.items[key.second].source));
          continue;
        }
        failures_[key] = reasons;
      }
      for (const auto& [key, shard] : state.done) {
        if (key.second >= job_.items.size() || find_output(key.first) == nullptr) {
          spdlog::warn("resume: the journal names item {} #{}, which this job does not have (it has {} items): ignored",
                       io::printable(key.first), key.second, job_.items.size());
          continue;
        }
        try {  // a committed shard must still open, and hold what its output stores: else it is redone
          // The journal is a file on disk: the only shard path it may name is the one this item's shard has
          // (never an absolute path, '..' or another item's file).
          if (shard != dir_.shard(key.first, key.second))
            throw FormatError(fmt::format("{}: the journal names shard '{}' for this item, expected '{}'",
                                          dir_.journal().string(), io::printable(shard),
                                          dir_.shard(key.first, key.second)));
          if (const auto bad = o_.unreadable_shards.find(shard); bad != o_.unreadable_shards.end())
            throw FormatError(bad->second);
          if (const fs::file_status st = fs::symlink_status(dir_.root / shard, ec); !fs::is_regular_file(st)) {
            // Gone before the redo writes there (write_atomically follows a link to refuse a device or pipe).
            if (fs::is_directory(st)) fs::remove_all(dir_.root / shard, ec);
            else if (fs::exists(st) || fs::is_symlink(st)) fs::remove(dir_.root / shard, ec);
            throw FormatError(fmt::format("{}: not a file of this batch's own (a link, a folder, or missing)",
                                          (dir_.root / shard).string()));
          }
          const io::ShardInfo info = io::read_shard_info(dir_.root / shard);
          if (const std::string& was = info.key.source_stamp; !was.empty()) {
            const std::string& source = job_.items[key.second].source;
            if (const std::string now = io::file_stamp(source); now.empty())  // gone: the shard is all there is
              spdlog::warn("resume: {}: cannot stat its source; kept what was converted", io::printable(source));
            else if (now != was)
              throw FormatError(fmt::format("{}: the source changed since it was converted", io::printable(source)));
          }
          if (const OutputSpec* output = find_output(key.first);
              output != nullptr && info.has_representation != stores_groups(output->method))
            throw FormatError(fmt::format("{}: holds {}, output '{}' stores {}", (dir_.root / shard).string(),
                                          info.has_representation ? "a representation group" : "an image",
                                          key.first, info.has_representation ? "images" : "groups"));
          done_[key] = shard;
        } catch (const Error& e) {
          spdlog::warn("resume: redoing {} #{}: {}", key.first, key.second, e.what());
        }
      }
      for (const auto& [key, parts] : state.parts) resume_bricks(key, parts);
      if (torn > 0) spdlog::info("resume: ignored a torn last journal line");
      // Shards a killed worker was writing (never committed, never journaled).
      if (const std::size_t left = io::remove_temporary_files(dir_.root / "shards"); left > 0)
        spdlog::info("resume: removed {} unfinished shard file(s)", left);
      if (const std::size_t left = io::remove_temporary_files(dir_.root / "bricks"); left > 0)
        spdlog::info("resume: removed {} unfinished brick file(s)", left);
      remove_unfinished_archives(o_.output);
    }
    if (!exists) own_shard_dirs();
    journal_ = std::make_unique<io::Journal>(io::Journal::open(dir_.journal()));
    journal_->append({{"event", "start"}, {"job", identity}});
    return pending();
  }

  /// The next tasks of every item neither done nor out of attempts: a whole item, or a huge item's plan, its
  /// missing pieces or its finish (jobs/brick_tasks.h). Forgets the tasks of earlier rounds.
  [[nodiscard]] std::vector<mpi::WorkItem> pending() {
    tasks_.clear();
    ++round_;
    std::vector<mpi::WorkItem> out;
    const std::size_t n = job_.items.size();
    for (std::size_t oi = 0; oi < job_.outputs.size(); ++oi) {
      for (std::size_t i = 0; i < n; ++i) {
        const io::JournalKey key{job_.outputs[oi].name, i};
        if (done_.contains(key) || out_of_attempts(key)) continue;
        if (by_bricks(oi, i))
          next_tasks(oi, i, out);
        else
          out.push_back(task(TaskKind::Whole, oi, i));
      }
    }
    return out;
  }

  /// The next tasks of huge item i of output oi, appended to `out`: its plan, or after the plan the item
  /// whole (no bricks after all), its missing pieces, or its finish.
  void next_tasks(std::size_t oi, std::size_t i, std::vector<mpi::WorkItem>& out) {
    const Staged& s = staged_[{job_.outputs[oi].name, i}];
    if (!s.brick_faces) {
      out.push_back(task(TaskKind::Plan, oi, i));
    } else if (s.brick_faces->empty()) {
      out.push_back(task(TaskKind::Whole, oi, i));
    } else {
      const std::size_t before = out.size();
      for (std::size_t b = 0; b < s.brick_faces->size(); ++b)
        if ((*s.brick_faces)[b] > 0 && !s.pieces.contains(b)) out.push_back(task(TaskKind::Piece, oi, i, b));
      if (out.size() == before) out.push_back(task(TaskKind::Finish, oi, i));
    }
  }

  /// The tasks the results so far made ready (the scheduler's follow_ups).
  [[nodiscard]] std::vector<mpi::WorkItem> ready() { return std::exchange(ready_, {}); }

  void on_result(const mpi::WorkResult& r) {
    const auto found = tasks_.find(r.id);
    if (found == tasks_.end()) throw LibraryError(fmt::format("batch: a result for task {}, which was never sent", r.id));
    const Task t = found->second;
    tasks_.erase(found);
    const OutputSpec& output = job_.outputs[t.output];
    const std::uint64_t index = t.index;
    const io::JournalKey key{output.name, index};
    if (t.kind != TaskKind::Whole && t.generation != generation_[key]) return;  // of a plan since replaced
    if (r.ok && (t.kind == TaskKind::Plan || t.kind == TaskKind::Piece)) {
      brick_done(t, key, r.payload);
      return;
    }
    if (!r.ok && r.payload.starts_with(kNoSpaceReason))
      throw IoError(fmt::format("{} ({}): {}; the batch stopped (the {} items done are kept: make room and run it again "
                                "with --resume)",
                                job_.items[index].source, output.name, r.payload.substr(kNoSpaceReason.size()),
                                done_.size()));
    if (!r.ok && out_of_attempts(key)) {  // a task of an item that has already failed for good
      spdlog::debug("{} ({}): {}", job_.items[index].source, output.name, r.payload);
      return;
    }
    if (!r.ok && r.payload.starts_with(kStaleBricksReason) && replans_[key] < kMaxReplans) {
      // A plan or piece unusable (the source changed, a work file damaged): plan again at once, no attempt lost.
      ++replans_[key];
      ++generation_[key];
      staged_.erase(key);
      spdlog::warn("{} ({}): {}", job_.items[index].source, output.name, r.payload);
      ready_.push_back(task(TaskKind::Plan, t.output, t.index));
      return;
    }
    if (!r.ok && failed_round_.contains(key) && failed_round_[key] == round_) {
      // Another task of the same item failed in this round: one attempt per item and round.
      spdlog::warn("{} ({}): {}", job_.items[index].source, output.name, r.payload);
      return;
    }
    if (r.ok) {
      journal_->append({{"event", "done"}, {"output", output.name}, {"name", job_.items[index].name},
                        {"index", index}, {"shard", dir_.shard(output.name, index)}});
      done_[key] = dir_.shard(output.name, index);
      ++completed_;
      if (t.kind == TaskKind::Finish) remove_brick_dir(output.name, index);  // its plan and pieces have served
    } else {
      // Planned again too often in this run: an ordinary failed attempt, with the cause as its reason.
      const std::string reason = r.payload.starts_with(kStaleBricksReason)
                                     ? r.payload.substr(kStaleBricksReason.size()) + " (its bricks were planned again twice)"
                                     : r.payload;
      const bool was_out = out_of_attempts(key);  // another task of the same item failed for good already
      failed_round_[key] = round_;
      failures_[key].push_back(reason);
      journal_->append({{"event", "failed"}, {"output", output.name}, {"name", job_.items[index].name},
                        {"index", index}, {"attempt", failures_[key].size()}, {"reason", reason}, {"stamp", t.stamp}});
      spdlog::warn("{} ({}): attempt {} failed: {}", job_.items[index].source, output.name, failures_[key].size(),
                   reason);
      if (!was_out && out_of_attempts(key)) ++failed_;  // an attempt that will be retried is no failure yet
    }
  }

  /// Merges every output into the archive (atomically) and removes the work directory. Returns the number
  /// of failed items.
  std::size_t merge() {
    std::vector<io::MergeInput> inputs;
    std::size_t failed = 0;
    for (const OutputSpec& output : job_.outputs) {
      io::MergeInput in;
      in.output = output.name;
      in.attributes = output.method.attributes();
      in.groups = stores_groups(output.method);
      for (std::size_t i = 0; i < job_.items.size(); ++i) {
        const io::JournalKey key{output.name, i};
        const CollectionItem& item = job_.items[i];
        in.sources[i] = item.source;  // as this run spells it, also for a shard of a run started elsewhere
        if (const auto it = done_.find(key); it != done_.end()) {
          in.shards.push_back(dir_.root / it->second);
        } else {
          const auto f = failures_.find(key);
          in.failed.push_back({{output.name, item.name, item.source, item.label, i},
                               f == failures_.end() ? "not converted" : f->second.back(),
                               f == failures_.end() ? 0 : static_cast<int>(f->second.size())});
          ++failed;
        }
      }
      inputs.push_back(std::move(in));
    }
    io::CreationInfo info;
    info.creator = o_.command_line;
    info.parameters_json = job_json(job_).dump();
    io::write_batch_archive(o_.output, info, inputs);
    journal_.reset();
    std::error_code ec;
    fs::remove_all(dir_.root, ec);
    if (ec) spdlog::warn("{}: could not remove the work directory: {}", dir_.root.string(), ec.message());
    return failed;
  }

  [[nodiscard]] std::size_t done_count() const { return done_.size(); }
  /// How many items (output, index) the tasks `items` (this round's, from pending) belong to.
  [[nodiscard]] std::size_t items_in(const std::vector<mpi::WorkItem>& items) const {
    std::set<io::JournalKey> keys;
    for (const mpi::WorkItem& w : items)
      if (const auto t = tasks_.find(w.id); t != tasks_.end()) keys.insert({job_.outputs[t->second.output].name, t->second.index});
    return keys.size();
  }
  /// Whether some pending item goes by brick tasks.
  [[nodiscard]] bool has_brick_items() const {
    return std::any_of(by_bricks_.begin(), by_bricks_.end(), [](const auto& entry) { return entry.second; });
  }
  /// True when --resume found this job's archive finished (its work directory is then removed): nothing to do.
  [[nodiscard]] bool complete() const { return complete_; }
  [[nodiscard]] std::size_t total() const { return job_.items.size() * job_.outputs.size(); }
  [[nodiscard]] std::size_t completed() const { return completed_; }
  [[nodiscard]] std::size_t failed() const { return failed_; }

 private:
  [[nodiscard]] const OutputSpec* find_output(const std::string& name) const {
    for (const OutputSpec& o : job_.outputs)
      if (o.name == name) return &o;
    return nullptr;
  }

  /// Whether the archive at the output records this job's identity (the one its merge writes).
  [[nodiscard]] bool written_by_this_job() const {
    const io::ArchiveInfo info = io::Archive::open(o_.output).info();
    const json stored = json::parse(info.creation_parameters, nullptr, /*allow_exceptions=*/false);
    return job_difference(stored, job_json(job_)).empty();
  }

  /// Whether item i of output oi goes by brick tasks (asked once per run: it opens the file's header).
  [[nodiscard]] bool by_bricks(std::size_t oi, std::size_t i) {
    const io::JournalKey key{job_.outputs[oi].name, i};
    if (const auto it = by_bricks_.find(key); it != by_bricks_.end()) return it->second;
    const bool bricks = converts_by_brick_tasks(job_.items[i].source, job_.outputs[oi].method);
    if (bricks) spdlog::info("{} ({}): converted by brick tasks", job_.items[i].source, job_.outputs[oi].name);
    return by_bricks_[key] = bricks;
  }

  /// A work item for task `kind` of item i of output oi, registered under a fresh id. Cost (the dispatch
  /// order, largest first): the file's triangles for a whole item and for a plan (the plan gates its
  /// pieces), a brick's faces for a piece, a quarter of the file for a finish.
  mpi::WorkItem task(TaskKind kind, std::size_t oi, std::size_t i, std::size_t brick = 0) {
    const OutputSpec& output = job_.outputs[oi];
    const CollectionItem& item = job_.items[i];
    auto [it, inserted] = triangles_.try_emplace(item.source, 0);
    if (inserted) it->second = io::estimate_triangles(item.source);
    std::uint64_t cost = it->second;
    json payload = {{"output", output_json(output)}, {"index", i}, {"name", item.name},
                    {"source", item.source}, {"label", item.label}, {"shard", dir_.shard(output.name, i)},
                    {"metric_samples", job_.metric_samples}, {"metric", job_.metric},
                    {"task", kTaskNames[static_cast<std::size_t>(kind)]}};
    if (kind != TaskKind::Whole) payload["bricks"] = dir_.bricks(output.name, i);
    if (kind == TaskKind::Piece) {
      payload["brick"] = brick;
      cost = staged_.at({output.name, i}).brick_faces->at(brick);
    }
    if (kind == TaskKind::Finish) cost /= 4;
    if (kind == TaskKind::Plan) fresh_brick_dir(output.name, i);
    const std::uint64_t id = next_task_++;
    tasks_[id] = {kind, oi, i, brick, generation_[{output.name, i}], io::file_stamp(item.source)};
    // How long rank 0 waits for this task's worker (--worker-timeout): conversions (whole, finish) are
    // bounded by --item-timeout too; planning and decimation only by an explicit --worker-timeout.
    const bool converts = kind == TaskKind::Whole || kind == TaskKind::Finish;
    return {id, cost, payload.dump(), milliseconds_up(converts ? worker_timeout_in_effect(o_) : std::max(0.0, o_.worker_timeout))};
  }

  /// A plan or a piece is done: journaled, and the item's next tasks made ready.
  void brick_done(const Task& t, const io::JournalKey& key, const std::string& payload) {
    const CollectionItem& item = job_.items[t.index];
    const fs::path dir = dir_.bricks(key.first, key.second);
    Staged& s = staged_[key];
    std::string part = "plan";
    fs::path file = brick_plan_file(dir);
    if (t.kind == TaskKind::Plan) {
      s = {};
      s.brick_faces = json::parse(payload).at("brick_faces").get<std::vector<std::uint64_t>>();
    } else {
      part = std::to_string(t.brick);
      file = brick_piece_file(dir, t.brick);
      s.pieces.insert(t.brick);
    }
    journal_->append({{"event", "brick"}, {"output", key.first}, {"name", item.name}, {"index", key.second},
                      {"part", part}, {"file", file.string()}});
    if (out_of_attempts(key) || !s.brick_faces) return;  // another task of the item failed for good
    // After the plan: every piece (or the item whole). After a piece: the finish once no piece is missing
    // (the others are in flight).
    if (t.kind == TaskKind::Piece)
      for (std::size_t b = 0; b < s.brick_faces->size(); ++b)
        if ((*s.brick_faces)[b] > 0 && !s.pieces.contains(b)) return;
    next_tasks(t.output, t.index, ready_);
  }

  /// Whether every folder of ROOT/`relative` (bricks/<output>/<index>, shards/<output>) is a real folder
  /// (not a link: the work directory is the batch's own, and nothing in it may lead outside). Returns the
  /// first component that is not, or an empty path.
  [[nodiscard]] fs::path foreign_component(const fs::path& relative) const {
    fs::path at = dir_.root;
    for (const fs::path& part : relative) {
      at /= part;
      std::error_code ec;
      const fs::file_status st = fs::symlink_status(at, ec);
      if (fs::exists(st) && !fs::is_directory(st)) return at;  // a link (to anything), a file, a FIFO
    }
    return {};
  }

  /// Makes the item's brick folder an empty folder of the batch's own before a new plan: whatever stands
  /// where one of its folders should be is removed (a link itself, never what it points to), and the earlier
  /// plan's entries go (remove_all does not follow links inside).
  void fresh_brick_dir(const std::string& output, std::uint64_t index) {
    own_dir(dir_.bricks(output, index));
    std::error_code ec;
    for (const fs::directory_entry& e : fs::directory_iterator(dir_.root / dir_.bricks(output, index), ec))
      fs::remove_all(e.path(), ec);
  }

  /// Makes ROOT/`relative` a folder of the batch's own: whatever stands where one of its folders should be
  /// (a link, a file) is removed, the link itself, never what it points to.
  void own_dir(const fs::path& relative) {
    std::error_code ec;
    for (fs::path bad = foreign_component(relative); !bad.empty(); bad = foreign_component(relative)) {
      spdlog::warn("{}: not a folder of this batch's own; removed", bad.string());
      if (!fs::remove(bad, ec) || ec) return;  // writing into it then fails, naming it
    }
    fs::create_directories(dir_.root / relative, ec);
  }

  /// Removes the item's brick folder, never through a link.
  void remove_brick_dir(const std::string& output, std::uint64_t index) {
    std::error_code ec;
    if (const fs::path bad = foreign_component(dir_.bricks(output, index)); !bad.empty())
      fs::remove(bad, ec);
    else
      fs::remove_all(dir_.root / dir_.bricks(output, index), ec);
  }

  /// --resume: the plan and pieces the journal lists for an unfinished item, kept when they still read back
  /// and the source is unchanged.
  void resume_bricks(const io::JournalKey& key, const std::map<std::string, std::string>& parts) {
    if (key.second >= job_.items.size() || find_output(key.first) == nullptr) {
      spdlog::warn("resume: the journal names brick files of {} #{}, which this job does not have; ignored",
                   io::printable(key.first), key.second);
      return;
    }
    if (done_.contains(key)) return;
    const fs::path dir = dir_.bricks(key.first, key.second);
    const std::string& source = job_.items[key.second].source;
    const auto plan = parts.find("plan");
    if (plan == parts.end()) return;
    if (const fs::path bad = foreign_component(dir_.bricks(key.first, key.second)); !bad.empty()) {
      spdlog::warn("resume: planning {} #{} again: {} is not a folder of this batch's own", key.first, key.second,
                   bad.string());
      return;
    }
    Staged s;
    BrickPlanSummary plan_read;
    try {
      if (plan->second != brick_plan_file(dir).string())
        throw FormatError(fmt::format("the journal names plan '{}', expected '{}'", io::printable(plan->second),
                                      brick_plan_file(dir).string()));
      plan_read = read_brick_plan(dir_.root / dir, source);
      s.brick_faces = plan_read.brick_faces;
    } catch (const std::exception& e) {
      spdlog::warn("resume: planning {} #{} again: {}", key.first, key.second, e.what());
      return;
    }
    for (const auto& [part, file] : parts) {
      if (part == "plan") continue;
      try {
        std::size_t b = 0;
        const auto [end, ec] = std::from_chars(part.data(), part.data() + part.size(), b);
        if (ec != std::errc{} || end != part.data() + part.size() || b >= s.brick_faces->size())
          throw FormatError(fmt::format("the journal names brick '{}'", io::printable(part)));
        if (file != brick_piece_file(dir, b).string())
          throw FormatError(fmt::format("the journal names piece '{}', expected '{}'", io::printable(file),
                                        brick_piece_file(dir, b).string()));
        check_brick_piece(dir_.root / dir, b, plan_read);
        s.pieces.insert(b);
      } catch (const std::exception& e) {
        spdlog::warn("resume: decimating {} #{} brick {} again: {}", key.first, key.second, io::printable(part), e.what());
      }
    }
    // The pieces not kept go (a folder or link in a piece's place would stop the new piece's commit).
    for (std::size_t b = 0; b < s.brick_faces->size(); ++b)
      if (!s.pieces.contains(b)) {
        std::error_code ec;
        fs::remove_all(dir_.root / brick_piece_file(dir, b), ec);
      }
    spdlog::info("resume: {} #{}: plan and {} of its pieces kept", key.first, key.second, s.pieces.size());
    staged_[key] = std::move(s);
  }

  [[nodiscard]] int attempts(const io::JournalKey& key) const {
    const auto it = failures_.find(key);
    return it == failures_.end() ? 0 : static_cast<int>(it->second.size());
  }

  /// No attempt is left: --max-retries used up, or a failure that a retry cannot mend.
  [[nodiscard]] bool out_of_attempts(const io::JournalKey& key) const {
    const auto it = failures_.find(key);
    if (it == failures_.end()) return false;
    return static_cast<int>(it->second.size()) >= 1 + o_.max_retries ||
           std::any_of(it->second.begin(), it->second.end(), is_final);
  }

  const BatchOptions& o_;
  BatchJob job_;
  WorkDir dir_;
  std::unique_ptr<io::Journal> journal_;
  std::map<io::JournalKey, std::string> done_;
  std::map<io::JournalKey, std::vector<std::string>> failures_;
  std::map<io::JournalKey, Staged> staged_;     // huge items: their brick tasks so far
  std::map<io::JournalKey, bool> by_bricks_;    // whether an item goes by brick tasks
  std::map<std::string, std::uint64_t> triangles_;  // estimated per source (dispatch costs)
  std::map<std::uint64_t, Task> tasks_;         // tasks dispatched this round, by work item id
  std::map<io::JournalKey, std::uint64_t> generation_;  // plans made of an item in this run (void older results)
  std::map<io::JournalKey, int> replans_;       // plans made again because the last was unusable
  std::map<io::JournalKey, int> failed_round_;  // the round of an item's last counted failure
  int round_{0};
  std::uint64_t next_task_{0};
  std::vector<mpi::WorkItem> ready_;            // tasks made ready by results, for the scheduler
  std::size_t completed_{0}, failed_{0};
  bool complete_{false};
};

}  // namespace

std::string worker_timeout_problem(const BatchOptions& options) {
  if (options.worker_timeout > 0.0 && options.item_timeout > 0.0 && options.worker_timeout < options.item_timeout + 10.0)
    return fmt::format("--worker-timeout {:g} must be at least --item-timeout {:g} + 10 s (the cancellation comes at the "
                       "item's next step, then its shard is written): a healthy worker would be given up on",
                       options.worker_timeout, options.item_timeout);
  return {};
}

BatchOutcome run_batch(const mpi::Comm& comm, const BatchOptions& options, const std::function<bool()>& stop_requested) {
  const WorkDir dir{fs::path(options.output + ".work")};

  std::unique_ptr<BatchCoordinator> master;
  std::unique_ptr<io::WriterLock> lock;  // rank 0: held until the archive is merged (or the run stops)
  std::vector<mpi::WorkItem> items;
  std::string error;
  if (comm.rank() == 0) {
    try {
      if (!(options.item_timeout >= 0.0 && options.item_timeout <= 1e9))  // CLI11 lets "nan" through
        throw InvalidInput(fmt::format("--item-timeout {} is not a number of seconds in [0, 1e9]", options.item_timeout));
      if (!(options.worker_timeout <= 1e9) || (options.worker_timeout < 0.0 && options.worker_timeout != -1.0))
        throw InvalidInput(fmt::format("--worker-timeout {} is not a number of seconds in [0, 1e9]", options.worker_timeout));
      if (const std::string why = worker_timeout_problem(options); !why.empty()) throw InvalidInput(why);
      // Before any work: the archive can be written there, and no other batch (or convert, or a --resume
      // of this job) writes it now; then the job, whose inputs the archive must not be.
      io::check_can_create(output_target(options.output));
      lock = lock_archive(options.output, options.wait);
      BatchJob job = make_job(options);
      for (const OutputSpec& o : job.outputs)  // every item of the output needs as much: refuse it whole
        check_conversion_memory("output '" + o.name + "'", o.method, job.metric ? std::max<std::size_t>(1000, job.metric_samples) : 0);
      std::vector<fs::path> inputs{options.list, options.job};
      for (const CollectionItem& item : job.items) inputs.emplace_back(item.source);
      refuse_output_over_inputs(options.output, inputs);
      refuse_foreign_work_dir(dir.root, inputs);
      master = std::make_unique<BatchCoordinator>(options, std::move(job), dir);
      items = master->prepare();
    } catch (const Error& e) {
      error = e.what();
    }
  }
  std::string status = !error.empty() ? "error" : (master && master->complete() ? "complete" : "run");
  comm.broadcast(status, 0);
  if (status == "error") {
    if (comm.rank() == 0) throw InvalidInput(error);  // main() prints it
    return {BatchStatus::Error};
  }
  if (status == "complete") {
    if (comm.rank() != 0) return {BatchStatus::AlreadyComplete};
    // The finished archive's own verdict: a run that ended with failed items ended with exit code 3, and so
    // does every --resume of it.
    std::size_t failed = 0, converted = 0;
    try {
      for (const io::BatchOutputSummary& output : io::read_batch_summary(options.output)) {
        failed += output.failed_names.size();
        converted += output.count;
      }
    } catch (const Error& e) {
      throw InvalidInput(fmt::format("{} (--resume found the archive, so it should be a finished batch)", e.what()));
    }
    fmt::print("{}: already complete; nothing to do: {} items converted, {} failed\n",
               options.output, converted, failed);
    if (failed > 0) return {BatchStatus::Partial, converted, converted + failed, failed};
    return {BatchStatus::AlreadyComplete, converted, converted, 0};
  }

  const EmbreeDevice device("threads=1");
  mpi::SchedulerOptions so;
  so.stop_requested = [&stop_requested, progress = options.progress, said = false]() mutable {
    if (!stop_requested || !stop_requested()) return false;
    if (!std::exchange(said, true) && progress)  // items in flight may take minutes: say so now, not after
      fmt::print(stderr, "gimforge batch: stopping: no new item is sent; the items in flight finish first (up to 5 "
                         "minutes; a second Ctrl-C ends at once, exit 130)\n");
    return true;
  };
  so.group_below_cost = 2000;  // meshes below 2K triangles take well under a second: send several at once
  if (master) {
    so.follow_ups = [&] { return master->ready(); };
    // Brick tasks: one message in flight per worker, so that no piece waits behind a long task on a busy
    // worker (and holds back its item's finish) while another worker idles.
    if (master->has_brick_items()) so.in_flight_per_worker = 1;
  }
  std::unique_ptr<BatchProgress> progress;
  if (master) {
    progress = std::make_unique<BatchProgress>(options.progress, master->done_count(), master->total());
    so.progress = [&](std::size_t, std::size_t) { progress->update(master->completed(), master->failed()); };
    if (options.progress)
      fmt::print(stderr, "gimforge batch: {} items to convert ({} already done) on {} rank(s)\n", master->items_in(items),
                 master->done_count(), comm.size());
  }
  const mpi::WorkFunction work = batch_worker(device, dir.root, options.item_timeout);
  // Rounds: failed items are retried up to --max-retries times (the journal counts attempts across runs).
  bool stopped = false;
  std::vector<int> lost;     // rank 0: workers given up on (--worker-timeout): no collective may follow
  so.on_worker_lost = [&lost](int rank) { lost.push_back(rank); };
  bool unresponsive = false;  // rank 0: a rank missed a barrier between rounds: no collective may follow
  // With a worker timeout, rank 0 waits that long at the barriers between rounds too (the others as long
  // as it takes): a rank stopped or hung outside any item would otherwise hold every rank there forever.
  const double wait = worker_timeout_in_effect(options);
  const auto all_arrive = [&] {
    return !(wait > 0.0) ||
           comm.barrier_within(comm.rank() == 0 ? milliseconds_up(wait) : std::chrono::milliseconds::max());
  };
  bool fatal = false;  // rank 0: a shard or the journal could not be written (disk full, ...): stop everybody
  for (int round = 0; round <= std::max(0, options.max_retries); ++round) {
    if (!all_arrive()) {  // rank 0 alone; the others wait in the barrier until the job is ended
      unresponsive = true;
      stopped = !items.empty();
      break;
    }
    if (comm.allreduce(std::uint64_t{items.size()}, mpi::ReduceOp::kMax) == 0) break;
    mpi::SchedulerReport report;
    try {
      report = mpi::run_master_worker(
          comm, std::move(items), work, [&](const mpi::WorkResult& r) { master->on_result(r); }, so);
    } catch (const Error& e) {  // the workers were told to stop. Said now, before the collective below lets them
      if (comm.rank() != 0) throw;  // end: one whose shard did not close (a full disk) ends without MPI_Finalize
      spdlog::error("{}", e.what());  // (h5::file_close_failed), and the launcher then ends every rank at once
      fatal = true;
    }
    // Rank 0 alone, after a lost worker or a rank that missed the barrier (one idle since its last item may
    // have stopped): the others wait in a collective until the job is ended.
    if (!lost.empty() || !all_arrive()) {
      unresponsive = lost.empty();
      if (!fatal) items = master->pending();  // what a retry would run: nothing left means the job is done
      stopped = report.stopped || !items.empty();
      break;
    }
    if (comm.allreduce(std::uint64_t{(report.stopped && master) || fatal ? 1u : 0u}, mpi::ReduceOp::kMax) != 0) {
      stopped = true;
      break;
    }
    if (master) items = master->pending();
  }
  if (lost.empty() && !unresponsive && !all_arrive()) unresponsive = true;  // e.g. stopped after its last item
  if (comm.rank() != 0) return {BatchStatus::Worker};
  const auto finish = [&]() -> BatchOutcome {
    if (fatal) return {BatchStatus::Error, 0, 0, 0, lost, unresponsive};  // said above; a lost rank: every rank ends
    progress->update(master->completed(), master->failed(), true);
    if (stopped) return {BatchStatus::Stopped, master->done_count(), master->total(), 0, lost, unresponsive};
    const std::size_t failed = master->merge();
    fmt::print("{}: {} items converted, {} failed\n", options.output, master->total() - failed, failed);
    fmt::print("load it with gimforge's examples/load_archive.py: python3 examples/load_archive.py {} (from the "
               "source tree)\n", options.output);
    return {failed > 0 ? BatchStatus::Partial : BatchStatus::Done, master->total() - failed, master->total(), failed, lost,
            unresponsive};
  };
  if (lost.empty() && !unresponsive) return finish();
  // A lost rank never takes part again: neither main()'s MPI_Finalize nor the others' collective can end,
  // so an error from here on is printed here and ends every rank.
  try {
    return finish();
  } catch (const std::exception& e) {
    fmt::print(stderr, "gimforge: error: {}\ngimforge batch: ending every rank (a rank stopped answering)\n", e.what());
    comm.abort(1);
  }
}

}  // namespace gimforge::jobs
