// `gimforge convert --method relief`: the summary of a relief map on a cubic cell complex (Apaza & Andújar);
// the conversion itself is jobs::convert_mesh.
#include <array>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "io/printable.h"
#include "jobs/cli/convert_common.h"
#include "kernels/relief/relief_map.h"

namespace gimforge::cli {
namespace {

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

}  // namespace

void print_relief_summary(const ConvertSummary& s) {
  const jobs::MethodOptions& ropt = s.options.method;
  const ReliefMap& map = s.conversion.relief.value();
  const auto& num = s.conversion.numbers;
  const CellCounts c = count_cells(map);
  const std::uint64_t total = std::uint64_t{map.n} * map.n * map.n;
  fmt::print("{} -> {}:/relief/{}\n", io::printable(s.options.mesh), io::printable(s.options.output), io::printable(s.name));
  fmt::print("  grid             N = {} ({}), cell size {:.6g}\n", map.n,
             ropt.grid == "auto" ? fmt::format("automatic, --max-grid {}", ropt.max_grid) : std::string("given"),
             map.cell_size);
  fmt::print("  cells            {} in all: {} grey ({} border, {} interior), {} white, {} black\n", total,
             map.cells.size(), c.border, c.interior, map.white_cells, map.black_cells);
  fmt::print("  domain faces     {} layers of {}x{} texels; cases {}\n", map.num_layers(), map.texture, map.texture,
             case_list(c));
  for (std::size_t k = 0; k < map.levels.size(); ++k) {
    const ReliefGridLevel& l = map.levels[k];
    const bool last = k + 1 == map.levels.size();
    std::string verdict;
    const bool occluded = l.occlusion_ratio() > ropt.occlusion_threshold;
    const bool edge_on = l.edge_on_ratio() > kEdgeOnRatioLimit;
    const std::string why = occluded ? fmt::format("> {:g}", ropt.occlusion_threshold)
                            : edge_on ? fmt::format("<= {:g}, but {:.0f} % of the faces seen edge-on", ropt.occlusion_threshold,
                                                    100.0 * l.edge_on_ratio())
                                      : fmt::format("<= {:g}", ropt.occlusion_threshold);
    if (ropt.grid != "auto")
      verdict = "(given grid)";
    else if (!last)
      verdict = why + ": doubled";
    else if (!occluded && !edge_on)
      verdict = why + ": kept";
    else
      verdict = fmt::format("{}, but N reached --max-grid {}: kept", why, ropt.max_grid);
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
  if (const auto v = num.find("reconstruction_vertices"); v != num.end())
    fmt::print("  reconstruction   {:.0f} vertices, {:.0f} faces (one per texel a face uses; 2x2 texel quads)\n", v->second,
               num.at("reconstruction_faces"));
  print_fidelity(s.conversion);
  print_times(s, fmt::format("cells {:.2f} s, sampling {:.2f} s", map.seconds_cells, map.seconds_sampling));
}

nlohmann::json relief_json_fields(const ConvertSummary& s) {
  const ReliefMap& map = s.conversion.relief.value();
  const CellCounts c = count_cells(map);
  nlohmann::json levels = nlohmann::json::array();
  for (const ReliefGridLevel& l : map.levels)
    levels.push_back({{"n", l.n}, {"grey_cells", l.grey_cells}, {"domain_faces", l.domain_faces},
                      {"samples", l.samples}, {"occluded", l.occluded}, {"occlusion_ratio", l.occlusion_ratio()},
                      {"edge_on_ratio", l.edge_on_ratio()}});
  nlohmann::json cases = nlohmann::json::object();
  for (std::size_t k = 0; k < c.cases.size(); ++k)
    if (c.cases[k] > 0) cases[std::string(relief_case_name(static_cast<ReliefCase>(k)))] = c.cases[k];
  return {{"n", map.n},
          {"grid", s.options.method.grid == "auto" ? "auto" : "given"},
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
          {"input_vertices", s.conversion.input_vertices},
          {"input_faces", s.conversion.input_faces}};
}

}  // namespace gimforge::cli
