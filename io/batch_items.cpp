/// \file batch_items.cpp
/// Items of a batch archive read back as images (see batch_items.h and docs/archive.md, "Batch archives").
#include "io/batch_items.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include <fmt/format.h>

#include "io/batch_archive.h"
#include "io/coded_image.h"
#include "io/gim_archive.h"
#include "io/printable.h"
#include "io/sphere_archive.h"
#include "kernels/core/errors.h"

namespace gimforge::io {
namespace {

[[noreturn]] void throw_item(const Archive& archive, const BatchItem& item, std::string_view cause) {
  throw FormatError(fmt::format("{}:/{}: {}", archive.path().string(), printable(item.path()), cause));
}

h5::Group output_group(const Archive& archive, const BatchItem& item) {
  return archive.root().open_group(fmt::format("batch/{}", item.output));
}

h5::Dataset open_dataset(const Archive& archive, const BatchItem& item, const h5::Group& g, std::string_view name) {
  if (!g.exists(name)) throw_item(archive, item, fmt::format("the output has no dataset '{}'", name));
  try {
    return g.open_dataset(name);
  } catch (const LibraryError& e) {
    throw_item(archive, item, dataset_open_failure(name, e));
  }
}

/// The stack `data` (N, 3, H, W) float32 after checking its type, rank and that it holds row k; `height`,
/// `width` return H and W. Nothing is read: the caller checks H and W before read_row allocates.
h5::Dataset open_stack(const Archive& archive, const BatchItem& item, const h5::Group& g, std::uint64_t& height,
                       std::uint64_t& width) {
  h5::Dataset data = open_dataset(archive, item, g, "data");
  const h5::Dims shape = data.shape();
  if (data.dtype() != h5::DType::kFloat32) throw_item(archive, item, "dataset 'data' is not float32");
  if (shape.size() != 4 || shape[0] <= item.k || shape[1] != 3)
    throw_item(archive, item, fmt::format("dataset 'data' has shape ({}), expected (N > {}, 3, H, W)",
                                          fmt::join(shape, ", "), item.k));
  height = shape[2];
  width = shape[3];
  return data;
}

/// Row k of the stack as interleaved samples (H·W·3), read one channel plane at a time.
/// Refuses a finite sample beyond ±kMaxCoordinate (far_sample_problem), as read_positions does.
std::vector<float> read_row(const Archive& archive, const h5::Dataset& data, const BatchItem& item, std::uint64_t height,
                            std::uint64_t width) {
  const std::size_t pixels = height * width;
  std::vector<float> xyz(3 * pixels);
  for (std::uint64_t c = 0; c < 3; ++c) {
    const std::vector<float> plane = data.read_slab<float>({item.k, c, 0, 0}, {1, 1, height, width});
    for (std::size_t p = 0; p < pixels; ++p) xyz[3 * p + c] = plane[p];
  }
  if (const std::string problem = far_sample_problem(xyz); !problem.empty()) throw_item(archive, item, problem);
  return xyz;
}

/// Item k's rows of the output's `sideband`; empty when the output or the item has none.
std::vector<std::int32_t> read_sideband_rows(const Archive& archive, const BatchItem& item, const h5::Group& g,
                                             std::uint64_t count, std::uint32_t& units_per_side) {
  if (!g.exists("sideband")) {
    if (g.exists("sideband_offsets")) throw_item(archive, item, "the output has 'sideband_offsets' but no 'sideband'");
    return {};
  }
  const h5::Dataset table = open_dataset(archive, item, g, "sideband");
  const h5::Dataset offsets = open_dataset(archive, item, g, "sideband_offsets");
  const h5::Dims shape = table.shape();
  if (table.dtype() != h5::DType::kInt32 || shape.size() != 2 || shape[1] != 3)
    throw_item(archive, item, "dataset 'sideband' is not an int32 (S, 3) table");
  if (offsets.dtype() != h5::DType::kInt64 || offsets.shape() != h5::Dims{count + 1})
    throw_item(archive, item, fmt::format("dataset 'sideband_offsets' is not int64 ({}) (one more than the items)", count + 1));
  // The table starts at 0 and ends at the rows of 'sideband'; item k's two entries lie in order between.
  // (Four values, not the table: its length comes from the file.)
  const auto at = [&](std::uint64_t i) { return offsets.read_slab<std::int64_t>({i}, {1}).front(); };
  const std::int64_t first = at(0), last = at(count), range[2] = {at(item.k), at(item.k + 1)};
  if (first != 0 || last < 0 || static_cast<std::uint64_t>(last) != shape[0] || range[0] < 0 || range[1] < range[0] ||
      range[1] > last)
    throw_item(archive, item, fmt::format("sideband_offsets ({} first, {} and {} for the item, {} last) do not index the "
                                          "{} rows of 'sideband'",
                                          first, range[0], range[1], last, shape[0]));
  if (range[1] == range[0]) return {};
  try {
    units_per_side = static_cast<std::uint32_t>(table.attribute_in_range("units_per_side", 1, Sideband::kMaxUnitsPerSide));
  } catch (const Error& e) {  // missing, another type or out of range
    throw_item(archive, item, fmt::format("dataset 'sideband': {}", e.what()));
  }
  if (static_cast<std::uint64_t>(range[1] - range[0]) > 4 * std::uint64_t{units_per_side})
    throw_item(archive, item, fmt::format("the item's sideband has {} rows, more than 4 * units_per_side", range[1] - range[0]));
  return table.read_slab<std::int32_t>({static_cast<std::uint64_t>(range[0]), 0},
                                       {static_cast<std::uint64_t>(range[1] - range[0]), 3});
}

}  // namespace

std::string BatchItem::path() const { return fmt::format("batch/{}/{}", output, name); }

std::string BatchItem::group_path() const { return fmt::format("batch/{}/items/{}", output, k); }

std::vector<BatchItem> batch_items(const Archive& archive) {
  std::vector<BatchItem> items;
  if (!archive.root().exists("batch")) return items;
  for (const BatchOutputSummary& s : read_batch_summary(archive)) {
    const auto method = s.attributes.find("method");
    for (std::uint64_t k = 0; k < s.count; ++k)
      items.push_back({s.output, s.names[k], k, method == s.attributes.end() ? std::string() : method->second, s.groups});
  }
  return items;
}

BatchItem find_batch_item(const Archive& archive, std::string_view qualified) {
  const std::string path = archive.path().string();
  if (!archive.root().exists("batch"))
    throw InvalidInput(fmt::format("{}: holds no batch outputs (no /batch group)", path));
  const std::vector<BatchOutputSummary> outputs = read_batch_summary(archive);
  std::vector<std::string> names;
  for (const BatchOutputSummary& s : outputs) names.push_back(printable(s.output));
  const auto slash = qualified.find('/');
  const std::string output(qualified.substr(0, slash));
  const auto s = std::find_if(outputs.begin(), outputs.end(), [&](const BatchOutputSummary& o) { return o.output == output; });
  if (s == outputs.end() || slash == std::string_view::npos)
    throw InvalidInput(fmt::format("{}: {} (--name batch/OUTPUT/ITEM names an item of a batch output; {})", path,
                                   s == outputs.end() ? fmt::format("no batch output '{}'", printable(output))
                                                      : fmt::format("'batch/{}' names no item", printable(output)),
                                   names.empty() ? std::string("the archive has none")
                                                 : fmt::format("outputs: {}", fmt::join(names, ", "))));
  const std::string name(qualified.substr(slash + 1));
  const auto it = std::find(s->names.begin(), s->names.end(), name);
  if (it == s->names.end()) {
    const h5::Group g = archive.root().open_group(fmt::format("batch/{}", s->output));
    if (const auto failed = std::find(s->failed_names.begin(), s->failed_names.end(), name); failed != s->failed_names.end()) {
      const auto f = static_cast<std::uint64_t>(failed - s->failed_names.begin());
      std::string reason = "(no reason stored)";
      if (g.exists("failed/reasons")) {
        const h5::Dataset reasons = g.open_dataset("failed/reasons");
        if (reasons.shape() == h5::Dims{s->failed_names.size()}) reason = printable(reasons.read_strings()[f]);
      }
      throw InvalidInput(fmt::format("{}: item '{}' of batch output '{}' was not converted: {}", path, printable(name),
                                     printable(output), reason));
    }
    std::vector<std::string> some;
    for (std::size_t k = 0; k < s->names.size() && k < 5; ++k) some.push_back(printable(s->names[k]));
    throw InvalidInput(fmt::format("{}: batch output '{}' has no item '{}' ({} items{}{}{})", path, printable(output),
                                   printable(name), s->count, some.empty() ? "" : ": ", fmt::join(some, ", "),
                                   s->count > some.size() ? ", ..." : ""));
  }
  BatchItem item{s->output, name, static_cast<std::uint64_t>(it - s->names.begin()), {}, s->groups, {}};
  if (std::find(it + 1, s->names.end(), name) != s->names.end())
    throw_item(archive, item, "the output names two items so (item names are unique in an output)");
  if (const auto method = s->attributes.find("method"); method != s->attributes.end()) item.method = method->second;
  // The item's source: a group items/<k> records its own, so a group that is not item k's is refused.
  const h5::Dataset sources = open_dataset(archive, item, archive.root().open_group("batch/" + s->output), "sources");
  if (sources.shape() != h5::Dims{s->count})
    throw_item(archive, item, fmt::format("dataset 'sources' does not hold {} strings", s->count));
  item.source = sources.read_strings()[item.k];
  return item;
}

GeometryImage read_batch_geometry_image(const Archive& archive, const BatchItem& item) {
  const h5::Group g = output_group(archive, item);
  std::uint64_t height = 0, width = 0;
  const h5::Dataset data = open_stack(archive, item, g, height, width);
  // Checked before anything is allocated (spherical stacks: against the layout their attributes name).
  if (height != width || height < 2 || height > kMaxGeometryImageSide)
    throw_item(archive, item, fmt::format("the stack holds {} x {} images; a geometry image is n x n, 2 <= n <= {}",
                                          height, width, kMaxGeometryImageSide));
  if (g.has_attribute("size") && g.attribute<std::string>("size") != std::to_string(height))
    throw_item(archive, item, fmt::format("the output's size {} disagrees with its {} x {} images",
                                          printable(g.attribute<std::string>("size")), height, width));
  GeometryImage image;
  image.size = static_cast<std::uint32_t>(height);
  std::uint32_t units = 0;
  const std::vector<std::int32_t> rows = read_sideband_rows(archive, item, g, data.shape()[0], units);
  if (!rows.empty() && (height - 1) % units != 0)
    throw_item(archive, item, fmt::format("image size {}: n - 1 is not a multiple of the sideband's units_per_side = {}",
                                          height, units));
  image.positions = read_row(archive, data, item, height, width);
  const auto bad = std::find_if_not(image.positions.begin(), image.positions.end(), [](float v) { return std::isfinite(v); });
  if (bad != image.positions.end())
    throw_item(archive, item, fmt::format("sample {} is {} (every sample of a geometry image must be finite)",
                                          (bad - image.positions.begin()) / 3, *bad));
  if (rows.empty()) {
    image.sideband.paths.clear();
    image.sideband.units_per_side = 0;  // none: the caller decides (reconstruct --no-fuse)
    return image;
  }
  try {
    image.sideband = sideband_from_table(rows, units);
  } catch (const InvalidInput& e) {
    throw_item(archive, item, e.what());
  }
  return image;
}

SphericalImage read_batch_spherical_image(const Archive& archive, const BatchItem& item) {
  const h5::Group g = output_group(archive, item);
  SphericalImage image;
  std::int64_t n = 0;
  try {
    image.domain = parse_spherical_domain(g.attribute<std::string>("domain"));
    const std::string text = g.attribute<std::string>("n");
    std::size_t used = 0;
    try {
      n = std::stoll(text, &used);
    } catch (const std::exception&) {
      used = std::string::npos;
    }
    if (used != text.size() || !std::in_range<std::uint32_t>(n))
      throw InvalidInput(fmt::format("n = '{}' is not a tessellation number", printable(text)));
    image.n = static_cast<std::uint32_t>(n);
    (void)image.layout();  // throws for an n outside the domain's range
  } catch (const std::exception& e) {
    throw_item(archive, item, fmt::format("the output's attributes domain and n do not name a spherical image: {}", e.what()));
  }
  const DomainImage layout = image.layout();
  std::uint64_t height = 0, width = 0;
  const h5::Dataset data = open_stack(archive, item, g, height, width);
  const h5::Dims want = sphere_image_shape(layout, 0);
  if (height != want[0] || width != want[1])
    throw_item(archive, item, fmt::format("the stack holds {} x {} images, domain {} at n = {} is {} x {}", height, width,
                                          to_string(image.domain), n, want[0], want[1]));
  image.positions = read_row(archive, data, item, height, width);
  if (g.exists("mask")) {
    const h5::Dataset mask = open_dataset(archive, item, g, "mask");
    const h5::Dims shape = mask.shape();
    if (mask.dtype() != h5::DType::kUInt8 || shape.size() != 4 || shape != h5::Dims{shape[0], 1, height, width} ||
        shape[0] <= item.k)
      throw_item(archive, item, fmt::format("dataset 'mask' is not uint8 (N, 1, {}, {})", height, width));
    image.mask = mask.read_slab<std::uint8_t>({item.k, 0, 0, 0}, {1, 1, height, width});
  } else {
    image.mask.assign(height * width, 1);
  }
  try {
    check_spherical_image(item.path(), image);
  } catch (const InvalidInput& e) {
    throw_item(archive, item, e.what());
  }
  return image;
}

Vec3 read_batch_item_origin(const Archive& archive, const BatchItem& item, double max_abs) {
  const h5::Group g = output_group(archive, item);
  Vec3 origin = Vec3::Zero();
  int present = 0, columns = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const std::string key = fmt::format("metrics/frame_origin_{}", "xyz"[axis]);
    if (!g.exists(key)) continue;
    ++columns;
    const h5::Dataset column = open_dataset(archive, item, g, key);
    if (column.dtype() != h5::DType::kFloat64 || column.shape().size() != 1 || column.shape()[0] <= item.k)
      throw_item(archive, item, fmt::format("dataset '{}' is not float64 with a value for item {}", key, item.k));
    const double x = column.read_slab<double>({item.k}, {1}).front();
    if (std::isnan(x)) continue;
    if (!(std::abs(x) <= max_abs))
      throw_item(archive, item, fmt::format("{} = {} is beyond ±{:g}", key, x, max_abs));
    origin[axis] = x;
    ++present;
  }
  if (present != 0 && present != 3)
    throw_item(archive, item, columns == 3 ? "the item's frame origin is NaN (none) on some axes only (metrics "
                                             "frame_origin_x, frame_origin_y, frame_origin_z)"
                                           : "the metrics hold only some of frame_origin_x, frame_origin_y, frame_origin_z");
  return origin;
}

}  // namespace gimforge::io
