#include "kernels/mcgim/mcgim_convert.h"

#include <algorithm>
#include <optional>
#include <array>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <tuple>

#include <fmt/format.h>

#include "kernels/core/edge_topology.h"
#include "kernels/core/manifold_cut.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "kernels/mcgim/chart_param.h"
#include "kernels/mcgim/chart_raster.h"
#include "kernels/mcgim/chart_smooth.h"

namespace gimforge {
namespace {

/// The first scale step at which every chart, in its best orientation, is no longer than the longest side any
/// allowed rectangle has (sqrt(samples · max_aspect)), less one for safety. Steps below it cannot pack; a
/// sliver chart (a 1 × 10⁻⁷ strip) would otherwise make the packer rasterize shapes of ~10¹⁰ cells there.
int least_fitting_step(const std::vector<std::vector<Vec2>>& uv, int orientations, double initial,
                       const PackOptions& pk) {
  const double longest_side = std::sqrt(static_cast<double>(pk.max_samples) * pk.max_aspect);
  double longest_chart = 0.0;  // the largest over charts of the chart's extent in its best orientation
  for (const std::vector<Vec2>& points : uv) {
    if (points.empty()) continue;
    double best = std::numeric_limits<double>::infinity();
    for (int o = 0; o < orientations; ++o) {
      const double a = 2.0 * std::numbers::pi * o / orientations, c = std::cos(a), sn = std::sin(a);
      Vec2 lo = Vec2::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
      for (const Vec2& p : points) {
        const Vec2 r(c * p.x() - sn * p.y(), sn * p.x() + c * p.y());
        lo = lo.cwiseMin(r);
        hi = hi.cwiseMax(r);
      }
      best = std::min(best, (hi - lo).maxCoeff());
    }
    longest_chart = std::max(longest_chart, best);
  }
  const double too_long = initial * longest_chart / longest_side;
  if (!(too_long > 1.0) || !std::isfinite(too_long)) return 0;
  const double steps = std::log(too_long) / -std::log1p(-pk.scale_step);
  return static_cast<int>(std::clamp(std::ceil(steps) - 1.0, 0.0, static_cast<double>(pk.max_scale_steps) + 1.0));
}


using Clock = std::chrono::steady_clock;
/// Rounds of splitting charts that parametrize badly, the pieces a chart is split into, and the λ of that
/// split (see convert_once).
constexpr int kMaxSplitRounds = 4;
constexpr std::uint32_t kSplitPieces = 4;
constexpr double kSplitLambda = 1000.0;
/// Rounds of enlarging charts whose sampled shape is too small for their cut-nodes (see convert_once).
constexpr int kEnlargeRounds = 3;
/// The largest boundary fold a chart's free map may keep, in samples (see convert_once).
constexpr double kFoldSamples = 1.0;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// Cells of a shape with a 4-neighbour outside it: a lower bound on its discrete boundary loop's length.
std::size_t boundary_cells(const ChartShape& shape) {
  std::size_t n = 0;
  for (std::uint32_t y = 0; y < shape.height; ++y)
    for (std::uint32_t x = 0; x < shape.width; ++x)
      if (shape.at(x, y) && (x == 0 || y == 0 || x + 1 == shape.width || y + 1 == shape.height || !shape.at(x - 1, y) ||
                             !shape.at(x + 1, y) || !shape.at(x, y - 1) || !shape.at(x, y + 1)))
        ++n;
  return n;
}

/// Removes the edge-connected pieces without surface area (a fin whose third corner lies on its edge, cut
/// off a non-manifold edge; a loose sliver): a chart of them has no stretch and no samples, and the relative
/// scaling of the others would be measured against nothing. Returns the faces removed; unused vertices stay.
std::size_t drop_arealess_pieces(TriMesh& mesh) {
  const EdgeTopology topo = build_edge_topology(mesh);
  UnionFind pieces(mesh.faces.size());
  for (std::size_t e = 0; e < topo.num_edges(); ++e)
    if (topo.valence(e) == 2)
      pieces.unite(topo.edge_halfedges[topo.edge_offsets[e]] / 3, topo.edge_halfedges[topo.edge_offsets[e] + 1] / 3);
  std::vector<double> area(mesh.faces.size(), 0.0);
  double total = 0.0;
  for (std::uint32_t f = 0; f < mesh.faces.size(); ++f) {
    const Face& t = mesh.faces[f];
    const double a = 0.5 * (mesh.positions[t[1]] - mesh.positions[t[0]]).cross(mesh.positions[t[2]] - mesh.positions[t[0]]).norm();
    area[pieces.find(f)] += a;
    total += a;
  }
  std::size_t kept = 0;
  for (std::uint32_t f = 0; f < mesh.faces.size(); ++f)
    if (area[pieces.find(f)] > 1e-14 * total) mesh.faces[kept++] = mesh.faces[f];
  const std::size_t dropped = mesh.faces.size() - kept;
  mesh.faces.resize(kept);
  return dropped;
}

void check_input(const TriMesh& mesh, const McgimOptions& options) {
  if (mesh.faces.empty()) throw InvalidInput("multi-chart geometry image: the mesh has no faces");
  if (options.samples < 64) throw InvalidInput(fmt::format("multi-chart geometry image: --samples {} is below 64", options.samples));
}

/// The chartification options at a given chart count.
ChartifyOptions chartify_options(const McgimOptions& options, std::uint32_t charts) {
  ChartifyOptions co = options.chartify;
  co.charts = charts;
  co.progress = options.progress;
  return co;
}

/// One conversion from a chartification made at a given chart count (everything but the optimization).
/// `chartify_seconds`: what the chartification took (it is reported with the boundary smoothing).
McgimResult convert_once(const TriMesh& mesh, const McgimOptions& options, std::uint32_t charts,
                         const Chartification& chartification, double chartify_seconds) {
  McgimResult r;
  McgimStats& s = r.stats;
  auto t0 = Clock::now();
  const ChartifyOptions co = chartify_options(options, charts);
  ChartParamOptions po;
  po.stretch = options.stretch;
  po.progress = options.progress;
  // A free boundary may cross itself in a loop narrower than a sample (parameter area equals surface area
  // before the packing, so a sample is about sqrt(area / samples) wide): a scan's jagged hole rim, folded
  // back over a few sliver faces. Holding the boundary and splitting such a chart cascaded the dragon (871K
  // faces, 407 holes) into 2102 charts at 0.33 stretch efficiency and 60.4 dB; keeping the folds, 620
  // charts at 0.84 and 70.3 dB in half the time (BENCHMARKS.md).
  po.fold_tolerance = kFoldSamples * std::sqrt(surface_area(mesh) / static_cast<double>(options.samples));
  // A chart that cannot be flattened one-to-one with a free boundary, or only with heavy stretch (a band the
  // clustering wrapped around a limb, which the disk rule kept from closing), is split into pieces by the
  // same clustering run on that chart alone (the pieces are disks again); the other charts keep their maps.
  std::vector<std::uint32_t> face_chart = chartification.face_chart;
  const BoundarySmoothing smoothing = smooth_chart_boundaries(mesh, face_chart);
  s.smoothed_faces = smoothing.teeth + smoothing.fan_faces;
  std::uint32_t num_charts = chartification.num_charts;
  std::vector<ChartMesh> chart_meshes = extract_charts(mesh, face_chart, num_charts);
  s.seconds_chartify = chartify_seconds + seconds_since(t0);
  t0 = Clock::now();
  ChartParametrization param = parametrize_charts(chart_meshes, po);
  s.boundary_folds = param.small_folds;
  for (int round = 0; round < kMaxSplitRounds; ++round) {
    std::vector<std::vector<Vec2>> reuse = param.uv;
    bool split_any = false;
    for (std::uint32_t c = 0; c < chart_meshes.size(); ++c) {
      if (!param.split[c] || chart_meshes[c].faces.size() < 2) continue;
      // Pieces of a centroidal geodesic partition (λ large: distance alone), which cuts a band across; the
      // normal-driven cost of the whole mesh tends to leave most of a band in one piece.
      ChartifyOptions sub = co;
      sub.charts = kSplitPieces;
      sub.lambda = kSplitLambda;
      sub.progress = {};
      const Chartification halves = chartify(chart_meshes[c].mesh, sub);
      if (halves.num_charts < 2) continue;
      for (std::size_t f = 0; f < halves.face_chart.size(); ++f) {
        const std::uint32_t k = halves.face_chart[f];
        face_chart[chart_meshes[c].faces[f]] = k == 0 ? c : num_charts + k - 1;
      }
      num_charts += halves.num_charts - 1;
      reuse[c].clear();
      reuse.resize(num_charts);
      ++s.split_charts;
      split_any = true;
    }
    if (!split_any) break;
    chart_meshes = extract_charts(mesh, face_chart, num_charts);
    param = parametrize_charts(chart_meshes, po, &reuse);
    s.boundary_folds += param.small_folds;
  }
  s.seconds_parametrize = seconds_since(t0);
  s.charts = num_charts;
  s.chartify_iterations = chartification.iterations;
  s.chartify_converged = chartification.converged;
  s.chartify_cycle = chartification.cycle;
  s.extra_seeds = chartification.extra_seeds;
  // A chart too small to get a boundary sample per cut-node at the atlas's scale (a scan's fragment, a pocket
  // the disk rule left) is scaled up until its parameter perimeter at 80 % of the initial scale (packings
  // end near 0.65 efficiency, i.e. ~0.8 of it) spans 2·cut-nodes + 6 samples.
  const double initial = std::sqrt(static_cast<double>(options.samples) / param.total.domain_area);
  const ChartLoops loops = chart_loops(mesh, build_edge_topology(mesh), face_chart, chart_meshes);
  for (std::size_t c = 0; c < chart_meshes.size(); ++c) {
    const std::vector<std::uint32_t>& b = chart_meshes[c].boundary;
    double perimeter = 0.0;
    for (std::size_t i = 0; i < b.size(); ++i) perimeter += (param.uv[c][b[(i + 1) % b.size()]] - param.uv[c][b[i]]).norm();
    const double need = 2.0 * static_cast<double>(loops.cut_nodes[c]) + 6.0, have = perimeter * 0.8 * initial;
    if (perimeter > 0.0 && have < need) {
      enlarge_chart(param, chart_meshes[c], c, need / have);
      ++s.enlarged_charts;
    }
  }
  s.optimizer_fallbacks = param.optimizer_fallbacks;
  for (const MeshStretch& cs : param.stretch) s.chart_efficiency.push_back(cs.efficiency);

  // Pack and sample. A chart whose sampled shape has fewer than 2·cut-nodes + 2 boundary cells (the zipper
  // needs a distinct boundary sample per cut-node; thin fragments get fewer than the estimate above) is
  // enlarged by the missing ratio and the charts are packed again, at most kEnlargeRounds times. Each round's
  // step search starts at the last round's answer; the packer's order restarts run once, on the final charts.
  const int orientations = std::max(1, options.pack.orientations);
  const auto angle = [&](int o) { return 2.0 * std::numbers::pi * o / orientations; };
  Packing packing;
  std::vector<Vec3> positions;
  std::vector<std::uint8_t> mask;
  std::vector<std::uint32_t> chart;
  std::vector<std::vector<Vec2>> vertex_image;
  // Packs at the parameter area after the enlargements (a scan's thousands of enlarged fragments made the
  // search start 131 steps too high when the scale came from the area before them).
  const auto pack = [&](int first_step, const std::function<bool(const Packing&)>& restart_if) {
    const auto start = Clock::now();
    PackOptions pk = options.pack;
    pk.max_samples = options.samples;
    pk.progress = options.progress;
    pk.first_step = first_step;
    pk.restart_if = restart_if;
    const double at_area = std::sqrt(static_cast<double>(options.samples) / param.total.domain_area);
    pk.min_step = least_fitting_step(param.uv, orientations, at_area, pk);
    Packing out;
    try {
      out = pack_charts(
          chart_meshes.size(), at_area,
          [&](std::size_t c, int o, double scale) { return rasterize_chart(chart_meshes[c], param.uv[c], angle(o), scale).shape; },
          pk);
    } catch (const ChartsDoNotFit& e) {  // too many charts (a mesh of many pieces) for the budget
      throw NumericalError(fmt::format("{} charts cannot be packed into {} samples ({}); a larger --samples helps",
                                       chart_meshes.size(), options.samples, e.what()));
    }
    s.seconds_pack += seconds_since(start);
    return out;
  };
  // Samples every chart where `packing` placed it; returns the charts too small for their cut-nodes, each with
  // the enlargement it needs.
  const auto sample = [&] {
    const auto start = Clock::now();
    s.scale = packing.scale;
    s.scale_steps = packing.scale_steps - packing.refined_steps;
    const std::uint32_t w = packing.width, h = packing.height;
    positions.assign(std::size_t{w} * h, Vec3::Zero());
    mask.assign(positions.size(), 0);
    chart.assign(positions.size(), kNoChart);
    vertex_image.assign(chart_meshes.size(), {});
    s.interior_samples = s.boundary_samples = s.dilated_samples = 0;
    std::vector<std::pair<std::size_t, double>> small;  // chart, enlargement
    for (std::size_t c = 0; c < chart_meshes.size(); ++c) {
      const Placement& p = packing.placements[c];
      const ChartRaster raster = rasterize_chart(chart_meshes[c], param.uv[c], angle(p.orientation), packing.scale);
      const double need = 2.0 * static_cast<double>(loops.cut_nodes[c]) + 2.0;
      if (const auto have = static_cast<double>(boundary_cells(raster.shape)); have < need)
        small.emplace_back(c, std::max(1.25, need / std::max(have, 1.0)));
      vertex_image[c] = raster.vertex_cells;
      for (Vec2& v : vertex_image[c]) v += Vec2(p.x, p.y);
      s.interior_samples += raster.interior;
      s.boundary_samples += raster.boundary;
      s.dilated_samples += raster.dilated;
      for (std::uint32_t y = 0; y < raster.shape.height; ++y)
        for (std::uint32_t x = 0; x < raster.shape.width; ++x) {
          if (!raster.shape.at(x, y)) continue;
          const std::size_t at = std::size_t{p.y + y} * w + (p.x + x);
          if (p.x + x >= w || p.y + y >= h || mask[at])
            throw NumericalError(fmt::format("chart {}: its placement leaves the rectangle or overlaps another chart", c));
          mask[at] = 1;
          chart[at] = static_cast<std::uint32_t>(c);
          positions[at] = raster.positions[std::size_t{y} * raster.shape.width + x];
        }
    }
    s.seconds_sample += seconds_since(start);
    return small;
  };
  for (int round = 0;; ++round) {
    // The packer's order restarts run only when these charts are final: none too small, or the last round.
    Packing plain;
    std::vector<std::pair<std::size_t, double>> small;  // of the plain packing
    const auto final_charts = [&](const Packing& p) {
      const auto t = Clock::now();
      packing = plain = p;
      small = sample();
      s.seconds_pack -= seconds_since(t);  // sampling time, not packing time
      return small.empty() || round == kEnlargeRounds;
    };
    packing = pack(round == 0 ? 0 : packing.scale_steps, final_charts);
    if (packing.scale != plain.scale && sample().size() > small.size()) {
      packing = std::move(plain);  // a restart's larger scale lost a chart a boundary cell: keep the plain one
      sample();
    }
    if (small.empty() || round == kEnlargeRounds) break;
    for (const auto& [c, factor] : small) enlarge_chart(param, chart_meshes[c], c, factor);
    s.enlarged_charts += static_cast<std::uint32_t>(small.size());
  }
  s.stretch = param.total;
  report_progress(options.progress, "sample", 1.0);
  const std::uint32_t w = packing.width, h = packing.height;

  t0 = Clock::now();
  MultiChartImage& image = r.image;
  s.zipper = zipper_charts(mesh, loops, chart_meshes, vertex_image, w, h, positions, mask, chart, image.unified);
  s.seconds_zipper = seconds_since(t0);
  report_progress(options.progress, "zipper", 1.0);

  image.width = w;
  image.height = h;
  image.mask = std::move(mask);
  image.chart = std::move(chart);
  image.positions.assign(3 * positions.size(), std::numeric_limits<float>::quiet_NaN());
  for (std::size_t i = 0; i < positions.size(); ++i)
    if (image.mask[i])
      for (int k = 0; k < 3; ++k) image.positions[3 * i + static_cast<std::size_t>(k)] = static_cast<float>(positions[i][k]);
  // The float image must keep the zipper exact: every sample of a cluster at its representative's value.
  for (std::size_t i = 0; i < positions.size(); ++i)
    if (image.mask[i])
      for (int k = 0; k < 3; ++k)
        image.positions[3 * i + static_cast<std::size_t>(k)] = image.positions[3 * std::size_t{image.unified[i]} + static_cast<std::size_t>(k)];
  s.defined_samples = image.defined_samples();
  s.unique_vertices = image.unique_vertices();
  s.packing_efficiency = static_cast<double>(s.defined_samples) / static_cast<double>(image.samples());
  // Charts thinner than a sample (a sliver, a ribbon narrower than the sampling step) sample to collinear
  // points: an image without area, which the fidelity report could only fail on ("no area to sample").
  if (const TriMesh surface = reconstruct_multichart(image); !(surface_area(surface) > 0.0))
    throw NumericalError(fmt::format("the image has no surface area: {} thinner than the sampling step of its "
                                     "{} x {} samples (--samples {}); a larger --samples or fewer --charts helps",
                                     num_charts == 1 ? "its chart is" : fmt::format("its {} charts are", num_charts), w,
                                     h, options.samples));
  return r;
}

}  // namespace

SurfaceFitResult optimize_multichart_image(const EmbreeDevice& device, const FitReference& reference, MultiChartImage& image,
                                           const SurfaceFitOptions& options) {
  std::vector<std::uint32_t> vertex_sample;
  const TriMesh start = reconstruct_multichart(image, &vertex_sample);
  std::vector<std::uint32_t> vertex_of_sample(image.samples(), kNoSample);
  for (std::uint32_t v = 0; v < vertex_sample.size(); ++v) vertex_of_sample[vertex_sample[v]] = v;
  // Representatives no face uses now (isolated degenerate clusters) get a vertex too: a moved diagonal may
  // use them.
  std::vector<Vec3> positions = start.positions;
  for (std::size_t sample = 0; sample < image.samples(); ++sample)
    if (image.mask[sample] && image.unified[sample] == sample && vertex_of_sample[sample] == kNoSample) {
      vertex_of_sample[sample] = static_cast<std::uint32_t>(positions.size());
      vertex_sample.push_back(static_cast<std::uint32_t>(sample));
      positions.emplace_back(image.positions[3 * sample], image.positions[3 * sample + 1], image.positions[3 * sample + 2]);
    }
  SurfaceFitResult fit = fit_surface(
      device, reference, std::move(positions),
      [&](std::span<const Vec3> p) { return triangulate_multichart(image, vertex_of_sample, p); }, {}, options);
  for (std::size_t sample = 0; sample < image.samples(); ++sample) {
    if (!image.mask[sample]) continue;
    const Vec3& p = fit.positions[vertex_of_sample[image.unified[sample]]];
    for (int k = 0; k < 3; ++k) image.positions[3 * sample + static_cast<std::size_t>(k)] = static_cast<float>(p[k]);
  }
  return fit;
}

bool auto_count_replaces(double best_rms, double candidate_rms) {
  // The estimate from 5·10⁴ samples each way varies by about 0.6 % (one σ) with the samples drawn (camel,
  // six seeds): a later count (more charts) must be closer by more than 1 %.
  constexpr double kAutoMargin = 0.01;
  return candidate_rms < best_rms * (1.0 - kAutoMargin);
}

McgimResult convert_to_multichart(const EmbreeDevice& device, const TriMesh& input, const McgimOptions& options) {
  check_input(input, options);
  // Charts are disks of an oriented 2-manifold: non-manifold edges and faces that cannot agree on an
  // orientation become boundaries, the other faces agree with their neighbours, and pinched vertices
  // become one vertex per fan (manifold_cut.h). The surface, and the distances to it, stay the input's.
  ManifoldCut cut = cut_to_manifold(input);
  const std::size_t arealess = drop_arealess_pieces(cut.mesh);
  if (cut.mesh.faces.empty()) throw InvalidInput("multi-chart geometry image: the mesh has no surface area");
  const TriMesh& mesh = cut.mesh;
  McgimResult best;
  const auto chartify_at = [&](std::uint32_t k, double& seconds) {
    const auto t0 = Clock::now();
    Chartification c = chartify(mesh, chartify_options(options, k));
    seconds = seconds_since(t0);
    return c;
  };
  if (options.charts > 0) {
    double seconds = 0.0;
    const Chartification c = chartify_at(options.charts, seconds);
    best = convert_once(mesh, options, options.charts, c, seconds);
  } else {
    if (options.auto_charts.empty()) throw InvalidInput("multi-chart geometry image: no chart counts to try");
    double best_rms = std::numeric_limits<double>::infinity();
    std::uint32_t kept = 0;
    std::vector<std::uint32_t> tried, attempted;  // converted (or the same charts as a converted count); all
    std::vector<double> rms;
    std::string failures;
    // A count whose chartification equals an earlier one's converts to the same image (a scan of many
    // components and holes may need more charts than either count asks for), or fails as it did: it is not
    // converted again.
    struct Seen {
      std::vector<std::uint32_t> charts;
      std::optional<double> rms;  ///< none: it failed
      std::uint32_t count;
    };
    std::vector<Seen> seen;
    std::vector<std::uint32_t> same_as;
    for (std::size_t i = 0; i < options.auto_charts.size(); ++i) {
      const std::uint32_t k = std::min<std::uint32_t>(options.auto_charts[i], static_cast<std::uint32_t>(mesh.faces.size()));
      // A small mesh: counts clamp to its faces, and a count is converted once.
      if (std::find(attempted.begin(), attempted.end(), k) != attempted.end()) continue;
      attempted.push_back(k);
      const auto progress = [&] {
        report_progress(options.progress, "charts auto", static_cast<double>(i + 1) / static_cast<double>(options.auto_charts.size()));
      };
      double seconds = 0.0;
      Chartification c = chartify_at(k, seconds);
      const auto same = std::find_if(seen.begin(), seen.end(), [&](const Seen& e) { return e.charts == c.face_chart; });
      if (same != seen.end() && same->rms) {
        tried.push_back(k);
        rms.push_back(*same->rms);
        same_as.push_back(same->count);
      } else if (same != seen.end()) {
        failures += fmt::format("; {} charts: the same charts as {}", k, same->count);
      }
      if (same != seen.end()) {
        progress();
        continue;
      }
      McgimResult r;
      try {
        r = convert_once(mesh, options, k, c, seconds);
      } catch (const NumericalError& e) {
        failures += fmt::format("{}{} charts: {}", failures.empty() ? "" : "; ", k, e.what());
        seen.push_back({std::move(c.face_chart), std::nullopt, k});
        continue;
      }
      HausdorffOptions h;
      h.samples = options.auto_metric_samples;
      const double d = symmetric_hausdorff(device, mesh, reconstruct_multichart(r.image), h).rms;
      tried.push_back(k);
      rms.push_back(d);
      same_as.push_back(0);
      seen.push_back({std::move(c.face_chart), d, k});
      progress();
      if (tried.size() == 1 || auto_count_replaces(best_rms, d)) best_rms = d, best = std::move(r), kept = k;
    }
    if (tried.empty()) throw NumericalError(fmt::format("no chart count gave a multi-chart geometry image ({})", failures));
    best.stats.auto_tried = std::move(tried);
    best.stats.auto_rms = std::move(rms);
    best.stats.auto_same_as = std::move(same_as);
    best.stats.auto_kept = kept;
  }
  if (options.optimize) {
    const auto t0 = Clock::now();
    SurfaceFitOptions fo = options.fit;
    fo.progress = options.progress;
    const SurfaceFitResult fit = optimize_multichart_image(device, mesh, best.image, fo);
    best.stats.fit_energy_before = fit.energy_before;
    best.stats.fit_energy_after = fit.energy_after;
    best.stats.seconds_optimize = seconds_since(t0);
  }
  best.normals = multichart_normals(best.image);
  best.stats.cut_nonmanifold_edges = cut.nonmanifold_edges;
  best.stats.cut_orientation_edges = cut.orientation_cuts;
  best.stats.flipped_faces = cut.flipped_faces;
  best.stats.split_vertices = cut.split_vertices;
  best.stats.arealess_faces = arealess;
  return best;
}

}  // namespace gimforge
