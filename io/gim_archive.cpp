#include "io/gim_archive.h"

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge::io {
namespace {

constexpr const RepresentationKind& kGim = kGeometryImages;

std::vector<float> read_image(const h5::Group& g, const Archive& archive, const std::string& name,
                              std::string_view item, std::uint32_t& size) {
  const h5::Dataset ds = open_item(g, archive, kGim, name, item);
  const h5::Dims shape = ds.shape();
  if (shape.size() != 3 || shape[0] != shape[1] || shape[2] != 3)
    throw representation_error(archive, kGim, name, fmt::format("dataset '{}' should have shape (n, n, 3)", item));
  size = static_cast<std::uint32_t>(shape[0]);
  return ds.read<float>();
}

}  // namespace

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
  std::vector<std::int32_t> table;
  for (const Sideband::Path& p : image.sideband.paths) {
    table.push_back(p.label);
    table.push_back(static_cast<std::int32_t>(p.start_unit));
    table.push_back(static_cast<std::int32_t>(p.units));
  }
  h5::Dataset sb = g.write_dataset("sideband", {image.sideband.paths.size(), 3}, table);
  sb.set_attribute("columns", "label,start_unit,units");
  g.set_attribute("units_per_side", static_cast<std::int64_t>(image.sideband.units_per_side));
  g.set_attribute("size", static_cast<std::int64_t>(image.size));
  g.set_attribute("normal_size", static_cast<std::int64_t>(image.normal_size));
  write_record(g, "gim", record);
}

GeometryImage read_geometry_image(const Archive& archive, const std::string& name) {
  const h5::Group g = open_representation(archive, kGim, name);
  GeometryImage image;
  image.positions = read_image(g, archive, name, "geometry", image.size);
  if (g.exists("normals")) image.normals = read_image(g, archive, name, "normals", image.normal_size);
  if (g.exists("colors")) image.colors = read_image(g, archive, name, "colors", image.color_size);
  image.sideband.units_per_side = static_cast<std::uint32_t>(g.attribute<std::int64_t>("units_per_side"));
  const h5::Dataset sb = open_item(g, archive, kGim, name, "sideband");
  const std::vector<std::int32_t> table = sb.read<std::int32_t>();
  if (table.size() % 3 != 0) throw representation_error(archive, kGim, name, "sideband is not a (q, 3) table");
  for (std::size_t i = 0; i < table.size(); i += 3)
    image.sideband.paths.push_back({table[i], static_cast<std::uint32_t>(table[i + 1]),
                                    static_cast<std::uint32_t>(table[i + 2])});
  try {
    image.sideband.check();
  } catch (const InvalidInput& e) {
    throw representation_error(archive, kGim, name, e.what());
  }
  return image;
}

GimRecord read_gim_record(const Archive& archive, const std::string& name) {
  return read_record(open_representation(archive, kGim, name));
}

std::vector<std::string> geometry_image_names(const Archive& archive) { return representation_names(archive, kGim); }

}  // namespace gimforge::io
