#include "kernels/relief_map.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>

#include <embree3/rtcore.h>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "kernels/embree_device.h"
#include "kernels/embree_scene.h"
#include "kernels/errors.h"

namespace gimforge {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

constexpr std::uint32_t kMaxGrid = 1024;
constexpr std::uint32_t kMaxTexture = 1024;
constexpr std::uint64_t kMaxTexels = std::uint64_t{1} << 31;

std::int8_t to_snorm8(double x) {
  return static_cast<std::int8_t>(std::lround(std::clamp(x, -1.0, 1.0) * 127.0));
}
std::uint8_t to_unorm8(double x) {
  return static_cast<std::uint8_t>(std::lround(std::clamp(x, 0.0, 1.0) * 255.0));
}

void check_options(const TriMesh& mesh, const ReliefOptions& o) {
  if (o.grid > kMaxGrid) throw InvalidInput(fmt::format("relief map: grid {} out of range 1..{} (0 = automatic)", o.grid, kMaxGrid));
  if (o.max_grid < 1 || o.max_grid > kMaxGrid)
    throw InvalidInput(fmt::format("relief map: maximum grid {} out of range 1..{}", o.max_grid, kMaxGrid));
  if (o.texture < 2 || o.texture > kMaxTexture)
    throw InvalidInput(fmt::format("relief map: texture size {} out of range 2..{}", o.texture, kMaxTexture));
  if (!std::isfinite(o.occlusion_threshold) || o.occlusion_threshold < 0.0)
    throw InvalidInput(fmt::format("relief map: occlusion threshold {} must be finite and >= 0", o.occlusion_threshold));
  if (!mesh.colors.empty() && mesh.colors.size() != mesh.positions.size())
    throw InvalidInput(fmt::format("relief map: {} vertex colours for {} vertices", mesh.colors.size(),
                                   mesh.positions.size()));
}

/// Fills the layer tables of `map` from the classified grid.
void set_cell_table(ReliefMap& map, const CellGrid& grid, std::uint32_t texture) {
  map.n = grid.n;
  map.origin = grid.origin;
  map.cell_size = grid.cell_size;
  map.texture = texture;
  map.distance_scale = distance_scale_for(grid.cell_size);
  map.cells = grid.grey_cells;
  map.external_faces.assign(grid.grey_cells.size(), 0);
  map.projections.resize(grid.grey_cells.size());
  map.first_layer.assign(grid.grey_cells.size() + 1, 0);
  map.layer_face.clear();
  map.layer_cell.clear();
  for (std::size_t g = 0; g < grid.grey_cells.size(); ++g) {
    map.external_faces[g] = grid.border[g] ? grid.external_faces[g] : 0;
    map.projections[g] = cell_projection(map.external_faces[g]);
    map.first_layer[g] = static_cast<std::uint32_t>(map.layer_face.size());
    for (int f = 0; f < 6; ++f) {
      if (((map.projections[g].domain_faces >> f) & 1u) == 0) continue;
      map.layer_face.push_back(static_cast<std::uint8_t>(f));
      map.layer_cell.push_back(static_cast<std::uint32_t>(g));
    }
  }
  map.first_layer.back() = static_cast<std::uint32_t>(map.layer_face.size());
  map.white_cells = grid.count(CellClass::White);
  map.black_cells = grid.count(CellClass::Black);
  map.inside_method = grid.inside_method;
  map.watertight_inside_test = grid.watertight_inside_test;
}

/// Exact (double) distance along the ray org + t·dir to the plane of face f; falls back to `t_float`
/// when the ray is parallel to the plane.
double refine_hit(const TriMesh& mesh, std::uint32_t f, const Vec3& org, const Vec3& dir, double t_float, Vec3& normal) {
  const Face& face = mesh.faces[f];
  const Vec3& a = mesh.positions[face[0]];
  normal = (mesh.positions[face[1]] - a).cross(mesh.positions[face[2]] - a);
  const double len = normal.norm();
  if (len > 0.0) normal /= len;
  const double denom = normal.dot(dir);
  if (len == 0.0 || std::abs(denom) < 1e-9) return t_float;
  return normal.dot(a - org) / denom;
}

/// Samples every layer of `map` (sizes its maps: distances, normals, colours when the mesh has them) and
/// returns (hits, occluded hits).
std::pair<std::uint64_t, std::uint64_t> sample_layers(ReliefMap& map, const TriMesh& mesh, RTCScene scene,
                                                      const ProgressCallback& progress) {
  const std::size_t layers = map.num_layers();
  const std::size_t tpl = map.texels_per_layer();
  const std::uint32_t T = map.texture;
  map.distances.assign(layers * tpl, kEmptyTexel);
  map.normals.assign(layers * tpl * 3, 0);
  map.colors.assign(mesh.has_colors() ? layers * tpl * 3 : 0, 0);
  std::atomic<std::uint64_t> hits_total{0}, occluded_total{0};
  std::atomic<std::size_t> layers_done{0};
  std::atomic<bool> cancelled{false};
  const double eps = 1e-6 * map.cell_size;

  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, layers, 4), [&](const tbb::blocked_range<std::size_t>& range) {
    if (cancelled.load(std::memory_order_relaxed)) return;
    std::uint64_t hits = 0, occluded = 0;
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    for (std::size_t l = range.begin(); l != range.end(); ++l) {
      const std::size_t g = map.layer_cell[l];
      const int face = map.layer_face[l];
      const CellProjection& proj = map.projections[g];
      const Vec3 cmin = map.cell_min(g);
      for (std::uint32_t j = 0; j < T; ++j) {
        for (std::uint32_t i = 0; i < T; ++i) {
          const Vec3 q = face_point(face, map.texel_coord(i), map.texel_coord(j));
          const ProjectionRay pr = projection_ray(proj, q);
          if (pr.length <= 0.0) continue;
          const Vec3 org = cmin + map.cell_size * q;
          const Vec3 dir = -pr.direction;
          const double tmax = pr.length * map.cell_size;
          double tnear = 0.0;
          int found = 0;
          double best_t = 0.0;
          std::uint32_t best_face = 0;
          Vec3 best_bary = Vec3::Zero();
          for (int guard = 0; guard < 64 && tnear <= tmax; ++guard) {  // at most 64 surface crossings counted
            RTCRayHit rh{};
            rh.ray.org_x = static_cast<float>(org.x());
            rh.ray.org_y = static_cast<float>(org.y());
            rh.ray.org_z = static_cast<float>(org.z());
            rh.ray.dir_x = static_cast<float>(dir.x());
            rh.ray.dir_y = static_cast<float>(dir.y());
            rh.ray.dir_z = static_cast<float>(dir.z());
            rh.ray.tnear = static_cast<float>(tnear);
            rh.ray.tfar = static_cast<float>(tmax * (1.0 + 1e-6) + eps);
            rh.ray.mask = 0xffffffffu;
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(scene, &context, &rh);
            if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) break;
            ++found;
            if (found == 1) {
              best_t = rh.ray.tfar;
              best_face = rh.hit.primID;
              const double bu = static_cast<double>(rh.hit.u), bv = static_cast<double>(rh.hit.v);
              best_bary = Vec3(1.0 - bu - bv, bu, bv);
            }
            tnear = static_cast<double>(rh.ray.tfar) + eps;
          }
          if (found == 0) continue;
          hits += static_cast<std::uint64_t>(found);
          occluded += static_cast<std::uint64_t>(found - 1);
          Vec3 normal;
          const double t = std::clamp(refine_hit(mesh, best_face, org, dir, best_t, normal), 0.0, tmax);
          const std::size_t ti = map.texel_index(l, i, j);
          map.distances[ti] = quantize_distance(t, map.distance_scale);
          for (int c = 0; c < 3; ++c) map.normals[3 * ti + static_cast<std::size_t>(c)] = to_snorm8(normal[c]);
          if (!map.colors.empty()) {
            const Face& f = mesh.faces[best_face];
            const Vec3f col = static_cast<float>(best_bary[0]) * mesh.colors[f[0]] +
                              static_cast<float>(best_bary[1]) * mesh.colors[f[1]] +
                              static_cast<float>(best_bary[2]) * mesh.colors[f[2]];
            for (int c = 0; c < 3; ++c) map.colors[3 * ti + static_cast<std::size_t>(c)] = to_unorm8(static_cast<double>(col[c]));
          }
        }
      }
    }
    hits_total += hits;
    occluded_total += occluded;
    const std::size_t done = layers_done += range.size();
    if (progress) {
      try {
        report_progress(progress, "relief sampling", static_cast<double>(done) / static_cast<double>(layers));
      } catch (const Cancelled&) {
        cancelled = true;
      }
    }
  });
  if (cancelled) throw Cancelled("relief sampling: cancelled");
  return {hits_total.load(), occluded_total.load()};
}

}  // namespace

std::uint16_t quantize_distance(double d, double scale) {
  const double q = std::round(d / scale);
  if (!(q > 0.0)) return 0;
  return q >= kMaxQuantizedDistance ? kMaxQuantizedDistance : static_cast<std::uint16_t>(q);
}

std::size_t ReliefMap::storage_bytes() const {
  return distances.size() * sizeof(std::uint16_t) + normals.size() + colors.size() + cells.size() * 5;
}

Vec3 ReliefMap::cell_min(std::size_t g) const {
  const std::size_t linear = cells[g];
  const auto nn = static_cast<std::size_t>(n);
  return origin + cell_size * Vec3(static_cast<double>(linear % nn), static_cast<double>(linear / nn % nn),
                                   static_cast<double>(linear / (nn * nn)));
}

Vec3 ReliefMap::texel_surface_point(std::size_t l, std::uint32_t i, std::uint32_t j) const {
  const std::size_t g = layer_cell[l];
  const Vec3 q = face_point(layer_face[l], texel_coord(i), texel_coord(j));
  const ProjectionRay pr = projection_ray(projections[g], q);
  const double d = dequantize_distance(distances[texel_index(l, i, j)], distance_scale);
  return to_world(g, q) - d * pr.direction;
}

void ReliefMap::check() const {
  auto fail = [](const std::string& what) { throw InvalidInput("relief map: " + what); };
  if (n < 1 || n > kMaxGrid) fail(fmt::format("grid {} out of range 1..{}", n, kMaxGrid));
  if (texture < 2 || texture > kMaxTexture) fail(fmt::format("texture size {} out of range 2..{}", texture, kMaxTexture));
  if (!origin.allFinite()) fail("non-finite origin");
  if (!std::isfinite(cell_size) || cell_size <= 0.0) fail(fmt::format("cell size {} is not positive", cell_size));
  if (!std::isfinite(distance_scale) || distance_scale <= 0.0)
    fail(fmt::format("distance scale {} is not positive", distance_scale));
  const std::size_t G = cells.size();
  const std::uint64_t total_cells = static_cast<std::uint64_t>(n) * n * n;
  if (external_faces.size() != G || projections.size() != G || first_layer.size() != G + 1)
    fail(fmt::format("cell table sizes disagree ({} cells, {} external-face entries, {} projections, {} layer offsets)",
                     G, external_faces.size(), projections.size(), first_layer.size()));
  for (std::size_t g = 0; g < G; ++g) {
    if (cells[g] >= total_cells) fail(fmt::format("grey cell {} has linear index {} outside the {}³ grid", g, cells[g], n));
    if (g > 0 && cells[g] <= cells[g - 1]) fail(fmt::format("grey cells not strictly increasing at {}", g));
    if (external_faces[g] & ~kAllCellFaces) fail(fmt::format("grey cell {}: invalid external faces {:#x}", g, external_faces[g]));
    const CellProjection expected = cell_projection(external_faces[g]);
    const CellProjection& p = projections[g];
    if (p.base_case != expected.base_case || p.type != expected.type || p.domain_faces != expected.domain_faces ||
        p.axis != expected.axis || (p.point - expected.point).norm() > 1e-12 ||
        (p.direction - expected.direction).norm() > 1e-12)
      fail(fmt::format("grey cell {}: projection does not match its external faces {:#x} (case {})", g,
                       external_faces[g], relief_case_name(expected.base_case)));
  }
  const std::size_t L = layer_face.size();
  if (layer_cell.size() != L) fail(fmt::format("{} layer faces but {} layer cells", L, layer_cell.size()));
  if (first_layer.front() != 0 || first_layer.back() != L) fail("layer offsets do not span the layers");
  for (std::size_t g = 0; g < G; ++g) {
    if (first_layer[g + 1] < first_layer[g]) fail(fmt::format("layer offsets decrease at cell {}", g));
    int f = 0;
    std::uint32_t l = first_layer[g];
    for (; f < 6; ++f) {
      if (((projections[g].domain_faces >> f) & 1u) == 0) continue;
      if (l >= first_layer[g + 1] || layer_face[l] != f || layer_cell[l] != g)
        fail(fmt::format("grey cell {}: layers do not list its domain faces in order", g));
      ++l;
    }
    if (l != first_layer[g + 1]) fail(fmt::format("grey cell {}: more layers than domain faces", g));
  }
  const std::uint64_t texels = static_cast<std::uint64_t>(L) * texture * texture;
  if (texels > kMaxTexels) fail(fmt::format("{} texels exceed the limit of {}", texels, kMaxTexels));
  if (distances.size() != texels) fail(fmt::format("{} distances, expected {}", distances.size(), texels));
  if (normals.size() != 3 * texels) fail(fmt::format("{} normal components, expected {}", normals.size(), 3 * texels));
  if (!colors.empty() && colors.size() != 3 * texels)
    fail(fmt::format("{} colour components, expected 0 or {}", colors.size(), 3 * texels));
}

ReliefMap build_relief_map(const TriMesh& mesh, const ReliefOptions& options) {
  check_options(mesh, options);
  const EmbreeDevice device;
  std::optional<detail::EmbreeScene> scene;

  ReliefMap map;
  const bool automatic = options.grid == 0;
  std::uint32_t n = automatic ? 1 : options.grid;
  while (true) {
    CellGridOptions co;
    co.n = n;
    co.padding = options.padding;
    co.inside_test = options.inside_test;
    co.progress = options.progress;
    auto t0 = Clock::now();
    const CellGrid grid = classify_cells(mesh, co);
    map.seconds_cells += seconds_since(t0);

    t0 = Clock::now();
    if (!scene) scene.emplace(device, mesh.positions, mesh.faces, RTC_BUILD_QUALITY_MEDIUM, "building the relief sampling BVH");
    set_cell_table(map, grid, options.texture);
    const std::uint64_t texels = static_cast<std::uint64_t>(map.num_layers()) * options.texture * options.texture;
    if (texels > kMaxTexels)
      throw InvalidInput(fmt::format("relief map: {} domain faces of {}² texels exceed the limit of {} texels; use a "
                                     "smaller grid or texture",
                                     map.num_layers(), options.texture, kMaxTexels));
    // Every level stores its attributes (they cost little next to the rays), so the level that is kept
    // needs no second pass.
    const auto [hits, occluded] = sample_layers(map, mesh, scene->get(), options.progress);
    device.check("relief sampling");
    map.seconds_sampling += seconds_since(t0);
    ReliefGridLevel level;
    level.n = n;
    level.grey_cells = map.cells.size();
    level.domain_faces = map.num_layers();
    level.samples = hits;
    level.occluded = occluded;
    map.levels.push_back(level);
    if (!automatic || n >= options.max_grid || level.occlusion_ratio() <= options.occlusion_threshold) break;
    n = std::min(2 * n, options.max_grid);
  }
  return map;
}

TriMesh reconstruct_relief(const ReliefMap& map, double max_edge_texels) {
  TriMesh out;
  const std::uint32_t T = map.texture;
  const double spacing = map.cell_size / (T - 1);
  const double max_edge = max_edge_texels * spacing;
  const double max_edge2 = max_edge * max_edge;
  const bool with_normals = map.normals.size() == map.distances.size() * 3;
  std::vector<std::uint32_t> vertex(map.texels_per_layer());
  for (std::size_t l = 0; l < map.num_layers(); ++l) {
    for (std::uint32_t j = 0; j < T; ++j) {
      for (std::uint32_t i = 0; i < T; ++i) {
        const std::size_t ti = map.texel_index(l, i, j);
        std::uint32_t& v = vertex[static_cast<std::size_t>(j) * T + i];
        if (map.distances[ti] == kEmptyTexel) {
          v = kNoFace;
          continue;
        }
        v = static_cast<std::uint32_t>(out.positions.size());
        out.positions.push_back(map.texel_surface_point(l, i, j));
        if (with_normals)
          out.normals.emplace_back(map.normals[3 * ti] / 127.0f, map.normals[3 * ti + 1] / 127.0f,
                                   map.normals[3 * ti + 2] / 127.0f);
      }
    }
    for (std::uint32_t j = 0; j + 1 < T; ++j) {
      for (std::uint32_t i = 0; i + 1 < T; ++i) {
        const std::uint32_t a = vertex[static_cast<std::size_t>(j) * T + i];
        const std::uint32_t b = vertex[static_cast<std::size_t>(j) * T + i + 1];
        const std::uint32_t c = vertex[static_cast<std::size_t>(j + 1) * T + i + 1];
        const std::uint32_t d = vertex[static_cast<std::size_t>(j + 1) * T + i];
        if (a == kNoFace || b == kNoFace || c == kNoFace || d == kNoFace) continue;
        const auto& P = out.positions;
        const double ac = (P[a] - P[c]).squaredNorm();
        const double bd = (P[b] - P[d]).squaredNorm();
        if (std::min(ac, bd) > max_edge2) continue;
        Face t1, t2;
        if (ac <= bd) {
          t1 = {a, b, c};
          t2 = {a, c, d};
        } else {
          t1 = {a, b, d};
          t2 = {b, c, d};
        }
        for (Face t : {t1, t2}) {
          const Vec3 e1 = P[t[1]] - P[t[0]];
          const Vec3 e2 = P[t[2]] - P[t[0]];
          if (e1.squaredNorm() > max_edge2 || e2.squaredNorm() > max_edge2 || (P[t[2]] - P[t[1]]).squaredNorm() > max_edge2)
            continue;
          const Vec3 nrm = e1.cross(e2);
          if (nrm.squaredNorm() == 0.0) continue;
          if (with_normals) {
            const Vec3f sn = out.normals[t[0]] + out.normals[t[1]] + out.normals[t[2]];
            if (nrm.dot(sn.cast<double>()) < 0.0) std::swap(t[1], t[2]);
          }
          out.faces.push_back(t);
        }
      }
    }
  }
  return out;
}

}  // namespace gimforge
