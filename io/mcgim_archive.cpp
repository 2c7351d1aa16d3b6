/// \file mcgim_archive.cpp
/// Multi-chart geometry images in the archive (see mcgim_archive.h and docs/archive.md).
#include "io/mcgim_archive.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

#include <fmt/format.h>

#include "io/coded_image.h"
#include "kernels/core/errors.h"
#include "kernels/core/hash.h"
#include "kernels/mcgim/mcgim_fuse.h"

namespace gimforge::io {
namespace {

constexpr const RepresentationKind& kMcgim = kMultiChartImages;
constexpr const char* kMethod = "mcgim";
/// Largest chart count a reader accepts (convert makes tens to hundreds).
constexpr std::int64_t kMaxCharts = std::int64_t{1} << 20;
constexpr float kUndefined = std::numeric_limits<float>::quiet_NaN();
constexpr const char* kStructureCrc = "structure_crc32";

std::string where_of(const Archive& archive, const std::string& name) {
  return fmt::format("{}:/{}/{}", archive.path().string(), kMcgim.group, name);
}

FormatError bad(std::string_view where, std::string_view cause) { return FormatError(fmt::format("{}: {}", where, cause)); }

/// A positive integer attribute no larger than `max`, checked before it is used in any arithmetic.
std::uint64_t bounded_attribute(const h5::Group& g, std::string_view where, std::string_view key, std::uint64_t max) {
  const auto value = g.attribute<std::int64_t>(key);
  if (value < 1 || static_cast<std::uint64_t>(value) > max)
    throw bad(where, fmt::format("attribute {} = {} is outside [1, {}]", key, value, max));
  return static_cast<std::uint64_t>(value);
}

h5::Dataset open_checked(const h5::Group& g, std::string_view where, std::string_view item, const h5::Dims& shape,
                         h5::DType type, std::string_view type_name) {
  if (!g.exists(item)) throw bad(where, fmt::format("no dataset '{}'", item));
  h5::Dataset ds = g.open_dataset(item);
  if (ds.shape() != shape) {
    std::vector<std::string> want;
    for (auto d : shape) want.push_back(std::to_string(d));
    throw bad(where, fmt::format("dataset '{}' does not have shape ({})", item, fmt::join(want, ", ")));
  }
  if (ds.dtype() != type) throw bad(where, fmt::format("dataset '{}' is not {}", item, type_name));
  return ds;
}

void check_extras(const MultiChartImage& image, const McgimExtras& extras) {
  if (!extras.normals.empty() && extras.normals.size() != 3 * image.samples())
    throw InvalidInput(fmt::format("multi-chart geometry image: {} normal values for {} samples", extras.normals.size(),
                                   image.samples()));
  if (extras.chart_stretch.empty()) throw InvalidInput("multi-chart geometry image: no per-chart stretch");
}

}  // namespace

void write_multichart_image(h5::Group& g, const MultiChartImage& image, const McgimExtras& extras,
                            const RepresentationRecord& record) {
  try {
    check_multichart_image(image, "multi-chart geometry image");
  } catch (const FormatError& e) {
    throw InvalidInput(e.what());
  }
  check_extras(image, extras);
  check_record(record, {"width", "height", "num_charts"});
  const h5::Dims vectors{image.height, image.width, 3};
  write_image(g, "geometry", vectors, image.positions);
  write_multichart_structure(g, image, extras.chart_stretch);
  if (!extras.normals.empty()) write_image(g, "normals", vectors, extras.normals);
  write_record(g, kMethod, record);
}

void write_multichart_structure(h5::Group& g, const MultiChartImage& image, std::span<const double> chart_stretch) {
  const h5::Dims plane{image.height, image.width};
  // gzip at its strongest: the chart ids are runs (the byte shuffle would break them), the zipper table's
  // rows are increasing sample indices (shuffled, their high bytes repeat). What a compressed item pays.
  const h5::DatasetOptions runs{{}, 9, false, false}, rows{{}, 9, true, false};
  write_image(g, "mask", plane, image.mask, ImageOptions{{}, 9, true});
  std::vector<std::int32_t> chart(image.samples());
  std::vector<std::int32_t> zipper;
  for (std::size_t s = 0; s < image.samples(); ++s) {
    chart[s] = image.chart[s] == kNoChart ? -1 : static_cast<std::int32_t>(image.chart[s]);
    if (image.mask[s] && image.unified[s] != s)
      zipper.insert(zipper.end(), {static_cast<std::int32_t>(s), static_cast<std::int32_t>(image.unified[s])});
  }
  g.write_dataset("chart", plane, chart, runs);
  g.write_dataset("zipper", {zipper.size() / 2, 2}, zipper, rows);
  if (!image.zipper_diagonals.empty())
    g.write_dataset("zipper_diagonals", {image.zipper_diagonals.size()}, image.zipper_diagonals);
  g.write_dataset("chart_stretch", {chart_stretch.size()}, chart_stretch);
  g.set_attribute("width", std::int64_t{image.width});
  g.set_attribute("height", std::int64_t{image.height});
  g.set_attribute("num_charts", static_cast<std::int64_t>(chart_stretch.size()));
}

void write_multichart_image(Archive& archive, const std::string& name, const MultiChartImage& image,
                            const McgimExtras& extras, const RepresentationRecord& record) {
  check_representation_name(kMcgim, name);
  try {
    check_multichart_image(image, fmt::format("multi-chart geometry image '{}'", name));
  } catch (const FormatError& e) {
    throw InvalidInput(e.what());
  }
  check_extras(image, extras);
  check_record(record, {"width", "height", "num_charts"});
  h5::Group g = create_representation(archive, kMcgim, name);
  write_multichart_image(g, image, extras, record);
}

namespace {

/// The reader behind both overloads: `name` is what the archive's messages call the item (its name, or a
/// batch item's label).
MultiChartImage read_image(const Archive& archive, const h5::Group& g, const std::string& name, std::string_view where) {
  if (!g.has_attribute("method") || g.attribute<std::string>("method") != kMethod)
    throw bad(where, fmt::format("method is not '{}'", kMethod));
  MultiChartImage image;
  const std::uint64_t w = bounded_attribute(g, where, "width", kMaxMcgimSamples);
  const std::uint64_t h = bounded_attribute(g, where, "height", kMaxMcgimSamples);
  if (w * h > kMaxMcgimSamples) throw bad(where, fmt::format("{} x {} samples exceed the limit of {}", w, h, kMaxMcgimSamples));
  const std::uint64_t charts = bounded_attribute(g, where, "num_charts", static_cast<std::uint64_t>(kMaxCharts));
  image.width = static_cast<std::uint32_t>(w);
  image.height = static_cast<std::uint32_t>(h);
  const std::size_t n = image.samples();
  image.mask = open_checked(g, where, "mask", {h, w}, h5::DType::kUInt8, "uint8").read<std::uint8_t>();
  if (const auto bad_mask = std::find_if(image.mask.begin(), image.mask.end(), [](std::uint8_t m) { return m > 1; });
      bad_mask != image.mask.end()) {  // before the zipper, whose check would name the wrong cause
    const auto s = static_cast<std::size_t>(bad_mask - image.mask.begin());
    throw bad(where, fmt::format("mask value {} at ({}, {}) is not 0 or 1", *bad_mask, s % w, s / w));
  }
  // chart_stretch is not needed here, but its shape says whether num_charts is the one the writer set.
  (void)open_checked(g, where, "chart_stretch", {charts}, h5::DType::kFloat64, "float64");
  const std::vector<std::int32_t> chart = open_checked(g, where, "chart", {h, w}, h5::DType::kInt32, "int32").read<std::int32_t>();
  image.chart.assign(n, kNoChart);
  for (std::size_t s = 0; s < n; ++s) {
    if (chart[s] == -1) continue;
    if (chart[s] < 0 || static_cast<std::uint64_t>(chart[s]) >= charts)
      throw bad(where, fmt::format("chart id {} of sample {} is outside [-1, {})", chart[s], s, charts));
    image.chart[s] = static_cast<std::uint32_t>(chart[s]);
  }
  if (!g.exists("zipper")) throw bad(where, "no dataset 'zipper'");
  const h5::Dataset zds = g.open_dataset("zipper");
  const h5::Dims zshape = zds.shape();
  if (zshape.size() != 2 || zshape[1] != 2 || zshape[0] > n || zds.dtype() != h5::DType::kInt32)
    throw bad(where, fmt::format("dataset 'zipper' is not an int32 (q, 2) table with q <= {}", n));
  const std::vector<std::int32_t> zipper = zds.read<std::int32_t>();
  image.unified.assign(n, kNoSample);
  for (std::size_t s = 0; s < n; ++s)
    if (image.mask[s] == 1) image.unified[s] = static_cast<std::uint32_t>(s);
  for (std::size_t i = 0; i < zipper.size(); i += 2) {
    const std::int64_t s = zipper[i], r = zipper[i + 1];
    if (s < 0 || r < 0 || static_cast<std::uint64_t>(s) >= n || static_cast<std::uint64_t>(r) >= n)
      throw bad(where, fmt::format("zipper row {} names a sample outside [0, {})", i / 2, n));
    const auto su = static_cast<std::size_t>(s);
    if (image.mask[su] != 1 || image.unified[su] != su)
      throw bad(where, fmt::format("zipper row {}: sample {} is undefined or listed twice", i / 2, s));
    if (r == s) throw bad(where, fmt::format("zipper row {}: sample {} names itself (a representative has no row)", i / 2, s));
    image.unified[su] = static_cast<std::uint32_t>(r);
  }
  if (g.exists("zipper_diagonals")) {
    const h5::Dataset dds = g.open_dataset("zipper_diagonals");
    if (dds.shape().size() != 1 || dds.shape()[0] > n / 8 + 1 || dds.dtype() != h5::DType::kUInt8)
      throw bad(where, fmt::format("dataset 'zipper_diagonals' is not a uint8 (b) vector with b <= {}", n / 8 + 1));
    image.zipper_diagonals = dds.read<std::uint8_t>();
    if (image.zipper_diagonals.empty()) throw bad(where, "dataset 'zipper_diagonals' is empty");
  }
  // The structure is checked before the positions are decoded with it.
  image.positions.assign(3 * n, kUndefined);
  check_multichart_structure(image, where);
  // float32, quantized or coded (io/coded_image.h): the undefined samples of the last two hold fill values.
  StoredPositions stored = read_positions(g, archive, kMcgim, name, h, w, LatticeExtension::Mirror);
  require_near_samples(stored.xyz, image.mask, stored.storage, archive, kMcgim, name);  // undefined samples: unused
  image.positions = std::move(stored.xyz);
  if (stored.storage != "float32")
    for (std::size_t s = 0; s < n; ++s)
      if (image.mask[s] == 0) image.positions[3 * s] = image.positions[3 * s + 1] = image.positions[3 * s + 2] = kUndefined;
  if (g.exists("chart_planes") && !stored.lossy_coded())
    throw bad(where, "dataset 'chart_planes' beside positions that are not coded");
  if (stored.lossy_coded()) {
    // The code is of the positions minus their chart's quadric (`chart_planes`), and the structure decides
    // where every decoded value goes: its checksum is compared before the quadrics are added back. Then the
    // members of each zipper cluster, which the coder reconstructs differently, are fused and the moves
    // diffused into their charts (mcgim_fuse.h), so a closed input is watertight again.
    if (!g.exists("chart_planes")) throw bad(where, "no dataset 'chart_planes' beside the coded positions");
    const std::vector<float> planes =
        open_checked(g, where, "chart_planes", {charts, kPlaneFloats}, h5::DType::kFloat32, "float32").read<float>();
    if (!std::all_of(planes.begin(), planes.end(), [](float v) { return std::isfinite(v); }))
      throw bad(where, "dataset 'chart_planes' holds a value that is not finite");
    if (!g.has_attribute(kStructureCrc)) throw bad(where, fmt::format("no attribute '{}' beside the coded positions", kStructureCrc));
    if (g.attribute<std::int64_t>(kStructureCrc) != std::int64_t{multichart_structure_crc(image, planes)})
      throw bad(where, "structure checksum mismatch (the mask, chart ids, zipper or chart_planes were damaged)");
    try {
      restore_decoded_multichart(image, planes);
    } catch (const InvalidInput& e) {
      throw bad(where, e.what());
    }
  }
  check_multichart_image(image, where);
  return image;
}

}  // namespace

std::uint32_t multichart_structure_crc(const MultiChartImage& image, std::span<const float> planes) {
  std::uint32_t crc = crc32(image.mask.data(), image.mask.size());
  const auto add = [&crc](std::uint32_t v) {
    const std::array<std::uint8_t, 4> le{static_cast<std::uint8_t>(v), static_cast<std::uint8_t>(v >> 8),
                                         static_cast<std::uint8_t>(v >> 16), static_cast<std::uint8_t>(v >> 24)};
    crc = crc32(le.data(), le.size(), crc);
  };
  for (std::size_t s = 0; s < image.samples(); ++s) add(image.chart[s] == kNoChart ? 0xffffffffu : image.chart[s]);
  for (std::size_t s = 0; s < image.samples(); ++s)
    if (image.mask[s] && image.unified[s] != s) add(static_cast<std::uint32_t>(s)), add(image.unified[s]);
  for (const float v : planes) add(std::bit_cast<std::uint32_t>(v));
  if (!image.zipper_diagonals.empty()) crc = crc32(image.zipper_diagonals.data(), image.zipper_diagonals.size(), crc);
  return crc;
}

MultiChartImage read_multichart_image(const Archive& archive, const h5::Group& group, const std::string& name) {
  return read_image(archive, group, name, fmt::format("{}: {} '{}'", archive.path().string(), kMcgim.what, name));
}

MultiChartImage read_multichart_image(const Archive& archive, const std::string& name) {
  const h5::Group g = open_representation(archive, kMcgim, name);
  return read_image(archive, g, name, where_of(archive, name));
}

McgimExtras read_multichart_extras(const Archive& archive, const std::string& name) {
  return read_multichart_extras(open_representation(archive, kMcgim, name), where_of(archive, name));
}

McgimExtras read_multichart_extras(const h5::Group& g, std::string_view where) {
  McgimExtras extras;
  const std::uint64_t w = bounded_attribute(g, where, "width", kMaxMcgimSamples);
  const std::uint64_t h = bounded_attribute(g, where, "height", kMaxMcgimSamples);
  if (w * h > kMaxMcgimSamples) throw bad(where, "too many samples");
  const std::uint64_t charts = bounded_attribute(g, where, "num_charts", static_cast<std::uint64_t>(kMaxCharts));
  if (g.exists("normals")) {
    const h5::Dataset normals = g.open_dataset("normals");
    if (normals.shape() != h5::Dims{h, w, 3}) throw bad(where, fmt::format("dataset 'normals' does not have shape ({}, {}, 3)", h, w));
    if (normals.dtype() != h5::DType::kFloat32) throw bad(where, "dataset 'normals' is not float32");
    extras.normals = normals.read<float>();
    for (float v : extras.normals)
      if (std::isinf(v)) throw bad(where, "a normal is infinite");
  }
  extras.chart_stretch = open_checked(g, where, "chart_stretch", {charts}, h5::DType::kFloat64, "float64").read<double>();
  return extras;
}

std::vector<std::string> multichart_image_names(const Archive& archive) { return representation_names(archive, kMcgim); }

}  // namespace gimforge::io
