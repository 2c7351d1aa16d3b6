// `gimforge convert-format IN -o OUT.ply`: any mesh format rewritten as the binary little-endian PLY of
// triangles that the brick paths read in pieces (io/ply_ranges.h): `mpirun ... metrics`, `convert` through a
// proxy and `convert --method relief` then go by bricks (docs/cli.md, "Huge inputs").

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "io/atomic_file.h"
#include "io/mesh_io.h"
#include "io/ply_ranges.h"
#include "io/printable.h"
#include "io/stl_stream.h"
#include "jobs/cli/commands.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/gim_store.h"
#include "jobs/memory_budget.h"
#include "kernels/core/errors.h"
#include "kernels/core/validate.h"

namespace gimforge::cli {
namespace {

/// Inputs other than binary STL are read whole: the file's bytes and the mesh built from them, about three
/// times the file. Refused, before anything is read, when that is more than the machine has available: an
/// out-of-memory kill would say nothing.
void refuse_if_too_large(const std::string& input) {
  std::error_code ec;
  const std::uintmax_t bytes = std::filesystem::file_size(input, ec);
  if (ec) return;  // the reader says what is wrong
  // Without a readable limit (or with GIMFORGE_MEMORY_CHECK=off) nothing is refused.
  const std::optional<jobs::MemoryLimit> limit = jobs::memory_limit();
  const double need = 3.0 * static_cast<double>(bytes);
  const double have = limit ? static_cast<double>(limit->bytes) : need;
  if (need > have)
    throw InvalidInput(fmt::format("{}: {:.1f} GB; convert-format reads this input whole, which takes about {:.1f} GB, "
                                   "more than the {:.1f} GB this machine has available (only a binary STL is "
                                   "streamed); a binary PLY of x y z and triangles needs no conversion: the bricks "
                                   "read it as it is",
                                   io::printable(input), static_cast<double>(bytes) / 1e9, need / 1e9, have / 1e9));
}

/// Binary STL, streamed (io/stl_stream.h): the same output as reading it whole, in bounded memory.
int convert_stl_in_pieces(const ConvertFormatOptions& o, std::chrono::steady_clock::time_point start) {
  // STL coordinates are floats: "auto" keeps them so, as for an STL read whole.
  const bool use_double = o.precision == "double";
  const io::StreamedMesh m = io::stream_stl_to_ply(o.input, o.output, "gimforge convert-format", use_double);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto bytes = std::filesystem::file_size(o.output);
  const char* precision = use_double ? "double" : "float";
  if (o.json) {
    const nlohmann::json j = {{"input", o.input},          {"output", o.output},        {"format", "STL"},
                              {"encoding", "binary"},      {"vertices", m.vertices},    {"faces", m.faces},
                              {"triangulated", 0},         {"welded", 0},               {"removed_faces", 0},
                              {"precision", precision},    {"normals", false},
                              {"colors", false},           {"readable_in_pieces", true}, {"relief_by_bricks", true},
                              {"streamed", true},          {"bytes", bytes},            {"seconds", seconds}};
    fmt::print("{}\n", j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace));
  } else {
    fmt::print("{} (STL binary, streamed) -> {}: {} vertices, {} faces, {} coordinates, {:.1f} MB in {:.1f} s\n",
               io::printable(o.input), io::printable(o.output), m.vertices, m.faces, precision,
               static_cast<double>(bytes) / 1e6, seconds);
  }
  return kExitOk;
}

}  // namespace

int run_convert_format(const ConvertFormatOptions& o) {
  const auto start = std::chrono::steady_clock::now();
  std::string extension = std::filesystem::path(o.output).extension().string();
  for (char& ch : extension) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (extension != ".ply")
    throw InvalidInput(fmt::format("{}: convert-format writes PLY; name the output .ply", io::printable(o.output)));
  io::check_can_create(o.output);
  jobs::refuse_output_over_inputs(o.output, {o.input});
  // --weld reads the STL whole: its corners are welded as streamed, but not its degenerate and duplicate faces.
  if (!o.weld && io::is_streamable_binary_stl(o.input)) return convert_stl_in_pieces(o, start);
  refuse_if_too_large(o.input);
  io::ReadInfo info;
  TriMesh mesh = io::read_mesh(o.input, &info);
  if (mesh.faces.empty()) throw InvalidInput(fmt::format("{}: the mesh has no faces", io::printable(o.input)));
  if (!info.dropped_normals.empty() && !o.positions_only)
    spdlog::warn("{}: {}: the output has no vertex normals", io::printable(o.input), info.dropped_normals);
  if (o.positions_only) {
    mesh.normals.clear();
    mesh.colors.clear();
  }
  std::size_t welded = 0, removed_faces = 0;
  if (o.weld) {
    welded = weld_positions(mesh);
    const RepairReport r = repair_mesh(mesh);
    removed_faces = r.removed_degenerate_faces + r.removed_duplicate_faces;
    if (mesh.faces.empty())
      throw InvalidInput(fmt::format("{}: no face is left after welding (every face had two corners at one position)",
                                     io::printable(o.input)));
  }
  // A mesh whose coordinates are all floats already (a float PLY, a binary STL) loses nothing as float, however
  // far from the origin it lies: auto keeps it so, and only --precision float over values a float would move
  // far from the origin is refused.
  // Auto also writes double when the input stored more than float32 (a double PLY, a text format) and float32
  // would resolve its coordinates coarser than kFloat32Tolerance: whole metres at UTM coordinates are float32
  // values, but a float file of them reads as one that lost its decimals (the loader warns about it).
  const bool exact = io::float32_exact(mesh);
  const double spacing = io::float32_relative_spacing(mesh);
  const bool coarse = !info.float32_coordinates && spacing > io::kFloat32Tolerance;
  const bool use_double = o.precision == "double" || (o.precision == "auto" && (!exact || coarse));
  if (!use_double && !exact && spacing > io::kFloat32Tolerance)
    throw InvalidInput(fmt::format("{}: --precision float would move its vertices by up to {:.2g} of the bounding-box "
                                   "diagonal (the mesh lies far from the origin); use --precision double or auto",
                                   io::printable(o.input), spacing / 2.0));
  if (!use_double)
    for (std::size_t v = 0; v < mesh.positions.size(); ++v)
      if (!mesh.positions[v].cast<float>().allFinite())
        throw InvalidInput(fmt::format("{}: vertex {} ({}, {}, {}) does not fit a float; use --precision double or auto",
                                       io::printable(o.input), v, mesh.positions[v].x(), mesh.positions[v].y(),
                                       mesh.positions[v].z()));
  io::write_ply(o.output, mesh, {.binary = true, .double_precision = use_double, .comment = "gimforge convert-format"});
  // What the brick paths will make of it (a mesh of over 2^31 - 1 vertices gets uint indices, which they read too).
  const std::optional<io::PlyTriangleFile> pieces = io::PlyTriangleFile::open(o.output);
  const bool in_pieces = pieces.has_value();
  // Relief by bricks also needs vertex records of x y z alone (no colours to lose).
  const bool relief_in_pieces = in_pieces && pieces->positions_only();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto bytes = std::filesystem::file_size(o.output);
  const char* precision = use_double ? "double" : "float";
  if (o.json) {
    const nlohmann::json j = {{"input", o.input},
                              {"output", o.output},
                              {"format", io::format_name(info.format)},
                              {"encoding", info.encoding},
                              {"vertices", mesh.num_vertices()},
                              {"faces", mesh.num_faces()},
                              {"triangulated", info.triangulated},
                              {"welded", welded},
                              {"removed_faces", removed_faces},
                              {"precision", precision},
                              {"normals", !mesh.normals.empty()},
                              {"colors", !mesh.colors.empty()},
                              {"readable_in_pieces", in_pieces},
                              {"relief_by_bricks", relief_in_pieces},
                              {"streamed", false},
                              {"bytes", bytes},
                              {"seconds", seconds}};
    fmt::print("{}\n", j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace));
  } else {
    fmt::print("{} ({} {}) -> {}: {} vertices, {} faces ({} polygon(s) fan-triangulated{}), {} coordinates{}, "
               "{:.1f} MB in {:.1f} s\n",
               io::printable(o.input), io::format_name(info.format), info.encoding, io::printable(o.output),
               mesh.num_vertices(), mesh.num_faces(), info.triangulated,
               o.weld ? fmt::format("; {} vertices welded, {} faces dropped", welded, removed_faces) : "", precision,
               mesh.colors.empty() && mesh.normals.empty() ? "" : " (with normals or colours)",
               static_cast<double>(bytes) / 1e6, seconds);
  }
  return kExitOk;
}

}  // namespace gimforge::cli
