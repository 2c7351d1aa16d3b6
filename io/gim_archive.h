#pragma once
/// \file gim_archive.h
/// Geometry images in the gimforge archive (docs/archive.md, "Geometry images"):
///   /gim/<name>/geometry   float32 (n, n, 3)       the geometry image
///   /gim/<name>/normals    float32 (m, m, 3)       the normal map (when sampled)
///   /gim/<name>/colors     float32 (n, n, 3)       per-vertex colours resampled (when the input had them)
///   /gim/<name>/sideband   int32 (q, 3)            per cut-path: label, start unit, units
///   /gim/<name>/sample_uv  float32 (n, n, 2)       adaptive sampling: each sample's parameter point
///   /gim/<name>/adapt_history float64 (r, 8)       adaptive sampling: figures per round (jobs/pipeline.cpp)
/// with attributes on /gim/<name>: units_per_side, source, cut statistics, stretch, fidelity, timings.
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "io/archive.h"
#include "io/representation.h"
#include "kernels/gim/geometry_image.h"

namespace gimforge::io {

/// Where geometry images live in the archive (/gim/<name>) and what messages call them.
inline constexpr RepresentationKind kGeometryImages{"gim", "geometry image"};

/// Largest geometry image (and normal map) the readers take, checked before any allocation: n = 2^14 + 1,
/// 3.2 GB of float32 samples; convert writes n = 65 ... 4097 and normal maps up to 8192.
inline constexpr std::uint64_t kMaxGeometryImageSide = (std::uint64_t{1} << 14) + 1;

/// Scalar facts stored as attributes of /gim/<name> (numbers) next to the images.
using GimRecord = RepresentationRecord;

/// Writes geometry image `name` (a new group /gim/<name>). Throws InvalidInput for an empty or invalid
/// name or a record number that collides with a structural attribute (size, normal_size, units_per_side,
/// method, source), LibraryError if the group exists or HDF5 fails.
void write_geometry_image(Archive& archive, const std::string& name, const GeometryImage& image,
                          const GimRecord& record);

/// Writes the sideband table `sideband` (int32 (q, 3), attribute `columns`) and the group's
/// `units_per_side`: what a compressed item (jobs/compress.h) keeps of the image's topology.
void write_sideband(h5::Group& g, const Sideband& sideband);

/// The sideband as write_sideband stores it: per cut-path label, start_unit, units (3·q values).
[[nodiscard]] std::vector<std::int32_t> sideband_table(const Sideband& sideband);

/// The sideband of a stored table (3·q values, as sideband_table) for `units_per_side` units per side, every
/// value checked: 1 <= q <= 4·units_per_side, rows inside the perimeter, Sideband::check. Throws InvalidInput
/// saying what is wrong (the caller names the item).
[[nodiscard]] Sideband sideband_from_table(std::span<const std::int32_t> table, std::uint32_t units_per_side);

/// Reads geometry image `name`: positions stored as float32, quantized (uint16) or coded (`geometry_code`,
/// io/coded_image.h; decoded, then the cut fused and the fusing displacements diffused, Gu et al. §5). Throws FormatError naming the archive and the missing/mistyped item.
[[nodiscard]] GeometryImage read_geometry_image(const Archive& archive, const std::string& name);

/// The same for a group laid out like /gim/<name> elsewhere in the archive (a compressed batch item,
/// /batch/<output>/items/<k>); `name` labels the messages.
[[nodiscard]] GeometryImage read_geometry_image(const Archive& archive, const h5::Group& group, const std::string& name);

/// Reads the record (attributes) of geometry image `name`.
[[nodiscard]] GimRecord read_gim_record(const Archive& archive, const std::string& name);

/// Names of the geometry images in the archive (children of /gim), sorted.
[[nodiscard]] std::vector<std::string> geometry_image_names(const Archive& archive);

}  // namespace gimforge::io
