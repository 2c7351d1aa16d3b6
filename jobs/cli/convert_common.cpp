#include "jobs/cli/convert_common.h"

#include <filesystem>

namespace gimforge::cli {

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

ConversionInput prepare_conversion(const ConvertOptions& options, jobs::ImageKind kind) {
  ConversionInput in;
  in.loaded = jobs::load_mesh(options.mesh, {.repair = true, .require_manifold = true, .require_oriented = true});
  in.name = options.name.empty() ? std::filesystem::path(options.mesh).stem().string() : options.name;
  jobs::refuse_taken_name(options.output, kind, in.name);
  return in;
}

HausdorffResult measure_fidelity(const EmbreeDevice& device, const TriMesh& mesh, const TriMesh& reconstruction,
                                 const ConvertOptions& options, jobs::TerminalProgress& progress) {
  HausdorffOptions hopt;
  hopt.samples = options.metric_samples;
  hopt.progress = progress.callback();
  return symmetric_hausdorff(device, mesh, reconstruction, hopt);
}

void add_fidelity(io::RepresentationRecord& record, const HausdorffResult& h) {
  record.numbers["psnr"] = h.psnr;
  record.numbers["hausdorff_rms"] = h.rms;
  record.numbers["hausdorff_max"] = h.max;
  record.numbers["bbox_diagonal"] = h.diag;
}

void print_json_summary(const ConvertOptions& options, const std::string& name, nlohmann::json fields,
                        const io::RepresentationRecord& record) {
  nlohmann::json j = {{"archive", options.output}, {"name", name}};
  j.update(fields);
  for (const auto& [k, v] : record.numbers) j[k] = v;
  fmt::print("{}\n", j.dump(2));
}

void print_fidelity(const HausdorffResult& h) {
  fmt::print("  fidelity         PSNR {:.2f} dB (rms {:.4e}, max {:.4e}, diag {:.6g})\n", h.psnr, h.rms, h.max, h.diag);
}

}  // namespace gimforge::cli
