#pragma once
/// \file relief_archive.h
/// Relief maps on cubic cell complexes in the gimforge archive (docs/archive.md, "Relief maps"; Apaza &
/// Andújar, §3.4: "a lookup table encoding the G cells, and the projection type for each G cell", one
/// distance map per domain face packed as an array texture, and an array texture per further signal).
/// With G grey cells, L layers (domain faces) and T texels per side:
///   /relief/<name>/cells              uint32 (G, 3)     i, j, k of every grey cell, increasing linear index
///   /relief/<name>/external_faces     uint8 (G)         CellFace bits (0: interior grey cell)
///   /relief/<name>/case               uint8 (G)         base case of §3.2 (ReliefCase: 0 = "0" ... 9 = "6")
///   /relief/<name>/projection         uint8 (G)         projection type (ProjectionType)
///   /relief/<name>/domain_faces       uint8 (G)         CellFace bits of the faces the cell projects onto
///   /relief/<name>/projection_params  float64 (G, 6)    point (3) and direction (3), unit-cell coordinates
///   /relief/<name>/layer_cell         uint32 (L)        grey cell of every layer
///   /relief/<name>/layer_face         uint8 (L)         face 0..5 of every layer
///   /relief/<name>/distances          uint16 (L, T, T)  quantized distances (attributes scale, offset, empty)
///   /relief/<name>/normals            int8 (L, T, T, 3) unit normals as snorm8
///   /relief/<name>/colors             uint8 (L, T, T, 3) RGB8 (only when the input had colours)
///   /relief/<name>/grid_levels        int64 (K, 5)      the grids tried: n, grey_cells, domain_faces, samples,
///                                                       occluded
/// with attributes on /relief/<name>: method "relief", source, n, texture, grey_cells, layers, white_cells,
/// black_cells, watertight_inside_test (int64), inside_method (string), origin (float64 (3)), cell_size
/// (float64, structural) and the record's numbers (fidelity, occlusion, storage, timings).
#include <string>
#include <vector>

#include "io/archive.h"
#include "io/representation.h"
#include "kernels/relief/relief_map.h"

namespace gimforge::io {

/// Where relief maps live in the archive (/relief/<name>) and what messages call them.
inline constexpr RepresentationKind kReliefMaps{"relief", "relief map"};

/// Scalar facts stored as attributes of /relief/<name> next to the maps (e.g. "psnr", "occlusion_ratio",
/// "storage_bytes", "seconds_sampling", "seconds_total").
using ReliefRecord = RepresentationRecord;

/// Writes relief map `name` (a new group /relief/<name>) with its cell table, layer table, distance,
/// normal and (when map.colors is not empty) colour maps, the grids tried (map.levels) and `record`.
/// Throws InvalidInput for an invalid name, a map that fails ReliefMap::check() (message naming the map),
/// grid levels whose last one is not the map's grid, or a record number that collides with a structural
/// attribute, before anything is written;
/// LibraryError if the group exists or HDF5 fails.
void write_relief_map(Archive& archive, const std::string& name, const ReliefMap& map, const ReliefRecord& record);

/// The checks write_relief_map makes before it writes (messages name map `name`).
void check_relief_map(const std::string& name, const ReliefMap& map, const ReliefRecord& record);

/// Writes the datasets and attributes of a relief map into the empty group `group`, in the layout of
/// /relief/<name> (batch archives keep one such group per item, docs/archive.md). Call check_relief_map
/// first. LibraryError if HDF5 fails.
void write_relief_map(h5::Group& group, const ReliefMap& map, const ReliefRecord& record);

/// Reads relief map `name`: the grid, the cell table (projections recomputed from the external faces and
/// checked against the stored case, projection type, domain faces and parameters), the layer table, the
/// maps, the grids tried and the construction facts stored as attributes (white_cells, black_cells,
/// inside_method, watertight_inside_test; seconds_cells and seconds_sampling from the record when present).
/// Every shape, element type and range is checked before use and the result passes ReliefMap::check().
/// Throws InvalidInput for an invalid name and FormatError "ARCHIVE: relief map 'NAME': CAUSE" naming the
/// missing or inconsistent item.
[[nodiscard]] ReliefMap read_relief_map(const Archive& archive, const std::string& name);

/// Reads the relief map stored in `group` (a batch archive's items/<k>, a shard's representation), with
/// the same checks; errors read "WHERE: CAUSE".
[[nodiscard]] ReliefMap read_relief_map(const h5::Group& group, std::string_view where);

/// Reads the record (float64 attributes) of relief map `name`; the structural float64 attribute cell_size
/// is not part of it. Throws FormatError when the map is absent.
[[nodiscard]] ReliefRecord read_relief_record(const Archive& archive, const std::string& name);

/// Names of the relief maps in the archive (children of /relief), sorted.
[[nodiscard]] std::vector<std::string> relief_map_names(const Archive& archive);

}  // namespace gimforge::io
