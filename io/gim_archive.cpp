#include "io/gim_archive.h"

#include <fmt/format.h>

#include "kernels/errors.h"

namespace gimforge::io {
namespace {

constexpr const char* kGroup = "gim";

void check_name(const std::string& name) {
  if (name.empty() || name.find('/') != std::string::npos || name == "." || name == "..")
    throw InvalidInput(fmt::format("invalid geometry image name '{}' (non-empty, no '/')", name));
}

std::vector<float> read_image(const h5::Group& g, const std::string& archive, const std::string& name,
                              std::uint32_t& size) {
  const h5::Dataset ds = g.open_dataset(name);
  const h5::Dims shape = ds.shape();
  if (shape.size() != 3 || shape[0] != shape[1] || shape[2] != 3)
    throw FormatError(fmt::format("{}: dataset '{}' should have shape (n, n, 3)", archive, name));
  size = static_cast<std::uint32_t>(shape[0]);
  return ds.read<float>();
}

}  // namespace

void write_geometry_image(Archive& archive, const std::string& name, const GeometryImage& image,
                          const GimRecord& record) {
  check_name(name);
  h5::Group gim = archive.root().require_group(kGroup);
  h5::Group g = gim.create_group(name);
  const std::uint64_t n = image.size;
  write_image(g, "geometry", {n, n, 3}, image.positions);
  if (image.normal_size > 0) {
    const std::uint64_t m = image.normal_size;
    write_image(g, "normals", {m, m, 3}, image.normals);
  }
  if (image.color_size > 0) write_image(g, "colors", {n, n, 3}, image.colors);
  std::vector<std::int32_t> table;
  for (const Sideband::Path& p : image.sideband.paths) {
    table.push_back(p.label);
    table.push_back(static_cast<std::int32_t>(p.start_unit));
    table.push_back(static_cast<std::int32_t>(p.units));
  }
  h5::Dataset sb = g.write_dataset("sideband", {image.sideband.paths.size(), 3}, table);
  sb.set_attribute("columns", "label,start_unit,units");
  g.set_attribute("units_per_side", static_cast<std::int64_t>(image.sideband.units_per_side));
  g.set_attribute("method", "gim");
  g.set_attribute("size", static_cast<std::int64_t>(image.size));
  g.set_attribute("normal_size", static_cast<std::int64_t>(image.normal_size));
  g.set_attribute("source", record.source);
  for (const auto& [key, value] : record.numbers) g.set_attribute(key, value);
}

GeometryImage read_geometry_image(const Archive& archive, const std::string& name) {
  check_name(name);
  const std::string path = archive.path().string();
  if (!archive.root().exists(std::string(kGroup) + "/" + name))
    throw FormatError(fmt::format("{}: no geometry image '{}' (has: {})", path, name,
                                  fmt::join(geometry_image_names(archive), ", ")));
  const h5::Group g = archive.root().open_group(std::string(kGroup) + "/" + name);
  GeometryImage image;
  image.positions = read_image(g, path, "geometry", image.size);
  if (g.exists("normals")) image.normals = read_image(g, path, "normals", image.normal_size);
  if (g.exists("colors")) image.colors = read_image(g, path, "colors", image.color_size);
  image.sideband.units_per_side = static_cast<std::uint32_t>(g.attribute<std::int64_t>("units_per_side"));
  const h5::Dataset sb = g.open_dataset("sideband");
  const std::vector<std::int32_t> table = sb.read<std::int32_t>();
  if (table.size() % 3 != 0) throw FormatError(fmt::format("{}: sideband of '{}' is not a (q, 3) table", path, name));
  for (std::size_t i = 0; i < table.size(); i += 3)
    image.sideband.paths.push_back({table[i], static_cast<std::uint32_t>(table[i + 1]),
                                    static_cast<std::uint32_t>(table[i + 2])});
  try {
    image.sideband.check();
  } catch (const InvalidInput& e) {
    throw FormatError(fmt::format("{}: geometry image '{}': {}", path, name, e.what()));
  }
  return image;
}

GimRecord read_gim_record(const Archive& archive, const std::string& name) {
  const h5::Group g = archive.root().open_group(std::string(kGroup) + "/" + name);
  GimRecord r;
  r.source = g.attribute<std::string>("source");
  for (const std::string& key : g.attribute_names()) {
    if (key == "source" || key == "method") continue;
    try {
      r.numbers[key] = g.attribute<double>(key);
    } catch (const FormatError&) {
      // not a number: skip
    }
  }
  return r;
}

std::vector<std::string> geometry_image_names(const Archive& archive) {
  if (!archive.root().exists(kGroup)) return {};
  return archive.root().open_group(kGroup).children();
}

}  // namespace gimforge::io
