#pragma once
/// \file mesh_header.h
/// Cheap size estimates for scheduling: the number of triangles a mesh file holds, from its header only
/// (no full read), so a batch can dispatch the largest items first.
#include <cstdint>
#include <filesystem>

namespace gimforge::io {

/// Triangle-count estimate of a mesh file, read from at most the first 64 KiB:
/// - PLY: the `element face N` count; binary STL: the 32-bit facet count (checked against the file size);
///   OFF: the face count of the header line (polygons count as one triangle each);
/// - OBJ and ASCII STL (no counts in a header): file size / 30 bytes (OBJ) or / 250 bytes (STL), about
///   one face line resp. one facet block.
/// Never throws for malformed content (the conversion reports that, with the cause): unreadable headers
/// fall back to the file-size estimate; a missing or unreadable file gives 0.
[[nodiscard]] std::uint64_t estimate_triangles(const std::filesystem::path& path) noexcept;

}  // namespace gimforge::io
