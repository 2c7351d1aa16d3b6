// The command-line interface (CLI11 is confined to this translation unit: it is slow to compile).
#include <cstdio>
#include <exception>
#include <memory>
#include <new>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>

#include "gimforge_version.h"
#include "jobs/commands.h"
#include "jobs/exit_codes.h"
#include "jobs/logging.h"
#include "kernels/errors.h"

namespace gimforge::cli {
namespace {

constexpr const char* kFooter = R"(
Exit codes: 0 success, 1 error (one line on stderr names the file and the cause), 2 usage error,
3 a batch finished with some failed items.
Mesh formats read: PLY (ascii, binary little/big endian), OBJ, OFF, STL (ascii, binary).
Documentation: docs/cli.md, docs/archive.md.)";

struct GlobalOptions {
  std::string log_level{"info"};
  bool verbose{false};
  bool quiet{false};
  int threads{0};
};

void add_global_options(CLI::App& app, GlobalOptions& g) {
  app.add_option("--log-level", g.log_level, "Log level: trace, debug, info, warn, error, off")
      ->capture_default_str()
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "off"}));
  app.add_flag("-v,--verbose", g.verbose, "Same as --log-level debug");
  app.add_flag("-q,--quiet", g.quiet, "Same as --log-level error (no warnings, no progress)");
  app.add_option("-j,--threads", g.threads, "Worker threads (default: all cores)")->check(CLI::NonNegativeNumber);
}

void add_info(CLI::App& app, InfoOptions& o) {
  auto* cmd = app.add_subcommand("info", "Describe a mesh: size, components, boundary loops, genus, flags, defects");
  cmd->add_option("mesh", o.mesh, "Mesh file (.ply .obj .off .stl)")->required();
  cmd->add_flag("--json", o.json, "Print JSON (keys: vertices faces components boundary_loops genus closed "
                                  "manifold bbox_diagonal ...; see docs/cli.md)");
  cmd->footer(
      "Repairable defects (degenerate faces, duplicate faces, unreferenced vertices) are repaired with a warning\n"
      "before the topology is computed; fatal ones (indices out of range, NaN/Inf coordinates) are errors.");
}

void add_validate(CLI::App& app, ValidateCmdOptions& o) {
  auto* cmd = app.add_subcommand(
      "validate", "Check meshes for the defects the conversion methods refuse (exit 1 if any file fails)");
  cmd->add_option("meshes", o.meshes, "Mesh files")->required();
  cmd->add_flag("--json", o.json, "Print the defects found as JSON");
  cmd->add_flag("--allow-non-manifold", o.allow_non_manifold, "Accept non-manifold edges and vertices");
  cmd->add_flag("--allow-inconsistent-orientation", o.allow_inconsistent_orientation,
                "Accept faces whose orientations disagree");
  cmd->footer(
      "Fatal: indices out of range, NaN/Inf coordinates, no faces. Refused: non-manifold edges/vertices,\n"
      "inconsistent orientation (unless allowed). Repaired with a warning: degenerate faces, duplicate faces,\n"
      "unreferenced vertices. Reported only: zero-area faces, vertices sharing a position.");
}

void add_metrics(CLI::App& app, MetricsOptions& o) {
  auto* cmd = app.add_subcommand(
      "metrics", "Symmetric Hausdorff distance and PSNR between two surfaces (the papers' fidelity measure)");
  cmd->add_option("a", o.a, "Original mesh (its bounding-box diagonal is the PSNR reference)")->required();
  cmd->add_option("b", o.b, "Mesh to compare (e.g. a reconstruction)")->required();
  cmd->add_option("-n,--samples", o.samples, "Area-weighted samples per direction")
      ->capture_default_str()
      ->check(CLI::Range(std::size_t{1}, std::size_t{1} << 32));
  cmd->add_option("--seed", o.seed, "Seed of the sample positions (results are deterministic)")->capture_default_str();
  cmd->add_flag("!--no-vertices", o.include_vertices, "Do not add the meshes' vertices to the samples");
  cmd->add_flag("--json", o.json, "Print JSON: {diag, ab:{max,mean,rms}, ba:{...}, max, rms, psnr}");
  cmd->footer(
      "d = sqrt((rms_ab^2 + rms_ba^2)/2), PSNR = 20 log10(diag/d), diag = A's bounding-box diagonal.\n"
      "Distances are exact point-to-triangle distances (Embree point queries). mean and rms are over the\n"
      "area-weighted samples; max also covers every vertex.");
}

int dispatch(CLI::App& app, const InfoOptions& info, const ValidateCmdOptions& validate, MetricsOptions& metrics,
             const GlobalOptions& g) {
  if (app.got_subcommand("info")) return run_info(info);
  if (app.got_subcommand("validate")) return run_validate(validate);
  if (app.got_subcommand("metrics")) {
    metrics.progress = !g.quiet;
    return run_metrics(metrics);
  }
  return kExitUsage;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"gimforge: turn triangle meshes into regular surface representations (geometry images and\n"
               "relatives), measure their fidelity, and store them in HDF5 archives."};
  app.set_version_flag("--version", std::string("gimforge ") + kVersion);
  app.footer(kFooter);
  app.require_subcommand(1);
  GlobalOptions global;
  InfoOptions info;
  ValidateCmdOptions validate;
  MetricsOptions metrics;
  add_global_options(app, global);
  add_info(app, info);
  add_validate(app, validate);
  add_metrics(app, metrics);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kExitOk : kExitUsage;
  }
  try {
    jobs::setup_logging(global.verbose ? "debug" : global.quiet ? "error" : global.log_level);
    std::unique_ptr<tbb::global_control> threads;
    if (global.threads > 0)
      threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                      static_cast<std::size_t>(global.threads));
    return dispatch(app, info, validate, metrics, global);
  } catch (const Error& e) {
    spdlog::error("{}", e.what());
  } catch (const std::bad_alloc&) {
    spdlog::error("out of memory");
  } catch (const std::exception& e) {
    spdlog::error("internal error: {}", e.what());
  }
  return kExitError;
}

}  // namespace gimforge::cli
