#pragma once
/// \file convert_common.h
/// What the conversion methods of `gimforge convert` share (internal to the executable): the result's
/// name, the fidelity measurement against the input, mesh-path prefixes on topology errors and the summary
/// output. run_convert (cmd_convert.cpp) dispatches to one function per method.
#include <chrono>
#include <string>
#include <utility>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "io/representation.h"
#include "jobs/cli/commands.h"
#include "jobs/gim_store.h"
#include "jobs/load_mesh.h"
#include "jobs/progress.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/mesh.h"

namespace gimforge::cli {

/// `convert --method gim` (cmd_convert.cpp).
int run_convert_gim(const ConvertOptions& options);
/// `convert --method sphere` (cmd_convert_sphere.cpp).
int run_convert_sphere(const ConvertOptions& options);
/// `convert --method relief` (cmd_convert_relief.cpp).
int run_convert_relief(const ConvertOptions& options);

/// Seconds since `start`.
[[nodiscard]] double seconds_since(std::chrono::steady_clock::time_point start);

/// What every conversion starts from: the input mesh and the name of the result in the archive.
struct ConversionInput {
  jobs::LoadedMesh loaded;  ///< repaired; refused unless manifold and consistently oriented
  std::string name;         ///< --name, else the mesh file's stem
};

/// Loads options.mesh (repaired; a non-manifold or inconsistently oriented mesh is refused, boundaries are
/// allowed) and refuses a name the output archive already holds for `kind` — before any long work. Throws
/// as jobs::load_mesh and jobs::refuse_taken_name do.
[[nodiscard]] ConversionInput prepare_conversion(const ConvertOptions& options, jobs::ImageKind kind);

/// Fidelity of `reconstruction` against the input `mesh` (the papers' symmetric RMS Hausdorff PSNR) with
/// options.metric_samples samples per direction, reporting progress.
[[nodiscard]] HausdorffResult measure_fidelity(const EmbreeDevice& device, const TriMesh& mesh,
                                               const TriMesh& reconstruction, const ConvertOptions& options,
                                               jobs::TerminalProgress& progress);

/// The record numbers every method stores for the fidelity: psnr, hausdorff_rms, hausdorff_max, bbox_diagonal.
void add_fidelity(io::RepresentationRecord& record, const HausdorffResult& h);

/// Runs `convert` (a kernel call) and prefixes a TopologyError's message with the mesh path, as every
/// other error about the input names the file.
template <class F>
auto with_mesh_path(const std::string& mesh, F&& convert) {
  try {
    return std::forward<F>(convert)();
  } catch (const TopologyError& e) {
    throw TopologyError(fmt::format("{}: {}", mesh, e.what()));
  }
}

/// Prints the JSON summary: archive, name, the method's `fields`, and every number of `record`.
void print_json_summary(const ConvertOptions& options, const std::string& name, nlohmann::json fields,
                        const io::RepresentationRecord& record);

/// The human summary's fidelity line: "  fidelity         PSNR 80.12 dB (rms ..., max ..., diag ...)".
void print_fidelity(const HausdorffResult& h);

}  // namespace gimforge::cli
