#include "kernels/gim/gim_convert.h"

#include <chrono>
#include <cmath>
#include <tuple>

#include <fmt/format.h>

#include "kernels/adaptive/local_hausdorff.h"
#include "kernels/adaptive/roi.h"
#include "kernels/gim/cut.h"
#include "kernels/core/edge_topology.h"
#include "kernels/core/errors.h"
#include "kernels/param/floater.h"
#include "kernels/gim/square_boundary.h"
#include "kernels/core/topology.h"

namespace gimforge {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

/// A cut with its square parametrization. `valid` is false when no bijective parametrization could be
/// computed in floating point (a very short cut squeezes whole limbs into slivers): such a cut counts as
/// infinitely stretched, so augmentation keeps extending it.
struct Parametrized {
  bool valid{false};
  bool optimizer_failed{false};
  Cut cut;
  CutMesh cut_mesh;
  SquareBoundary boundary;
  std::vector<Vec2> uv;
  MeshStretch floater;
  MeshStretch stretch;
};

void require_single_surface(const TriMesh& mesh) {
  const TopologyReport t = analyze_topology(mesh);
  if (t.components.size() != 1)
    throw TopologyError(fmt::format("the mesh has {} connected components; a geometry image needs one connected "
                                    "surface (use the multi-chart method for several components)",
                                    t.components.size()));
  if (!t.manifold)
    throw TopologyError(fmt::format("the mesh is not a 2-manifold ({} non-manifold edges, {} non-manifold vertices)",
                                    t.nonmanifold_edges, t.nonmanifold_vertices));
  if (!t.orientable) throw TopologyError("the mesh is not orientable");
  if (!t.oriented)
    throw TopologyError(fmt::format("the faces are not consistently oriented ({} edges)", t.inconsistent_edges));
}

/// A bijective start for the stretch optimizer: Floater's shape-preserving map, or, where rounding left a
/// sliver flipped, mean-value and then uniform (Tutte) weights, which are also bijective onto the square.
std::vector<Vec2> embedding_start(const SquareBoundary& b) {
  using W = FloaterOptions::Weights;
  std::size_t flipped = 0;
  for (W weights : {W::ShapePreserving, W::MeanValue, W::Uniform}) {
    std::vector<Vec2> uv = floater_parametrization(b.disk, b.boundary, b.boundary_uv, {weights});
    flipped = mesh_stretch(b.disk, uv).flipped;
    if (flipped == 0) return uv;
  }
  throw NumericalError(fmt::format("no bijective start parametrization: {} triangles stay flipped even with uniform "
                                   "weights",
                                   flipped));
}

Parametrized parametrize(const TriMesh& mesh, Cut cut, const GimOptions& options) {
  Parametrized p;
  p.cut = std::move(cut);
  p.cut_mesh = open_cut(mesh, p.cut);
  if (mesh.has_colors()) {
    p.cut_mesh.disk.colors.resize(p.cut_mesh.disk.positions.size());
    for (std::size_t v = 0; v < p.cut_mesh.original_vertex.size(); ++v)
      p.cut_mesh.disk.colors[v] = mesh.colors[p.cut_mesh.original_vertex[v]];
  }
  p.boundary = map_boundary_to_square(p.cut_mesh, {options.units_per_side});
  std::vector<Vec2> start;
  try {
    start = embedding_start(p.boundary);
  } catch (const NumericalError&) {
    return p;  // invalid: see Parametrized
  }
  std::vector<char> fixed(p.boundary.disk.positions.size(), 0);
  for (std::uint32_t v : p.boundary.boundary) fixed[v] = 1;
  try {
    StretchOptimizerResult r = optimize_stretch(p.boundary.disk, start, fixed, options.stretch);
    p.uv = std::move(r.uv);
    p.floater = r.initial;
    p.stretch = r.final;
  } catch (const NumericalError&) {
    // The optimizer could not re-insert a vertex bijectively: keep the (bijective) start map.
    p.floater = p.stretch = mesh_stretch(p.boundary.disk, start);
    p.uv = start;
    p.optimizer_failed = true;
  }
  p.valid = true;
  return p;
}

/// The ROI of options.roi in the parameter square of `boundary` (a vertex of a split has no vertex of the
/// input: kInvalidIndex, not flagged).
RoiMask roi_mask(const EmbreeDevice& device, const SquareBoundary& boundary, std::span<const Vec2> uv,
                 const GimOptions& options) {
  std::vector<std::uint8_t> face_in;
  if (options.roi.kind == RoiSource::Kind::Vertices) {
    const auto flagged = [&](std::uint32_t v) {
      const std::uint32_t o = boundary.original_vertex[v];
      return o < options.roi.vertices.size() && options.roi.vertices[o] != 0;
    };
    face_in.reserve(boundary.disk.faces.size());
    for (const Face& f : boundary.disk.faces) face_in.push_back(flagged(f[0]) || flagged(f[1]) || flagged(f[2]) ? 1 : 0);
  }
  return resolve_roi_mask(device, boundary.disk, uv, options.image.size, options.roi, face_in);
}

/// Adaptive sampling (kernels/adaptive): the start grid (the regular one, the vertex-density strips of
/// §3.1, or under AdaptStart::Auto whichever of the two is closer to the surface by the symmetric RMS of
/// the local Hausdorff distances), then the Hausdorff-driven adjustment of §3.3.
std::vector<Vec2> adaptive_samples(const EmbreeDevice& device, const SquareBoundary& boundary, std::span<const Vec2> uv,
                                   const GimOptions& options, GimStats& stats) {
  const std::uint32_t n = options.image.size;
  AdaptOptions adapt = options.adapt;
  adapt.progress = options.progress;
  adapt.roi = nullptr;  // set by sample_roi_adaptively alone, to the mask it makes
  const Sideband sideband = Sideband::from_boundary(boundary);
  adapt.measure.glue.mate = [sideband](double c) { return glued_perimeter_coordinate(sideband, c); };
  adapt.measure.glue.node = [sideband](double c) { return is_cut_node(sideband, c); };
  adapt.measure.glue.position = boundary_curve(boundary);
  // The samples' positions on a grid, boundary included (the sideband's mates copy each other).
  const auto positions_at = [&](const std::vector<Vec2>& grid) {
    GeometryImageOptions o = options.image;
    o.sample_uv = grid;
    o.normal_size = 0;
    const GeometryImage image = sample_geometry_image(device, boundary, uv, o);
    std::vector<Vec3> positions(grid.size());
    for (std::size_t p = 0; p < positions.size(); ++p)
      positions[p] = Vec3(image.positions[3 * p], image.positions[3 * p + 1], image.positions[3 * p + 2]);
    return positions;
  };
  if (options.roi.kind != RoiSource::Kind::None) {
    const RoiMask mask = roi_mask(device, boundary, uv, options);
    // Cut-path mates and a cut-node's copies lie on different sides of the square, in mask cells that need
    // not agree: the sideband's classes glue their flags.
    RoiSampling r = sample_roi_adaptively(device, boundary.disk, uv, n, options.adapt_start, positions_at, mask,
                                          options.roi.enhance, adapt, boundary_classes(sideband, n));
    stats.adapt_started_from_strips = r.started_from_strips;
    stats.adapt_history = std::move(r.history);
    stats.roi = std::move(r.summary);
    return std::move(r.sample_uv);
  }
  AdaptiveSampling adapted = sample_adaptively(device, boundary.disk, uv, n, options.adapt_start, positions_at, adapt);
  stats.adapt_started_from_strips = adapted.started_from_strips;
  stats.adapt_rms_uniform_start = adapted.rms_uniform_start;
  stats.adapt_rms_strips_start = adapted.rms_strips_start;
  stats.adapt_history = std::move(adapted.history);
  return std::move(adapted.sample_uv);
}

bool closed_genus_zero(const TriMesh& mesh) {
  const TopologyReport t = analyze_topology(mesh);
  return t.closed && t.euler_characteristic == 2;
}

}  // namespace

GimResult convert_to_geometry_image(const EmbreeDevice& device, const TriMesh& mesh, const GimOptions& options) {
  if (options.image.size < 2 || (options.image.size - 1) % options.units_per_side != 0)
    throw InvalidInput(fmt::format("geometry image size {}: size - 1 must be a multiple of {} (sizes 2^k + 1 >= {})",
                                   options.image.size, options.units_per_side, options.units_per_side + 1));
  require_single_surface(mesh);
  if (options.roi.kind != RoiSource::Kind::None && options.sampling != GimSampling::Adaptive)
    throw InvalidInput("a region of interest needs adaptive sampling");
  if (options.roi.kind == RoiSource::Kind::Vertices && options.roi.vertices.size() != mesh.num_vertices())
    throw InvalidInput(fmt::format("region of interest: {} vertex flags for {} vertices", options.roi.vertices.size(),
                                   mesh.num_vertices()));
  GimResult result;
  auto t0 = Clock::now();
  report_progress(options.progress, "cut", 0.0);
  Cut cut = initial_cut(mesh);
  result.stats.seconds_cut = seconds_since(t0);

  t0 = Clock::now();
  report_progress(options.progress, "parametrize", 0.0);
  Parametrized best = parametrize(mesh, std::move(cut), options);
  const bool genus_zero = closed_genus_zero(mesh);
  // Iterated cut augmentation. Gu et al. stop at the first extension that makes the stretch worse. A cut
  // whose parametrization failed in floating point (a short cut squeezes whole limbs into slivers) says
  // nothing about its stretch: the search goes on from it (`current`) instead of stopping, and `best`
  // keeps the best valid parametrization. The genus-0 re-seeding is always explored.
  Parametrized current = best;
  int steps = 0;
  // Extends `current` through the extremum of its Floater map over the circle; false if there is none.
  auto extend = [&](bool reseed) {
    const CutMesh& cm = current.cut_mesh;
    const std::vector<Vec2> circle = floater_parametrization(cm.disk, cm.boundary, circle_boundary(cm.disk, cm.boundary));
    const std::uint32_t extremum = extremal_vertex(cm, circle);
    if (extremum == kInvalidIndex) return false;  // every vertex is on the cut already
    current = parametrize(mesh, reseed ? two_edge_cut(mesh, extremum) : extend_cut(mesh, current.cut, extremum), options);
    ++steps;
    return true;
  };
  for (int it = 0; it < options.max_augmentations; ++it) {
    report_progress(options.progress, "augment", static_cast<double>(it) / options.max_augmentations);
    const bool reseed = genus_zero && it == 0;
    if (!extend(reseed)) break;
    const bool worse = best.valid && current.valid && current.stretch.l2 > best.stretch.l2;
    if (worse && !reseed) break;
    if (current.valid && !worse) {
      best = current;
      result.stats.augmentations = steps;
    }
  }
  // Without any valid parametrization yet, keep extending the cut (each step opens a protrusion).
  while (!best.valid && steps < options.max_augmentations + 64 && extend(false)) {
    if (current.valid) {
      best = current;
      result.stats.augmentations = steps;
    }
  }
  if (!best.valid) throw NumericalError("no cut found whose parametrization is bijective in floating point");
  result.stats.seconds_parametrize = seconds_since(t0);

  GeometryImageOptions image_options = options.image;
  if (options.sampling == GimSampling::Adaptive) {
    t0 = Clock::now();
    report_progress(options.progress, "adapt", 0.0);
    image_options.sample_uv = adaptive_samples(device, best.boundary, best.uv, options, result.stats);
    result.stats.seconds_adapt = seconds_since(t0);
  }
  t0 = Clock::now();
  report_progress(options.progress, "sample", 0.0);
  result.image = sample_geometry_image(device, best.boundary, best.uv, image_options);
  result.stats.seconds_sample = seconds_since(t0);
  result.stats.cut_edges = best.cut.edges.size();
  result.stats.cut_paths = best.boundary.paths.size();
  result.stats.corner_splits = best.boundary.corner_splits;
  result.stats.side_splits = best.boundary.side_splits;
  result.stats.floater = best.floater;
  result.stats.stretch = best.stretch;
  result.stats.optimizer_fallback = best.optimizer_failed;
  report_progress(options.progress, "sample", 1.0);
  return result;
}

}  // namespace gimforge
