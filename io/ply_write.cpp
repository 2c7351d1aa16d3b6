// PLY writer: ASCII or binary little-endian, float or double coordinates, optional normals and colours,
// through the one atomic write (io/atomic_file.h). The reader is io/ply.cpp.
#include <algorithm>
#include <array>
#include <bit>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <new>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

#include "io/formats_internal.h"
#include "kernels/core/errors.h"

namespace gimforge::io {

namespace detail {
namespace {

void check_writable(const std::string& shown, const TriMesh& mesh, const PlyWriteOptions& options) {
  const std::size_t nv = mesh.num_vertices();
  if (mesh.has_colors() && mesh.colors.size() != nv) {
    throw InvalidInput(fmt::format("{}: cannot write PLY: {} colours for {} vertices", shown, mesh.colors.size(), nv));
  }
  if (mesh.has_normals() && mesh.normals.size() != nv) {
    throw InvalidInput(fmt::format("{}: cannot write PLY: {} normals for {} vertices", shown, mesh.normals.size(), nv));
  }
  if (nv > UINT32_MAX) throw InvalidInput(fmt::format("{}: cannot write PLY: {} vertices is too many", shown, nv));
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    for (const std::uint32_t v : mesh.faces[f]) {
      if (v >= nv) {
        throw InvalidInput(fmt::format("{}: cannot write PLY: face {}: vertex index {} is out of range ({} vertices)",
                                       shown, f, v, nv));
      }
    }
  }
  if (options.comment.find_first_of("\r\n") != std::string::npos) {
    throw InvalidInput(fmt::format("{}: cannot write PLY: the comment contains a line break", shown));
  }
}

bool needs_uint_indices(const TriMesh& mesh) { return mesh.num_vertices() > static_cast<std::size_t>(INT32_MAX); }

std::string ply_header(const TriMesh& mesh, const PlyWriteOptions& options) {
  std::string h = fmt::format("ply\nformat {} 1.0\n", options.binary ? "binary_little_endian" : "ascii");
  if (!options.comment.empty()) h += fmt::format("comment {}\n", options.comment);
  const char* coord = options.double_precision ? "double" : "float";
  h += fmt::format("element vertex {}\nproperty {} x\nproperty {} y\nproperty {} z\n", mesh.num_vertices(), coord,
                   coord, coord);
  if (mesh.has_normals()) h += "property float nx\nproperty float ny\nproperty float nz\n";
  if (mesh.has_colors()) h += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  h += fmt::format("element face {}\nproperty list uchar {} vertex_indices\nend_header\n", mesh.num_faces(),
                   needs_uint_indices(mesh) ? "uint" : "int");
  return h;
}

std::uint8_t color_byte(float c) {
  if (!(c > 0.0f)) return 0;  // also NaN
  return c >= 1.0f ? std::uint8_t{255} : static_cast<std::uint8_t>(std::lround(c * 255.0f));
}

/// Appends `v` in little-endian byte order.
template <class T>
void put(char*& p, T v) {
  auto bytes = std::bit_cast<std::array<char, sizeof(T)>>(v);
  if constexpr (std::endian::native == std::endian::big) std::reverse(bytes.begin(), bytes.end());
  std::memcpy(p, bytes.data(), sizeof(T));
  p += sizeof(T);
}

void append_binary_body(std::string& out, const TriMesh& mesh, const PlyWriteOptions& options) {
  const std::size_t coord = options.double_precision ? 8 : 4;
  const std::size_t vertex = 3 * coord + (mesh.has_normals() ? 12 : 0) + (mesh.has_colors() ? 3 : 0);
  const std::size_t start = out.size();
  out.resize(start + mesh.num_vertices() * vertex + mesh.num_faces() * 13);
  char* p = out.data() + start;
  for (std::size_t i = 0; i < mesh.num_vertices(); ++i) {
    for (const double x : mesh.positions[i]) {
      if (options.double_precision) {
        put(p, x);
      } else {
        put(p, to_float(x));
      }
    }
    if (mesh.has_normals()) {
      for (const float x : mesh.normals[i]) put(p, x);
    }
    if (mesh.has_colors()) {
      for (const float x : mesh.colors[i]) put(p, color_byte(x));
    }
  }
  for (const Face& f : mesh.faces) {
    put(p, std::uint8_t{3});
    for (const std::uint32_t v : f) put(p, v);  // same bytes as int for indices < 2^31
  }
}

void append_ascii_body(std::string& out, const TriMesh& mesh, const PlyWriteOptions& options) {
  auto it = std::back_inserter(out);
  for (std::size_t i = 0; i < mesh.num_vertices(); ++i) {
    const Vec3& p = mesh.positions[i];
    if (options.double_precision) {
      fmt::format_to(it, "{} {} {}", p.x(), p.y(), p.z());
    } else {
      fmt::format_to(it, "{} {} {}", to_float(p.x()), to_float(p.y()), to_float(p.z()));
    }
    if (mesh.has_normals())
      fmt::format_to(it, " {} {} {}", mesh.normals[i].x(), mesh.normals[i].y(), mesh.normals[i].z());
    if (mesh.has_colors()) {
      const Vec3f& c = mesh.colors[i];
      fmt::format_to(it, " {} {} {}", color_byte(c.x()), color_byte(c.y()), color_byte(c.z()));
    }
    out += '\n';
  }
  for (const Face& f : mesh.faces) fmt::format_to(it, "3 {} {} {}\n", f[0], f[1], f[2]);
}

}  // namespace
}  // namespace detail

void write_ply(const std::filesystem::path& path, const TriMesh& mesh, const PlyWriteOptions& options) {
  const std::string shown = path.string();
  detail::check_writable(shown, mesh, options);
  try {
    std::string bytes = detail::ply_header(mesh, options);
    if (options.binary) {
      detail::append_binary_body(bytes, mesh, options);
    } else {
      detail::append_ascii_body(bytes, mesh, options);
    }
    detail::write_file_atomically(path, bytes);
  } catch (const std::bad_alloc&) {
    throw IoError(fmt::format("{}: out of memory while writing PLY", shown));
  } catch (const std::length_error&) {
    throw IoError(fmt::format("{}: out of memory while writing PLY", shown));
  }
}

}  // namespace gimforge::io
