#pragma once
/// \file batch_archive.h
/// The consolidated batch archive: the merge of a batch's shards (io/batch_shard.h) into one gimforge
/// archive laid out for loading (docs/archive.md, "Batch archives"). Per output (method + resolution):
///   /batch/<output>/data            float32 (N, C, H, W), one item per chunk, shuffle + gzip
///   /batch/<output>/mask            uint8 (N, 1, H, W) (only when some item has a mask)
///   /batch/<output>/sideband        int32 (S, 3), geometry images: every item's sideband, item k's rows
///                                   sideband_offsets[k] .. sideband_offsets[k + 1] (int64 (N + 1))
///   /batch/<output>/items/<k>       instead of data and mask, for methods whose results differ in size
///                                   (relief maps): item k's representation group, as `convert` writes it
///   /batch/<output>/names, sources, labels      strings (N)
///   /batch/<output>/index           int64 (N): ItemKey::index
///   /batch/<output>/label_index     int32 (N) into label_names (-1: no label); label_names strings
///   /batch/<output>/metrics/<key>   float64 (N), NaN where an item lacks the metric
///   /batch/<output>/failed/{names, sources, labels, reasons} strings, {index int64, attempts int32}
/// Items are stored in ItemKey::index order, whatever the order of the shards, so the arrays do not depend
/// on how many ranks converted them or in which order they finished.
#include <cstdint>
#include <filesystem>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "io/archive.h"
#include "io/batch_shard.h"
#include "io/batch_types.h"

namespace gimforge::io {

/// An item that could not be converted (after all its attempts).
struct FailedItem {
  ItemKey key{};
  std::string reason{};  ///< the last failure's message (bad mesh, exception, timeout, ...)
  int attempts{0};     ///< how many times it was tried
};

/// Everything the merge stores for one output.
struct MergeInput {
  std::string output{};                            ///< the group name /batch/<output>
  std::vector<std::filesystem::path> shards{};     ///< committed shards of this output, any order
  std::vector<FailedItem> failed{};                ///< items of this output that failed, any order
  std::map<std::string, std::string> attributes{}; ///< string attributes of the group: method, size, domain, ...
  bool groups{false};                              ///< items are representation groups (items/<k>), not images
  /// By item index, the source to record (the job's spelling of it), in place of the one a shard holds: a
  /// run started in another directory recorded it relative to that one. Items not named keep theirs.
  std::map<std::uint64_t, std::string> sources{};
};

/// Merges the shards of every output into the archive `archive`, which is written to
/// temporary_path(archive) (io/atomic_file.h) in the same directory and renamed into place only when
/// complete: an existing archive at `archive` stays intact until then, and no failure leaves a partial
/// file at either name. The root carries the usual archive attributes from `info` (io/archive.h).
///
/// Everything is checked before the file is created, shard by shard from metadata only (pixels are then
/// streamed one item at a time, so memory does not grow with N). Throws
/// - InvalidInput for an invalid or repeated output name, a shard or failed item whose key names another
///   output, an index or item name that occurs twice in an output (among shards and failed items: no item
///   is ever stored twice), items of one output with different (C, H, W) ("...: item 'NAME' (index I,
///   shard PATH) has shape (3, 129, 129), item 'FIRST' has (3, 257, 257)"), an attribute called `count`
///   or `failed_count`, or an invalid metric name;
/// - FormatError (read_shard_info, read_shard) naming a missing or damaged shard;
/// - IoError or LibraryError when the archive cannot be written or committed.
void write_batch_archive(const std::filesystem::path& archive, const CreationInfo& info,
                         std::span<const MergeInput> outputs);

/// What one output of a batch archive holds (read back for tests, reports and the CLI).
struct BatchOutputSummary {
  std::string output;                             ///< group name under /batch
  std::uint64_t count{0};                         ///< N, the converted items
  h5::Dims item_shape;                            ///< (C, H, W) of every item; empty when N = 0
  bool has_mask{false};                           ///< whether /batch/<output>/mask exists
  bool groups{false};                             ///< items are groups items/<k> (relief maps), not images
  std::vector<std::string> names;                 ///< item names in storage (index) order
  std::vector<std::uint64_t> indices;             ///< their ItemKey::index, increasing
  std::vector<std::string> label_names;           ///< the sorted distinct non-empty labels
  std::vector<std::string> metric_keys;           ///< names under metrics/, sorted
  std::vector<std::string> failed_names;          ///< failed items, in index order
  std::map<std::string, std::string> attributes;  ///< the string attributes of the group (MergeInput::attributes)
};

/// Reads the summary of every output of the batch archive at `archive`, sorted by output name.
/// Throws what Archive::open throws, FormatError "PATH: no batch outputs (no /batch group)" for another
/// kind of archive, and FormatError naming the archive and dataset when an output is inconsistent
/// (missing dataset, lengths that differ from `count`).
[[nodiscard]] std::vector<BatchOutputSummary> read_batch_summary(const std::filesystem::path& archive);
/// The same for an open archive.
[[nodiscard]] std::vector<BatchOutputSummary> read_batch_summary(const Archive& archive);
/// The summary of output `name` alone, checked as read_batch_summary checks every output (what `ls` and the
/// XDMF sidecar read before they describe it).
[[nodiscard]] BatchOutputSummary read_batch_output(const Archive& archive, const std::string& name);

}  // namespace gimforge::io
