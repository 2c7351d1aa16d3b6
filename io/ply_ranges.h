#pragma once
/// \file ply_ranges.h
/// A binary PLY of triangles read in pieces, for scans too large to load whole (issue #17): any range of
/// its vertices or faces is streamed in bounded chunks, and the positions of a sorted list of vertices are
/// picked out of one pass over the vertex records. Several ranks read the same file at once, each the
/// ranges it needs, with plain positioned reads (the page cache serves the repeats).
///
/// Eligible files: binary PLY in this machine's byte order, a vertex element of fixed-size records with
/// float or double x y z, and a face element of one list of int32/uint32 indices in which every face is a
/// triangle (the file's size says so). Anything else opens as std::nullopt: read it whole with read_mesh.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "io/formats_internal.h"
#include "kernels/core/errors.h"
#include "kernels/core/mesh.h"

namespace gimforge::io {

/// The largest coordinate magnitude a mesh may have: beyond it squared distances overflow single precision
/// (Embree's BVH, float32 images) and, from about 1e77 on, areas overflow double, so every measure of the
/// mesh would be inf or NaN, named after whatever computed it ("no area", "non-manifold vertices").
/// Whole-mesh loading (jobs::load_mesh) and the brick readers below refuse it alike.
inline constexpr double kMaxCoordinate = 1e18;
/// The refusal: "SHOWN: vertex I has a coordinate of magnitude M, beyond ±1e+18, where ... (scale the mesh down)".
[[nodiscard]] FormatError far_coordinate_error(std::string_view shown, std::uint64_t vertex, double magnitude);

/// The smallest bounding-box diagonal a mesh may have: below it squared distances at 10^-7 of the mesh's
/// size underflow single precision (10^-38; Embree's BVH queries then visit every face, float32 images lose
/// their digits), and from about 1e-150 on areas underflow double ("no area"). jobs::load_mesh and the brick
/// scan (jobs::scan_mesh) refuse it alike, and a mesh whose vertices all coincide (diagonal 0: the "no area"
/// errors of the methods named other causes, and validate passed it). Callers measure the diagonal with
/// stableNorm (its square underflows below 1e-162) over the vertices the faces use, and skip a mesh without faces.
inline constexpr double kMinDiagonal = 1e-12;
/// The refusal: "SHOWN: the mesh is only D across (bounding-box diagonal), below 1e-12, where ... (scale the
/// mesh up)", or for 0 "SHOWN: the mesh is 0 across: all the vertices its faces use coincide ..."; nullopt
/// when `diagonal` is at least kMinDiagonal or not finite.
[[nodiscard]] std::optional<InvalidInput> small_extent_error(std::string_view shown, double diagonal);

class PlyTriangleFile {
 public:
  /// Opens `path` and parses its header. std::nullopt when the file is not of the eligible layout (a PLY
  /// with polygons or trailing bytes included); IoError when it cannot be read, FormatError for a bad
  /// header or a file shorter than its header's counts ("truncated binary PLY: ...").
  [[nodiscard]] static std::optional<PlyTriangleFile> open(const std::filesystem::path& path);
  PlyTriangleFile(PlyTriangleFile&&) noexcept;
  PlyTriangleFile& operator=(PlyTriangleFile&&) noexcept;
  PlyTriangleFile(const PlyTriangleFile&) = delete;
  PlyTriangleFile& operator=(const PlyTriangleFile&) = delete;
  ~PlyTriangleFile();

  [[nodiscard]] std::uint64_t vertices() const { return layout_.vertices; }
  [[nodiscard]] std::uint64_t faces() const { return layout_.faces; }
  [[nodiscard]] const std::string& shown() const { return shown_; }
  /// Whether a vertex record holds x y z only (no colours, normals or other properties).
  [[nodiscard]] bool positions_only() const {
    return layout_.vertex_stride == 3 * (layout_.coord_double ? sizeof(double) : sizeof(float));
  }

  /// Calls `chunk(first_index, positions)` for the vertices [first, last) in order, a bounded number at a
  /// time. Throws FormatError "PATH: vertex I has a non-finite coordinate (...)", or "... a coordinate of
  /// magnitude M, beyond ±1e+18 ..." (kMaxCoordinate, as jobs::load_mesh refuses it).
  void read_vertices(std::uint64_t first, std::uint64_t last,
                     const std::function<void(std::uint64_t, std::span<const Vec3>)>& chunk) const;
  /// Calls `chunk(first_index, faces)` for the faces [first, last) in order. Throws FormatError "PATH: face
  /// I has K corners ..." for a record that is not a triangle and "PATH: face I: vertex index V out of
  /// range" for an index beyond the vertices.
  void read_faces(std::uint64_t first, std::uint64_t last,
                  const std::function<void(std::uint64_t, std::span<const Face>)>& chunk) const;
  /// The positions of the vertices `ids` (sorted, unique, < vertices()), in that order.
  [[nodiscard]] std::vector<Vec3> read_positions(std::span<const std::uint32_t> ids) const;

 private:
  PlyTriangleFile(int fd, std::string shown, const detail::PlyFixedLayout& layout)
      : fd_(fd), shown_(std::move(shown)), layout_(layout) {}
  void read_bytes(char* out, std::size_t bytes, std::uint64_t offset) const;

  int fd_{-1};
  std::string shown_;
  detail::PlyFixedLayout layout_;
};

}  // namespace gimforge::io
