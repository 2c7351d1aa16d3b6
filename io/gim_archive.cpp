#include "io/gim_archive.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>

#include "io/coded_image.h"
#include "kernels/core/errors.h"
#include "kernels/gim/gim_fuse.h"

namespace gimforge::io {
namespace {

constexpr const RepresentationKind& kGim = kGeometryImages;

/// Opens image `item` (shape (m, m, 3), lo <= m <= kMaxGeometryImageSide; float32 or quantized, see io/coded_image.h)
/// and returns its side m, before anything is allocated.
h5::Dataset open_image(const h5::Group& g, const Archive& archive, const std::string& name, std::string_view item,
                       std::uint64_t lo, std::uint32_t& size) {
  h5::Dataset ds = open_item(g, archive, kGim, name, item);
  const h5::Dims shape = ds.shape();
  if (shape.size() != 3 || shape[0] != shape[1] || shape[2] != 3)
    throw representation_error(archive, kGim, name, fmt::format("dataset '{}' should have shape (n, n, 3)", item));
  if (shape[0] < lo || shape[0] > kMaxGeometryImageSide)
    throw representation_error(archive, kGim, name,
                               fmt::format("dataset '{}' has side {}, outside [{}, {}]", item, shape[0], lo, kMaxGeometryImageSide));
  size = static_cast<std::uint32_t>(shape[0]);
  return ds;
}

/// Checks every value of image `item` is finite (a geometry image has no undefined samples).
std::vector<float> check_finite(std::vector<float> values, const Archive& archive, const std::string& name,
                                std::string_view item) {
  const auto bad = std::find_if_not(values.begin(), values.end(), [](float v) { return std::isfinite(v); });
  if (bad != values.end()) {
    const auto k = static_cast<std::size_t>(bad - values.begin());
    throw representation_error(archive, kGim, name,
                               fmt::format("sample {} of dataset '{}' is {} (every sample must be finite)", k / 3,
                                           item, *bad));
  }
  return values;
}

/// Checks the optional integer attribute `key` (written by write_geometry_image) equals `want`.
void check_size_attribute(const h5::Group& g, const Archive& archive, const std::string& name, std::string_view key,
                          std::uint64_t want, std::string_view what) {
  if (!g.has_attribute(key)) return;
  const auto got = g.attribute<std::int64_t>(key);
  if (got < 0 || static_cast<std::uint64_t>(got) != want)
    throw representation_error(archive, kGim, name, fmt::format("attribute {} = {} disagrees with {}", key, got, what));
}

/// Reads the sideband table after checking its shape, type and every value's range against the
/// perimeter of `units_per_side` units per side.
Sideband read_sideband(const h5::Group& g, const Archive& archive, const std::string& name,
                       std::uint32_t units_per_side) {
  const h5::Dataset ds = open_item(g, archive, kGim, name, "sideband");
  const h5::Dims shape = ds.shape();
  if (shape.size() != 2 || shape[1] != 3)
    throw representation_error(archive, kGim, name, "sideband is not a (q, 3) table");
  if (shape[0] < 1 || shape[0] > 4 * std::uint64_t{units_per_side})
    throw representation_error(archive, kGim, name,
                               fmt::format("sideband has {} paths, outside [1, {}] (4 * units_per_side)", shape[0],
                                           4 * std::uint64_t{units_per_side}));
  if (ds.dtype() != h5::DType::kInt32) throw representation_error(archive, kGim, name, "sideband is not int32");
  try {
    return sideband_from_table(ds.read<std::int32_t>(), units_per_side);
  } catch (const InvalidInput& e) {
    throw representation_error(archive, kGim, name, e.what());
  }
}

}  // namespace

std::vector<std::int32_t> sideband_table(const Sideband& sideband) {
  std::vector<std::int32_t> table;
  for (const Sideband::Path& p : sideband.paths) {
    table.push_back(p.label);
    table.push_back(static_cast<std::int32_t>(p.start_unit));
    table.push_back(static_cast<std::int32_t>(p.units));
  }
  return table;
}

Sideband sideband_from_table(std::span<const std::int32_t> table, std::uint32_t units_per_side) {
  Sideband sb;
  sb.units_per_side = units_per_side;
  const std::uint64_t total = 4 * std::uint64_t{units_per_side};
  if (table.size() % 3 != 0 || table.empty() || table.size() / 3 > total)
    throw InvalidInput(fmt::format("sideband has {} values, not 3 for each of 1 to {} paths (4 * units_per_side)",
                                   table.size(), total));
  const auto q = static_cast<std::int64_t>(table.size() / 3);
  for (std::size_t i = 0; i < table.size(); i += 3) {
    const std::int64_t label = table[i], start = table[i + 1], units = table[i + 2];
    if (label < -q || label > q || start < 0 || static_cast<std::uint64_t>(start) >= total || units < 1 ||
        static_cast<std::uint64_t>(units) > total)
      throw InvalidInput(fmt::format("sideband row {} (label {}, start_unit {}, units {}) is outside the "
                                     "perimeter of {} units and {} paths",
                                     i / 3, label, start, units, total, q));
    sb.paths.push_back(
        {static_cast<std::int32_t>(label), static_cast<std::uint32_t>(start), static_cast<std::uint32_t>(units)});
  }
  sb.check();
  return sb;
}

void write_sideband(h5::Group& g, const Sideband& sideband) {
  h5::Dataset sb = g.write_dataset("sideband", {sideband.paths.size(), 3}, sideband_table(sideband));
  sb.set_attribute("columns", "label,start_unit,units");
  g.set_attribute("units_per_side", static_cast<std::int64_t>(sideband.units_per_side));
}

void write_geometry_image(Archive& archive, const std::string& name, const GeometryImage& image,
                          const GimRecord& record) {
  check_record(record, {"size", "normal_size", "units_per_side"});
  h5::Group g = create_representation(archive, kGim, name);
  const std::uint64_t n = image.size;
  write_image(g, "geometry", {n, n, 3}, image.positions);
  if (image.normal_size > 0) {
    const std::uint64_t m = image.normal_size;
    write_image(g, "normals", {m, m, 3}, image.normals);
  }
  if (image.color_size > 0) write_image(g, "colors", {n, n, 3}, image.colors);
  if (!image.sample_uv.empty()) {
    if (image.sample_uv.size() != n * n * 2)
      throw InvalidInput(fmt::format("geometry image '{}': {} sample coordinates for a {}x{} image", name,
                                     image.sample_uv.size(), n, n));
    write_image(g, "sample_uv", {n, n, 2}, image.sample_uv);
  }
  write_sideband(g, image.sideband);
  g.set_attribute("size", static_cast<std::int64_t>(image.size));
  g.set_attribute("normal_size", static_cast<std::int64_t>(image.normal_size));
  write_record(g, "gim", record);
}

GeometryImage read_geometry_image(const Archive& archive, const std::string& name) {
  return read_geometry_image(archive, open_representation(archive, kGim, name), name);
}

GeometryImage read_geometry_image(const Archive& archive, const h5::Group& g, const std::string& name) {
  if (g.has_attribute("method")) check_method(g, archive, kGim, name, "gim");
  GeometryImage image;
  // Every size is checked before it is used in arithmetic or an allocation (docs/archive.md, "What
  // readers refuse"): units_per_side first, then the images' sides against it.
  const auto units = g.attribute_in_range("units_per_side", 1, Sideband::kMaxUnitsPerSide);
  if (has_coded_positions(g)) {
    image.size = static_cast<std::uint32_t>(g.attribute_in_range("size", 2, static_cast<std::int64_t>(kMaxGeometryImageSide)));
  } else {
    (void)open_image(g, archive, name, "geometry", 2, image.size);
  }
  const std::uint64_t n = image.size;
  if ((n - 1) % static_cast<std::uint64_t>(units) != 0)
    throw representation_error(archive, kGim, name,
                               fmt::format("image size {}: n - 1 is not a multiple of units_per_side = {}", n, units));
  check_size_attribute(g, archive, name, "size", n, fmt::format("dataset 'geometry' ({}x{})", n, n));
  std::optional<h5::Dataset> normals, colors;
  if (g.exists("normals")) normals = open_image(g, archive, name, "normals", 1, image.normal_size);
  check_size_attribute(g, archive, name, "normal_size", image.normal_size,
                       normals ? fmt::format("dataset 'normals' ({0}x{0})", image.normal_size)
                               : std::string("the missing dataset 'normals'"));
  if (g.exists("colors")) {
    colors = open_image(g, archive, name, "colors", 1, image.color_size);
    if (image.color_size != n)
      throw representation_error(archive, kGim, name,
                                 fmt::format("dataset 'colors' is {0}x{0}, the geometry {1}x{1}", image.color_size, n));
  }
  image.sideband = read_sideband(g, archive, name, static_cast<std::uint32_t>(units));
  if (g.exists("sample_uv")) image.sample_uv = read_sample_uv(g, archive, kGim, name, n);
  StoredPositions stored = read_positions(g, archive, kGim, name, n, n, LatticeExtension::Mirror);
  require_near_samples(stored.xyz, {}, stored.storage, archive, kGim, name);
  image.positions = check_finite(std::move(stored.xyz), archive, name, "geometry");
  if (stored.lossy_coded()) {
    // Gu et al. §5: the coder reconstructs cut mates differently; fuse them from the sideband and diffuse
    // the displacements into the interior, so a closed input is watertight again.
    std::vector<Vec3> displacement;
    // ROI-first coding: a class with a sample in the window takes the window's value (trusted).
    (void)fuse_cut(image.positions, image.size, image.sideband, displacement, stored.trusted);
    diffuse_fusing(image.positions, image.size, displacement);
  }
  if (normals) image.normals = check_finite(read_real_image(*normals, archive, kGim, name, "normals"), archive, name, "normals");
  if (colors) image.colors = check_finite(read_real_image(*colors, archive, kGim, name, "colors"), archive, name, "colors");
  return image;
}

GimRecord read_gim_record(const Archive& archive, const std::string& name) {
  return read_record(open_representation(archive, kGim, name));
}

std::vector<std::string> geometry_image_names(const Archive& archive) { return representation_names(archive, kGim); }

}  // namespace gimforge::io
