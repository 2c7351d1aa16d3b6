#pragma once
/// \file batch_items.h
/// One item of a batch archive read back as the image `convert` would have stored (docs/archive.md, "Batch
/// archives"): what `reconstruct`, `preview` and `render` read for `--name batch/OUTPUT/ITEM`. Items stored as
/// groups (`items/<k>`: relief maps, multi-chart images, `batch --codec` outputs) are read by the group readers
/// of their kind; geometry images and spherical images stacked in `data` are read here, one row, with the
/// checks the group readers make on what reconstruction uses (every size before any allocation, finite
/// samples, the mask, the sideband); the adaptive sample positions `sample_uv` are not read.
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "io/archive.h"
#include "kernels/core/mesh.h"
#include "kernels/gim/geometry_image.h"
#include "kernels/sphere/sphere_convert.h"

namespace gimforge::io {

/// An item of output /batch/<output>: its name (the output's `names[k]`) and position k.
struct BatchItem {
  std::string output;   ///< the output's group name under /batch, e.g. "gim_257"
  std::string name;     ///< the item's name, e.g. "chair/0001" (unique in the output)
  std::uint64_t k{0};   ///< its position in the output (row of the stacks, items/<k>)
  std::string method;   ///< the output's `method` attribute: "gim", "sphere", "relief" or "mcgim"
  bool group{false};    ///< stored as the group items/<k> (relief, mcgim, batch --codec), not in the stacks
  std::string source{}; ///< the output's `sources[k]`, the mesh it was converted from

  /// "batch/OUTPUT/NAME": how commands name it (--name).
  [[nodiscard]] std::string path() const;
  /// "batch/OUTPUT/items/K": the group of an item stored as one (meaningful only when `group`).
  [[nodiscard]] std::string group_path() const;
};

/// Every converted item of every output of the archive, outputs by name, items in storage order; empty
/// when the archive has no /batch group. Throws what read_batch_summary throws for a damaged output.
[[nodiscard]] std::vector<BatchItem> batch_items(const Archive& archive);

/// The item `qualified` = "OUTPUT/NAME" (the part of --name after "batch/"). Throws InvalidInput
/// "ARCHIVE: no batch output 'OUTPUT' (...)", "ARCHIVE: batch output 'OUTPUT' has no item 'NAME' (N items:
/// ...)" or, for an item that failed, "ARCHIVE: item 'NAME' of batch output 'OUTPUT' was not converted:
/// REASON"; FormatError when the output names two items so or its `sources` do not match `names`, and what
/// read_batch_summary throws.
[[nodiscard]] BatchItem find_batch_item(const Archive& archive, std::string_view qualified);

/// Item `item` of a geometry-image output stacked in `data` (N, 3, n, n): its positions, and its sideband
/// from `sideband` / `sideband_offsets` (empty when the item has none: a batch written before they were
/// stored). Throws FormatError "ARCHIVE:/batch/OUTPUT/NAME: CAUSE" for a wrong shape or type, a sample that is
/// not finite, an invalid sideband or offsets.
[[nodiscard]] GeometryImage read_batch_geometry_image(const Archive& archive, const BatchItem& item);

/// Item `item` of a spherical-image output stacked in `data` (N, 3, S, W), laid out by the output's
/// attributes `domain` and `n`, with its `mask` row (all defined without one). Throws FormatError as
/// read_batch_geometry_image, also for a mask that disagrees with the positions (NaN exactly where it is 0).
[[nodiscard]] SphericalImage read_batch_spherical_image(const Archive& archive, const BatchItem& item);

/// The frame origin of a stacked item: its metrics frame_origin_x, frame_origin_y, frame_origin_z (zero when
/// all three are missing or NaN: a batch written before they were recorded). Throws FormatError when only
/// some are there or one lies beyond ±`max_abs`.
[[nodiscard]] Vec3 read_batch_item_origin(const Archive& archive, const BatchItem& item, double max_abs);

}  // namespace gimforge::io
