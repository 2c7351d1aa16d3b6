#pragma once
/// \file ply_stream.h
/// A binary little-endian PLY written piece by piece, for meshes too large to hold (synthetic scans of 10^7–
/// 10^8 faces): the header needs the counts first, then vertices and faces are appended in blocks. The
/// file is written under write_atomically's temporary name and committed only when every declared vertex
/// and face has been written, so a failure or a kill never leaves a partial PLY under the final name.
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <span>
#include <string>

#include "kernels/core/mesh.h"

namespace gimforge::io {

struct PlyStreamHeader {
  std::uint64_t vertices{0};
  std::uint64_t faces{0};
  bool double_precision{false};  ///< double x y z (georeferenced coordinates) instead of float
  std::string comment;           ///< one header comment line (no line breaks); none when empty
};

/// Appends vertices, then faces, to the PLY being written (see write_ply_streamed).
class PlyStreamWriter {
 public:
  /// Appends vertex positions. Throws Error when more vertices than declared arrive, or after a face, and
  /// InvalidInput for a coordinate that is not finite as stored (a double beyond float's range in a float
  /// file included).
  void add_vertices(std::span<const Vec3> positions);
  /// Appends triangles. Throws Error before every declared vertex is written, for more faces than
  /// declared, and InvalidInput for an index ≥ the declared vertex count.
  void add_faces(std::span<const Face> faces);

 private:
  friend void write_ply_streamed(const std::filesystem::path&, const PlyStreamHeader&,
                                 const std::function<void(PlyStreamWriter&)>&);
  PlyStreamWriter(std::FILE* file, const std::string& shown, const PlyStreamHeader& header);
  void flush();
  void finish();

  std::FILE* file_;
  std::string shown_;
  PlyStreamHeader header_;
  std::uint64_t vertices_{0};
  std::uint64_t faces_{0};
  std::string buffer_;
};

/// Writes `path` as a binary PLY of `header`'s counts: `fill` appends every vertex and face through the
/// writer. Throws InvalidInput for a comment with a line break or counts beyond 32-bit indices, IoError
/// "PATH: cannot write ..." on a write failure, Error when `fill` wrote fewer or more items than declared;
/// the final file appears only on success.
void write_ply_streamed(const std::filesystem::path& path, const PlyStreamHeader& header,
                        const std::function<void(PlyStreamWriter&)>& fill);

}  // namespace gimforge::io
