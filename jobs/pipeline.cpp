#include "jobs/pipeline.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <span>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "gimforge_version.h"
#include "io/gim_archive.h"
#include "io/mcgim_archive.h"
#include "io/relief_archive.h"
#include "io/sphere_archive.h"
#include "jobs/error_naming.h"
#include "jobs/memory_budget.h"
#include "jobs/proxy.h"
#include "jobs/roi.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/manifold_cut.h"
#include "kernels/core/surface_sampling.h"
#include "kernels/relief/relief_fidelity.h"

namespace gimforge::jobs {
namespace {

using Clock = std::chrono::steady_clock;

/// A sphere map's stretch efficiency below which the conversion warns (12x below the shared meshes' lowest).
constexpr double kPoorSphereMap = 0.02;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// The process's command line (set_command_line), guarded: batch workers read it from their threads.
std::mutex command_line_mutex;
std::string process_command_line;

/// `arg` as a POSIX shell reads it back: as is when it holds only safe characters, else in single quotes.
std::string shell_quoted(std::string_view arg) {
  const bool safe = !arg.empty() && arg.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                                          "0123456789@%+=:,./_-") == std::string_view::npos;
  if (safe) return std::string(arg);
  std::string out(1, '\'');
  for (const char ch : arg) {
    if (ch == '\'')
      out.append("'\\''");  // close the quotes, an escaped quote, reopen
    else
      out.push_back(ch);
  }
  out.push_back('\'');
  return out;
}

/// Interleaved (H·W·channels) samples to channel-first (channels·H·W).
std::vector<float> channel_first(const std::vector<float>& xyz, std::size_t pixels, std::size_t channels = 3) {
  std::vector<float> out(channels * pixels);
  for (std::size_t p = 0; p < pixels; ++p)
    for (std::size_t c = 0; c < channels; ++c) out[c * pixels + p] = xyz[channels * p + c];
  return out;
}

/// Geometry-image optimization (Sander et al. 2003 §4.6): the pixels as a full-mask grid image whose clusters
/// are the sideband's glued pixels, so mates move together and stay bit-identical.
SurfaceFitResult optimize_geometry_image(const EmbreeDevice& device, const FitReference& reference, GimResult& gim,
                                         const ProgressCallback& progress) {
  GeometryImage& image = gim.image;
  MultiChartImage grid;
  grid.width = grid.height = image.size;
  grid.positions = image.positions;
  grid.mask.assign(grid.samples(), 1);
  grid.chart.assign(grid.samples(), 0);
  grid.unified = boundary_classes(image.sideband, image.size);
  SurfaceFitOptions options = default_mcgim_fit();
  options.progress = progress;
  SurfaceFitResult fit = optimize_multichart_image(device, reference, grid, options);
  image.positions = std::move(grid.positions);
  return fit;
}

/// The §4.6 fit of the image in `c` against `reference`, recorded as each method records its --optimize
/// (sphere's seconds_optimize is its parametrization's: its fit's are seconds_fit).
void fit_and_record(const EmbreeDevice& device, const FitReference& reference, Conversion& c,
                    const ProgressCallback& progress) {
  SurfaceFitOptions fo = default_mcgim_fit();
  fo.progress = progress;
  SurfaceFitResult fit;
  if (c.gim) {
    fit = optimize_geometry_image(device, reference, *c.gim, progress);
  } else if (c.sphere) {
    fit = optimize_spherical_image(device, reference, c.sphere->image, fo);
  } else if (c.mcgim) {
    fit = optimize_multichart_image(device, reference, c.mcgim->image, fo);
    c.mcgim->normals = multichart_normals(c.mcgim->image);  // of the fitted positions, as a direct conversion's
    McgimStats& s = c.mcgim->stats;
    s.fit_energy_before = fit.energy_before;
    s.fit_energy_after = fit.energy_after;
    s.seconds_optimize = fit.seconds;
  } else {
    return;
  }
  c.numbers["fit_energy_before"] = fit.energy_before;
  c.numbers["fit_energy_after"] = fit.energy_after;
  c.numbers[c.sphere ? "seconds_fit" : "seconds_optimize"] = fit.seconds;
}

/// Figures of an adaptive sampling: symmetric figures of the local Hausdorff distances (local_hausdorff.h),
/// the largest of either direction and sqrt((rms_d1² + rms_d2²) / 2) as the PSNR's d, before and after.
void record_adaptive(std::map<std::string, double>& num, const std::vector<AdaptRound>& history, double seconds, bool strips) {
  const auto max_of = [](const AdaptRound& r) { return std::max(r.max_d1, r.max_d2); };
  const auto rms_of = [](const AdaptRound& r) { return std::sqrt(0.5 * (r.rms_d1 * r.rms_d1 + r.rms_d2 * r.rms_d2)); };
  std::uint64_t moves = 0;
  for (const AdaptRound& r : history) moves += r.moves;
  num["adapt_rounds_run"] = static_cast<double>(history.size() - 1);
  num["adapt_moves"] = static_cast<double>(moves);
  num["adapt_max_before"] = max_of(history.front());
  num["adapt_max_after"] = max_of(history.back());
  num["adapt_rms_before"] = rms_of(history.front());
  num["adapt_rms_after"] = rms_of(history.back());
  num["seconds_adapt"] = seconds;
  num["adapt_start_strips"] = strips ? 1.0 : 0.0;
}

/// How much larger the RMS distance from the image to the input outside a ROI may end than on the start grid
/// before the log says so (docs/adaptive.md: 4× is typical at the default gain).
constexpr double kSteepOutsideGrowth = 10.0;

/// The ROI (§4): its samples, and the directed distances inside and outside it, on the start grid (before)
/// and at the end (after); "roi_d2" is the objective, from the ROI's reconstruction. A ROI that ended worse
/// than its start grid (which is then kept) is also said in the log, naming `source`, and so is an error outside
/// the ROI grown more than kSteepOutsideGrowth times.
void record_roi(std::map<std::string, double>& num, const RoiSummary& roi, const AdaptRound& last,
                const std::string& source) {
  if (roi.kept_start)
    spdlog::warn("{}: --roi: the region of interest ended with a larger error than on the start grid ({:.4g} > {:.4g}: "
                 "more samples than the image can give it, a high --roi-gain or a small image); the start grid was kept",
                 source, roi.rejected_max_d2, roi.roi_start.max_d2);
  num["roi_kept_start"] = roi.kept_start ? 1.0 : 0.0;
  num["roi_samples_before"] = static_cast<double>(roi.samples_start);
  num["roi_samples_enhanced"] = static_cast<double>(roi.samples_enhanced);
  num["roi_samples_after"] = static_cast<double>(roi.samples_final);
  num["roi_weight"] = roi.weight;
  num["roi_iterations"] = roi.iterations;
  const auto region = [&](std::string_view prefix, const RegionFigures& before, const RegionFigures& after) {
    num[fmt::format("{}_max_d1_before", prefix)] = before.max_d1;
    num[fmt::format("{}_max_d1_after", prefix)] = after.max_d1;
    num[fmt::format("{}_max_d2_before", prefix)] = before.max_d2;
    num[fmt::format("{}_max_d2_after", prefix)] = after.max_d2;
    num[fmt::format("{}_rms_d1_before", prefix)] = before.rms_d1;
    num[fmt::format("{}_rms_d1_after", prefix)] = after.rms_d1;
    num[fmt::format("{}_rms_d2_before", prefix)] = before.rms_d2;
    num[fmt::format("{}_rms_d2_after", prefix)] = after.rms_d2;
  };
  region("roi", roi.roi_start, last.roi);
  region("outside", roi.outside_start, last.outside);
  // The price of the ROI's samples is paid outside it: said when it is steep (fist 65 with a corner box at the
  // default gain: 68 % of the samples in the ROI, the rest's error 30×, the whole surface's PSNR 61 → 32 dB).
  // The figure convert prints as "outside roi": the RMS distance from the image's surface there to the input.
  const double before = roi.outside_start.rms_d2, after = last.outside.rms_d2;
  if (!roi.kept_start && before > 0.0 && after > kSteepOutsideGrowth * before)
    spdlog::warn("{}: --roi: outside the region of interest the error grew {:.0f}× (rms {:.4g} → {:.4g}): the region "
                 "holds {} of the {} samples; a lower --roi-gain or a larger image costs the rest less",
                 source, after / before, before, after, roi.samples_final, roi.inside.size());
}

/// AdaptStart::Auto: the symmetric local RMS of either start grid.
void record_start_choice(std::map<std::string, double>& num, double rms_uniform, double rms_strips) {
  if (rms_uniform <= 0.0) return;
  num["adapt_rms_uniform_start"] = rms_uniform;
  num["adapt_rms_strips_start"] = rms_strips;
}

/// The kernel's region of interest for an adaptive image (none without --roi).
RoiSource region_of_interest(const ConversionRequest& request) {
  const MethodOptions& m = request.method;
  RoiSource roi = request.roi;
  roi.enhance.gain = m.roi_gain;
  if (!m.roi.empty() && roi.kind == RoiSource::Kind::None)
    throw InvalidInput(fmt::format("--roi {} was not resolved against the mesh (a conversion split in bricks "
                                   "across ranks takes no region of interest: convert on one rank)",
                                   m.roi));
  return roi;
}

/// The record's numbers of what cutting the input into an oriented 2-manifold changed (manifold_cut.h).
void record_cut(const McgimStats& s, std::map<std::string, double>& num) {
  num["cut_nonmanifold_edges"] = static_cast<double>(s.cut_nonmanifold_edges);
  num["cut_orientation_edges"] = static_cast<double>(s.cut_orientation_edges);
  num["flipped_faces"] = static_cast<double>(s.flipped_faces);
  num["split_vertices"] = static_cast<double>(s.split_vertices);
  num["arealess_faces"] = static_cast<double>(s.arealess_faces);
}

/// The method's kernel: fills the typed result and its statistics.
void run_kernel(const EmbreeDevice& device, const TriMesh& mesh, const ConversionRequest& request, Conversion& c) {
  const MethodOptions& m = request.method;
  auto& num = c.numbers;
  switch (m.method) {
    case Method::Gim: {
      GimOptions o;
      o.image.size = m.size;
      o.image.normal_size = m.normal_size;
      o.max_augmentations = m.max_augmentations;
      o.sampling = m.adaptive() ? GimSampling::Adaptive : GimSampling::Uniform;
      o.adapt.rounds = m.adapt_rounds;
      o.adapt_start = m.adapt_start == "uniform" ? AdaptStart::Uniform
                      : m.adapt_start == "strips" ? AdaptStart::Strips
                                                  : AdaptStart::Auto;
      o.roi = region_of_interest(request);
      o.progress = request.progress;
      c.gim = convert_to_geometry_image(device, mesh, o);
      const GimStats& s = c.gim->stats;
      num = {{"cut_edges", static_cast<double>(s.cut_edges)},
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
             {"seconds_sample", s.seconds_sample}};
      if (!s.adapt_history.empty()) {
        record_adaptive(num, s.adapt_history, s.seconds_adapt, s.adapt_started_from_strips);
        if (!s.roi.inside.empty()) record_roi(num, s.roi, s.adapt_history.back(), request.source);
        record_start_choice(num, s.adapt_rms_uniform_start, s.adapt_rms_strips_start);
      }
      if (m.optimize) fit_and_record(device, mesh, c, request.progress);
      return;
    }
    case Method::Sphere: {
      SphereOptions o;
      o.domain = parse_spherical_domain(m.domain);
      o.n = m.n;
      o.progress = request.progress;
      o.adaptive = m.adaptive();
      o.adapt.rounds = m.adapt_rounds;
      o.adapt_start = m.adapt_start == "uniform" ? AdaptStart::Uniform
                      : m.adapt_start == "strips" ? AdaptStart::Strips
                                                  : AdaptStart::Auto;
      o.roi = region_of_interest(request);
      c.sphere = request.sphere_map ? convert_with_sphere_map(device, mesh, *request.sphere_map, o)
                                    : convert_to_spherical_image(device, mesh, o);
      const SphereStats& s = c.sphere->stats;
      // Above the kernel's collapse refusal (1e-4) a map can still leave most of the surface to few samples: a
      // 1 x 1 x 10^-4 box's efficiency 7e-4 gave 23 dB where gim gives 68 (the shared meshes: 0.24 .. 0.88).
      if (s.map_stretch.efficiency < kPoorSphereMap)
        spdlog::warn("{}: the sphere map's stretch efficiency is {:.2g}: most samples fall on a small part of the "
                     "surface; a shape this flat, thin or elongated suits --method gim, mcgim or relief better",
                     request.source, s.map_stretch.efficiency);
      num = {{"map_efficiency", s.map_stretch.efficiency},
             {"map_l2_stretch", s.map_stretch.l2},
             {"flipped_triangles", static_cast<double>(s.map_stretch.flipped)},
             {"domain_efficiency", s.domain_efficiency},
             {"efficiency_domain_to_mesh", s.efficiency_domain_to_mesh},
             {"holes_filled", static_cast<double>(s.holes_filled)},
             {"hole_faces", static_cast<double>(s.hole_faces)},
             {"masked_samples", static_cast<double>(s.masked_samples)},
             {"holes_without_samples", static_cast<double>(s.holes_without_samples)},
             {"base_vertices", static_cast<double>(s.base_vertices)},
             {"vertex_splits", static_cast<double>(s.vertex_splits)},
             {"seconds_simplify", s.seconds_simplify},
             {"seconds_optimize", s.seconds_optimize},
             {"seconds_sample", s.seconds_sample}};
      if (!s.adapt_history.empty()) {
        record_adaptive(num, s.adapt_history, s.seconds_adapt, s.adapt_started_from_strips);
        record_start_choice(num, s.adapt_rms_uniform_start, s.adapt_rms_strips_start);
        num["adapt_disk_faces"] = static_cast<double>(s.adapt_disk_faces);
        num["adapt_disk_flipped"] = static_cast<double>(s.adapt_disk_flipped);
        if (!s.roi.inside.empty()) record_roi(num, s.roi, s.adapt_history.back(), request.source);
      }
      if (m.optimize) fit_and_record(device, mesh, c, request.progress);
      return;
    }
    case Method::Relief: {
      c.relief = build_relief_map(mesh, relief_options(request));
      record_relief(c);
      return;
    }
    case Method::Mcgim: {
      McgimOptions o;
      o.samples = m.samples;
      o.charts = m.mcgim_charts();
      o.optimize = m.optimize;
      o.progress = request.progress;
      c.mcgim = convert_to_multichart(device, mesh, o);
      const McgimStats& s = c.mcgim->stats;
      num = {{"charts", static_cast<double>(s.charts)},
             {"chartify_iterations", s.chartify_iterations},
             {"chartify_converged", s.chartify_converged ? 1.0 : 0.0},
             {"chartify_cycle", s.chartify_cycle ? 1.0 : 0.0},
             {"extra_seeds", static_cast<double>(s.extra_seeds)},
             {"smoothed_faces", static_cast<double>(s.smoothed_faces)},
             {"stretch_efficiency", s.stretch.efficiency},
             {"l2_stretch", s.stretch.l2},
             {"optimizer_fallbacks", static_cast<double>(s.optimizer_fallbacks)},
             {"boundary_folds", static_cast<double>(s.boundary_folds)},
             {"enlarged_charts", static_cast<double>(s.enlarged_charts)},
             {"packing_efficiency", s.packing_efficiency},
             {"scale", s.scale},
             {"scale_steps", s.scale_steps},
             {"defined_samples", static_cast<double>(s.defined_samples)},
             {"unique_vertices", static_cast<double>(s.unique_vertices)},
             {"boundary_samples", static_cast<double>(s.boundary_samples)},
             {"dilated_samples", static_cast<double>(s.dilated_samples)},
             {"cut_nodes", static_cast<double>(s.zipper.cut_nodes)},
             {"cut_paths", static_cast<double>(s.zipper.cut_paths)},
             {"unified_samples", static_cast<double>(s.zipper.unified_samples)},
             {"seconds_chartify", s.seconds_chartify},
             {"seconds_parametrize", s.seconds_parametrize},
             {"seconds_pack", s.seconds_pack},
             {"seconds_sample", s.seconds_sample},
             {"seconds_zipper", s.seconds_zipper}};
      record_cut(s, num);
      if (m.optimize) {
        num["fit_energy_before"] = s.fit_energy_before;
        num["fit_energy_after"] = s.fit_energy_after;
        num["seconds_optimize"] = s.seconds_optimize;
      }
      return;
    }
  }
}

/// The papers' fidelity against `mesh`: the symmetric RMS Hausdorff distance to the reconstruction (gim: fused,
/// level 0; sphere: level 0, holes open as in the input; relief: the geometry-based one of §3.5.1).
HausdorffResult measure(const EmbreeDevice& device, const TriMesh& mesh, const ConversionRequest& request,
                        Conversion& c) {
  HausdorffOptions h;
  h.samples = request.fidelity.samples;
  h.progress = request.progress;
  switch (c.method) {
    case Method::Gim:
    case Method::Sphere:
    case Method::Mcgim: return symmetric_hausdorff(device, mesh, image_reconstruction(c), h);
    case Method::Relief: {
      // Measured from the texels, without building the reconstruction's tens of millions of triangles
      // (kernels/relief/relief_fidelity.h); the same figures as symmetric_hausdorff against it.
      const ReliefMap& map = c.relief.value();
      const ReliefFidelity f = [&] {
        try {
          return relief_fidelity(device, mesh, map, h);
        } catch (const InvalidInput& e) {
          // Too coarse a map for the surface: finer texels give it triangles.
          if (std::string_view(e.what()).find("reconstructs to no") == std::string_view::npos) throw;
          throw InvalidInput(fmt::format("{}{}", e.what(), coarse_relief_hint(map.cell_size, map.texture)));
        }
      }();
      c.numbers["reconstruction_vertices"] = static_cast<double>(f.reconstruction_vertices);
      c.numbers["reconstruction_faces"] = static_cast<double>(f.reconstruction_faces);
      return f.hausdorff;
    }
  }
  throw InvalidInput("unknown method");
}

}  // namespace

void check_frame_origin(const std::string& source, const Vec3& origin) {
  // What the readers accept back (item_origin): an archive gimforge writes must be one it reads.
  if (!(origin.cwiseAbs().maxCoeff() <= kMaxFrameOrigin))
    throw InvalidInput(fmt::format("{}: the mesh lies {:.3g} from the origin; archives hold local frames within "
                                   "±1e12 of it (move the mesh nearer first)",
                                   source, origin.cwiseAbs().maxCoeff()));
}

Conversion begin_conversion(const ConversionRequest& request, std::size_t input_vertices, std::size_t input_faces,
                            const Vec3& origin) {
  request.method.check(method_name(request.method.method));
  check_frame_origin(request.source, origin);
  Conversion c;
  c.method = request.method.method;
  c.source = request.source;
  c.command_line = request.command_line.empty() ? command_line() : request.command_line;
  c.parameters = creation_parameters(request);
  c.input_vertices = input_vertices;
  c.input_faces = input_faces;
  c.origin = origin;
  return c;
}

void run_method(const EmbreeDevice& device, const TriMesh& mesh, const ConversionRequest& request, Conversion& c,
                const std::string& wrap) {
  name_errors(request.source, [&] { run_kernel(device, mesh, request, c); }, wrap, &mesh);
}

std::size_t fit_reference_samples(const Conversion& c) {
  std::size_t samples = 0;
  if (c.gim) samples = c.gim->image.positions.size() / 3;
  if (c.sphere) samples = c.sphere->image.mask.size();
  if (c.mcgim) samples = c.mcgim->image.defined_samples();
  return std::max(default_mcgim_fit().reference_samples, 4 * samples);
}

std::uint64_t fit_reference_seed() { return default_mcgim_fit().seed; }

void fit_image(const EmbreeDevice& device, std::span<const Vec3> reference_samples, Conversion& c,
               const ProgressCallback& progress) {
  // Samples farther than kFitReach mean edges from the moved image lie on parts it does not represent
  // (pieces a wrap left out, scanned insides it sealed): fitted to, they would pull its nearest vertices
  // into spikes. Every sample of a part it represents lies within a fraction of an edge of it.
  constexpr double kFitReach = 2.0;
  const TriMesh start = image_reconstruction(c);
  double edges = 0.0, length = 0.0;
  for (const Face& f : start.faces)
    for (int k = 0; k < 3; ++k, edges += 1.0)
      length += (start.positions[f[static_cast<std::size_t>(k)]] - start.positions[f[static_cast<std::size_t>((k + 1) % 3)]]).norm();
  const double reach = edges > 0.0 ? kFitReach * length / edges : 0.0;
  const std::vector<double> distance = distances_to_surface(reference_samples, TriangleBvh(device, start));
  const auto far = static_cast<std::size_t>(std::count_if(distance.begin(), distance.end(), [&](double d) { return d > reach; }));
  if (far == 0 || far == distance.size()) {  // all near (no copy), or none: a broken image, fitted to all
    c.numbers["fit_samples_left_out"] = 0.0;
    fit_and_record(device, FitReference::samples(reference_samples), c, progress);
    return;
  }
  std::vector<Vec3> near;
  near.reserve(distance.size() - far);
  for (std::size_t i = 0; i < distance.size(); ++i)
    if (distance[i] <= reach) near.push_back(reference_samples[i]);
  c.numbers["fit_samples_left_out"] = static_cast<double>(far);
  fit_and_record(device, FitReference::samples(near), c, progress);
}

TriMesh image_reconstruction(const Conversion& c) {
  switch (c.method) {
    case Method::Gim: {
      const GeometryImage& image = c.gim.value().image;
      return reconstruct_geometry_image(image.positions, image.size, &image.sideband);
    }
    case Method::Sphere: return reconstruct_spherical_geometry(c.sphere.value().image);
    case Method::Mcgim: return reconstruct_multichart(c.mcgim.value().image);
    case Method::Relief: break;
  }
  throw InvalidInput("a relief map has no image reconstruction");
}

ReliefOptions relief_options(const ConversionRequest& request) {
  const MethodOptions& m = request.method;
  ReliefOptions o;
  o.grid = m.relief_grid();
  o.texture = m.texture;
  o.max_grid = m.max_grid;
  o.occlusion_threshold = m.occlusion_threshold;
  if (const auto limit = memory_limit()) o.max_map_bytes = std::max<std::uint64_t>(1, limit->bytes);
  o.progress = request.progress;
  return o;
}

void record_relief(Conversion& c) {
  const ReliefMap& map = c.relief.value();
  const ReliefGridLevel& kept = map.levels.back();
  const std::map<std::string, double> numbers{{"occlusion_ratio", kept.occlusion_ratio()},
                                                {"samples", static_cast<double>(kept.samples)},
                                                {"occluded_samples", static_cast<double>(kept.occluded)},
                                                {"grid_levels_tried", static_cast<double>(map.levels.size())},
                                                {"storage_bytes", static_cast<double>(map.storage_bytes())},
                                                {"seconds_cells", map.seconds_cells},
                                                {"seconds_sampling", map.seconds_sampling}};
  for (const auto& [key, value] : numbers) c.numbers[key] = value;
}

void record_fidelity(Conversion& c, const HausdorffResult& fidelity) {
  c.fidelity = fidelity;
  c.numbers["psnr"] = fidelity.psnr;
  c.numbers["hausdorff_rms"] = fidelity.rms;
  c.numbers["hausdorff_max"] = fidelity.max;
  c.numbers["bbox_diagonal"] = fidelity.diag;
}

void finish_conversion(Conversion& c, double seconds_construct, double seconds_metric, double seconds_total) {
  // In the record too, so that a batch item, whose stacked image has no group of its own, keeps it (metrics
  // frame_origin_x/y/z) and both commands record the same numbers.
  c.numbers["frame_origin_x"] = c.origin.x();
  c.numbers["frame_origin_y"] = c.origin.y();
  c.numbers["frame_origin_z"] = c.origin.z();
  c.seconds_construct = seconds_construct;
  c.seconds_metric = seconds_metric;
  c.seconds_total = seconds_total;
  c.numbers["seconds_construct"] = c.seconds_construct;
  c.numbers["seconds_metric"] = c.seconds_metric;
  c.numbers["seconds_total"] = c.seconds_total;
  c.created = io::utc_timestamp();
}

Conversion convert_mesh(const EmbreeDevice& device, const TriMesh& mesh, const ConversionRequest& request) {
  return convert_mesh(device, TriMesh(mesh), request);
}

Conversion convert_mesh(const EmbreeDevice& device, TriMesh&& mesh, const ConversionRequest& request) {
  const auto start = Clock::now();
  // Float images and Embree's float BVH far from the origin (georeferenced scans) would keep a few bits of the
  // surface: the conversion and its fidelity run in the local frame, independent of where the mesh lies.
  check_conversion_memory(request.source, request.method, request.fidelity.enabled ? request.fidelity.samples : 0);
  Conversion c = begin_conversion(request, mesh.num_vertices(), mesh.num_faces(), local_frame_origin(mesh));
  TriMesh local = std::move(mesh);
  to_local_frame(local, c.origin);
  // A huge input reaches an image method through a decimated proxy whose samples then move onto the input's
  // surface (jobs/proxy.h); the fidelity below is measured against the input, never the proxy.
  // With --wrap the proxy is a closed one-piece wrap of the input (of the decimated proxy of a huge one, so
  // that ranks and one process agree), decimated in turn (jobs/proxy.h).
  const auto wrap = request.method.wrap_voxels();
  const std::size_t huge_faces = request.sphere_map && request.method.proxy_faces == "auto"
                                     ? 0  // a stored sphere map is one per input vertex
                                     : request.method.proxy_target(local.num_faces());
  const std::size_t proxy_faces = wrap ? request.method.wrap_proxy_target() : huge_faces;
  if (proxy_faces > 0 && request.sphere_map)
    throw InvalidInput(fmt::format("{}: --sphere-map reuses the map of a whole mesh; it cannot be combined with {}",
                                   request.source, wrap ? "--wrap " + request.method.wrap
                                                        : "--proxy-faces " + request.method.proxy_faces));
  std::optional<TriMesh> proxy;
  if (proxy_faces > 0) {
    name_errors(request.source, [&] {
      std::map<std::string, double> proxy_numbers;
      // A multi-chart image takes a non-manifold or misoriented input (manifold_cut.h): the input is cut before
      // it is decimated, so the proxy keeps every face and the record counts the input's cut, not the proxy's.
      std::optional<ManifoldCut> cut;
      if (request.method.method == Method::Mcgim && !wrap) {  // a clean huge input is not copied
        const ManifoldCheck check = check_manifold(local, build_edge_topology(local));
        if (!check.nonmanifold_edges.empty() || !check.nonmanifold_vertices.empty() || !check.inconsistent_edges.empty())
          cut = cut_to_manifold(local);
      }
      const TriMesh& source = cut ? cut->mesh : local;
      if (huge_faces > 0)
        proxy = request.proxy_maker
                    ? request.proxy_maker(source, c.origin, huge_faces, request.progress, proxy_numbers)
                    : make_proxy(source, huge_faces, request.method.proxy_bricks, request.progress, proxy_numbers);
      if (wrap)
        proxy = make_wrap_proxy(proxy ? *proxy : source, wrap->first, wrap->second, proxy_faces,
                                request.method.proxy_bricks, request.source, request.progress, proxy_numbers);
      warn_proxy_rejections(request.source, proxy_numbers);
      ConversionRequest on_proxy = request;
      on_proxy.method.optimize = false;  // fitted after the transfer, to the full surface (fit_image)
      if (request.roi.kind == RoiSource::Kind::Vertices)  // the ROI's vertex flags, carried to the proxy's vertices
        on_proxy.roi = roi_for_proxy(device, request.roi, local, *proxy);
      run_kernel(device, *proxy, on_proxy, c);
      c.numbers.merge(proxy_numbers);
      if (cut && c.mcgim) {  // the input's cut, not the proxy's
        McgimStats& st = c.mcgim->stats;
        st.cut_nonmanifold_edges = cut->nonmanifold_edges;
        st.cut_orientation_edges = cut->orientation_cuts;
        st.flipped_faces = cut->flipped_faces;
        st.split_vertices = cut->split_vertices;
        record_cut(st, c.numbers);
      }
      transfer_to_full_surface(device, *proxy, local, c, request.progress);
    }, wrap ? request.method.wrap : std::string{}, wrap ? nullptr : &local);
    if (request.method.optimize)  // against the input itself: its errors are not the wrap's
      name_errors(request.source, [&] {
        fit_image(device, sample_surface(local, {fit_reference_samples(c), fit_reference_seed()}).points, c,
                  request.progress);
      });
  } else {
    run_method(device, local, request, c);
  }
  const double seconds_construct = seconds_since(start);
  double seconds_metric = 0.0;
  if (request.fidelity.enabled) {
    const auto metric_start = Clock::now();
    name_errors(request.source, [&] { record_fidelity(c, measure(device, local, request, c)); });
    if (proxy) {
      // What the transfer gained: the proxy's own fidelity, measured the same way.
      HausdorffOptions h;
      h.samples = request.fidelity.samples;
      h.progress = request.progress;
      name_errors(request.source, [&] { c.numbers["proxy_psnr"] = symmetric_hausdorff(device, local, *proxy, h).psnr; });
    }
    seconds_metric = seconds_since(metric_start);
  }
  finish_conversion(c, seconds_construct, seconds_metric, seconds_since(start));
  return c;
}

void write_conversion(io::Archive& archive, const std::string& name, const Conversion& conversion) {
  const io::RepresentationRecord record{conversion.source, conversion.numbers};
  switch (conversion.method) {
    case Method::Gim: io::write_geometry_image(archive, name, conversion.gim.value().image, record); break;
    case Method::Sphere: {
      const SphereResult& r = conversion.sphere.value();
      // The sphere map is one vector per vertex of the mesh that was parametrized: the proxy, when there was one.
      const auto parametrized = [&](const char* proxy_key, std::size_t input) {
        const auto it = conversion.numbers.find(proxy_key);
        return it == conversion.numbers.end() ? input : static_cast<std::size_t>(it->second);
      };
      const io::SphereParametrization p{r.sphere, parametrized("proxy_vertices", conversion.input_vertices),
                                        parametrized("proxy_faces", conversion.input_faces)};
      io::write_spherical_image(archive, name, r.image, p, record);
      break;
    }
    case Method::Relief: io::write_relief_map(archive, name, conversion.relief.value(), record); break;
    case Method::Mcgim: {
      const McgimResult& r = conversion.mcgim.value();
      io::write_multichart_image(archive, name, r.image, {r.normals, r.stats.chart_efficiency}, record);
      break;
    }
  }
  h5::Group group = io::open_representation(archive, representation(conversion.method), name);
  write_item_facts(group, conversion);
  const std::vector<AdaptRound>* adapt_history = conversion.method == Method::Gim      ? &conversion.gim->stats.adapt_history
                                                 : conversion.method == Method::Sphere ? &conversion.sphere->stats.adapt_history
                                                                                       : nullptr;
  if (adapt_history != nullptr && !adapt_history->empty()) {
    // Per round of the adaptive sampling: what it measured and did (docs/archive.md).
    std::vector<double> rows;
    for (const AdaptRound& r : *adapt_history)
      rows.insert(rows.end(), {static_cast<double>(r.round), r.max_d1, r.max_d2, r.rms_d1, r.rms_d2,
                               static_cast<double>(r.targets), static_cast<double>(r.moves), static_cast<double>(r.folds)});
    h5::Dataset history = group.write_dataset("adapt_history", {rows.size() / 8, 8}, rows);
    history.set_attribute("columns", "round,max_d1,max_d2,rms_d1,rms_d2,targets,moves,folds");
    const RoiSummary& roi = conversion.method == Method::Gim ? conversion.gim->stats.roi : conversion.sphere->stats.roi;
    if (!roi.inside.empty()) {
      // The region of interest: which samples lie in it, and per round the figures inside and outside it
      // (row 0: the start grid before enhancement; row r: after round r − 1, row 1 the enhanced grid).
      const auto side = conversion.method == Method::Gim ? std::uint64_t{conversion.gim->image.size}
                                                         : static_cast<std::uint64_t>(conversion.sphere->image.layout().width());
      h5::Dataset mask = group.write_dataset("roi_mask", {side, side}, roi.inside);
      mask.set_attribute("roi", conversion.parameters.value("roi", std::string()));
      std::vector<double> roi_rows;
      const auto add = [&](double round, const RegionFigures& in, const RegionFigures& out) {
        roi_rows.insert(roi_rows.end(), {round, in.max_d1, in.max_d2, in.rms_d1, in.rms_d2, out.max_d1, out.max_d2,
                                         out.rms_d1, out.rms_d2});
      };
      add(-1.0, roi.roi_start, roi.outside_start);
      for (const AdaptRound& r : *adapt_history) add(static_cast<double>(r.round), r.roi, r.outside);
      h5::Dataset roi_history = group.write_dataset("roi_history", {roi_rows.size() / 9, 9}, roi_rows);
      roi_history.set_attribute("columns", "round,roi_max_d1,roi_max_d2,roi_rms_d1,roi_rms_d2,outside_max_d1,"
                                           "outside_max_d2,outside_rms_d1,outside_rms_d2");
    }
  }
  // The root describes the archive, to which later conversions may append: when and by what it was last
  // changed, and parameters true of every item (each item records its own).
  h5::File& root = archive.root();
  root.set_attribute("modified", conversion.created);
  root.set_attribute("modified_by", conversion.command_line);
  // A batch archive keeps its job's identity: `batch --resume` reads it to know the job finished.
  if (!root.exists("batch")) root.set_attribute("creation_parameters", kConvertArchiveParameters);
  // An older archive extended by this gimforge now holds items of this layout (local frames).
  root.set_attribute("format_version", io::kArchiveFormatVersion);
}

void write_frame_origin(h5::Group& group, const Vec3& origin) {
  const std::array<double, 3> o{origin.x(), origin.y(), origin.z()};
  group.set_attribute("frame_origin", std::span<const double>(o));
}

void write_item_facts(h5::Group& group, const Conversion& conversion) {
  write_frame_origin(group, conversion.origin);
  group.set_attribute("gimforge_version", kVersion);
  group.set_attribute("command_line", conversion.command_line);
  group.set_attribute("created", conversion.created);
  group.set_attribute("creation_parameters", conversion.parameters.dump());
}

Vec3 item_origin(const h5::Group& group, std::string_view where) {
  if (!group.has_attribute("frame_origin")) return Vec3::Zero();
  std::vector<double> o;
  try {
    o = group.attribute<std::vector<double>>("frame_origin");
  } catch (const FormatError&) {
    o.clear();  // another type: reported below
  }
  // Beyond ±1e12 double resolves a coordinate only to 10⁻⁴ and worse; no georeferenced input lies there, and
  // gimforge writes no such origin (begin_conversion).
  if (o.size() != 3 || !std::all_of(o.begin(), o.end(), [](double x) { return std::abs(x) <= kMaxFrameOrigin; }))
    throw FormatError(fmt::format("{}: attribute frame_origin is not 3 finite numbers within ±1e12", where));
  return {o[0], o[1], o[2]};
}

Vec3 item_origin(const io::Archive& archive, Method kind, const std::string& name) {
  const io::RepresentationKind& r = representation(kind);
  const h5::Group group = io::open_representation(archive, r, name);
  return item_origin(group, fmt::format("{}:/{}/{}", archive.path().string(), r.group, name));
}

io::PlyWriteOptions ply_options_for(const TriMesh& mesh) {
  io::PlyWriteOptions o;
  o.double_precision = io::float32_relative_spacing(mesh) > io::kFloat32Tolerance;
  return o;
}

void set_command_line(int argc, const char* const* argv) {
  std::string text;
  for (int i = 0; i < argc; ++i) {
    if (i > 0) text.push_back(' ');
    text.append(shell_quoted(argv[i] != nullptr ? argv[i] : ""));
  }
  set_command_line(std::move(text));
}

void set_command_line(std::string text) {
  const std::lock_guard lock(command_line_mutex);
  process_command_line = std::move(text);
}

std::string command_line() {
  const std::lock_guard lock(command_line_mutex);
  return process_command_line;
}

BatchItem batch_item(const Conversion& conversion) {
  BatchItem item;
  io::ItemArrays& out = item.arrays;
  out.metrics = conversion.numbers;
  out.metrics["input_faces"] = static_cast<double>(conversion.input_faces);
  switch (conversion.method) {
    case Method::Gim: {
      const GeometryImage& image = conversion.gim.value().image;
      out.channels = 3;
      out.height = out.width = image.size;
      out.data = channel_first(image.positions, std::size_t{image.size} * image.size);
      const std::size_t pixels = std::size_t{image.size} * image.size;
      // Adaptive sampling: the parameter points, channel-first (2, H, W).
      if (!image.sample_uv.empty()) out.sample_uv = channel_first(image.sample_uv, pixels, 2);
      out.sideband = io::sideband_table(image.sideband);  // the cut's gluing: reconstruct reads the item back
      out.units_per_side = image.sideband.units_per_side;
      break;
    }
    case Method::Sphere: {
      const SphereResult& r = conversion.sphere.value();
      const DomainImage layout = r.image.layout();
      out.channels = 3;
      out.height = static_cast<std::uint32_t>(layout.faces() * layout.height());
      out.width = static_cast<std::uint32_t>(layout.width());
      out.data = channel_first(r.image.positions, layout.num_samples());
      if (r.stats.masked_samples > 0) out.mask = r.image.mask;
      if (!r.image.sample_uv.empty()) out.sample_uv = channel_first(r.image.sample_uv, layout.num_samples(), 2);
      break;
    }
    case Method::Relief: {
      // Relief maps differ in size from item to item (grey cells, layers): each item keeps its own group.
      const ReliefMap* map = &conversion.relief.value();
      const io::RepresentationRecord record{conversion.source, conversion.numbers};
      io::check_relief_map("batch item", *map, record);
      item.representation = [map, record, &conversion](h5::Group& group) {
        io::write_relief_map(group, *map, record);
        write_item_facts(group, conversion);
      };
      break;
    }
    case Method::Mcgim: {
      const McgimResult* r = &conversion.mcgim.value();
      const io::RepresentationRecord record{conversion.source, conversion.numbers};
      item.representation = [r, record, &conversion](h5::Group& group) {
        io::write_multichart_image(group, r->image, {r->normals, r->stats.chart_efficiency}, record);
        write_item_facts(group, conversion);
      };
      break;
    }
  }
  return item;
}

nlohmann::json creation_parameters(const ConversionRequest& request) {
  nlohmann::json j = request.method.to_json();
  j["metric"] = request.fidelity.enabled;
  j["metric_samples"] = request.fidelity.samples;
  return j;
}

}  // namespace gimforge::jobs
