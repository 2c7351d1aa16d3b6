#include <chrono>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "io/gim_archive.h"
#include "jobs/cli/commands.h"
#include "jobs/cli/convert_common.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/gim_store.h"
#include "jobs/progress.h"
#include "kernels/core/errors.h"
#include "kernels/gim/gim_convert.h"
#include "kernels/core/hausdorff.h"

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
               {"seconds_cut", s.seconds_cut},
               {"seconds_parametrize", s.seconds_parametrize},
               {"seconds_sample", s.seconds_sample},
               {"seconds_total", seconds}};
  add_fidelity(r, h);
  return r;
}

}  // namespace

int run_convert(const ConvertOptions& options) {
  if (options.method == "gim") return run_convert_gim(options);
  if (options.method == "sphere") return run_convert_sphere(options);
  if (options.method == "relief") return run_convert_relief(options);
  throw InvalidInput(fmt::format("unknown method '{}' (available: gim, sphere, relief)", options.method));
}

int run_convert_gim(const ConvertOptions& options) {
  const auto start = Clock::now();
  const auto [m, name] = prepare_conversion(options, jobs::ImageKind::Geometry);
  const EmbreeDevice device;
  jobs::TerminalProgress progress("convert", options.progress);
  GimOptions gopt;
  gopt.image.size = options.size;
  gopt.image.normal_size = options.normal_size;
  gopt.max_augmentations = options.max_augmentations;
  gopt.progress = progress.callback();
  const GimResult result = with_mesh_path(options.mesh, [&] { return convert_to_geometry_image(device, m.mesh, gopt); });
  // Fidelity of the reconstruction against the input (the papers' PSNR).
  const TriMesh recon = reconstruct_geometry_image(result.image.positions, result.image.size, &result.image.sideband);
  const HausdorffResult h = measure_fidelity(device, m.mesh, recon, options, progress);
  progress.finish();
  const double seconds = seconds_since(start);

  const io::GimRecord record = make_record(options, result.stats, h, seconds);
  jobs::add_to_archive(options.output, options.command_line, parameters(options).dump(),
                       [&](io::Archive& archive) { io::write_geometry_image(archive, name, result.image, record); });

  const GimStats& s = result.stats;
  if (options.json) {
    print_json_summary(options, name, {{"size", result.image.size}, {"normal_size", result.image.normal_size}}, record);
  } else {
    fmt::print("{} -> {}:/gim/{}\n", options.mesh, options.output, name);
    fmt::print("  geometry image   {0}x{0} (normal map {1}x{1})\n", result.image.size, result.image.normal_size);
    fmt::print("  cut              {} edges, {} cut-paths, {} augmentation(s)\n", s.cut_edges, s.cut_paths,
               s.augmentations);
    fmt::print("  stretch eff.     {:.4f} (Floater start {:.4f})\n", s.stretch.efficiency, s.floater.efficiency);
    print_fidelity(h);
    fmt::print("  time             cut {:.2f} s, parametrize {:.2f} s, sample {:.2f} s, total {:.2f} s\n",
               s.seconds_cut, s.seconds_parametrize, s.seconds_sample, seconds);
  }
  return kExitOk;
}

}  // namespace gimforge::cli
