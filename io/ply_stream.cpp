#include "io/ply_stream.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <limits>
#include <system_error>

#include <fmt/format.h>

#include "io/atomic_file.h"
#include "io/formats_internal.h"
#include "kernels/core/errors.h"

namespace gimforge::io {
namespace {

constexpr std::size_t kFlushBytes = std::size_t{8} << 20;  // 8 MiB blocks

}  // namespace

PlyStreamWriter::PlyStreamWriter(std::FILE* file, const std::string& shown, const PlyStreamHeader& header)
    : file_(file), shown_(shown), header_(header) {
  buffer_ = fmt::format("ply\nformat binary_little_endian 1.0\n");
  if (!header.comment.empty()) buffer_ += fmt::format("comment {}\n", header.comment);
  const char* coord = header.double_precision ? "double" : "float";
  buffer_ += fmt::format("element vertex {}\nproperty {} x\nproperty {} y\nproperty {} z\n", header.vertices, coord, coord, coord);
  buffer_ += fmt::format("element face {}\nproperty list uchar {} vertex_indices\nend_header\n", header.faces,
                         header.vertices > static_cast<std::uint64_t>(std::numeric_limits<std::int32_t>::max()) ? "uint" : "int");
}

void PlyStreamWriter::add_vertices(std::span<const Vec3> positions) {
  if (faces_ > 0) throw Error(fmt::format("{}: PLY stream: vertices after faces", shown_));
  if (positions.size() > header_.vertices - vertices_)
    throw Error(fmt::format("{}: PLY stream: more than the {} declared vertices", shown_, header_.vertices));
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const Vec3& p = positions[i];
    for (const double x : p) {
      const double stored = header_.double_precision ? x : static_cast<double>(detail::to_float(x));
      if (!std::isfinite(stored))
        throw InvalidInput(fmt::format("{}: PLY stream: vertex {} has a coordinate that is not a finite {} ({})", shown_,
                                       vertices_ + i, header_.double_precision ? "double" : "float", x));
      if (header_.double_precision) {
        detail::put_le(buffer_, x);
      } else {
        detail::put_le(buffer_, detail::to_float(x));
      }
    }
    if (buffer_.size() >= kFlushBytes) flush();
  }
  vertices_ += positions.size();
}

void PlyStreamWriter::add_faces(std::span<const Face> faces) {
  if (vertices_ != header_.vertices)
    throw Error(fmt::format("{}: PLY stream: faces after {} of the {} declared vertices", shown_, vertices_, header_.vertices));
  if (faces.size() > header_.faces - faces_)
    throw Error(fmt::format("{}: PLY stream: more than the {} declared faces", shown_, header_.faces));
  for (const Face& f : faces) {
    detail::put_le(buffer_, std::uint8_t{3});
    for (const std::uint32_t v : f) {
      if (v >= header_.vertices)
        throw InvalidInput(fmt::format("{}: PLY stream: face {}: vertex index {} is out of range ({} vertices)", shown_,
                                       faces_, v, header_.vertices));
      detail::put_le(buffer_, v);  // the same bytes as int for indices < 2^31
    }
    ++faces_;
    if (buffer_.size() >= kFlushBytes) flush();
  }
}

void PlyStreamWriter::flush() {
  if (!buffer_.empty() && std::fwrite(buffer_.data(), 1, buffer_.size(), file_) != buffer_.size())
    throw IoError(fmt::format("{}: cannot write: {}", shown_, std::generic_category().message(errno)));
  buffer_.clear();
}

void PlyStreamWriter::finish() {
  if (vertices_ != header_.vertices || faces_ != header_.faces)
    throw Error(fmt::format("{}: PLY stream: {} vertices and {} faces written, {} and {} declared", shown_, vertices_,
                            faces_, header_.vertices, header_.faces));
  flush();
}

void write_ply_streamed(const std::filesystem::path& path, const PlyStreamHeader& header,
                        const std::function<void(PlyStreamWriter&)>& fill) {
  const std::string shown = path.string();
  if (header.comment.find_first_of("\r\n") != std::string::npos)
    throw InvalidInput(fmt::format("{}: cannot write PLY: the comment contains a line break", shown));
  constexpr std::uint64_t kMax = std::numeric_limits<std::uint32_t>::max();
  if (header.vertices > kMax || header.faces > kMax)
    throw InvalidInput(fmt::format("{}: cannot write PLY: {} vertices and {} faces exceed 32-bit indices", shown,
                                   header.vertices, header.faces));
  write_atomically(
      path,
      [&](const std::filesystem::path& tmp) {
        std::FILE* file = std::fopen(tmp.c_str(), "wb");
        if (file == nullptr)
          throw IoError(fmt::format("{}: cannot create the temporary file '{}': {}", shown, tmp.string(),
                                    std::generic_category().message(errno)));
        try {
          PlyStreamWriter writer(file, shown, header);
          fill(writer);
          writer.finish();
        } catch (...) {
          std::fclose(file);
          throw;
        }
        if (std::fclose(file) != 0)
          throw IoError(fmt::format("{}: cannot write: {}", shown, std::generic_category().message(errno)));
      },
      ParentDirectory::kMustExist);
}

}  // namespace gimforge::io
