#pragma once
/// \file batch_types.h
/// Plain data shared by the batch pipeline (jobs/batch_*.h), its shard files and the consolidated archive
/// (io/batch_shard.h, io/batch_archive.h). No behaviour here.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace gimforge::io {

/// Identity of one unit of batch work: one mesh converted for one output (method + resolution).
/// `index` is the item's position in the collection sorted by `source` (stable, independent of ranks and
/// scheduling): the consolidated archive stores items in this order.
struct ItemKey {
  std::string output{};  ///< output name, e.g. "gim_257" or "sphere_octa_128" (a group of the archive)
  std::string name{};    ///< item name (unique within the collection), e.g. "chair/0001"
  std::string source{};  ///< mesh path as given / discovered
  std::string label{};   ///< class label (e.g. the parent folder's name); may be empty
  std::uint64_t index{0};
  /// The source file's size and modification time ("SIZE:MTIME_NS", io/input_file.h file_stamp) when it was
  /// read for this item; empty when unknown (shards written before it). A resume redoes an item whose source
  /// has another stamp now.
  std::string source_stamp{};
};

/// The arrays and figures of one converted item, channel-first and ready to be stacked into (N, C, H, W).
struct ItemArrays {
  std::uint32_t channels{0};             ///< C (3 for x, y, z)
  std::uint32_t height{0};               ///< H
  std::uint32_t width{0};                ///< W
  std::vector<float> data;               ///< C·H·W values, channel-first: data[(c·H + y)·W + x]
  std::vector<std::uint8_t> mask;        ///< H·W (1 defined, 0 undefined), or empty when every sample is defined
  std::map<std::string, double> metrics; ///< psnr, hausdorff_rms, hausdorff_max, stretch_efficiency, seconds_*, ...
  std::vector<float> sample_uv;          ///< 2·H·W channel-first parameter points of the samples (adaptive
                                         ///< sampling, values in [0, 1]), or empty
  /// Geometry images: the sideband that glues the image's boundary (io::sideband_table: label, start_unit,
  /// units per cut-path, 3·q values) and its units per side; empty and 0 for other images.
  std::vector<std::int32_t> sideband{};
  std::uint32_t units_per_side{0};
};

}  // namespace gimforge::io
