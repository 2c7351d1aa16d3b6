#include <algorithm>
#include <chrono>
#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "io/gim_archive.h"
#include "jobs/commands.h"
#include "jobs/exit_codes.h"
#include "jobs/gim_store.h"
#include "jobs/load_mesh.h"
#include "jobs/progress.h"
#include "kernels/errors.h"
#include "kernels/gim_convert.h"
#include "kernels/hausdorff.h"

namespace gimforge::cli {
namespace {

using Clock = std::chrono::steady_clock;

nlohmann::json parameters(const ConvertOptions& o) {
  return {{"method", o.method}, {"size", o.size}, {"normal_size", o.normal_size},
          {"max_augmentations", o.max_augmentations}, {"metric_samples", o.metric_samples}};
}

io::GimRecord make_record(const ConvertOptions& o, const GimStats& s, const HausdorffResult& h, double seconds) {
  io::GimRecord r;
  r.source = o.mesh;
  r.numbers = {{"cut_edges", static_cast<double>(s.cut_edges)},
               {"cut_paths", static_cast<double>(s.cut_paths)},
               {"augmentations", s.augmentations},
               {"corner_splits", static_cast<double>(s.corner_splits)},
               {"side_splits", static_cast<double>(s.side_splits)},
               {"stretch_efficiency", s.stretch.efficiency},
               {"l2_stretch", s.stretch.l2},
               {"floater_efficiency", s.floater.efficiency},
               {"optimizer_fallback", s.optimizer_fallback ? 1.0 : 0.0},
               {"psnr", h.psnr},
               {"hausdorff_rms", h.rms},
               {"hausdorff_max", h.max},
               {"bbox_diagonal", h.diag},
               {"seconds_cut", s.seconds_cut},
               {"seconds_parametrize", s.seconds_parametrize},
               {"seconds_sample", s.seconds_sample},
               {"seconds_total", seconds}};
  return r;
}

}  // namespace

int run_convert(const ConvertOptions& options) {
  if (options.method != "gim")
    throw InvalidInput(fmt::format("method '{}' is not available yet (available: gim)", options.method));
  const auto start = Clock::now();
  const jobs::LoadedMesh m =
      jobs::load_mesh(options.mesh, {.repair = true, .require_manifold = true, .require_oriented = true});
  const std::string name = options.name.empty() ? std::filesystem::path(options.mesh).stem().string() : options.name;

  // Refuse a taken name before the work, not after it.
  if (std::filesystem::exists(options.output)) {
    const auto names = io::geometry_image_names(io::Archive::open(options.output));
    if (std::find(names.begin(), names.end(), name) != names.end())
      throw InvalidInput(fmt::format("{}: already holds a geometry image '{}' (choose another --name or output)",
                                     options.output, name));
  }
  const EmbreeDevice device;
  jobs::TerminalProgress progress("convert", options.progress);
  GimOptions gopt;
  gopt.image.size = options.size;
  gopt.image.normal_size = options.normal_size;
  gopt.max_augmentations = options.max_augmentations;
  gopt.progress = progress.callback();
  GimResult result;
  try {
    result = convert_to_geometry_image(device, m.mesh, gopt);
  } catch (const TopologyError& e) {
    throw TopologyError(fmt::format("{}: {}", options.mesh, e.what()));
  }
  // Fidelity of the reconstruction against the input (the papers' PSNR).
  const TriMesh recon = reconstruct_geometry_image(result.image.positions, result.image.size, &result.image.sideband);
  HausdorffOptions hopt;
  hopt.samples = options.metric_samples;
  hopt.progress = progress.callback();
  const HausdorffResult h = symmetric_hausdorff(device, m.mesh, recon, hopt);
  progress.finish();
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();

  const io::GimRecord record = make_record(options, result.stats, h, seconds);
  jobs::add_to_archive(options.output, options.command_line, parameters(options).dump(),
                       [&](io::Archive& archive) { io::write_geometry_image(archive, name, result.image, record); });

  const GimStats& s = result.stats;
  if (options.json) {
    nlohmann::json j = {{"archive", options.output}, {"name", name}, {"size", result.image.size},
                        {"normal_size", result.image.normal_size}};
    for (const auto& [k, v] : record.numbers) j[k] = v;
    fmt::print("{}\n", j.dump(2));
  } else {
    fmt::print("{} -> {}:/gim/{}\n", options.mesh, options.output, name);
    fmt::print("  geometry image   {0}x{0} (normal map {1}x{1})\n", result.image.size, result.image.normal_size);
    fmt::print("  cut              {} edges, {} cut-paths, {} augmentation(s)\n", s.cut_edges, s.cut_paths,
               s.augmentations);
    fmt::print("  stretch eff.     {:.4f} (Floater start {:.4f})\n", s.stretch.efficiency, s.floater.efficiency);
    fmt::print("  fidelity         PSNR {:.2f} dB (rms {:.4e}, max {:.4e}, diag {:.6g})\n", h.psnr, h.rms, h.max,
               h.diag);
    fmt::print("  time             cut {:.2f} s, parametrize {:.2f} s, sample {:.2f} s, total {:.2f} s\n",
               s.seconds_cut, s.seconds_parametrize, s.seconds_sample, seconds);
  }
  return kExitOk;
}

}  // namespace gimforge::cli
