#pragma once
/// \file stored_image.h
/// Reading the image an ImageRef names (jobs/gim_store.h), wherever the archive keeps it: a representation
/// group /<group>/<name> written by convert, or an item of a batch output (io/batch_items.h), stacked or
/// in its own group items/<k>. reconstruct, preview and render read through here, so a batch item is read
/// with the same checks and gives the same mesh and pictures as the image convert stores.
#include <optional>
#include <string>

#include "io/archive.h"
#include "io/hdf5.h"
#include "io/mcgim_archive.h"
#include "jobs/gim_store.h"
#include "kernels/core/mesh.h"
#include "kernels/gim/geometry_image.h"
#include "kernels/mcgim/mcgim_image.h"
#include "kernels/relief/relief_map.h"
#include "kernels/sphere/sphere_convert.h"

namespace gimforge::jobs {

/// The group that holds the image with the layout of a convert archive's group: /<group>/<name>, or
/// items/<k> of a batch output that stores groups; none for an item stacked in a batch output's `data`.
[[nodiscard]] std::optional<h5::Group> image_group(const io::Archive& archive, const ImageRef& ref);

/// "ARCHIVE:/PATH": how messages name the image.
[[nodiscard]] std::string image_where(const io::Archive& archive, const ImageRef& ref);

/// The image's frame origin (pipeline.h item_origin): what to add to its positions for the input's coordinates.
[[nodiscard]] Vec3 image_origin(const io::Archive& archive, const ImageRef& ref);

/// The image of a geometry-image reference. A stacked batch item written before batch archives kept the
/// sideband has none (sideband.paths empty, units_per_side 0).
[[nodiscard]] GeometryImage read_gim(const io::Archive& archive, const ImageRef& ref);
[[nodiscard]] SphericalImage read_sphere(const io::Archive& archive, const ImageRef& ref);
[[nodiscard]] ReliefMap read_relief(const io::Archive& archive, const ImageRef& ref);
[[nodiscard]] MultiChartImage read_mcgim(const io::Archive& archive, const ImageRef& ref);
[[nodiscard]] io::McgimExtras read_mcgim_extras(const io::Archive& archive, const ImageRef& ref);

}  // namespace gimforge::jobs
