#pragma once
/// \file mcgim_archive.h
/// Multi-chart geometry images in the gimforge archive (docs/archive.md, "Multi-chart geometry images"):
///   /mcgim/<name>/geometry       float32 (H, W, 3)   samples; NaN where undefined
///   /mcgim/<name>/mask           uint8   (H, W)      1 where defined
///   /mcgim/<name>/chart          int32   (H, W)      chart of each defined sample, −1 elsewhere
///   /mcgim/<name>/zipper         int32   (q, 2)      (sample, representative) for every zippered sample
///                                                    whose cluster representative is another sample;
///                                                    sample index = row · W + column
///   /mcgim/<name>/normals        float32 (H, W, 3)   per-sample normals (§3 central differences)
///   /mcgim/<name>/chart_stretch  float64 (num_charts,) stretch efficiency of every chart
/// with attributes width, height, num_charts on /mcgim/<name>, and the record (statistics, fidelity, timings).
/// Row 0 of the images is the bottom row of the packing (the reconstruction's faces are counter-clockwise
/// in (column, row)).
#include <span>
#include <string>
#include <vector>

#include "io/archive.h"
#include "io/representation.h"
#include "kernels/mcgim/mcgim_image.h"

namespace gimforge::io {

/// Where multi-chart geometry images live in the archive (/mcgim/<name>) and what messages call them.
inline constexpr RepresentationKind kMultiChartImages{"mcgim", "multi-chart geometry image"};

/// Largest image a reader accepts: W·H ≤ 2^26 samples (convert writes up to its --samples bound).
inline constexpr std::uint64_t kMaxMcgimSamples = std::uint64_t{1} << 26;

/// What is stored beside the image.
struct McgimExtras {
  std::vector<float> normals;          ///< H·W·3 or empty (not stored)
  std::vector<double> chart_stretch;   ///< per chart (its size is the `num_charts` attribute)
};

/// Writes multi-chart geometry image `name` (a new group /mcgim/<name>). Throws InvalidInput for an invalid
/// name, an image that does not pass check_multichart_image, extras of the wrong size, or a record number
/// that collides with a structural attribute (width, height, num_charts, method, source); LibraryError if the
/// group exists or HDF5 fails.
void write_multichart_image(Archive& archive, const std::string& name, const MultiChartImage& image,
                            const McgimExtras& extras, const RepresentationRecord& record);

/// Writes the same layout into an existing group (a batch item).
void write_multichart_image(h5::Group& group, const MultiChartImage& image, const McgimExtras& extras,
                            const RepresentationRecord& record);

/// Writes the layout without positions and normals: `mask`, `chart`, `zipper`, `chart_stretch` and the
/// attributes width, height, num_charts (what a compressed item stores beside its positions; io/coded_image.h).
/// The caller checked the image.
void write_multichart_structure(h5::Group& group, const MultiChartImage& image, std::span<const double> chart_stretch);

/// CRC-32 of what decides where a coded item's decoded values go: the mask bytes, then as little-endian
/// uint32 every sample's chart id (0xffffffff where undefined), the zipper rows (sample, representative) in
/// increasing sample order, the `chart_planes` floats and the `zipper_diagonals` bytes (when there are). A
/// coded item stores it as attribute
/// `structure_crc32` (int64); readers compare it before decoding into the structure.
[[nodiscard]] std::uint32_t multichart_structure_crc(const MultiChartImage& image, std::span<const float> planes);

/// Reads multi-chart geometry image `name`, checking every size against its attributes before anything is
/// allocated and every value (mask, chart ids, zipper entries, finite positions, unified positions equal).
/// Positions stored quantized or coded (io/coded_image.h, `gimforge compress`) are decoded; a lossy code's
/// zipper clusters are fused and the fusing diffused (kernels/mcgim/mcgim_fuse.h).
/// Throws FormatError naming the archive, the item and the problem.
[[nodiscard]] MultiChartImage read_multichart_image(const Archive& archive, const std::string& name);

/// The same from any group of that layout in `archive` (a batch item); `name` is what the errors call it.
[[nodiscard]] MultiChartImage read_multichart_image(const Archive& archive, const h5::Group& group, const std::string& name);

/// Reads the extras (normals when stored, per-chart stretch) of `name`, checked like the image.
[[nodiscard]] McgimExtras read_multichart_extras(const Archive& archive, const std::string& name);

/// The same from any group of that layout (a batch item); `where` prefixes the errors.
[[nodiscard]] McgimExtras read_multichart_extras(const h5::Group& group, std::string_view where);

/// Names of the multi-chart geometry images in the archive (children of /mcgim), sorted.
[[nodiscard]] std::vector<std::string> multichart_image_names(const Archive& archive);

}  // namespace gimforge::io
