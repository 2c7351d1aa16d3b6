// `gimforge convert`: one mesh through the one conversion pipeline (jobs/pipeline.h) into an archive; the
// geometry-image summary is here, the others in cmd_convert_sphere.cpp and cmd_convert_relief.cpp.
#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>

#include "io/atomic_file.h"
#include "io/printable.h"
#include "io/xdmf.h"
#include "jobs/cli/commands.h"
#include "jobs/cli/convert_common.h"
#include "jobs/cli/crash_guard.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/batch_item.h"
#include "jobs/brick_convert.h"
#include "jobs/brick_relief.h"
#include "jobs/gim_store.h"
#include "jobs/load_mesh.h"
#include "jobs/memory_budget.h"
#include "jobs/roi.h"
#include "jobs/pipeline.h"
#include "jobs/progress.h"
#include "kernels/core/embree_device.h"
#include "mpi/agree.h"
#include "mpi/environment.h"
#include "mpi/mpi_comm.h"

namespace gimforge::cli {
namespace {

using Clock = std::chrono::steady_clock;

void print_summary(const ConvertSummary& s) {
  switch (s.conversion.method) {
    case jobs::Method::Gim: return print_gim_summary(s);
    case jobs::Method::Sphere: return print_sphere_summary(s);
    case jobs::Method::Relief: return print_relief_summary(s);
    case jobs::Method::Mcgim: return print_mcgim_summary(s);
  }
}

nlohmann::json json_fields(const ConvertSummary& s) {
  switch (s.conversion.method) {
    case jobs::Method::Gim: return gim_json_fields(s);
    case jobs::Method::Sphere: return sphere_json_fields(s);
    case jobs::Method::Relief: return relief_json_fields(s);
    case jobs::Method::Mcgim: return mcgim_json_fields(s);
  }
  return {};
}

}  // namespace

int convert_on(const mpi::Comm& comm, const ConvertOptions& options);

int run_convert(const ConvertOptions& options) {
  // Under an MPI launcher a huge binary PLY is converted by bricks (jobs/brick_convert.h); anything else is
  // converted by rank 0 alone while the other ranks wait. Alone, no MPI is started.
  std::optional<mpi::MpiEnvironment> mpi_env;
  mpi::Comm comm = mpi::Comm::serial();
  if (mpi::launched_by_mpi()) {
    mpi_env.emplace();
    comm = mpi::mpi_world();
  }
  try {
    return convert_on(comm, options);
  } catch (const mpi::PeerFailed&) {
    return kExitOk;  // the failing rank prints the cause and exits 1 (see cmd_metrics.cpp)
  }
}

/// The conversion over `comm` (the serial one alone).
int convert_on(const mpi::Comm& comm, const ConvertOptions& options) {
  const auto start = Clock::now();
  const bool root = comm.rank() == 0;
  const jobs::Method method = options.method.method;
  options.method.check("convert");
  jobs::ConversionRequest request;
  request.source = options.mesh;
  request.method = options.method;
  request.fidelity = {.enabled = !options.no_metric, .samples = options.metric_samples};
  bool bricks = false;
  if (comm.size() > 1) {
    mpi::run_agreed(comm, [&] {
      bricks = options.sphere_map.empty() && (jobs::converts_in_bricks(comm, options.mesh, request) ||
                                              jobs::converts_relief_in_bricks(comm, options.mesh, request));
    });
    // Every rank must take the same path (a file seen differently would leave rank 0 alone in a collective).
    bricks = comm.allreduce(std::int64_t{bricks ? 1 : 0}, mpi::ReduceOp::kMin) == 1;
  }
  if (!bricks && !root) return kExitOk;  // rank 0 converts the whole mesh
  std::unique_ptr<tbb::global_control> one_thread;  // ranks are the parallelism, as in batch and metrics
  if (bricks && options.threads == 0)
    one_thread = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, 1);
  // Before any work: the archive can be created there, it is not the mesh itself, and no other writer
  // has it (the lock is held until the archive is renamed into place).
  const std::string name =
      options.name.empty() ? std::filesystem::path(options.mesh).stem().string() : options.name;
  std::unique_ptr<io::WriterLock> lock;
  const auto checks = [&] {
    if (!root) return;
    jobs::check_conversion_memory(options.mesh, request.method, request.fidelity.enabled ? request.fidelity.samples : 0);
    if (bricks && !options.method.roi.empty())
      throw InvalidInput(fmt::format("--roi {}: a conversion split in bricks across ranks takes no region of interest "
                                     "(convert on one rank, without mpirun)",
                                     options.method.roi));
    io::check_can_create(jobs::output_target(options.output));
    if (options.xdmf) io::check_can_create(io::xdmf_sidecar_path(options.output));  // before the work, not after
    jobs::refuse_output_over_inputs(options.output, {options.mesh});
    jobs::refuse_unfinished_batch(options.output);  // before the work, not after it
    lock = jobs::lock_archive(options.output, options.wait);
    // The archives this run reads (the one it extends, the one holding --sphere-map) are read in full in a
    // child process first: HDF5 itself crashes on some crafted files (crash_guard.h), and that must be one
    // error line before any work, not a signal after it.
    if (std::filesystem::exists(options.output)) probe_archive(options.output);
    if (!options.sphere_map.empty()) {
      std::string source = options.sphere_map;  // ARCHIVE[:NAME]
      if (const auto colon = source.rfind(':'); colon != std::string::npos && !std::filesystem::exists(source))
        source.resize(colon);
      if (std::filesystem::exists(source)) probe_archive(source);
    }
    jobs::refuse_taken_name(options.output, method, name);  // before any long work
  };
  if (bricks)
    mpi::run_agreed(comm, checks);
  else
    checks();
  jobs::TerminalProgress progress("convert", options.progress && root);
  request.progress = progress.callback();
  const EmbreeDevice device;
  jobs::LoadedMesh m;
  jobs::Conversion conversion;
  std::optional<jobs::Conversion> by_bricks;
  if (bricks && method == jobs::Method::Relief) {
    m.path = options.mesh;
    conversion = jobs::brick_relief(comm, device, options.mesh, request);
    if (!root) return kExitOk;
  } else if (bricks) {
    m.path = options.mesh;
    const std::filesystem::path scratch = std::filesystem::absolute(options.output).parent_path();
    by_bricks = jobs::brick_convert(comm, device, options.mesh, request, scratch);
    if (!root) return kExitOk;
    if (by_bricks) {
      conversion = std::move(*by_bricks);
    } else {
      bricks = false;  // without degenerate faces the scan needs no proxy: rank 0 converts it whole
      one_thread.reset();
    }
  }
  if (!bricks) {
    m = jobs::load_mesh(options.mesh, jobs::load_policy(options.method, /*warn=*/true));
    jobs::check_faces_left(m);
    if (method == jobs::Method::Sphere && !options.sphere_map.empty())
      request.sphere_map = stored_sphere_map(options, m.mesh);
    request.roi = jobs::resolve_roi(request.method, m);
    conversion = jobs::convert_mesh(device, std::move(m.mesh), request);  // not needed after: no copy
  }
  progress.finish();

  jobs::add_to_archive(options.output, options.command_line, jobs::creation_parameters(request).dump(),
                       [&](io::Archive& archive) { jobs::write_conversion(archive, name, conversion); });
  if (options.xdmf) {
    const std::filesystem::path sidecar = io::write_xdmf_sidecar(options.output);
    if (!options.json) spdlog::info("wrote {}", sidecar.string());
  }

  const ConvertSummary summary{options, name, m, conversion,
                               std::chrono::duration<double>(Clock::now() - start).count()};
  if (options.json) {
    nlohmann::json j = {{"archive", options.output}, {"name", name}, {"method", jobs::method_name(method)}};
    j.update(json_fields(summary));
    for (const auto& [k, v] : conversion.numbers) j[k] = v;
    j["seconds_command"] = summary.seconds_command;
    if (bricks) j["ranks"] = comm.size();
    fmt::print("{}\n", j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace));
  } else {
    print_summary(summary);
  }
  return kExitOk;
}

void print_gim_summary(const ConvertSummary& s) {
  const GimResult& r = s.conversion.gim.value();
  const GimStats& st = r.stats;
  fmt::print("{} -> {}:/gim/{}\n", io::printable(s.options.mesh), io::printable(s.options.output), io::printable(s.name));
  fmt::print("  geometry image   {0}x{0} (normal map {1}x{1})\n", r.image.size, r.image.normal_size);
  fmt::print("  cut              {} edges, {} cut-paths, {} augmentation(s)\n", st.cut_edges, st.cut_paths,
             st.augmentations);
  fmt::print("  stretch eff.     {:.4f} (Floater start {:.4f})\n", st.stretch.efficiency, st.floater.efficiency);
  if (const auto& n = s.conversion.numbers; n.contains("fit_energy_before"))
    fmt::print("  optimization     energy {:.4g} -> {:.4g} in {:.2f} s\n", n.at("fit_energy_before"),
               n.at("fit_energy_after"), n.at("seconds_optimize"));
  print_adaptive(s.conversion);
  print_fidelity(s.conversion);
  print_times(s, fmt::format("cut {:.2f} s, parametrize {:.2f} s, sample {:.2f} s", st.seconds_cut,
                             st.seconds_parametrize, st.seconds_sample));
}

nlohmann::json gim_json_fields(const ConvertSummary& s) {
  const GeometryImage& image = s.conversion.gim.value().image;
  return {{"size", image.size}, {"normal_size", image.normal_size}};
}

}  // namespace gimforge::cli
