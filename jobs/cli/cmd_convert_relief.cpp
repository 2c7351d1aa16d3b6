// `gimforge convert --method relief`: relief maps on cubic cell complexes (Apaza & Andújar).
#include <algorithm>
#include <array>
#include <charconv>
#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "io/relief_archive.h"
#include "jobs/cli/commands.h"
#include "jobs/cli/convert_common.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/gim_store.h"
#include "jobs/load_mesh.h"
#include "jobs/progress.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "kernels/relief/relief_map.h"

namespace gimforge::cli {
namespace {

using Clock = std::chrono::steady_clock;

/// Largest grid and texture of build_relief_map (kernels/relief/relief_map.h).
constexpr std::uint32_t kMaxReliefGrid = 1024;
constexpr std::uint32_t kMaxReliefTexture = 1024;

nlohmann::json parameters(const ConvertOptions& o) {
  return {{"method", o.method},         {"grid", o.grid},
          {"texture", o.texture},       {"max_grid", o.max_grid},
          {"occlusion_threshold", o.occlusion_threshold}, {"metric_samples", o.metric_samples}};
}

/// --grid: "auto" is 0 (the automatic choice), else N in 1..1024. The CLI checks it already; this guards
/// other callers.
std::uint32_t parse_grid(const std::string& text) {
  if (text == "auto") return 0;
  std::uint32_t n = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), n);
  if (ec != std::errc{} || end != text.data() + text.size() || n < 1 || n > kMaxReliefGrid)
    throw InvalidInput(fmt::format("--grid '{}' is neither 'auto' nor a number of cells per axis in [1, {}]", text,
                                   kMaxReliefGrid));
  return n;
}

ReliefOptions relief_options(const ConvertOptions& o) {
  ReliefOptions r;
  r.grid = parse_grid(o.grid);
  if (o.texture < 2 || o.texture > kMaxReliefTexture)
    throw InvalidInput(fmt::format("--texture {} is out of range [2, {}]", o.texture, kMaxReliefTexture));
  r.texture = o.texture;
  r.max_grid = o.max_grid;
  r.occlusion_threshold = o.occlusion_threshold;
  return r;
}

/// Grey cells with at least one external face (border grey, BG) and their base cases.
struct CellCounts {
  std::size_t border{0};
  std::size_t interior{0};
  std::array<std::size_t, kNumReliefCases> cases{};
};

CellCounts count_cells(const ReliefMap& map) {
  CellCounts c;
  for (std::size_t g = 0; g < map.cells.size(); ++g) {
    ++(map.external_faces[g] != 0 ? c.border : c.interior);
    ++c.cases[static_cast<std::size_t>(map.projections[g].base_case)];
  }
  return c;
}

io::ReliefRecord make_record(const ConvertOptions& o, const ReliefMap& map, const TriMesh& recon,
                             const HausdorffResult& h, double seconds_metric, double seconds) {
  const ReliefGridLevel& kept = map.levels.back();
  io::ReliefRecord r;
  r.source = o.mesh;
  r.numbers = {{"occlusion_ratio", kept.occlusion_ratio()},
               {"samples", static_cast<double>(kept.samples)},
               {"occluded_samples", static_cast<double>(kept.occluded)},
               {"grid_levels_tried", static_cast<double>(map.levels.size())},
               {"storage_bytes", static_cast<double>(map.storage_bytes())},
               {"reconstruction_vertices", static_cast<double>(recon.num_vertices())},
               {"reconstruction_faces", static_cast<double>(recon.num_faces())},
               {"seconds_cells", map.seconds_cells},
               {"seconds_sampling", map.seconds_sampling},
               {"seconds_metric", seconds_metric},
               {"seconds_total", seconds}};
  add_fidelity(r, h);
  return r;
}

/// "1.23 MiB" and the like.
std::string bytes(std::size_t b) {
  if (b < 1024) return fmt::format("{} B", b);
  if (b < 1024 * 1024) return fmt::format("{:.1f} KiB", static_cast<double>(b) / 1024.0);
  return fmt::format("{:.2f} MiB", static_cast<double>(b) / (1024.0 * 1024.0));
}

/// "5: 120, 4b: 30, 6: 2" (cases that occur, in the paper's order).
std::string case_list(const CellCounts& c) {
  std::vector<std::string> parts;
  for (std::size_t k = 0; k < c.cases.size(); ++k)
    if (c.cases[k] > 0)
      parts.push_back(fmt::format("{}: {}", relief_case_name(static_cast<ReliefCase>(k)), c.cases[k]));
  return fmt::format("{}", fmt::join(parts, ", "));
}

void print_summary(const ConvertOptions& o, const ReliefOptions& ropt, const std::string& name, const ReliefMap& map,
                   const TriMesh& recon, const HausdorffResult& h, double seconds_metric, double seconds) {
  const CellCounts c = count_cells(map);
  const std::uint64_t total = std::uint64_t{map.n} * map.n * map.n;
  fmt::print("{} -> {}:/relief/{}\n", o.mesh, o.output, name);
  fmt::print("  grid             N = {} ({}), cell size {:.6g}\n", map.n,
             ropt.grid == 0 ? fmt::format("automatic, --max-grid {}", ropt.max_grid) : std::string("given"),
             map.cell_size);
  fmt::print("  cells            {} in all: {} grey ({} border, {} interior), {} white, {} black\n", total,
             map.cells.size(), c.border, c.interior, map.white_cells, map.black_cells);
  fmt::print("  domain faces     {} layers of {}x{} texels; cases {}\n", map.num_layers(), map.texture, map.texture,
             case_list(c));
  for (std::size_t k = 0; k < map.levels.size(); ++k) {
    const ReliefGridLevel& l = map.levels[k];
    const bool last = k + 1 == map.levels.size();
    std::string verdict;
    if (ropt.grid != 0)
      verdict = "(given grid)";
    else if (!last)
      verdict = fmt::format("> {:g}: doubled", ropt.occlusion_threshold);
    else if (l.occlusion_ratio() <= ropt.occlusion_threshold)
      verdict = fmt::format("<= {:g}: kept", ropt.occlusion_threshold);
    else
      verdict = fmt::format("> {:g}, but N reached --max-grid {}: kept", ropt.occlusion_threshold, ropt.max_grid);
    fmt::print("  {}  N = {:<4} {} grey cells, {} domain faces, occlusion {:.4f} ({} of {} samples hidden) {}\n",
               k == 0 ? "levels tried   " : "               ", l.n, l.grey_cells, l.domain_faces, l.occlusion_ratio(),
               l.occluded, l.samples, verdict);
  }
  if (map.watertight_inside_test)
    fmt::print("  inside test      {}\n", map.inside_method);
  else
    fmt::print("  inside test      FALLBACK (the mesh is not watertight): {}\n", map.inside_method);
  fmt::print("  storage          {} ({} bytes: distances 2 B{} per texel, 5 B per grey cell)\n",
             bytes(map.storage_bytes()), map.storage_bytes(), map.colors.empty() ? ", normals 3 B" : ", normals 3 B, colours 3 B");
  fmt::print("  reconstruction   {} vertices, {} faces (one per non-empty texel; 2x2 texel quads)\n",
             recon.num_vertices(), recon.num_faces());
  print_fidelity(h);
  fmt::print("  time             cells {:.2f} s, sampling {:.2f} s, metric {:.2f} s, total {:.2f} s\n", map.seconds_cells,
             map.seconds_sampling, seconds_metric, seconds);
}

nlohmann::json json_fields(const ReliefOptions& ropt, const ReliefMap& map, const jobs::LoadedMesh& m) {
  const CellCounts c = count_cells(map);
  nlohmann::json levels = nlohmann::json::array();
  for (const ReliefGridLevel& l : map.levels)
    levels.push_back({{"n", l.n}, {"grey_cells", l.grey_cells}, {"domain_faces", l.domain_faces},
                      {"samples", l.samples}, {"occluded", l.occluded}, {"occlusion_ratio", l.occlusion_ratio()}});
  nlohmann::json cases = nlohmann::json::object();
  for (std::size_t k = 0; k < c.cases.size(); ++k)
    if (c.cases[k] > 0) cases[std::string(relief_case_name(static_cast<ReliefCase>(k)))] = c.cases[k];
  return {{"method", "relief"},
          {"n", map.n},
          {"grid", ropt.grid == 0 ? "auto" : "given"},
          {"texture", map.texture},
          {"cell_size", map.cell_size},
          {"origin", {map.origin.x(), map.origin.y(), map.origin.z()}},
          {"grey_cells", map.cells.size()},
          {"border_cells", c.border},
          {"interior_cells", c.interior},
          {"white_cells", map.white_cells},
          {"black_cells", map.black_cells},
          {"domain_faces", map.num_layers()},
          {"cases", cases},
          {"levels", levels},
          {"inside_method", map.inside_method},
          {"watertight_inside_test", map.watertight_inside_test},
          {"colors", !map.colors.empty()},
          {"input_vertices", m.mesh.num_vertices()},
          {"input_faces", m.mesh.num_faces()}};
}

}  // namespace

int run_convert_relief(const ConvertOptions& options) {
  const auto start = Clock::now();
  ReliefOptions ropt = relief_options(options);
  // Any triangle soup will do: several components, boundaries, non-manifold edges (the inside test falls
  // back to parity votes when the mesh is not watertight).
  const jobs::LoadedMesh m = jobs::load_mesh(options.mesh, {.repair = true});
  const std::string name =
      options.name.empty() ? std::filesystem::path(options.mesh).stem().string() : options.name;
  jobs::refuse_taken_name(options.output, jobs::ImageKind::Relief, name);

  jobs::TerminalProgress progress("convert", options.progress);
  ropt.progress = progress.callback();
  const ReliefMap map = [&] {
    try {
      return build_relief_map(m.mesh, ropt);
    } catch (const InvalidInput& e) {
      throw InvalidInput(fmt::format("{}: {}", options.mesh, e.what()));
    }
  }();
  // Fidelity of the geometry-based reconstruction (§3.5.1) against the input (the papers' PSNR).
  const auto metric_start = Clock::now();
  const TriMesh recon = reconstruct_relief(map);
  if (recon.num_faces() == 0)
    throw InvalidInput(fmt::format("{}: the relief map (N = {}, {}x{} texels) reconstructs to no triangles; use a "
                                   "larger --texture",
                                   options.mesh, map.n, map.texture, map.texture));
  const EmbreeDevice device;
  const HausdorffResult h = measure_fidelity(device, m.mesh, recon, options, progress);
  progress.finish();
  const double seconds_metric = seconds_since(metric_start);
  const double seconds = seconds_since(start);

  const io::ReliefRecord record = make_record(options, map, recon, h, seconds_metric, seconds);
  jobs::add_to_archive(options.output, options.command_line, parameters(options).dump(),
                       [&](io::Archive& archive) { io::write_relief_map(archive, name, map, record); });

  if (options.json)
    print_json_summary(options, name, json_fields(ropt, map, m), record);
  else
    print_summary(options, ropt, name, map, recon, h, seconds_metric, seconds);
  return kExitOk;
}

}  // namespace gimforge::cli
