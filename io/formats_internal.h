#pragma once
/// \file formats_internal.h
/// Internal to gimforge_io: what the format readers share. A reader gets the whole file in memory (a
/// Source) and either returns the mesh or throws a FormatError whose one-line message is
/// "<path>: <cause>". Index checks, polygon triangulation, finiteness checks and colour conversion live
/// here so that every format reports the same problem with the same words.
#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "io/mesh_io.h"
#include "kernels/core/mesh.h"

namespace gimforge::io::detail {

/// A file's whole contents and the path to name in messages.
struct Source {
  std::string path;       ///< the path as the caller gave it
  std::string_view data;  ///< every byte of the file
  std::string_view vertex_scalar{};  ///< read_ply: also this vertex property, into ReadInfo::vertex_scalar
};

/// Throws InvalidInput "SHOWN: 32-bit float coordinates would move ... : INSTEAD" when float32 resolves the
/// mesh coarser than kFloat32Tolerance of its diagonal and some coordinate is not a float already (the STL
/// writer calls it; a mesh read from floats loses nothing).
void check_float32_resolves(const std::string& shown, const TriMesh& mesh, std::string_view instead);

/// Throws FormatError("<path>: <cause>").
[[noreturn]] void fail(const Source& src, std::string_view cause);

/// Throws FormatError("<path>: line <line>: <cause>"), or without the line part when `line` is 0.
[[noreturn]] void fail_line(const Source& src, std::size_t line, std::string_view cause);

/// Throws FormatError("<path>: not <a PLY> file (<what the contents look like>)").
[[noreturn]] void fail_not_format(const Source& src, MeshFormat expected);

/// Throws FormatError for a non-finite value: "[line L: ]<item> <index> has a non-finite <what> (nan)".
[[noreturn]] void fail_non_finite(const Source& src, std::string_view item, std::uint64_t index, const Vec3& v,
                                  std::string_view what, std::size_t line = 0);

/// Checks that the three values of vertex `index` are finite (`what`: "coordinate", "normal", "colour").
inline void check_finite(const Source& src, std::uint64_t index, const Vec3& v, std::string_view what,
                         std::size_t line = 0) {
  if (!v.allFinite()) fail_non_finite(src, "vertex", index, v, what, line);
}

/// A T from the bytes at `p` (any alignment), byte-swapped when `swap`.
template <class T>
[[nodiscard]] T load_bytes(const char* p, bool swap) {
  std::array<char, sizeof(T)> bytes;
  std::memcpy(bytes.data(), p, sizeof(T));
  if (swap) std::reverse(bytes.begin(), bytes.end());
  return std::bit_cast<T>(bytes);
}

/// A little-endian T from the bytes at `p`.
template <class T>
[[nodiscard]] T load_le(const char* p) {
  return load_bytes<T>(p, std::endian::native == std::endian::big);
}

/// Appends `v` to `out` as little-endian bytes.
template <class T>
void put_le(std::string& out, T v) {
  auto bytes = std::bit_cast<std::array<char, sizeof(T)>>(v);
  if constexpr (std::endian::native == std::endian::big) std::reverse(bytes.begin(), bytes.end());
  out.append(bytes.data(), bytes.size());
}

/// The welding key of an STL corner (stl.cpp, stl_stream.cpp): its exact float bits, −0 counted as +0.
using CornerKey = std::array<std::uint32_t, 3>;
[[nodiscard]] inline CornerKey corner_key(float x, float y, float z) {
  const auto bits = [](float v) { return std::bit_cast<std::uint32_t>(v == 0.0f ? 0.0f : v); };
  return {bits(x), bits(y), bits(z)};
}
/// Hashes a CornerKey, or any three unsigned words (the 64-bit keys of a text STL's double corners).
struct CornerKeyHash {
  template <class Key>
  std::size_t operator()(const Key& k) const noexcept {
    std::uint64_t h = k[0];
    h = (h * 0x9E3779B97F4A7C15ULL) ^ k[1];
    h = (h * 0x9E3779B97F4A7C15ULL) ^ k[2];
    h ^= h >> 29;
    return static_cast<std::size_t>(h * 0xBF58476D1CE4E5B9ULL);
  }
};

/// `v` rounded to float; values beyond float's range become +-inf (a plain cast would be undefined).
[[nodiscard]] inline float to_float(double v) {
  constexpr double kMax = static_cast<double>(std::numeric_limits<float>::max());
  if (v > kMax) return std::numeric_limits<float>::infinity();
  if (v < -kMax) return -std::numeric_limits<float>::infinity();
  return static_cast<float>(v);
}

/// Parses `token` as a number (text formats) or throws "line L: <what>: <token> is not a number".
[[nodiscard]] double number_at(const Source& src, std::size_t line, std::string_view token, std::string_view what);

/// Parses `token` as an integer (text formats) or throws "line L: <what>: <token> is not an integer".
[[nodiscard]] std::int64_t integer_at(const Source& src, std::size_t line, std::string_view token,
                                      std::string_view what);

/// An RGB colour from values meant to lie in [0,1]: checked finite (error names vertex `index`), then
/// clamped into [0,1].
[[nodiscard]] Vec3f unit_color(const Source& src, std::uint64_t index, const Vec3& rgb, std::size_t line = 0);

/// Throws "[line L: ]face F has N vertices; a face needs at least 3".
[[noreturn]] void fail_face_size(const Source& src, std::int64_t count, std::uint64_t face_no, std::size_t line = 0);

/// Checks that a face has at least 3 vertices (fail_face_size otherwise).
inline void check_face_size(const Source& src, std::int64_t count, std::uint64_t face_no, std::size_t line = 0) {
  if (count < 3) fail_face_size(src, count, face_no, line);
}

/// Checks polygons, converts them to triangles (fan from the first vertex) and appends them to a face
/// list. Used by every reader, so index and face-size errors read the same in every format.
class FaceBuilder {
 public:
  /// Appends to `faces`; valid indices are [0, num_vertices). `index_base` is added to indices shown in
  /// messages (1 for OBJ, whose files count from 1).
  FaceBuilder(const Source& src, std::vector<Face>& faces, std::uint64_t num_vertices, std::int64_t index_base = 0)
      : src_(src), faces_(faces), num_vertices_(num_vertices), index_base_(index_base) {}

  /// Throws "[line L: ]face F has N vertices; a face needs at least 3" unless count >= 3.
  void check_count(std::int64_t count, std::uint64_t face_no, std::size_t line = 0) const {
    check_face_size(src_, count, face_no, line);
  }

  /// Checks polygon `face_no` (size and every index) and appends its triangles.
  void add(std::span<const std::int64_t> polygon, std::uint64_t face_no, std::size_t line = 0);

  /// Throws the out-of-range message for `index` (0-based) in face `face_no`.
  [[noreturn]] void fail_index(std::int64_t index, std::uint64_t face_no, std::size_t line = 0) const;

  /// Number of polygons with more than 3 vertices that add() triangulated.
  [[nodiscard]] std::size_t triangulated() const { return triangulated_; }

 private:
  const Source& src_;
  std::vector<Face>& faces_;
  std::uint64_t num_vertices_;
  std::int64_t index_base_;
  std::size_t triangulated_{0};
};

/// Appends the fan triangulation (v0,v1,v2), (v0,v2,v3), ... of a polygon with at least 3 vertices.
void fan_triangulate(std::span<const std::uint32_t> polygon, std::vector<Face>& faces);

// ---- content sniffing (each defined next to its format) ----

/// The file starts with the PLY magic line "ply".
[[nodiscard]] bool looks_like_ply(std::string_view data);
/// The first non-comment token is an OFF keyword (OFF, COFF, NOFF, ...).
[[nodiscard]] bool looks_like_off(std::string_view data);
/// The first non-comment line starts with an OBJ statement (v, vn, vt, f, o, g, mtllib, ...).
[[nodiscard]] bool looks_like_obj(std::string_view data);
/// The file starts with "solid" (ASCII STL).
[[nodiscard]] bool looks_like_ascii_stl(std::string_view data);
/// The file's size is exactly 84 + 50 * (its binary STL triangle count).
[[nodiscard]] bool looks_like_binary_stl(std::string_view data);

/// What the contents look like, for "not a PLY file (...)": "it looks like an OBJ file", "it contains
/// binary data (byte 0x00 at offset 17)", "it starts with 'hello'". Never names `expected`.
[[nodiscard]] std::string describe_contents(std::string_view data, MeshFormat expected);

// ---- the readers (ply.cpp, obj.cpp, off.cpp, stl.cpp); each fills info.encoding/polygons/triangulated ----

[[nodiscard]] TriMesh read_ply(const Source& src, ReadInfo& info);
[[nodiscard]] TriMesh read_obj(const Source& src, ReadInfo& info);
[[nodiscard]] TriMesh read_off(const Source& src, ReadInfo& info);
[[nodiscard]] TriMesh read_stl(const Source& src, ReadInfo& info);

/// The layout of a binary PLY in this machine's byte order with a vertex element of fixed-size records
/// (float or double x y z) followed by a face element of one index list (io/ply_ranges.h reads it in
/// pieces). Only meaningful when every face is a triangle: then each face record is `face_stride` bytes.
struct PlyFixedLayout {
  std::uint64_t vertices{0};
  std::uint64_t faces{0};
  std::size_t body_offset{0};  ///< first vertex record
  std::size_t vertex_stride{0};
  std::array<std::size_t, 3> coord_offset{};
  bool coord_double{false};
  std::size_t count_size{1};   ///< bytes of the list length (1 or 4)
  bool index_signed{true};     ///< int32 or uint32 indices
  [[nodiscard]] std::size_t face_stride() const { return count_size + 12; }
  [[nodiscard]] std::uint64_t triangle_file_bytes() const { return body_offset + vertices * vertex_stride + faces * face_stride(); }
};
/// Parses the PLY header in `src` (the file's first bytes, end_header included); std::nullopt for any other
/// layout (ASCII, other byte order, more elements, vertex lists). Throws FormatError for a bad header.
[[nodiscard]] std::optional<PlyFixedLayout> ply_fixed_layout(const Source& src);

// ---- the writers (obj.cpp, off.cpp, stl.cpp): the whole file's bytes for a mesh write_mesh has checked ----

/// OBJ text: "v x y z [r g b]" per vertex, "vn" per vertex when it has normals, "f a b c" (1-based;
/// "a//a ..." with normals). Coordinates print as the shortest text that reads back to the same double.
[[nodiscard]] std::string obj_bytes(const TriMesh& mesh);
/// OFF text ("OFF", "NOFF", "COFF" or "CNOFF"): "x y z [nx ny nz] [r g b]" per vertex (colours as reals in
/// [0,1], always with a decimal point), "3 a b c" per face; coordinates exact as for OBJ.
[[nodiscard]] std::string off_bytes(const TriMesh& mesh);
/// Binary STL: 80-byte header, triangle count, per triangle its unit normal and three corners as float32.
/// STL has no shared vertices, colours or vertex normals: reading it back welds corners by position.
[[nodiscard]] std::string stl_bytes(const TriMesh& mesh);

/// The shortest text that reads back to exactly `v` ("0.1", "1e+30", "3").
[[nodiscard]] std::string exact_text(double v);

/// Writes `bytes` to `path` through io::write_atomically (its directory must exist); throws IoError
/// naming `path` and the cause.
void write_file_atomically(const std::filesystem::path& path, std::string_view bytes);

}  // namespace gimforge::io::detail
