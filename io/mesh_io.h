#pragma once
/// \file mesh_io.h
/// Reading and writing mesh files. Readers are strict: every count, index and byte is checked, and a
/// failure throws gimforge::FormatError / IoError whose one-line message starts with the path and names
/// the cause (e.g. "bunny.ply: truncated binary PLY: face 1021 of 69451 ends past the end of the file").
/// Readers never repair anything: the returned mesh is exactly what the file says (polygons
/// fan-triangulated), and validation/repair is the job of kernels/core/validate.h.
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "kernels/core/mesh.h"

namespace gimforge::io {

/// Mesh file formats gimforge reads.
enum class MeshFormat { Ply, Obj, Off, Stl };

/// Facts about a file that was read, for reports.
struct ReadInfo {
  MeshFormat format{MeshFormat::Ply};  ///< the format read (from the extension, confirmed by the contents)
  std::string encoding;             ///< "ascii", "binary_little_endian", "binary_big_endian", "binary" (STL)
  std::size_t file_bytes{0};        ///< size of the file read
  std::size_t polygons{0};          ///< faces as stored in the file (before triangulation)
  std::size_t triangulated{0};      ///< faces with more than 3 vertices that were fan-triangulated
  std::vector<double> vertex_scalar;  ///< read_ply_vertex_scalar: the property's value per vertex
  /// The file stores the coordinates as 32-bit floats (PLY x, y, z declared float, binary STL): whatever
  /// the source had beyond float32 was lost when it was written. Text values (OBJ, OFF, ASCII STL) are not.
  bool float32_coordinates{false};
  /// Why the file's vertex normals were dropped ("vertex 10 has a non-finite normal (nan, 0, 1)"), or empty:
  /// gimforge computes the normals it uses, so a broken one costs the file's normals, not the mesh.
  std::string dropped_normals;
};

/// Reads a mesh. The format is chosen by the file's extension (case-insensitive: .ply .obj .off .stl) and
/// then confirmed from the contents; a mismatch ("x.ply" holding OBJ text) is an error naming both.
/// Throws IoError (missing, unreadable, a directory, unknown extension) or FormatError (malformed content,
/// truncation, counts larger than the file, face with fewer than 3 vertices, index out of range,
/// non-numeric or non-finite values; a non-finite vertex normal drops the normals instead, said in
/// ReadInfo::dropped_normals).
/// Every message is one line starting with the path as given, then ": ", then the cause. Hostile headers
/// (counts larger than the file can hold) are rejected before anything is allocated for them.
/// Binary little-endian PLY with the common layout is decoded by a fast path (whole file read at once,
/// fixed-stride memcpy decoding).
[[nodiscard]] TriMesh read_mesh(const std::filesystem::path& path, ReadInfo* info = nullptr);

/// The values of the scalar vertex property `name` of a PLY file (e.g. "quality", "confidence"), one per
/// vertex in file order, read with the same checks as read_mesh (the mesh itself is checked and dropped).
/// Throws IoError for a file that is not .ply, FormatError naming the file when the vertex element has no
/// such scalar (with the names it has), when `name` is a position, normal or colour property, or when a
/// value is not finite.
[[nodiscard]] std::vector<double> read_ply_vertex_scalar(const std::filesystem::path& path, const std::string& name);

/// Format from the extension; throws IoError for an extension gimforge does not know.
[[nodiscard]] MeshFormat format_from_extension(const std::filesystem::path& path);

/// Short upper-case name of a format: "PLY", "OBJ", "OFF", "STL".
[[nodiscard]] const char* format_name(MeshFormat f);

/// The spacing of 32-bit floats around the mesh's largest coordinate, as a fraction of its bounding-box
/// diagonal (0 for an empty mesh or one without extent). Above kFloat32Tolerance a float32 file loses detail:
/// a georeferenced mesh (|x| ~ 10^6 to 10^7) of metres' size collapses to a few points.
[[nodiscard]] double float32_relative_spacing(const TriMesh& mesh);
inline constexpr double kFloat32Tolerance = 1e-6;

/// Whether every coordinate is a 32-bit float already (a float32 file of it loses nothing; false for NaN).
[[nodiscard]] bool float32_exact(const TriMesh& mesh);

/// Options for write_ply.
struct PlyWriteOptions {
  bool binary{true};            ///< binary_little_endian (default) or ascii
  bool double_precision{false}; ///< write x,y,z as double instead of float
  std::string comment{};        ///< optional header comment line (no newlines)
};

/// Writes the mesh as PLY (vertex x,y,z [+ nx,ny,nz] [+ red,green,blue uchar]; face uchar count +
/// int vertex_indices). Written through io::write_atomically (io/atomic_file.h): a temporary file in the
/// same directory, synced and renamed over `path`, so a reader never sees half a file; the directory must
/// exist.
/// Indices are written as int (uint when the mesh has more than 2^31-1 vertices); colours as uchar
/// round(255*c) of the colour clamped into [0,1]. ASCII output prints the shortest text that reads back
/// to the same float/double, so a write/read round trip is exact.
/// Throws InvalidInput (message starts with the path) when the mesh is inconsistent: colours or normals
/// not one per vertex, a face index out of range, a comment with a line break; IoError when the file
/// cannot be written.
void write_ply(const std::filesystem::path& path, const TriMesh& mesh, const PlyWriteOptions& options = {});

/// The format write_mesh writes for `path`: the one its extension names (case-insensitive .ply .obj .off
/// .stl). Throws InvalidInput "PATH: cannot write a mesh as '.xyz' (the extension names the format;
/// gimforge writes .ply, .obj, .off, .stl)" for any other extension or none. Commands call it before their
/// work, so a wrong name is refused at once.
[[nodiscard]] MeshFormat output_format(const std::filesystem::path& path);

/// Writes the mesh in the format its extension names (output_format): PLY through write_ply (binary,
/// with normals and colours); OBJ text (positions exact, colours, normals as vn); OFF text ([C][N]OFF,
/// positions exact); binary STL (float32 corners, face normals; STL keeps no vertex sharing, colours or
/// vertex normals). Written through io::write_atomically: the directory must exist. Every format reads
/// back (read_mesh) to the same faces and positions (STL: to float precision, welded by position).
/// Throws InvalidInput as output_format does and for an inconsistent mesh (colours or normals not one per
/// vertex, a face index out of range, more than 2^32 - 1 faces for STL), IoError when the file cannot be
/// written. `ply` applies to PLY output (e.g. double coordinates for a mesh far from the origin: OBJ and OFF
/// always keep doubles exactly, STL is float32 by definition).
void write_mesh(const std::filesystem::path& path, const TriMesh& mesh, const PlyWriteOptions& ply = {});

}  // namespace gimforge::io
