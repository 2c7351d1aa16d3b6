/// \file batch_shard.cpp
/// Batch shard files (see batch_shard.h and docs/archive.md, "Batch shards").
#include "io/batch_shard.h"

#include "io/gim_archive.h"
#include "io/sphere_archive.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <fmt/format.h>
#include <hdf5.h>

#include "io/archive.h"
#include "io/atomic_file.h"
#include "io/mcgim_archive.h"
#include "io/relief_archive.h"
#include "kernels/core/errors.h"

namespace gimforge::io {
namespace {

constexpr const char* kData = "data";
constexpr const char* kMask = "mask";
constexpr const char* kSampleUv = "sample_uv";
constexpr const char* kSideband = "sideband";
constexpr const char* kUnitsPerSide = "units_per_side";
constexpr const char* kMetrics = "metrics";
constexpr const char* kRepresentation = "representation";

/// Metric names become datasets /batch/<output>/metrics/<key> of the archive.
constexpr RepresentationKind kMetricNames{"metrics", "metric"};

[[noreturn]] void throw_item(const ItemKey& key, std::string_view cause) {
  throw InvalidInput(fmt::format("item '{}' (output '{}', index {}): {}", key.name, key.output, key.index, cause));
}

/// `message` without a leading "PATH:" or "PATH: " (the h5 layer's messages start with the file name).
std::string_view without_path(std::string_view message, const std::string& path) {
  if (!path.empty() && message.starts_with(path) && message.substr(path.size()).starts_with(':')) {
    message.remove_prefix(path.size() + 1);
    if (message.starts_with(' ')) message.remove_prefix(1);
  }
  return message;
}

/// Runs `read` on the shard at `path`, turning every failure into FormatError naming the shard.
template <class F>
auto read_guarded(const std::filesystem::path& path, F&& read) -> decltype(read()) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw FormatError(fmt::format("{}: batch shard is missing", path.string()));
  try {
    return read();
  } catch (const Error& e) {
    throw FormatError(
        fmt::format("{}: unreadable batch shard: {}", path.string(), without_path(e.what(), path.string())));
  }
}

/// Throws FormatError with `cause` (read_guarded adds the path).
[[noreturn]] void damaged(std::string_view cause) { throw FormatError(std::string(cause)); }

/// Largest channel count and image side of a shard: the biggest image a method writes is a cube-domain
/// spherical image at n = 4096 (6 · 4097 rows); the bound keeps C·H·W far from overflow before any
/// allocation (h5::kMaxReadBytes bounds the read itself).
constexpr std::uint64_t kMaxChannels = 64;
constexpr std::uint64_t kMaxSide = std::uint64_t{1} << 16;

std::uint32_t extent(std::uint64_t value, std::uint64_t max, std::string_view what) {
  if (value < 1 || value > max)
    damaged(fmt::format("dataset '{}' has an extent {} outside 1..{}", what, value, max));
  return static_cast<std::uint32_t>(value);
}

/// Checks the pixels of an image item: a defined sample (mask 1, or every sample without a mask) is finite
/// in every channel. Masked samples may hold anything (NaN by the archive's convention).
void check_pixels(const ItemArrays& a) {
  const std::size_t pixels = std::size_t{a.height} * a.width;
  for (std::size_t p = 0; p < pixels; ++p) {
    if (!a.mask.empty() && a.mask[p] == 0) continue;
    for (std::size_t c = 0; c < a.channels; ++c)
      if (const float v = a.data[c * pixels + p]; !std::isfinite(v))
        damaged(fmt::format("dataset 'data' holds {} at channel {}, pixel ({}, {}) of a defined sample", v, c,
                            p / a.width, p % a.width));
  }
}

void read_image_info(const h5::File& file, ShardInfo& info);

/// Reads and checks everything but the pixel data of an open shard.
ShardInfo read_info(const h5::File& file) {
  if (!file.has_attribute("format")) damaged("not a batch shard (no 'format' attribute)");
  if (const auto format = file.attribute<std::string>("format"); format != kShardFormat)
    damaged(fmt::format("not a batch shard (format is '{}')", format));
  if (const auto version = file.attribute<std::int64_t>("format_version"); version != kShardFormatVersion)
    damaged(fmt::format("shard format_version {}, this gimforge reads {}", version, kShardFormatVersion));

  ShardInfo info;
  info.key.output = file.attribute<std::string>("output");
  info.key.name = file.attribute<std::string>("name");
  info.key.source = file.attribute<std::string>("source");
  info.key.label = file.attribute<std::string>("label");
  if (file.has_attribute("source_stamp")) info.key.source_stamp = file.attribute<std::string>("source_stamp");
  const std::int64_t index = file.attribute<std::int64_t>("index");
  if (index < 0) damaged(fmt::format("negative index {}", index));
  info.key.index = static_cast<std::uint64_t>(index);

  if (file.exists(kRepresentation)) {
    if (file.exists(kData) || file.exists(kMask)) damaged("both a group 'representation' and an image");
    // Checked whole, as reconstruct would read it: a damaged group is a damaged shard (redone on resume).
    const h5::Group group = file.open_group(kRepresentation);
    const std::string method = group.has_attribute("method") ? group.attribute<std::string>("method") : "";
    if (method == "relief")
      (void)read_relief_map(group, "group 'representation'");
    else if (method == "mcgim" || method == "gim" || method == "sphere") {
      // A multi-chart image, or a compressed image (batch --codec): read whole (payload CRC, decoded and
      // fused) as decompress reads it.
      const Archive view = Archive::open_unchecked(file.file_name());
      const h5::Group g = view.root().open_group(kRepresentation);
      if (method == "mcgim")
        (void)read_multichart_image(view, g, "group 'representation'");
      else if (method == "gim")
        (void)read_geometry_image(view, g, "group 'representation'");
      else
        (void)read_spherical_image(view, g, "group 'representation'");
    } else
      damaged(fmt::format("group 'representation' holds method '{}' (only relief maps, multi-chart images and "
                          "compressed images are stored as groups)",
                          method));
    info.has_representation = true;
  } else {
    read_image_info(file, info);
  }
  if (file.exists(kMetrics)) {
    const h5::Group metrics = file.open_group(kMetrics);
    const std::vector<std::string> keys = metrics.attribute_names();
    if (keys.size() > 4096) damaged(fmt::format("group 'metrics' has {} attributes (at most 4096)", keys.size()));
    for (const std::string& key : keys) {
      check_representation_name(kMetricNames, key);
      info.metrics[key] = metrics.attribute<double>(key);
    }
  }
  return info;
}

/// The shape and mask presence of a shard that stores an image.
void read_image_info(const h5::File& file, ShardInfo& info) {
  if (!file.exists(kData)) damaged("no dataset 'data'");
  const h5::Dataset data = file.open_dataset(kData);
  if (data.dtype() != h5::DType::kFloat32) damaged("dataset 'data' is not float32");
  const h5::Dims shape = data.shape();
  if (shape.size() != 3) damaged(fmt::format("dataset 'data' has rank {}, expected 3 (C, H, W)", shape.size()));
  info.channels = extent(shape[0], kMaxChannels, kData);
  info.height = extent(shape[1], kMaxSide, kData);
  info.width = extent(shape[2], kMaxSide, kData);

  info.has_mask = file.exists(kMask);
  if (info.has_mask) {
    const h5::Dataset mask = file.open_dataset(kMask);
    if (mask.dtype() != h5::DType::kUInt8) damaged("dataset 'mask' is not uint8");
    if (mask.shape() != h5::Dims{shape[1], shape[2]})
      damaged(fmt::format("dataset 'mask' has shape ({}), expected ({}, {})", fmt::join(mask.shape(), ", "),
                          shape[1], shape[2]));
  }
  if (file.exists(kSideband)) {
    const h5::Dataset sb = file.open_dataset(kSideband);
    if (sb.dtype() != h5::DType::kInt32) damaged("dataset 'sideband' is not int32");
    const h5::Dims sb_shape = sb.shape();
    if (sb_shape.size() != 2 || sb_shape[1] != 3 || sb_shape[0] < 1 || sb_shape[0] > 4 * Sideband::kMaxUnitsPerSide)
      damaged(fmt::format("dataset 'sideband' has shape ({}), expected (q, 3)", fmt::join(sb_shape, ", ")));
    const std::int64_t units = sb.attribute<std::int64_t>(kUnitsPerSide);
    if (units < 1 || units > std::int64_t{Sideband::kMaxUnitsPerSide} || shape[1] != shape[2] ||
        (shape[1] - 1) % static_cast<std::uint64_t>(units) != 0)
      damaged(fmt::format("dataset 'sideband' has units_per_side {} for a {} x {} image", units, shape[1], shape[2]));
    info.sideband_rows = sb_shape[0];
    info.units_per_side = static_cast<std::uint32_t>(units);
  }
  info.has_sample_uv = file.exists(kSampleUv);
  if (info.has_sample_uv) {
    const h5::Dataset uv = file.open_dataset(kSampleUv);
    if (uv.dtype() != h5::DType::kFloat32) damaged("dataset 'sample_uv' is not float32");
    if (uv.shape() != h5::Dims{2, shape[1], shape[2]})
      damaged(fmt::format("dataset 'sample_uv' has shape ({}), expected (2, {}, {})", fmt::join(uv.shape(), ", "),
                          shape[1], shape[2]));
  }
}

}  // namespace

h5::DatasetOptions item_storage(const h5::Dims& chunk) {
  const ImageOptions image;
  return {.chunk = chunk, .deflate = image.deflate, .shuffle = image.shuffle, .resizable = false};
}

void check_item(const ItemKey& key, const ItemArrays& arrays, bool has_representation) {
  if (key.name.empty()) throw_item(key, "empty item name");
  try {
    check_representation_name(kBatchOutputs, key.output);
    for (const auto& entry : arrays.metrics) check_representation_name(kMetricNames, entry.first);
  } catch (const InvalidInput& e) {
    throw_item(key, e.what());
  }
  if (has_representation) {
    if (arrays.channels != 0 || arrays.height != 0 || arrays.width != 0 || !arrays.data.empty() || !arrays.mask.empty() ||
        !arrays.sample_uv.empty() || !arrays.sideband.empty())
      throw_item(key, "an item stored as a representation group has no image");
    return;
  }
  if (arrays.channels < 1 || arrays.height < 1 || arrays.width < 1)
    throw_item(key, fmt::format("empty item shape ({}, {}, {})", arrays.channels, arrays.height, arrays.width));
  const std::uint64_t pixels = std::uint64_t{arrays.height} * arrays.width;
  if (arrays.data.size() != arrays.channels * pixels)
    throw_item(key, fmt::format("{} data values for shape ({}, {}, {})", arrays.data.size(), arrays.channels,
                                arrays.height, arrays.width));
  if (!arrays.mask.empty() && arrays.mask.size() != pixels)
    throw_item(key, fmt::format("{} mask values for {} x {} samples", arrays.mask.size(), arrays.height,
                                arrays.width));
  if (const auto odd = std::find_if(arrays.mask.begin(), arrays.mask.end(), [](std::uint8_t m) { return m > 1; });
      odd != arrays.mask.end())
    throw_item(key, fmt::format("mask value {} at {} (expected 0 or 1)", *odd, odd - arrays.mask.begin()));
  if (!arrays.sample_uv.empty() && arrays.sample_uv.size() != 2 * pixels)
    throw_item(key, fmt::format("{} sample coordinates for {} x {} samples", arrays.sample_uv.size(), arrays.height,
                                arrays.width));
  if (const auto odd = std::find_if_not(arrays.sample_uv.begin(), arrays.sample_uv.end(),
                                        [](float v) { return v >= 0.0f && v <= 1.0f; });
      odd != arrays.sample_uv.end())
    throw_item(key, fmt::format("sample coordinate {} at {} (expected 0 to 1)", *odd, odd - arrays.sample_uv.begin()));
  if (!arrays.sideband.empty()) {
    if (arrays.height != arrays.width || arrays.units_per_side < 1 || (arrays.height - 1) % arrays.units_per_side != 0)
      throw_item(key, fmt::format("a sideband of {} units per side for a {} x {} image", arrays.units_per_side,
                                  arrays.height, arrays.width));
    try {
      (void)sideband_from_table(arrays.sideband, arrays.units_per_side);
    } catch (const InvalidInput& e) {
      throw_item(key, e.what());
    }
  }
}

void write_shard(const std::filesystem::path& path, const ItemKey& key, const ItemArrays& arrays,
                 const RepresentationWriter& representation, ParentDirectory parent) {
  check_item(key, arrays, static_cast<bool>(representation));
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    h5::File file = h5::File::create(tmp);
    file.set_attribute("format", kShardFormat);
    file.set_attribute("format_version", kShardFormatVersion);
    file.set_attribute("output", key.output);
    file.set_attribute("name", key.name);
    file.set_attribute("source", key.source);
    file.set_attribute("label", key.label);
    file.set_attribute("index", key.index);
    if (!key.source_stamp.empty()) file.set_attribute("source_stamp", key.source_stamp);
    if (representation) {
      h5::Group group = file.create_group(kRepresentation);
      representation(group);
    } else {
      const h5::Dims shape{arrays.channels, arrays.height, arrays.width};
      file.write_dataset(kData, shape, arrays.data, item_storage(shape));
    }
    if (!arrays.mask.empty()) {
      const h5::Dims mask_shape{arrays.height, arrays.width};
      file.write_dataset(kMask, mask_shape, arrays.mask, item_storage(mask_shape));
    }
    if (!arrays.sample_uv.empty()) {
      const h5::Dims uv_shape{2, arrays.height, arrays.width};
      file.write_dataset(kSampleUv, uv_shape, arrays.sample_uv, item_storage(uv_shape));
    }
    if (!arrays.sideband.empty()) {
      h5::Dataset sb = file.write_dataset(kSideband, {arrays.sideband.size() / 3, 3}, arrays.sideband);
      sb.set_attribute(kUnitsPerSide, static_cast<std::int64_t>(arrays.units_per_side));
    }
    {
      h5::Group metrics = file.create_group(kMetrics);
      for (const auto& [name, value] : arrays.metrics) metrics.set_attribute(name, value);
    }
    file.close();
  }, parent);
}

ShardInfo read_shard_info(const std::filesystem::path& path) {
  return read_guarded(path, [&] { return read_info(h5::File::open(path)); });
}

Shard read_shard(const std::filesystem::path& path) {
  return read_guarded(path, [&] {
    const h5::File file = h5::File::open(path);
    ShardInfo info = read_info(file);
    Shard shard{.key = std::move(info.key), .arrays = {}};
    ItemArrays& a = shard.arrays;
    a.channels = info.channels;
    a.height = info.height;
    a.width = info.width;
    a.metrics = std::move(info.metrics);
    if (info.has_representation) return shard;
    a.data = file.open_dataset(kData).read<float>();
    if (info.has_mask) {
      a.mask = file.open_dataset(kMask).read<std::uint8_t>();
      if (std::any_of(a.mask.begin(), a.mask.end(), [](std::uint8_t m) { return m > 1; }))
        damaged("dataset 'mask' holds values other than 0 and 1");
    }
    if (info.has_sample_uv) {
      a.sample_uv = file.open_dataset(kSampleUv).read<float>();
      if (!std::all_of(a.sample_uv.begin(), a.sample_uv.end(), [](float v) { return v >= 0.0f && v <= 1.0f; }))
        damaged("dataset 'sample_uv' holds values outside [0, 1]");
    }
    if (info.sideband_rows > 0) {
      a.sideband = file.open_dataset(kSideband).read<std::int32_t>();
      a.units_per_side = info.units_per_side;
      try {
        (void)sideband_from_table(a.sideband, a.units_per_side);
      } catch (const InvalidInput& e) {
        damaged(fmt::format("dataset 'sideband': {}", e.what()));
      }
    }
    check_pixels(a);
    return shard;
  });
}

void copy_representation(const std::filesystem::path& path, h5::Group& destination, std::string_view name) {
  const h5::File file = read_guarded(path, [&] {
    h5::File f = h5::File::open(path);
    if (!read_info(f).has_representation) damaged("no group 'representation'");
    return f;
  });
  file.copy_to(kRepresentation, destination, name);
}

void read_shard_fully(const std::filesystem::path& path) {
  if (!read_shard_info(path).has_representation) {
    (void)read_shard(path);
    return;
  }
  h5::FileAccess memory;  // the core driver without a backing store: nothing is written to disk
  memory.add("core driver", [](h5::Hid plist) { return H5Pset_fapl_core(plist, 1 << 16, 0); });
  h5::File scratch = h5::File::create(path.string() + ".probe", h5::CreateMode::kTruncate, memory);
  copy_representation(path, scratch, "item");
}

}  // namespace gimforge::io
