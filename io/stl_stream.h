#pragma once
/// \file stl_stream.h
/// A binary STL rewritten as a binary little-endian PLY of triangles without holding the file (issue #17
/// item 1; `gimforge convert-format`): facets are read in chunks of 1M, their corners welded as read_mesh
/// welds them (the exact float bits, −0 as +0, vertices numbered in order of first appearance), each new
/// vertex and each face appended to a temporary file beside the output, and the two are joined behind the
/// PLY header when the last facet is read. The output is byte for byte what write_ply writes of read_mesh's
/// mesh. Memory: the welding table, about 44 bytes per distinct vertex (some 1.1 GB for a 50M-facet scan of
/// 25M vertices), never the file (2.5 GB) or its faces. Disk: the side files take as much as the output
/// until they are joined (they are removed on any error; a killed process leaves them as *.tmp).
#include <cstdint>
#include <filesystem>
#include <string>

namespace gimforge::io {

/// Whether stream_stl_to_ply takes `path`: a .stl file (read_mesh goes by the extension) holding a binary STL
/// whose size matches its facet count and which does
/// not also read as ASCII STL (a file that starts with "solid" is taken only when its first 64 KiB hold a
/// byte no text has; read_mesh decides the others). Never throws.
[[nodiscard]] bool is_streamable_binary_stl(const std::filesystem::path& path) noexcept;

struct StreamedMesh {
  std::uint64_t vertices{0};
  std::uint64_t faces{0};
};

/// Writes `ply` (atomically; coordinates as float, or as double when `double_precision`) from the binary STL
/// `stl` (is_streamable_binary_stl). Throws IoError when reading or writing fails, FormatError "STL: triangle
/// T has a non-finite coordinate (V)" as read_mesh does, InvalidInput when the STL has no facet or more
/// distinct vertices than a PLY index holds.
StreamedMesh stream_stl_to_ply(const std::filesystem::path& stl, const std::filesystem::path& ply,
                               const std::string& comment, bool double_precision);

}  // namespace gimforge::io
