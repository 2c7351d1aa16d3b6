// `gimforge synth subdivide|terrain`: synthetic scans of any size written as binary PLY, piece by piece
// (kernels/scan/synth.h, io/ply_stream.h), so tests make small ones and benchmarks 50M-face ones on the fly.
#include <algorithm>
#include <array>
#include <chrono>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "io/atomic_file.h"
#include "io/ply_ranges.h"
#include "io/ply_stream.h"
#include "jobs/cli/commands.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/gim_store.h"
#include "jobs/load_mesh.h"
#include "jobs/progress.h"
#include "kernels/core/errors.h"
#include "kernels/scan/synth.h"

namespace gimforge::cli {
namespace {

constexpr std::uint64_t kVertexBlock = 1 << 16;

Vec3 offset_of(const SynthOptions& o) {
  if (o.offset.empty()) return Vec3::Zero();
  if (o.offset.size() != 3) throw InvalidInput(fmt::format("--offset needs three numbers X,Y,Z, not {}", o.offset.size()));
  for (const double x : o.offset)  // what every reader takes (the mesh's detail is gone long before)
    if (!(std::abs(x) <= io::kMaxCoordinate))
      throw InvalidInput(fmt::format("--offset {:g} is beyond ±{:g}, which no command reads back", x, io::kMaxCoordinate));
  return {o.offset[0], o.offset[1], o.offset[2]};
}

/// Prints the summary of a written scan.
void summarize(const SynthOptions& o, std::uint64_t vertices, std::uint64_t faces, const nlohmann::json& extra, double seconds) {
  const auto bytes = std::filesystem::file_size(o.output);
  if (o.json) {
    nlohmann::json j = extra;
    j["output"] = o.output;
    j["vertices"] = vertices;
    j["faces"] = faces;
    j["bytes"] = bytes;
    j["seconds"] = seconds;
    fmt::print("{}\n", j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace));
  } else {
    fmt::print("{}: {} vertices, {} faces, {:.1f} MB in {:.1f} s\n", o.output, vertices, faces, static_cast<double>(bytes) / 1e6, seconds);
  }
}

/// Writes the subdivided scan; returns its segments, vertex and face counts.
std::array<std::uint64_t, 3> run_subdivide(const SynthOptions& o, jobs::TerminalProgress& progress, const Vec3& offset) {
  const jobs::LoadedMesh base = jobs::load_mesh(o.base, jobs::LoadPolicy{.repair = true, .warn = true});
  SubdivideOptions so;
  so.segments = o.segments;
  if (o.faces > 0) {  // the least n with F0·n² ≥ faces
    const double ratio = static_cast<double>(o.faces) / static_cast<double>(std::max<std::size_t>(1, base.mesh.faces.size()));
    const double n = std::max(1.0, std::ceil(std::sqrt(ratio) - 1e-9));
    if (n > 65535.0) throw InvalidInput(fmt::format("--faces {}: too many for 32-bit indices", o.faces));
    so.segments = static_cast<std::uint32_t>(n);
  }
  so.amplitude = o.amplitude;
  so.wavelength = o.wavelength;
  so.seed = o.seed;
  so.offset = offset;
  const SubdividedScan scan(base.mesh, so);
  const auto cb = progress.callback();
  io::PlyStreamHeader header{scan.num_vertices(), scan.num_faces(), o.double_precision || offset != Vec3::Zero(),
                             fmt::format("gimforge synth subdivide {} segments {} seed {}", std::filesystem::path(o.base).filename().string(), so.segments, o.seed)};
  io::write_ply_streamed(o.output, header, [&](io::PlyStreamWriter& w) {
    std::vector<Vec3> vertices;
    for (std::uint64_t first = 0; first < scan.num_vertices(); first += kVertexBlock) {
      vertices.clear();
      scan.vertices(first, kVertexBlock, vertices);
      w.add_vertices(vertices);
      report_progress(cb, "vertices", static_cast<double>(first) / static_cast<double>(scan.num_vertices()));
    }
    std::vector<Face> faces;
    for (std::size_t f = 0; f < scan.num_base_faces(); ++f) {
      faces.clear();
      scan.faces_of(f, faces);
      w.add_faces(faces);
      if (f % 1024 == 0) report_progress(cb, "faces", static_cast<double>(f) / static_cast<double>(scan.num_base_faces()));
    }
  });
  return {so.segments, scan.num_vertices(), scan.num_faces()};
}

}  // namespace

int run_synth(const SynthOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  io::check_can_create(o.output);
  std::string ext = std::filesystem::path(o.output).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext != ".ply") throw InvalidInput(fmt::format("{}: synth writes binary PLY: give a .ply file name", o.output));
  if (o.kind == "subdivide") jobs::refuse_output_over_inputs(o.output, {o.base});  // also through a link
  io::remove_stale_temporaries(o.output);  // leftovers of synth runs that were killed before their commit
  const Vec3 offset = offset_of(o);
  jobs::TerminalProgress progress("synth", o.progress);
  nlohmann::json extra;
  std::uint64_t vertices = 0, faces = 0;
  if (o.kind == "subdivide") {
    const auto [segments, nv, nf] = run_subdivide(o, progress, offset);
    extra["segments"] = segments;
    vertices = nv;
    faces = nf;
  } else {
    TerrainOptions to;
    if (o.faces > 0) {  // a square grid of ≈ faces triangles before the holes
      const double side = std::ceil(std::sqrt(static_cast<double>(o.faces) / 2.0));
      if (side > 46340.0) throw InvalidInput(fmt::format("--faces {}: too many for 32-bit indices", o.faces));
      to.nx = to.ny = static_cast<std::uint32_t>(side);
    } else {
      if (o.grid.empty() || o.grid.size() > 2) throw InvalidInput("synth terrain: give --grid NX[,NY] or --faces F");
      to.nx = o.grid[0];
      to.ny = o.grid.size() == 2 ? o.grid[1] : o.grid[0];
    }
    to.spacing = o.spacing;
    to.relief = o.relief;
    to.noise = o.noise;
    to.holes = o.holes;
    to.hole_radius = o.hole_radius;
    to.seed = o.seed;
    to.offset = offset;
    const TerrainScan scan(to);
    const auto cb = progress.callback();
    io::PlyStreamHeader header{scan.num_vertices(), scan.num_faces(), o.double_precision || offset != Vec3::Zero(),
                               fmt::format("gimforge synth terrain {}x{} seed {}", to.nx, to.ny, o.seed)};
    io::write_ply_streamed(o.output, header, [&](io::PlyStreamWriter& w) {
      std::vector<Vec3> row;
      for (std::uint32_t y = 0; y <= to.ny; ++y) {
        row.clear();
        scan.vertex_row(y, row);
        w.add_vertices(row);
        report_progress(cb, "vertices", static_cast<double>(y) / to.ny);
      }
      std::vector<Face> tri;
      for (std::uint32_t y = 0; y < to.ny; ++y) {
        tri.clear();
        scan.face_row(y, tri);
        w.add_faces(tri);
        report_progress(cb, "faces", static_cast<double>(y) / to.ny);
      }
    });
    extra["grid"] = {to.nx, to.ny};
    vertices = scan.num_vertices();
    faces = scan.num_faces();
  }
  progress.finish();
  const auto seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  summarize(o, vertices, faces, extra, seconds);
  return kExitOk;
}

}  // namespace gimforge::cli
