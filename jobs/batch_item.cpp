#include "jobs/batch_item.h"

#include <fmt/format.h>

#include "jobs/load_mesh.h"
#include "kernels/core/errors.h"
#include "kernels/gim/gim_convert.h"
#include "kernels/core/hausdorff.h"
#include "kernels/sphere/sphere_convert.h"

namespace gimforge::jobs {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// Interleaved (H·W·3) samples to channel-first (3·H·W).
std::vector<float> channel_first(const std::vector<float>& xyz, std::size_t pixels) {
  std::vector<float> out(3 * pixels);
  for (std::size_t p = 0; p < pixels; ++p)
    for (std::size_t c = 0; c < 3; ++c) out[c * pixels + p] = xyz[3 * p + c];
  return out;
}

/// A progress callback that cancels the kernel once the deadline has passed.
ProgressCallback deadline_callback(Clock::time_point deadline, Clock::time_point start) {
  if (deadline == Clock::time_point::max()) return {};
  return [deadline, start](std::string_view, double) {
    if (Clock::now() <= deadline) return true;
    throw Cancelled(fmt::format("timed out after {:.0f} s", std::chrono::duration<double>(deadline - start).count()));
  };
}

void add_fidelity(io::ItemArrays& out, const HausdorffResult& h) {
  out.metrics["psnr"] = h.psnr;
  out.metrics["hausdorff_rms"] = h.rms;
  out.metrics["hausdorff_max"] = h.max;
  out.metrics["bbox_diagonal"] = h.diag;
}

}  // namespace

io::ItemArrays convert_item(const EmbreeDevice& device, const std::string& source, const OutputSpec& output,
                            std::size_t metric_samples, Clock::time_point deadline) {
  const auto start = Clock::now();
  const LoadedMesh m = load_mesh(source, {.repair = true, .require_manifold = true, .require_oriented = true, .warn = false});
  const ProgressCallback progress = deadline_callback(deadline, start);
  io::ItemArrays out;
  TriMesh recon;
  try {
    if (output.method == "gim") {
      GimOptions o;
      o.image.size = output.size;
      o.image.normal_size = 0;
      o.max_augmentations = output.max_augmentations;
      o.progress = progress;
      const GimResult r = convert_to_geometry_image(device, m.mesh, o);
      out.channels = 3;
      out.height = out.width = r.image.size;
      out.data = channel_first(r.image.positions, std::size_t{r.image.size} * r.image.size);
      out.metrics["stretch_efficiency"] = r.stats.stretch.efficiency;
      out.metrics["cut_paths"] = static_cast<double>(r.stats.cut_paths);
      out.metrics["augmentations"] = r.stats.augmentations;
      recon = reconstruct_geometry_image(r.image.positions, r.image.size, &r.image.sideband);
    } else if (output.method == "sphere") {
      SphereOptions o;
      o.domain = parse_spherical_domain(output.domain);
      o.n = output.n;
      o.progress = progress;
      const SphereResult r = convert_to_spherical_image(device, m.mesh, o);
      const DomainImage layout = r.image.layout();
      out.channels = 3;
      out.height = static_cast<std::uint32_t>(layout.faces() * layout.height());
      out.width = static_cast<std::uint32_t>(layout.width());
      out.data = channel_first(r.image.positions, layout.num_samples());
      if (r.stats.masked_samples > 0) out.mask = r.image.mask;
      out.metrics["stretch_efficiency"] = r.stats.map_stretch.efficiency;
      out.metrics["domain_efficiency"] = r.stats.domain_efficiency;
      out.metrics["efficiency_domain_to_mesh"] = r.stats.efficiency_domain_to_mesh;
      out.metrics["holes_filled"] = static_cast<double>(r.stats.holes_filled);
      out.metrics["masked_samples"] = static_cast<double>(r.stats.masked_samples);
      recon = reconstruct_spherical_geometry(r.image);
    } else {
      throw InvalidInput(fmt::format("unknown method '{}'", output.method));
    }
  } catch (const TopologyError& e) {
    throw TopologyError(fmt::format("{}: {}", source, e.what()));
  } catch (const Cancelled& e) {
    throw Cancelled(fmt::format("{}: {}", source, e.what()));
  }
  out.metrics["seconds_convert"] = seconds_since(start);
  const auto metric_start = Clock::now();
  HausdorffOptions h;
  h.samples = metric_samples;
  add_fidelity(out, symmetric_hausdorff(device, m.mesh, recon, h));
  out.metrics["seconds_metric"] = seconds_since(metric_start);
  out.metrics["input_faces"] = static_cast<double>(m.mesh.num_faces());
  return out;
}

}  // namespace gimforge::jobs
