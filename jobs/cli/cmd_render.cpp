// `gimforge render`: ray casting of a relief map (Apaza & Andújar §3.5.2) and, with --reference, the
// Embree render of the original mesh from the same camera and their comparison.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <optional>
#include <sstream>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include "io/atomic_file.h"
#include "io/png_image.h"
#include "io/printable.h"
#include "io/relief_archive.h"
#include "jobs/cli/commands.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/gim_store.h"
#include "jobs/load_mesh.h"
#include "jobs/pipeline.h"
#include "jobs/stored_image.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/relief/mesh_render.h"
#include "kernels/relief/relief_map.h"
#include "kernels/relief/relief_raycast.h"

namespace gimforge::cli {
namespace {

/// "AZ,EL" in degrees.
OrbitView parse_view(const RenderOptions& o) {
  OrbitView view;
  const auto comma = o.view.find(',');
  std::size_t used_az = 0, used_el = 0;
  bool ok = comma != std::string::npos;
  if (ok) {
    try {
      const std::string az = o.view.substr(0, comma), el = o.view.substr(comma + 1);
      view.azimuth_deg = std::stod(az, &used_az);
      view.elevation_deg = std::stod(el, &used_el);
      ok = used_az == az.size() && used_el == el.size() && std::isfinite(view.azimuth_deg) &&
           std::isfinite(view.elevation_deg);
    } catch (const std::exception&) {
      ok = false;
    }
  }
  if (!ok) throw InvalidInput(fmt::format("--view '{}': expected AZIMUTH,ELEVATION in degrees, e.g. 30,20", o.view));
  if (view.elevation_deg < -90.0 || view.elevation_deg > 90.0)
    throw InvalidInput(fmt::format("--view '{}': elevation {} is outside -90..90", o.view, view.elevation_deg));
  view.fov_deg = o.fov;
  view.up_axis = o.up == "x" ? 0 : o.up == "z" ? 2 : 1;
  return view;
}

/// `ref` when it is a relief map; render draws nothing else.
jobs::ImageRef checked_relief(const RenderOptions& o, jobs::ImageRef ref) {
  if (ref.kind != jobs::Method::Relief)
    throw InvalidInput(fmt::format("{}: {} is a {}, not a relief map: render draws relief maps only",
                                   io::printable(o.archive), io::printable(ref.path()),
                                   jobs::representation(ref.kind).what));
  return ref;
}

/// The relief map to draw: --name (NAME, relief/NAME or batch/OUTPUT/ITEM), or the only relief map of the archive.
jobs::ImageRef choose_relief(const io::Archive& archive, const RenderOptions& o) {
  if (o.name.empty()) {
    const auto names = jobs::image_names(archive, jobs::Method::Relief);
    if (names.size() == 1) return {jobs::Method::Relief, names.front()};
    if (names.empty() && archive.root().exists("batch") && jobs::image_names(archive, jobs::Method::Gim).empty() &&
        jobs::image_names(archive, jobs::Method::Sphere).empty() && jobs::image_names(archive, jobs::Method::Mcgim).empty())
      return checked_relief(o, jobs::choose_image(archive, "", jobs::BatchItems::kAccepted));  // its only item
    if (names.empty())
      throw InvalidInput(fmt::format("{}: holds no relief map (convert --method relief makes one{})", o.archive,
                                     archive.root().exists("batch") ? "; a batch's relief map: --name batch/OUTPUT/ITEM" : ""));
    std::string list;
    for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
    throw InvalidInput(fmt::format("{}: holds several relief maps ({}); choose one with --name", o.archive, list));
  }
  return checked_relief(o, jobs::choose_image(archive, o.name, jobs::BatchItems::kAccepted));
}

/// OUTPUT's path with "_reference" before its extension.
std::filesystem::path reference_path(const std::string& output) {
  const std::filesystem::path p(output);
  return p.parent_path() / (p.stem().string() + "_reference" + p.extension().string());
}

/// Renders twice and keeps the second image: the first warms the caches and starts the worker threads,
/// so the time reported is the steady one.
template <class Renderer>
RenderImage render_timed(const Renderer& renderer, const Camera& camera) {
  (void)renderer.render(camera);
  return renderer.render(camera);
}

/// Before any work: the PNGs can be created and neither replaces an input (the archive, the mesh).
void check_outputs(const RenderOptions& options) {
  std::string extension = std::filesystem::path(options.output).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension != ".png")
    throw InvalidInput(fmt::format("{}: render writes PNG pictures; name the output .png", options.output));
  std::vector<std::filesystem::path> outputs{options.output};
  if (!options.reference.empty()) outputs.push_back(reference_path(options.output));
  for (const std::filesystem::path& output : outputs) {
    io::check_can_create(output);
    jobs::refuse_output_over_inputs(output, {options.archive, options.reference});
  }
}

}  // namespace

int run_render(const RenderOptions& options) {
  const OrbitView view = parse_view(options);
  check_outputs(options);
  const io::Archive archive = io::Archive::open(options.archive);
  const jobs::ImageRef image_ref = choose_relief(archive, options);
  const std::string name = image_ref.batch ? image_ref.path() : image_ref.name;  // as the JSON report names it
  const ReliefMap map = jobs::read_relief(archive, image_ref);
  const BoundingBox box = relief_surface_bounds(map);
  if (box.empty())
    throw InvalidInput(fmt::format("{}:/{}: the map holds no surface sample", options.archive, io::printable(image_ref.path())));
  const Camera camera = orbit_camera(box, view, options.size, options.size);
  // The reference mesh is read before the ray casting: a missing or broken one leaves no picture behind.
  std::optional<jobs::LoadedMesh> reference;
  if (!options.reference.empty())
    reference = jobs::load_mesh(options.reference, jobs::LoadPolicy{.repair = true, .warn = true});

  RaycastOptions ro;
  ro.linear_steps = options.steps;
  ro.binary_steps = options.refine;
  ro.filter = options.filter == "nearest" ? ReliefFilter::Nearest : ReliefFilter::Bilinear;
  const ReliefRaycaster caster(map, ro);
  const RenderImage image = render_timed(caster, camera);
  io::write_png_rgb(options.output, image.width, image.height, image.shaded_rgb());
  // -j limits the threads through tbb::global_control, which the arena's concurrency does not reflect.
  const int threads = static_cast<int>(std::min<std::size_t>(
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism),
      static_cast<std::size_t>(tbb::this_task_arena::max_concurrency())));

  nlohmann::json report;
  report["archive"] = options.archive;
  report["name"] = name;
  report["output"] = options.output;
  report["view"] = {{"azimuth", view.azimuth_deg},
                    {"elevation", view.elevation_deg},
                    {"up", options.up},
                    {"fov", view.fov_deg},
                    {"eye", {camera.eye.x(), camera.eye.y(), camera.eye.z()}}};
  report["size"] = options.size;
  report["map"] = {
      {"n", map.n}, {"texture", map.texture}, {"grey_cells", map.cells.size()}, {"layers", map.num_layers()}};
  report["raycast"] = {{"rays", image.rays},
                       {"hits", image.hits},
                       {"seconds", image.seconds},
                       {"rays_per_second", image.rays_per_second()},
                       {"threads", threads},
                       {"tests_per_ray", static_cast<double>(image.samples) / static_cast<double>(image.rays)},
                       {"linear_steps", ro.linear_steps},
                       {"binary_steps", ro.binary_steps},
                       {"filter", options.filter},
                       {"vectorized", caster.vectorized()}};

  if (!options.json) {
    fmt::print("{}:/{} view {:g},{:g} (up {}) {}x{} -> {}\n", io::printable(options.archive), io::printable(image_ref.path()),
               view.azimuth_deg, view.elevation_deg, options.up, options.size, options.size, io::printable(options.output));
    fmt::print("  relief map     N = {}, T = {}, {} grey cells, {} domain faces\n", map.n, map.texture,
               map.cells.size(), map.num_layers());
    fmt::print("  ray casting    {} rays in {:.1f} ms: {:.2f} Mrays/s on {} thread{}{}, {:.1f} inside tests per ray, "
               "{} hits\n",
               image.rays, 1e3 * image.seconds, 1e-6 * image.rays_per_second(), threads, threads == 1 ? "" : "s",
               caster.vectorized() ? " (AVX2)" : "",
               static_cast<double>(image.samples) / static_cast<double>(image.rays), image.hits);
  }

  if (!options.reference.empty()) {
    jobs::LoadedMesh& mesh = *reference;
    // Into the map's frame (the local frame it was made in), where the camera is, before Embree's float BVH.
    jobs::to_local_frame(mesh.mesh, jobs::image_origin(archive, image_ref));
    const EmbreeDevice device;
    const MeshRenderer renderer(device, mesh.mesh, ro.ambient);
    const RenderImage ref = render_timed(renderer, camera);
    const auto ref_png = reference_path(options.output);
    io::write_png_rgb(ref_png, ref.width, ref.height, ref.shaded_rgb());
    const RenderComparison cmp = compare_renders(image, ref);
    const double diagonal = bounding_box(mesh.mesh).diagonal();
    report["reference"] = {{"mesh", options.reference},
                           {"output", ref_png.string()},
                           {"hits", ref.hits},
                           {"seconds", ref.seconds},
                           {"rays_per_second", ref.rays_per_second()}};
    report["comparison"] = {{"psnr", std::isfinite(cmp.psnr) ? nlohmann::json(cmp.psnr) : nlohmann::json(nullptr)},
                            {"mse", cmp.mse},
                            {"iou", cmp.iou},
                            {"hits_relief", cmp.hits_a},
                            {"hits_reference", cmp.hits_b},
                            {"depth_mean_abs", cmp.depth_mean_abs},
                            {"depth_rms", cmp.depth_rms},
                            {"depth_p95", cmp.depth_p95},
                            {"diagonal", diagonal},
                            {"normal_mean_deg", cmp.normal_mean_deg}};
    if (!options.json) {
      fmt::print("  reference      {} -> {} (Embree, {:.1f} ms, {} hits)\n", io::printable(options.reference),
                 io::printable(ref_png.string()),
                 1e3 * ref.seconds, ref.hits);
      fmt::print("  comparison     PSNR {:.2f} dB (shaded 8-bit images, all pixels), silhouette IoU {:.4f}\n", cmp.psnr,
                 cmp.iou);
      fmt::print("                 depth error mean {:.3g} ({:.2e} of the diagonal), 95th percentile {:.3g}; normals "
                 "{:.2f} deg\n",
                 cmp.depth_mean_abs, cmp.depth_mean_abs / diagonal, cmp.depth_p95, cmp.normal_mean_deg);
    }
  }
  if (options.json) fmt::print("{}\n", report.dump(2, ' ', false, nlohmann::json::error_handler_t::replace));
  return kExitOk;
}

}  // namespace gimforge::cli
