#pragma once
/// \file batch_job.h
/// What a batch converts: the collection (meshes with names and labels) and the outputs (method and
/// resolution), from the command line (`--input DIR` / `--list FILE` plus method options) or from a TOML
/// job file (`--job JOB.toml`, format in docs/cli.md "Batch job files").
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/batch_types.h"
#include "jobs/method.h"

namespace gimforge::jobs {

struct BatchOptions;  // jobs/batch_run.h

/// The largest geometry image size (`--size`, job files' `size`): an 8193 x 8193 image is 805 MB of
/// positions; a larger one would only run out of memory after its work.
inline constexpr std::uint32_t kMaxGimSize = 8193;

/// One representation every mesh of the collection is converted to.
struct OutputSpec {
  std::string name;       ///< archive group /batch/<name>; default MethodOptions::default_output_name()
  MethodOptions method;   ///< the method and its options (jobs/method.h)

  /// Throws InvalidInput naming the output and the bad field.
  void check() const;
};

/// One mesh of the collection.
struct CollectionItem {
  std::string name;    ///< unique in the job: path relative to the collection root without extension
  std::string source;  ///< path
  std::string label;   ///< class label (folder name, fixed, or empty)
};

struct BatchJob {
  std::vector<CollectionItem> items;  ///< sorted by source path
  std::vector<OutputSpec> outputs;    ///< at least one, distinct names
  std::size_t metric_samples{200'000};
  bool metric{true};                  ///< false (--no-metric, `metric = false`): no fidelity report per item

  /// All (output, item) pairs as archive keys: index = position of the item in `items`.
  [[nodiscard]] std::vector<io::ItemKey> keys() const;
};

/// How items are labelled.
enum class LabelRule { Folder, None, Fixed };

/// A collection source: a directory searched recursively for .ply .obj .off .stl files (names relative to
/// it), or a list file with one mesh path per line (relative paths resolved against the list's folder;
/// blank lines and lines starting with '#' skipped; names are the file stems).
struct CollectionSpec {
  std::filesystem::path input{};  ///< directory, or
  std::filesystem::path list{};   ///< list file
  LabelRule label_rule{LabelRule::Folder};
  std::string label{};            ///< LabelRule::Fixed
  std::string prefix{};           ///< prepended to item names ("" or e.g. "train/")
};

/// Finds the meshes of the collections, sorted by path. Throws IoError for a missing directory or list,
/// InvalidInput for an empty collection or two items with the same name (both named).
[[nodiscard]] std::vector<CollectionItem> discover(const std::vector<CollectionSpec>& collections);

/// Reads a TOML job file: `metric_samples = N` and `metric = false` (optional), one or more `[[collection]]` tables
/// (`input` or `list`, optional `label = "folder" | "none" | "<fixed>"`, `prefix`), one or more
/// `[[output]]` tables (`method`, `name`, `size`, `max_augmentations`, `domain`, `n`). Relative paths are
/// resolved against the job file's folder. Throws FormatError naming the file, line and cause.
[[nodiscard]] BatchJob load_job_file(const std::filesystem::path& path);

/// The job of `batch`'s options: --job's file (with --metric-samples and --no-metric applied), or the one
/// output of --input or --list. Throws InvalidInput for options that do not go together, and as discover
/// and load_job_file do.
[[nodiscard]] BatchJob make_job(const BatchOptions& o);

/// The job's identity for the journal and the archive's `creation_parameters`: items (name, source, label)
/// and outputs. A resumed run must describe the same job.
[[nodiscard]] nlohmann::json job_json(const BatchJob& job);

/// An output in that identity: the fields journals have always had (so that jobs journaled by earlier
/// versions stay resumable), and each method's own options.
[[nodiscard]] nlohmann::json output_json(const OutputSpec& o);
[[nodiscard]] OutputSpec output_from_json(const nlohmann::json& j);

/// How the job `now` (job_json) differs from `stored` (a journal's or an archive's), in words ("item 4 was
/// a/fist.ply, now a/kitten.ply"); empty when they are the same job. Sources are compared as files (`c2/a.ply`,
/// `./c2/a.ply` and its absolute path are one; a relative one read from the directory its job was started in,
/// job_json's `directory`, so that a resume from another directory is the same job), and a stored label that differs only because an earlier
/// gimforge labelled `--list` items by the line's last directory part (".." for "../a.ply") is no difference:
/// such a job keeps the stored labels (`legacy_labels`, set when that happened).
[[nodiscard]] std::string job_difference(const nlohmann::json& stored, const nlohmann::json& now,
                                         bool* legacy_labels = nullptr);

}  // namespace gimforge::jobs
