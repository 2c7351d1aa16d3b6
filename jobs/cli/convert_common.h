#pragma once
/// \file convert_common.h
/// The summaries `gimforge convert` prints (internal to the executable): run_convert (cmd_convert.cpp)
/// runs the one pipeline (jobs/pipeline.h) for every method and calls the method's summary here: the
/// human-readable lines (cmd_convert.cpp for gim, cmd_convert_sphere.cpp, cmd_convert_relief.cpp,
/// cmd_convert_mcgim.cpp) or the
/// JSON fields beside the record's numbers.
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "jobs/cli/commands.h"
#include "jobs/load_mesh.h"
#include "jobs/pipeline.h"
#include "kernels/core/mesh.h"

namespace gimforge::cli {

/// What a summary describes: the command's options, the result's name, the loaded input, the conversion.
struct ConvertSummary {
  const ConvertOptions& options;
  const std::string& name;
  const jobs::LoadedMesh& input;
  const jobs::Conversion& conversion;
  double seconds_command{0.0};  ///< the whole command so far: load, conversion, report, archive write
};

void print_gim_summary(const ConvertSummary& s);
void print_sphere_summary(const ConvertSummary& s);
void print_relief_summary(const ConvertSummary& s);
void print_mcgim_summary(const ConvertSummary& s);
/// The method's fields of the JSON summary (beside archive, name and every number of the record).
[[nodiscard]] nlohmann::json gim_json_fields(const ConvertSummary& s);
[[nodiscard]] nlohmann::json sphere_json_fields(const ConvertSummary& s);
[[nodiscard]] nlohmann::json relief_json_fields(const ConvertSummary& s);
[[nodiscard]] nlohmann::json mcgim_json_fields(const ConvertSummary& s);

/// The sphere map of --sphere-map ARCHIVE[:NAME] (NAME defaults to the mesh file's stem), checked against
/// the mesh it is applied to (cmd_convert_sphere.cpp).
[[nodiscard]] std::vector<Vec3> stored_sphere_map(const ConvertOptions& o, const TriMesh& mesh);

/// Adaptive sampling (gim, flat-octa sphere): the "adaptive" line (local Hausdorff figures before and after
/// the moves), and with a ROI its samples and distances inside and outside it; nothing for uniform sampling.
void print_adaptive(const jobs::Conversion& c);

/// The fidelity line: "  fidelity         PSNR 80.12 dB (rms ..., max ..., diag ...)", or that it was not
/// measured (--no-metric).
void print_fidelity(const jobs::Conversion& c);

/// The time line: the method's construction (with its own `stages`, e.g. "cut 0.12 s, parametrize 1.02 s"),
/// the fidelity report, and the whole command (loading and writing included), so that what dominates is
/// visible.
void print_times(const ConvertSummary& s, const std::string& stages);

}  // namespace gimforge::cli
