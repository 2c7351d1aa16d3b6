/// \file stored_image.cpp
/// Reading the image an ImageRef names (see stored_image.h).
#include "jobs/stored_image.h"

#include <fmt/format.h>

#include "io/gim_archive.h"
#include "io/printable.h"
#include "io/relief_archive.h"
#include "io/sphere_archive.h"
#include "jobs/pipeline.h"

namespace gimforge::jobs {
namespace {

/// The group of a relief map or multi-chart image: batch outputs keep them as items/<k>, never stacked.
h5::Group required_group(const io::Archive& archive, const ImageRef& ref) {
  std::optional<h5::Group> g = image_group(archive, ref);
  if (!g)
    throw FormatError(fmt::format("{}: the output stacks its items in 'data', which holds geometry and spherical "
                                  "images only (method '{}')",
                                  image_where(archive, ref), io::printable(ref.batch->method)));
  return std::move(*g);
}

}  // namespace

std::optional<h5::Group> image_group(const io::Archive& archive, const ImageRef& ref) {
  if (!ref.batch) return io::open_representation(archive, representation(ref.kind), ref.name);
  if (!ref.batch->group) return std::nullopt;
  const std::string path = ref.batch->group_path();
  if (!archive.root().exists(path))
    throw FormatError(fmt::format("{}: the output has no group '{}'", image_where(archive, ref), path));
  h5::Group group = archive.root().open_group(path);
  // Each group records its source: one that is not item k's (groups swapped or copied over) is refused.
  if (group.has_attribute("source")) {
    const auto source = group.attribute<std::string>("source");
    if (source != ref.batch->source)
      throw FormatError(fmt::format("{}: group '{}' holds the item converted from '{}', but the output's sources "
                                    "name '{}' for it",
                                    image_where(archive, ref), path, io::printable(source),
                                    io::printable(ref.batch->source)));
  }
  return group;
}

std::string image_where(const io::Archive& archive, const ImageRef& ref) {
  return fmt::format("{}:/{}", archive.path().string(), io::printable(ref.path()));
}

Vec3 image_origin(const io::Archive& archive, const ImageRef& ref) {
  if (ref.batch && !ref.batch->group) return io::read_batch_item_origin(archive, *ref.batch, kMaxFrameOrigin);
  return item_origin(required_group(archive, ref), image_where(archive, ref));
}

GeometryImage read_gim(const io::Archive& archive, const ImageRef& ref) {
  if (!ref.batch) return io::read_geometry_image(archive, ref.name);
  if (!ref.batch->group) return io::read_batch_geometry_image(archive, *ref.batch);
  return io::read_geometry_image(archive, required_group(archive, ref), ref.path());
}

SphericalImage read_sphere(const io::Archive& archive, const ImageRef& ref) {
  if (!ref.batch) return io::read_spherical_image(archive, ref.name);
  if (!ref.batch->group) return io::read_batch_spherical_image(archive, *ref.batch);
  return io::read_spherical_image(archive, required_group(archive, ref), ref.path());
}

ReliefMap read_relief(const io::Archive& archive, const ImageRef& ref) {
  if (!ref.batch) return io::read_relief_map(archive, ref.name);
  return io::read_relief_map(required_group(archive, ref), image_where(archive, ref));
}

MultiChartImage read_mcgim(const io::Archive& archive, const ImageRef& ref) {
  if (!ref.batch) return io::read_multichart_image(archive, ref.name);
  return io::read_multichart_image(archive, required_group(archive, ref), ref.path());
}

io::McgimExtras read_mcgim_extras(const io::Archive& archive, const ImageRef& ref) {
  if (!ref.batch) return io::read_multichart_extras(archive, ref.name);
  return io::read_multichart_extras(required_group(archive, ref), image_where(archive, ref));
}

}  // namespace gimforge::jobs
