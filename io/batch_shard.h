#pragma once
/// \file batch_shard.h
/// Batch shards: one small, serially written HDF5 file per converted (item, output), the unit a batch
/// worker commits. Shards are written atomically (io/atomic_file.h), so a file at a shard's path is
/// always complete; the merge (io/batch_archive.h) stacks them into the consolidated archive.
///
/// Layout (docs/archive.md, "Batch shards"):
///   /            attributes format = "gimforge-shard", format_version = 1, output, name, source, label
///                (strings), index (int64)
///   /data        float32 (C, H, W), channel-first, one chunk, shuffle + gzip
///   /mask        uint8 (H, W), 1 defined / 0 undefined (only when the item has a mask)
///   /sideband    int32 (q, 3), attribute units_per_side (geometry images; io::sideband_table)
///   /metrics     group whose float64 attributes are the item's metrics
///   /representation  instead of /data and /mask, for methods whose results differ in size from item to
///                item (relief maps): the item's representation group, laid out as in a `convert` archive
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <string_view>

#include "io/atomic_file.h"
#include "io/batch_types.h"
#include "io/hdf5.h"
#include "io/representation.h"

namespace gimforge::io {

/// Value of the root attribute `format` of a batch shard.
inline constexpr std::string_view kShardFormat = "gimforge-shard";
/// The shard layout version this build writes and reads.
inline constexpr std::int64_t kShardFormatVersion = 1;

/// Where the outputs of a batch live in the consolidated archive (/batch/<output>, io/batch_archive.h) and
/// what messages call them. An output name must be a valid name of such a group (check_item).
inline constexpr RepresentationKind kBatchOutputs{"batch", "batch output"};

/// Storage of per-item arrays in shards and in the batch archive: chunk shape `chunk` (one item per chunk)
/// and the compression of image datasets (io::ImageOptions defaults: shuffle + gzip level 4).
[[nodiscard]] h5::DatasetOptions item_storage(const h5::Dims& chunk);

/// Fills an item's representation group (see the layout above); empty for items stored as images.
using RepresentationWriter = std::function<void(h5::Group&)>;

/// A shard read back whole.
struct Shard {
  ItemKey key{};
  ItemArrays arrays{};
};

/// What a shard holds, without its pixel data (metadata reads only; cheap).
struct ShardInfo {
  ItemKey key{};
  std::uint32_t channels{0};               ///< C
  std::uint32_t height{0};                 ///< H
  std::uint32_t width{0};                  ///< W
  bool has_mask{false};                    ///< whether /mask is present
  bool has_sample_uv{false};               ///< whether /sample_uv is present
  bool has_representation{false};          ///< a /representation group instead of /data (C, H, W are 0)
  std::uint64_t sideband_rows{0};          ///< q of /sideband (geometry images), 0 without one
  std::uint32_t units_per_side{0};         ///< its units per side, 0 without one
  std::map<std::string, double> metrics{}; ///< as in ItemArrays::metrics
};

/// Throws InvalidInput "item 'NAME' (output 'OUTPUT', index I): CAUSE" unless `arrays` can be stored for
/// `key`: output and metric names are non-empty HDF5 link names without '/' (they become group and
/// dataset names of the archive), C, H, W >= 1, `data` holds C·H·W values, `mask` is empty or H·W values
/// that are 0 or 1, a sideband is a valid one (io::sideband_from_table) of a square image whose n − 1 is a
/// multiple of its units per side. With `has_representation`, the item has no image: C, H, W are 0, data and mask empty.
void check_item(const ItemKey& key, const ItemArrays& arrays, bool has_representation = false);

/// Writes the shard of item `key` to `path` atomically: the file is written to temporary_path(path),
/// closed, synced and renamed into place (replacing an existing shard); on failure the temporary file is
/// removed and `path` is untouched. Missing parent directories are created unless `parent` is kMustExist
/// (a batch's worker: its shard folder is made by the coordinator, and once the batch has merged and
/// removed it, a worker the master gave up on that wakes up late must not bring it back).
/// Throws what check_item throws, IoError when the file cannot be created or committed, LibraryError for
/// other HDF5 failures.
/// With a `representation` writer the shard holds the group it fills instead of an image (`arrays` then
/// holds only metrics).
void write_shard(const std::filesystem::path& path, const ItemKey& key, const ItemArrays& arrays,
                 const RepresentationWriter& representation = {},
                 ParentDirectory parent = ParentDirectory::kCreate);

/// Reads the key, shape, mask presence and metrics of the shard at `path` and checks its structure
/// (identity attributes, dataset types and shapes), without reading pixel data.
/// Throws FormatError "PATH: batch shard is missing" when there is no file and "PATH: unreadable batch
/// shard: CAUSE" when it is damaged, truncated, not HDF5 or not a shard.
[[nodiscard]] ShardInfo read_shard_info(const std::filesystem::path& path);

/// Reads the shard at `path` whole (as read_shard_info, plus the data and mask, which are checked: the
/// mask holds only 0 and 1). Throws FormatError as read_shard_info does, also when a data chunk cannot be
/// decoded.
[[nodiscard]] Shard read_shard(const std::filesystem::path& path);

/// Copies the /representation group of the shard at `path` to `destination` as `name` (with everything in
/// it). Throws FormatError as read_shard_info does, also when the shard has no representation group.
void copy_representation(const std::filesystem::path& path, h5::Group& destination, std::string_view name);

/// Reads everything of the shard at `path` that `batch --resume` and the merge read: read_shard_info, then
/// the pixels (read_shard) or the representation group (copy_representation into an in-memory file).
/// Throws what they throw. What jobs/cli/crash_guard.h's probe_shards runs in a child process.
void read_shard_fully(const std::filesystem::path& path);

}  // namespace gimforge::io
