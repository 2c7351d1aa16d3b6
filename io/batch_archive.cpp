/// \file batch_archive.cpp
/// The consolidated batch archive (see batch_archive.h and docs/archive.md, "Batch archives").
#include "io/batch_archive.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <set>
#include <utility>

#include <fmt/format.h>

#include "io/atomic_file.h"
#include "io/representation.h"
#include "kernels/core/errors.h"

namespace gimforge::io {
namespace {

constexpr const char* kCount = "count";
constexpr const char* kFailedCount = "failed_count";
constexpr const char* kFailed = "failed";
constexpr const char* kMetrics = "metrics";
constexpr const char* kItems = "items";

/// One converted item of an output: its committed shard and what the shard's metadata says.
struct PlannedItem {
  std::filesystem::path shard;
  ShardInfo info;
};

/// An output checked and ordered, ready to be written.
struct PlannedOutput {
  const MergeInput* input = nullptr;
  std::vector<PlannedItem> items;          ///< by ItemKey::index
  std::vector<FailedItem> failed;          ///< by ItemKey::index
  h5::Dims item_shape;                     ///< (C, H, W); empty without items or for representation items
  bool has_mask = false;
  bool has_sample_uv = false;              ///< adaptive geometry images: every item has its sample points
  std::uint64_t sideband_rows = 0;         ///< geometry images: the rows of every item's sideband together
  std::uint32_t units_per_side = 0;        ///< their units per side (one for the output), 0 without sidebands
  bool groups = false;                     ///< the items are representation groups (items/<k>), not images
  std::vector<std::string> metric_keys;    ///< sorted union over the items
  std::vector<std::string> label_names;    ///< sorted distinct non-empty labels
};

const ItemKey& key_of(const PlannedItem& item) { return item.info.key; }
const ItemKey& key_of(const FailedItem& item) { return item.key; }

std::string describe(const PlannedItem& item) {
  return fmt::format("item '{}' (index {}, shard {})", item.info.key.name, item.info.key.index, item.shard.string());
}
std::string describe(const FailedItem& item) {
  return fmt::format("failed item '{}' (index {})", item.key.name, item.key.index);
}

std::string shape_text(const h5::Dims& shape) { return fmt::format("({})", fmt::join(shape, ", ")); }

[[noreturn]] void throw_output(const std::string& output, std::string_view cause) {
  throw InvalidInput(fmt::format("{} '{}': {}", kBatchOutputs.what, output, cause));
}

/// Sorts `items` by index and checks that each belongs to `output` and that no index or name repeats
/// within the output; `seen_index` and `seen_name` carry the items checked before (the other list).
template <class T>
void order_and_check(std::vector<T>& items, const std::string& output, std::map<std::uint64_t, std::string>& seen_index,
                     std::map<std::string, std::string>& seen_name) {
  std::stable_sort(items.begin(), items.end(),
                   [](const T& a, const T& b) { return key_of(a).index < key_of(b).index; });
  for (const T& item : items) {
    const ItemKey& key = key_of(item);
    if (key.output != output) throw_output(output, fmt::format("{} belongs to output '{}'", describe(item), key.output));
    if (const auto [it, fresh] = seen_index.emplace(key.index, describe(item)); !fresh)
      throw_output(output, fmt::format("index {} occurs twice: {} and {}", key.index, it->second, describe(item)));
    if (const auto [it, fresh] = seen_name.emplace(key.name, describe(item)); !fresh)
      throw_output(output, fmt::format("name '{}' occurs twice: {} and {}", key.name, it->second, describe(item)));
  }
}

/// Reads the metadata of every shard of `input` and checks the output can be written (see the header).
PlannedOutput plan_output(const MergeInput& input) {
  check_representation_name(kBatchOutputs, input.output);
  for (const char* reserved : {kCount, kFailedCount})
    if (input.attributes.contains(reserved))
      throw_output(input.output, fmt::format("attribute '{}' is reserved for the merge", reserved));

  PlannedOutput plan;
  plan.input = &input;
  for (const auto& shard : input.shards) {
    plan.items.push_back({shard, read_shard_info(shard)});
    ItemKey& key = plan.items.back().info.key;
    if (const auto it = input.sources.find(key.index); it != input.sources.end()) key.source = it->second;
  }
  plan.failed = input.failed;
  std::map<std::uint64_t, std::string> seen_index;
  std::map<std::string, std::string> seen_name;
  order_and_check(plan.items, input.output, seen_index, seen_name);
  order_and_check(plan.failed, input.output, seen_index, seen_name);

  std::set<std::string> metric_keys, labels;
  plan.groups = input.groups;
  for (const PlannedItem& item : plan.items) {
    const ShardInfo& info = item.info;
    if (info.has_representation != plan.groups)
      throw_output(input.output, fmt::format("{} holds {}, this output stores {}", describe(item),
                                             info.has_representation ? "a representation group" : "an image",
                                             plan.groups ? "representation groups" : "images"));
    const h5::Dims shape{info.channels, info.height, info.width};
    if (plan.groups) {
      // Representation groups differ in size by design; nothing to compare.
    } else if (plan.item_shape.empty()) {
      plan.item_shape = shape;
    } else if (shape != plan.item_shape)
      throw_output(input.output, fmt::format("{} has shape {}, item '{}' has {}", describe(item), shape_text(shape),
                                             plan.items.front().info.key.name, shape_text(plan.item_shape)));
    plan.has_mask = plan.has_mask || info.has_mask;
    if (plan.items.front().info.has_sample_uv != info.has_sample_uv)
      throw_output(input.output, fmt::format("{} {} sample points, item '{}' {}", describe(item),
                                             info.has_sample_uv ? "has" : "has no", plan.items.front().info.key.name,
                                             info.has_sample_uv ? "has none" : "has them"));
    plan.has_sample_uv = info.has_sample_uv;
    if (info.sideband_rows > 0) {
      if (plan.units_per_side != 0 && info.units_per_side != plan.units_per_side)
        throw_output(input.output, fmt::format("{} has a sideband of {} units per side, an item before it {}",
                                               describe(item), info.units_per_side, plan.units_per_side));
      plan.units_per_side = info.units_per_side;
      plan.sideband_rows += info.sideband_rows;
    }
    for (const auto& entry : info.metrics) metric_keys.insert(entry.first);
    if (!info.key.label.empty()) labels.insert(info.key.label);
  }
  plan.metric_keys.assign(metric_keys.begin(), metric_keys.end());
  plan.label_names.assign(labels.begin(), labels.end());
  return plan;
}

/// Writes `names`, `sources`, `labels` and `index` of `items` under `group`.
template <class T>
void write_key_columns(h5::Group& group, const std::vector<T>& items) {
  std::vector<std::string> names, sources, labels;
  std::vector<std::int64_t> index;
  for (const T& item : items) {
    const ItemKey& key = key_of(item);
    names.push_back(key.name);
    sources.push_back(key.source);
    labels.push_back(key.label);
    index.push_back(static_cast<std::int64_t>(key.index));
  }
  group.write_strings("names", names);
  group.write_strings("sources", sources);
  group.write_strings("labels", labels);
  group.write_dataset("index", {items.size()}, index);
}

/// Streams the pixels of every item into the stacked `data` (and `mask`) datasets, one chunk per item.
void write_stacks(h5::Group& group, const PlannedOutput& plan) {
  const std::uint64_t n = plan.items.size();
  const h5::Dims item = plan.item_shape.empty() ? h5::Dims{0, 0, 0} : plan.item_shape;
  const h5::Dims data_chunk{1, item[0], item[1], item[2]}, mask_chunk{1, 1, item[1], item[2]};
  h5::Dataset data = group.create_dataset("data", h5::DataType::of<float>(), {n, item[0], item[1], item[2]},
                                          item_storage(data_chunk));
  std::optional<h5::Dataset> mask;
  if (plan.has_mask)
    mask = group.create_dataset("mask", h5::DataType::of<std::uint8_t>(), {n, 1, item[1], item[2]},
                                item_storage(mask_chunk));
  std::optional<h5::Dataset> sample_uv;
  const h5::Dims uv_chunk{1, 2, item[1], item[2]};
  if (plan.has_sample_uv)
    sample_uv = group.create_dataset("sample_uv", h5::DataType::of<float>(), {n, 2, item[1], item[2]},
                                     item_storage(uv_chunk));
  // Geometry images: every item's sideband, rows sideband_offsets[k] .. sideband_offsets[k + 1] (none: equal).
  std::optional<h5::Dataset> sideband;
  std::vector<std::int64_t> sideband_offsets{0};
  if (plan.sideband_rows > 0) {
    sideband = group.create_dataset("sideband", h5::DataType::of<std::int32_t>(), {plan.sideband_rows, 3});
    sideband->set_attribute("columns", "label,start_unit,units");
    sideband->set_attribute("units_per_side", static_cast<std::int64_t>(plan.units_per_side));
  }
  const std::vector<std::uint8_t> all_defined(plan.has_mask ? item[1] * item[2] : 0, 1);
  for (std::uint64_t i = 0; i < n; ++i) {
    const PlannedItem& planned = plan.items[i];
    const Shard shard = read_shard(planned.shard);
    const h5::Dims shape{shard.arrays.channels, shard.arrays.height, shard.arrays.width};
    if (shard.key.index != planned.info.key.index || shape != item || shard.arrays.mask.empty() == planned.info.has_mask ||
        shard.arrays.sideband.size() != 3 * planned.info.sideband_rows)
      throw FormatError(fmt::format("{}: batch shard changed during the merge", planned.shard.string()));
    const auto rows = static_cast<std::uint64_t>(sideband_offsets.back());
    if (sideband && planned.info.sideband_rows > 0)
      sideband->write_slab({rows, 0}, {planned.info.sideband_rows, 3}, shard.arrays.sideband);
    sideband_offsets.push_back(static_cast<std::int64_t>(rows + planned.info.sideband_rows));
    data.write_slab({i, 0, 0, 0}, data_chunk, shard.arrays.data);
    if (mask)
      mask->write_slab({i, 0, 0, 0}, mask_chunk, shard.arrays.mask.empty() ? all_defined : shard.arrays.mask);
    if (sample_uv) {
      if (shard.arrays.sample_uv.empty())
        throw FormatError(fmt::format("{}: batch shard changed during the merge", planned.shard.string()));
      sample_uv->write_slab({i, 0, 0, 0}, uv_chunk, shard.arrays.sample_uv);
    }
  }
  if (sideband) group.write_dataset("sideband_offsets", {sideband_offsets.size()}, sideband_offsets);
}

/// Copies the representation group of every item into items/<k>, k = 0..N-1 in storage order.
void write_groups(h5::Group& group, const PlannedOutput& plan) {
  h5::Group items = group.create_group(kItems);
  for (std::size_t k = 0; k < plan.items.size(); ++k) {
    copy_representation(plan.items[k].shard, items, std::to_string(k));
    // The group's `source` as the `sources` column records it (MergeInput::sources).
    h5::Group copied = items.open_group(std::to_string(k));
    const std::string& source = plan.items[k].info.key.source;
    if (copied.has_attribute("source") && copied.attribute<std::string>("source") != source)
      copied.set_attribute("source", source);
  }
}

/// Writes `label_index` and `label_names`.
void write_labels(h5::Group& group, const PlannedOutput& plan) {
  std::vector<std::int32_t> label_index;
  for (const PlannedItem& item : plan.items) {
    const std::string& label = item.info.key.label;
    const auto it = std::lower_bound(plan.label_names.begin(), plan.label_names.end(), label);
    label_index.push_back(label.empty() ? -1 : static_cast<std::int32_t>(it - plan.label_names.begin()));
  }
  group.write_dataset("label_index", {label_index.size()}, label_index);
  group.write_strings("label_names", plan.label_names);
}

/// Writes metrics/<key> for the union of the items' metric keys, NaN where an item lacks one.
void write_metrics(h5::Group& group, const PlannedOutput& plan) {
  h5::Group metrics = group.create_group(kMetrics);
  for (const std::string& key : plan.metric_keys) {
    std::vector<double> column;
    for (const PlannedItem& item : plan.items) {
      const auto it = item.info.metrics.find(key);
      column.push_back(it != item.info.metrics.end() ? it->second : std::numeric_limits<double>::quiet_NaN());
    }
    metrics.write_dataset(key, {column.size()}, column);
  }
}

/// Writes the table of failed items: failed/{names, sources, labels, index, reasons, attempts}.
void write_failed(h5::Group& group, const PlannedOutput& plan) {
  h5::Group failed = group.create_group(kFailed);
  write_key_columns(failed, plan.failed);
  std::vector<std::string> reasons;
  std::vector<std::int32_t> attempts;
  for (const FailedItem& item : plan.failed) {
    reasons.push_back(item.reason);
    attempts.push_back(item.attempts);
  }
  failed.write_strings("reasons", reasons);
  failed.write_dataset("attempts", {attempts.size()}, attempts);
}

void write_output(Archive& archive, const PlannedOutput& plan) {
  const MergeInput& input = *plan.input;
  h5::Group group = archive.root().require_group(kBatchOutputs.group).create_group(input.output);
  if (plan.groups)
    write_groups(group, plan);  // also without items: an empty items/ group, no data
  else
    write_stacks(group, plan);
  write_key_columns(group, plan.items);
  write_labels(group, plan);
  write_metrics(group, plan);
  write_failed(group, plan);
  for (const auto& [key, value] : input.attributes) group.set_attribute(key, value);
  group.set_attribute(kCount, plan.items.size());
  group.set_attribute(kFailedCount, plan.failed.size());
}

/// Reads the summary of output `name` (group `group`) of `archive`.
BatchOutputSummary read_output(const Archive& archive, const h5::Group& group, const std::string& name) {
  const auto open = [&](std::string_view item) { return open_item(group, archive, kBatchOutputs, name, item); };
  BatchOutputSummary s;
  s.output = name;
  // Range-checked before it sizes anything: a batch holds far fewer than 2^40 items.
  s.count = static_cast<std::uint64_t>(group.attribute_in_range(kCount, 0, std::int64_t{1} << 40));

  if (group.exists(kItems)) {
    s.groups = true;
    const std::vector<std::string> items = group.open_group(kItems).children();
    std::string missing;
    for (std::uint64_t k = 0; missing.empty() && k < s.count; ++k)
      if (!std::binary_search(items.begin(), items.end(), std::to_string(k))) missing = std::to_string(k);
    if (!missing.empty() || items.size() != s.count)
      throw representation_error(
          archive, kBatchOutputs, name,
          missing.empty() ? fmt::format("group 'items' holds {} groups, expected the {} named 0..{}", items.size(), s.count,
                                        s.count == 0 ? 0 : s.count - 1)
                          : fmt::format("group 'items' has no group '{}' (its {} items are groups 0..{})", missing,
                                        s.count, s.count - 1));
  } else {
    if (!group.exists("data"))
      throw representation_error(archive, kBatchOutputs, name, "holds neither dataset 'data' nor group 'items'");
    const h5::Dims shape = open("data").shape();
    if (shape.size() != 4 || shape[0] != s.count)
      throw representation_error(archive, kBatchOutputs, name,
                                 fmt::format("dataset 'data' has shape {}, expected ({}, C, H, W)", shape_text(shape),
                                             s.count));
    if (s.count > 0) s.item_shape.assign(shape.begin() + 1, shape.end());
    s.has_mask = group.exists("mask");
  }

  for (const char* column : {"names", "index", "label_index"})
    check_shape(open(column), archive, kBatchOutputs, name, column, {s.count});
  s.names = open("names").read_strings();
  for (const std::int64_t index : open("index").read<std::int64_t>()) {
    if (index < 0 || (!s.indices.empty() && static_cast<std::uint64_t>(index) <= s.indices.back()))
      throw representation_error(archive, kBatchOutputs, name,
                                 fmt::format("dataset 'index' holds {} after {} (indices are increasing, >= 0)", index,
                                             s.indices.empty() ? std::string("nothing") : std::to_string(s.indices.back())));
    s.indices.push_back(static_cast<std::uint64_t>(index));
  }
  s.label_names = open("label_names").read_strings();
  for (const std::int32_t label : open("label_index").read<std::int32_t>())
    if (label < -1 || (label >= 0 && static_cast<std::size_t>(label) >= s.label_names.size()))
      throw representation_error(archive, kBatchOutputs, name,
                                 fmt::format("dataset 'label_index' holds {}, not -1 (no label) or an index of the {} "
                                             "label names", label, s.label_names.size()));
  if (group.exists(kMetrics)) s.metric_keys = group.open_group(kMetrics).children();
  s.failed_names = open("failed/names").read_strings();
  // failed_count, range-checked first: the count a reader (and load_archive.py) sizes the table with.
  if (const std::int64_t failed = group.attribute_in_range(kFailedCount, 0, std::int64_t{1} << 40);
      static_cast<std::uint64_t>(failed) != s.failed_names.size())
    throw representation_error(archive, kBatchOutputs, name,
                               fmt::format("attribute {} = {} disagrees with the {} rows of 'failed/names'", kFailedCount,
                                           failed, s.failed_names.size()));
  for (const std::string& key : group.attribute_names())
    if (key != kCount && key != kFailedCount) s.attributes[key] = group.attribute<std::string>(key);
  return s;
}

}  // namespace

void write_batch_archive(const std::filesystem::path& archive, const CreationInfo& info,
                         std::span<const MergeInput> outputs) {
  std::set<std::string> names;
  for (const MergeInput& input : outputs)
    if (!names.insert(input.output).second) throw_output(input.output, "given twice");
  std::vector<PlannedOutput> plans;
  for (const MergeInput& input : outputs) plans.push_back(plan_output(input));

  write_atomically(archive, [&](const std::filesystem::path& tmp) {
    Archive out = Archive::create(tmp, info);
    out.root().require_group(kBatchOutputs.group);
    for (const PlannedOutput& plan : plans) write_output(out, plan);
    out.close();
  });
}

std::vector<BatchOutputSummary> read_batch_summary(const std::filesystem::path& archive) {
  return read_batch_summary(Archive::open(archive));
}

std::vector<BatchOutputSummary> read_batch_summary(const Archive& a) {
  if (!a.root().exists(kBatchOutputs.group))
    throw FormatError(fmt::format("{}: no batch outputs (no /{} group)", a.path().string(), kBatchOutputs.group));
  std::vector<BatchOutputSummary> out;
  for (const std::string& name : representation_names(a, kBatchOutputs)) out.push_back(read_batch_output(a, name));
  return out;
}

BatchOutputSummary read_batch_output(const Archive& a, const std::string& name) {
  try {
    return read_output(a, open_representation(a, kBatchOutputs, name), name);
  } catch (const InvalidInput& e) {  // a name no writer gives (".."): the archive is damaged, say which
    throw FormatError(fmt::format("{}: {}", a.path().string(), e.what()));
  }
}

}  // namespace gimforge::io
