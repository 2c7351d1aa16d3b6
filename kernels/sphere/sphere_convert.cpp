#include "kernels/sphere/sphere_convert.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "kernels/sphere/domain_map.h"
#include "kernels/core/edge_topology.h"
#include "kernels/core/errors.h"
#include "kernels/sphere/sphere_adapt.h"
#include "kernels/sphere/sphere_resample.h"

namespace gimforge {
namespace {

constexpr std::uint32_t kMaxN = 4096;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void check_n(std::uint32_t n) {
  if (n < 1 || n > kMaxN) throw InvalidInput(fmt::format("spherical geometry image: n = {} is outside 1..{}", n, kMaxN));
}

/// I → D → S → M for every stored sample of the image: the domain map gives the direction, the locator
/// the face of the (hole-filled) mesh and the barycentric coordinates that interpolate it.
/// `holes_without_samples`: set to the filled holes that no sample fell into (each hole's fan has its own
/// centre vertex, appended after the input's in the order of the holes: fill_holes).
SphericalImage sample_image(const EmbreeDevice& device, const FilledMesh& filled, std::span<const Vec3> sphere,
                            SphericalDomain domain, std::uint32_t n, const ProgressCallback& progress,
                            std::size_t& holes_without_samples) {
  const std::size_t first_centre = filled.mesh.positions.size() - filled.holes;
  std::vector<std::atomic<bool>> hole_sampled(filled.holes);
  const DomainImage layout(domain, n);
  const std::vector<Vec3> directions = sample_domain_map(builtin_domain_map(domain), layout);
  const SphericalLocator locator(device, filled.mesh, sphere);
  SphericalImage image;
  image.domain = domain;
  image.n = n;
  const std::size_t count = layout.num_samples();
  image.positions.assign(3 * count, std::numeric_limits<float>::quiet_NaN());
  image.mask.assign(count, 0);
  const bool colored = filled.mesh.has_colors();
  if (colored) image.colors.assign(3 * count, 0.0f);
  report_progress(progress, "sample", 0.0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t k = r.begin(); k != r.end(); ++k) {
      const SphericalLocator::Location loc = locator.locate(directions[k]);
      const Face& f = filled.mesh.faces[loc.face];
      if (filled.hole_face[loc.face]) {
        if (f[2] >= first_centre && f[2] - first_centre < hole_sampled.size())
          hole_sampled[f[2] - first_centre].store(true, std::memory_order_relaxed);
        continue;
      }
      const Vec3 p = loc.barycentric[0] * filled.mesh.positions[f[0]] + loc.barycentric[1] * filled.mesh.positions[f[1]] +
                     loc.barycentric[2] * filled.mesh.positions[f[2]];
      for (int c = 0; c < 3; ++c) image.positions[3 * k + static_cast<std::size_t>(c)] = static_cast<float>(p[c]);
      image.mask[k] = 1;
      if (colored) {
        const Vec3f col = static_cast<float>(loc.barycentric[0]) * filled.mesh.colors[f[0]] +
                                    static_cast<float>(loc.barycentric[1]) * filled.mesh.colors[f[1]] +
                                    static_cast<float>(loc.barycentric[2]) * filled.mesh.colors[f[2]];
        for (int c = 0; c < 3; ++c) image.colors[3 * k + static_cast<std::size_t>(c)] = col[c];
      }
    }
  });
  report_progress(progress, "sample", 1.0);
  holes_without_samples = static_cast<std::size_t>(
      std::count_if(hole_sampled.begin(), hole_sampled.end(), [](const std::atomic<bool>& s) { return !s.load(); }));
  return image;
}

/// `x` as both ways to a sphere map use it: normalized unless it is unit to within 1e-15. Normalizing a unit
/// vector again may change its last bits, and a --sphere-map run must convert with exactly the map of the run
/// that stored it (a flat-octa adaptive image drifted 0.26 dB apart from those last bits over its rounds).
Vec3 canonical_unit(Vec3 x) {
  if (std::abs(x.squaredNorm() - 1.0) > 1e-15) x.normalize();
  return x;
}

std::vector<Vec3> to_vec3(std::span<const float> xyz) {
  std::vector<Vec3> out(xyz.size() / 3);
  for (std::size_t k = 0; k < out.size(); ++k)
    out[k] = Vec3(static_cast<double>(xyz[3 * k]), static_cast<double>(xyz[3 * k + 1]),
                  static_cast<double>(xyz[3 * k + 2]));
  return out;
}

/// Checks a given sphere map against the hole-filled mesh (size, unit vectors, embedding); returns it
/// normalized. Throws InvalidInput or NumericalError.
std::vector<Vec3> checked_sphere_map(const FilledMesh& filled, std::span<const Vec3> sphere);

/// Refuses adaptive sampling where it is not built, before any work.
void check_adaptive(const SphereOptions& options, const FilledMesh& filled) {
  if (!options.adaptive && options.roi.kind != RoiSource::Kind::None)
    throw InvalidInput("a region of interest needs adaptive sampling");
  if (!options.adaptive) return;
  if (options.domain != SphericalDomain::FlatOctahedron)
    throw InvalidInput(fmt::format("adaptive sampling of a spherical image is built for the flat-octa domain (its image is "
                                   "a square folded at its side midpoints; this is {})",
                                   to_string(options.domain)));
  if (options.n < 2)
    throw InvalidInput(fmt::format("adaptive sampling of a spherical image needs n >= 2 (n = {}: the image has no "
                                   "sample to move)",
                                   options.n));
  if (filled.holes != 0)
    throw InvalidInput(fmt::format("adaptive sampling of a spherical image needs a closed mesh; this one has {} "
                                   "hole(s), filled for the sphere map (use --method gim, or uniform sampling)",
                                   filled.holes));
  if (options.roi.kind == RoiSource::Kind::Vertices && options.roi.vertices.size() != filled.mesh.num_vertices())
    throw InvalidInput(fmt::format("region of interest: {} vertex flags for {} vertices", options.roi.vertices.size(),
                                   filled.mesh.num_vertices()));
}

/// Moves the samples of result.image (sphere_adapt.h).
void adapt_into(const EmbreeDevice& device, const FilledMesh& filled, const SphereOptions& options, SphereResult& result) {
  const auto t0 = std::chrono::steady_clock::now();
  AdaptOptions adapt = options.adapt;
  adapt.progress = options.progress;
  SphericalImage& image = result.image;
  SphereAdaptResult r =
      adapt_flat_octahedron(device, filled.mesh, result.sphere, options.n, options.adapt_start, adapt, options.roi);
  for (std::size_t k = 0; k < r.positions.size(); ++k)
    for (std::size_t c = 0; c < 3; ++c) image.positions[3 * k + c] = static_cast<float>(r.positions[k][static_cast<Eigen::Index>(c)]);
  if (!image.colors.empty() && !r.colors.empty())
    for (std::size_t k = 0; k < r.colors.size(); ++k)
      for (std::size_t c = 0; c < 3; ++c) image.colors[3 * k + c] = r.colors[k][static_cast<Eigen::Index>(c)];
  image.sample_uv.resize(2 * r.sample_uv.size());
  for (std::size_t k = 0; k < r.sample_uv.size(); ++k) {
    image.sample_uv[2 * k] = static_cast<float>(r.sample_uv[k].x());
    image.sample_uv[2 * k + 1] = static_cast<float>(r.sample_uv[k].y());
  }
  SphereStats& s = result.stats;
  s.adapt_history = std::move(r.sampling.history);
  s.adapt_started_from_strips = r.sampling.started_from_strips;
  s.adapt_rms_uniform_start = r.sampling.rms_uniform_start;
  s.adapt_rms_strips_start = r.sampling.rms_strips_start;
  s.adapt_disk_faces = r.disk_faces;
  s.adapt_disk_flipped = r.disk_flipped;
  s.roi = std::move(r.roi);
  s.seconds_adapt = seconds_since(t0);
}

/// Samples the image of `result.sphere` and fills the sampling figures of `result.stats`.
void sample_into(const EmbreeDevice& device, const FilledMesh& filled, const SphereOptions& options,
                 SphereResult& result) {
  const auto t0 = std::chrono::steady_clock::now();
  result.image = sample_image(device, filled, result.sphere, options.domain, options.n, options.progress,
                              result.stats.holes_without_samples);
  result.stats.seconds_sample = seconds_since(t0);
  if (options.adaptive) adapt_into(device, filled, options, result);
  for (std::uint8_t m : result.image.mask) result.stats.masked_samples += m ? 0 : 1;
  result.stats.domain_efficiency = domain_map_stretch(builtin_domain_map(options.domain)).efficiency;
  result.stats.efficiency_domain_to_mesh =
      domain_to_surface_efficiency(result.image.layout(), to_vec3(result.image.positions));
}

/// Below this S->M stretch efficiency a sphere map has collapsed: a 10^5 : 1 cylinder's was 1.5e-10, its
/// samples all at one end (10 dB); the shared meshes have 0.24 .. 0.88. Refused before any sampling.
constexpr double kMinMapEfficiency = 1e-4;

void check_not_collapsed(double efficiency) {
  if (!(efficiency >= kMinMapEfficiency))
    throw InvalidInput(fmt::format("spherical parametrization: the map collapsed (S->M stretch efficiency {:.2g}, "
                                   "below {:g}): the shape is too elongated or thin, or its triangles too slivered, "
                                   "for one sphere map (--method mcgim or relief convert it)",
                                   efficiency, kMinMapEfficiency));
}

}  // namespace

SphereResult convert_to_spherical_image(const EmbreeDevice& device, const TriMesh& mesh, const SphereOptions& options) {
  check_n(options.n);
  SphereResult result;
  const FilledMesh filled = fill_holes(mesh);
  check_adaptive(options, filled);
  result.stats.holes_filled = filled.holes;
  result.stats.hole_faces = filled.mesh.faces.size() - mesh.faces.size();

  SphereMapOptions map_options = options.map;
  map_options.progress = options.progress;
  SphereMapResult map = spherical_parametrization(filled.mesh, filled.hole_face, map_options);
  result.stats.seconds_simplify = map.seconds_simplify;
  result.stats.seconds_optimize = map.seconds_optimize;
  result.stats.vertex_splits = map.vertex_splits;
  result.sphere = std::move(map.sphere);
  for (Vec3& x : result.sphere) x = canonical_unit(x);  // as a --sphere-map run will read it back
  result.stats.map_stretch =
      spherical_stretch(MeshView(filled.mesh.positions, mesh.faces), result.sphere, options.map.stretch);
  check_not_collapsed(result.stats.map_stretch.efficiency);
  sample_into(device, filled, options, result);
  return result;
}

SphereResult convert_with_sphere_map(const EmbreeDevice& device, const TriMesh& mesh, std::span<const Vec3> sphere,
                                     const SphereOptions& options) {
  check_n(options.n);
  SphereResult result;
  const FilledMesh filled = fill_holes(mesh);
  check_adaptive(options, filled);
  result.stats.holes_filled = filled.holes;
  result.stats.hole_faces = filled.mesh.faces.size() - mesh.faces.size();
  result.sphere = checked_sphere_map(filled, sphere);
  result.stats.map_stretch =
      spherical_stretch(MeshView(filled.mesh.positions, mesh.faces), result.sphere, options.map.stretch);
  check_not_collapsed(result.stats.map_stretch.efficiency);
  sample_into(device, filled, options, result);
  return result;
}

SphericalImage resample_spherical_image(const EmbreeDevice& device, const TriMesh& mesh, std::span<const Vec3> sphere,
                                        SphericalDomain domain, std::uint32_t n, ProgressCallback progress) {
  check_n(n);
  const FilledMesh filled = fill_holes(mesh);
  std::size_t holes_without_samples = 0;
  return sample_image(device, filled, checked_sphere_map(filled, sphere), domain, n, progress, holes_without_samples);
}

namespace {

std::vector<Vec3> checked_sphere_map(const FilledMesh& filled, std::span<const Vec3> sphere) {
  if (sphere.size() != filled.mesh.positions.size())
    throw InvalidInput(fmt::format("the spherical parametrization has {} vectors; the mesh (with {} filled holes) has "
                                   "{} vertices",
                                   sphere.size(), filled.holes, filled.mesh.positions.size()));
  for (std::size_t v = 0; v < sphere.size(); ++v)
    if (!(std::abs(sphere[v].squaredNorm() - 1.0) < 1e-6))
      throw InvalidInput(fmt::format("the spherical parametrization's vector {} is not a unit vector", v));
  std::vector<Vec3> unit(sphere.begin(), sphere.end());
  for (Vec3& x : unit) x = canonical_unit(x);
  if (const std::size_t flipped = count_flipped_spherical(filled.mesh, unit); flipped != 0)
    throw NumericalError(fmt::format("the spherical parametrization is not an embedding of this mesh ({} flipped "
                                     "triangles)",
                                     flipped));
  return unit;
}

}  // namespace

TriMesh reconstruct_spherical_geometry(const SphericalImage& image, std::uint32_t level) {
  const DomainImage layout = image.layout();
  if (image.positions.size() != 3 * layout.num_samples())
    throw InvalidInput(fmt::format("reconstruct: {} coordinates for a {} image at n = {} ({} samples)",
                                   image.positions.size(), to_string(image.domain), image.n, layout.num_samples()));
  const TriMesh full = reconstruct_spherical_image(layout, to_vec3(image.positions), level);
  // Drop faces that touch undefined samples, then unused vertices.
  TriMesh out;
  std::vector<std::uint32_t> remap(full.positions.size(), kInvalidIndex);
  for (const Face& f : full.faces) {
    if (!full.positions[f[0]].allFinite() || !full.positions[f[1]].allFinite() || !full.positions[f[2]].allFinite())
      continue;
    Face g;
    for (std::size_t c = 0; c < 3; ++c) {
      std::uint32_t& r = remap[f[c]];
      if (r == kInvalidIndex) {
        r = static_cast<std::uint32_t>(out.positions.size());
        out.positions.push_back(full.positions[f[c]]);
      }
      g[c] = r;
    }
    out.faces.push_back(g);
  }
  return out;
}


SurfaceFitResult optimize_spherical_image(const EmbreeDevice& device, const FitReference& reference, SphericalImage& image,
                                          const SurfaceFitOptions& options) {
  const DomainImage layout = image.layout();
  const std::size_t samples = layout.num_samples();
  if (image.positions.size() != 3 * samples || image.mask.size() != samples)
    throw InvalidInput(fmt::format("optimize: {} coordinates and {} mask entries for a {} image at n = {} ({} samples)",
                                   image.positions.size(), image.mask.size(), to_string(image.domain), image.n, samples));
  // One vertex per domain point (ids in order of first appearance, as the level-0 reconstruction numbers
  // its vertices), at the mean of its samples; undefined where any of its samples is.
  const std::vector<std::uint32_t> ids = layout.vertex_ids();
  const std::size_t points = layout.num_domain_points();
  std::vector<Vec3> positions(points, Vec3::Zero());
  std::vector<int> count(points, 0);
  std::vector<char> undefined(points, 0);
  for (std::size_t k = 0; k < samples; ++k) {
    const Vec3 p(image.positions[3 * k], image.positions[3 * k + 1], image.positions[3 * k + 2]);
    if (!image.mask[k] || !p.allFinite()) {
      undefined[ids[k]] = 1;
      continue;
    }
    positions[ids[k]] += p;
    ++count[ids[k]];
  }
  for (std::size_t v = 0; v < points; ++v) {
    if (count[v] > 0 && !undefined[v]) positions[v] /= static_cast<double>(count[v]);
    else undefined[v] = 1, positions[v] = Vec3::Zero();  // held, and in no face
  }
  std::vector<Vec3> per_sample(samples);
  const auto triangulate = [&](std::span<const Vec3> p) {
    for (std::size_t k = 0; k < samples; ++k) per_sample[k] = p[ids[k]];
    TriMesh mesh = reconstruct_spherical_image(layout, per_sample);
    std::erase_if(mesh.faces, [&](const Face& f) { return undefined[f[0]] || undefined[f[1]] || undefined[f[2]]; });
    return std::move(mesh.faces);
  };
  SurfaceFitResult fit = fit_surface(device, reference, std::move(positions), triangulate, undefined, options);
  for (std::size_t k = 0; k < samples; ++k) {
    if (undefined[ids[k]]) continue;
    for (std::size_t c = 0; c < 3; ++c) image.positions[3 * k + c] = static_cast<float>(fit.positions[ids[k]][static_cast<Eigen::Index>(c)]);
  }
  return fit;
}

}  // namespace gimforge
