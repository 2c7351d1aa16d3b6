#include "kernels/relief/relief_map.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include "kernels/core/embree_device.h"  // kNoFace
#include "kernels/core/errors.h"
#include "kernels/core/validate.h"
#include "kernels/relief/relief_map_detail.h"

namespace gimforge {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

constexpr std::uint32_t kMaxGrid = 1024;
constexpr std::uint32_t kMaxTexture = 1024;
constexpr std::uint64_t kMaxTexels = std::uint64_t{1} << 31;
/// Bytes per texel while a map is sampled (distances, normals, colours, the sampling's buffers): a little
/// below the 5 measured (BENCHMARKS.md "Memory refused up front").
constexpr std::uint64_t kBytesPerTexel = 4;

void check_options(const TriMesh& mesh, const ReliefOptions& o) {
  check_relief_options(o);
  if (!mesh.colors.empty() && mesh.colors.size() != mesh.positions.size())
    throw InvalidInput(fmt::format("relief map: {} vertex colours for {} vertices", mesh.colors.size(),
                                   mesh.positions.size()));
  // Nothing would be sampled: a map of empty texels that no reader can use (render, reconstruct refuse it).
  if (!(surface_area(mesh) > 0.0)) throw InvalidInput("relief map: the mesh has no surface area");
}

}  // namespace

void check_relief_options(const ReliefOptions& o) {
  if (o.grid > kMaxGrid) throw InvalidInput(fmt::format("relief map: grid {} out of range 1..{} (0 = automatic)", o.grid, kMaxGrid));
  if (o.max_grid < 1 || o.max_grid > kMaxGrid)
    throw InvalidInput(fmt::format("relief map: maximum grid {} out of range 1..{}", o.max_grid, kMaxGrid));
  if (o.texture < 2 || o.texture > kMaxTexture)
    throw InvalidInput(fmt::format("relief map: texture size {} out of range 2..{}", o.texture, kMaxTexture));
  if (!std::isfinite(o.occlusion_threshold) || o.occlusion_threshold < 0.0)
    throw InvalidInput(fmt::format("relief map: occlusion threshold {} must be finite and >= 0", o.occlusion_threshold));
}

std::uint32_t next_relief_grid(const ReliefOptions& options, const ReliefGridLevel& level) {
  if (options.grid != 0 || level.n >= options.max_grid) return 0;
  if (level.occlusion_ratio() <= options.occlusion_threshold && level.edge_on_ratio() <= kEdgeOnRatioLimit) return 0;
  return std::min(2 * level.n, options.max_grid);
}

EdgeOnCounts count_edge_on_faces(const ReliefMap& layout, MeshView part) {
  const std::uint64_t n = layout.n;
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, part.faces.size(), 4096), EdgeOnCounts{},
      [&](const tbb::blocked_range<std::size_t>& range, EdgeOnCounts counts) {
        for (std::size_t f = range.begin(); f != range.end(); ++f) {
          const Face& t = part.faces[f];
          const Vec3& a = part.positions[t[0]];
          const Vec3 normal = (part.positions[t[1]] - a).cross(part.positions[t[2]] - a);
          const double length = normal.norm();
          if (!(length > 0.0) || !std::isfinite(length)) continue;
          const Vec3 centroid = (a + part.positions[t[1]] + part.positions[t[2]]) / 3.0;
          std::array<std::uint64_t, 3> index{};
          for (int k = 0; k < 3; ++k) {
            const double c = std::floor((centroid[k] - layout.origin[k]) / layout.cell_size);
            index[static_cast<std::size_t>(k)] = static_cast<std::uint64_t>(std::clamp(c, 0.0, static_cast<double>(n - 1)));
          }
          const auto linear = static_cast<std::uint32_t>((index[2] * n + index[1]) * n + index[0]);
          const auto it = std::lower_bound(layout.cells.begin(), layout.cells.end(), linear);
          if (it == layout.cells.end() || *it != linear) continue;
          const auto g = static_cast<std::size_t>(it - layout.cells.begin());
          ++counts.faces;
          const Vec3 local = (centroid - layout.cell_min(g)) / layout.cell_size;
          FaceProjection at;
          if (!project_point(layout.projections[g], local, at)) {  // the centre or the axis itself
            ++counts.edge_on;
            continue;
          }
          const ProjectionRay ray = projection_ray(layout.projections[g], face_point(at.face, at.u, at.v));
          if (std::abs(normal.dot(ray.direction)) < kEdgeOnCosine * length) ++counts.edge_on;
        }
        return counts;
      },
      [](EdgeOnCounts x, const EdgeOnCounts& y) {
        x.faces += y.faces;
        x.edge_on += y.edge_on;
        return x;
      });
}

void set_relief_layout(ReliefMap& map, const CellGrid& grid, std::uint32_t texture) {
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
      if (!has_cell_face(map.projections[g].domain_faces, f)) continue;
      map.layer_face.push_back(static_cast<std::uint8_t>(f));
      map.layer_cell.push_back(static_cast<std::uint32_t>(g));
    }
  }
  map.first_layer.back() = static_cast<std::uint32_t>(map.layer_face.size());
  map.white_cells = grid.count(CellClass::White);
  map.black_cells = grid.count(CellClass::Black);
  map.inside_method = grid.inside_method;
  map.watertight_inside_test = grid.watertight_inside_test;
  const std::uint64_t texels = static_cast<std::uint64_t>(map.num_layers()) * texture * texture;
  if (texels > kMaxTexels)
    throw InvalidInput(fmt::format("relief map: {} domain faces of {}² texels exceed the limit of {} texels; use a "
                                   "smaller grid or texture",
                                   map.num_layers(), texture, kMaxTexels));
}

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
      if (!has_cell_face(projections[g].domain_faces, f)) continue;
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
    set_relief_layout(map, grid, options.texture);
    if (const std::uint64_t bytes = kBytesPerTexel * map.num_layers() * options.texture * options.texture;
        options.max_map_bytes > 0 && bytes > options.max_map_bytes)
      throw InvalidInput(fmt::format("relief map: {} domain faces of {}² texels need about {:.1f} GB of memory, more "
                                     "than the {:.1f} GB this process can have; use a smaller grid or texture",
                                     map.num_layers(), options.texture, static_cast<double>(bytes) / 1e9,
                                     static_cast<double>(options.max_map_bytes) / 1e9));
    // Every level stores its attributes (they cost little next to the segment tests), so the level that
    // is kept needs no second pass.
    const ReliefSampleCounts counts = detail::sample_relief_layers(map, mesh, grid, options.progress);
    map.seconds_sampling += seconds_since(t0);
    ReliefGridLevel level;
    level.n = n;
    level.grey_cells = map.cells.size();
    level.domain_faces = map.num_layers();
    level.samples = counts.samples;
    level.occluded = counts.occluded;
    const EdgeOnCounts edge_on = count_edge_on_faces(map, mesh);
    level.faces = edge_on.faces;
    level.edge_on = edge_on.edge_on;
    map.levels.push_back(level);
    n = next_relief_grid(options, level);
    if (n == 0) break;
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
  (void)repair_mesh(out, /*duplicates=*/false);  // the texels no triangle uses (no other defect is made above)
  return out;
}

}  // namespace gimforge
