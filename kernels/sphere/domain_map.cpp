#include "kernels/sphere/domain_map.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <mutex>

#include <fmt/format.h>

#include "kernels/sphere/domain_tables.h"
#include "kernels/core/errors.h"
#include "kernels/sphere/sphere_vertex_optimizer.h"
#include "kernels/param/stretch.h"

namespace gimforge {
namespace {

/// True when the cell with lower-left sample (i, j) is split along its main diagonal (c00–c11) rather than
/// the anti-diagonal (c10–c01). See the file comment of domain_map.h.
bool main_diagonal(const DomainImage& image, std::int32_t i, std::int32_t j) {
  if (image.domain() != SphericalDomain::Octahedron && image.domain() != SphericalDomain::FlatOctahedron) return false;
  const std::int32_t cx = 2 * i + 1 - 2 * image.n(), cy = 2 * j + 1 - 2 * image.n();
  return (cx > 0) != (cy > 0);
}

/// Columns where cells start: the tetrahedron image wraps around, so its last column starts a cell too.
std::int32_t cell_columns(const DomainImage& image) {
  return image.domain() == SphericalDomain::Tetrahedron ? image.width() : image.width() - 1;
}

/// The tessellated domain as a closed triangle mesh over its distinct points (DomainImage::vertex_ids),
/// counter-clockwise in the image, with the domain-face 2D coordinates of every triangle's corners.
struct DomainMesh {
  std::vector<std::uint32_t> ids;  ///< vertex of every stored sample
  std::size_t vertices{0};
  std::vector<Face> faces;
  std::vector<std::array<Vec2, 3>> domain_uv;  ///< isometric 2D coordinates of each face's corners
  double domain_area{0.0};
};

DomainMesh build_domain_mesh(const DomainImage& image) {
  DomainMesh m;
  m.ids = image.vertex_ids();
  m.vertices = image.num_domain_points();
  const std::vector<Vec3> points = domain_positions(image, DomainEmbedding::Polyhedron);
  std::vector<Vec3> by_vertex(m.vertices);
  for (std::size_t k = 0; k < m.ids.size(); ++k) by_vertex[m.ids[k]] = points[k];
  auto id = [&](std::int32_t f, std::int32_t i, std::int32_t j) { return m.ids[image.linear_index(image.resolve(f, i, j))]; };
  auto add = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    m.faces.push_back({a, b, c});
    const Vec3 e1 = by_vertex[b] - by_vertex[a], e2 = by_vertex[c] - by_vertex[a];
    const double l1 = e1.norm(), area2 = e1.cross(e2).norm();
    m.domain_uv.push_back({Vec2(0.0, 0.0), Vec2(l1, 0.0), Vec2(e2.dot(e1) / l1, area2 / l1)});
    m.domain_area += 0.5 * area2;
  };
  for (std::int32_t f = 0; f < image.faces(); ++f)
    for (std::int32_t j = 0; j + 1 < image.height(); ++j)
      for (std::int32_t i = 0; i < cell_columns(image); ++i) {
        const std::uint32_t c00 = id(f, i, j), c10 = id(f, i + 1, j), c01 = id(f, i, j + 1), c11 = id(f, i + 1, j + 1);
        if (main_diagonal(image, i, j)) {
          add(c00, c10, c11);
          add(c00, c11, c01);
        } else {
          add(c00, c10, c01);
          add(c10, c11, c01);
        }
      }
  return m;
}

/// ½(σ₁² + σ₂²)·A_S of the D → S map on one triangle, +infinity when the spherical triangle is flipped.
struct DomainEnergy {
  const DomainMesh* mesh;
  double operator()(std::uint32_t f, const Vec3& s0, const Vec3& s1, const Vec3& s2) const {
    if (!(s0.dot(s1.cross(s2)) > 0.0)) return std::numeric_limits<double>::infinity();
    const auto& uv = mesh->domain_uv[f];
    const TriangleStretch t = triangle_stretch(uv[0], uv[1], uv[2], s0, s1, s2);
    return t.l2 * t.l2 * 0.5 * (s1 - s0).cross(s2 - s0).norm();
  }
};

std::vector<Vec3> per_vertex(const DomainMesh& m, std::span<const Vec3> per_sample) {
  std::vector<Vec3> out(m.vertices, Vec3::Zero());
  for (std::size_t k = 0; k < m.ids.size(); ++k) out[m.ids[k]] = per_sample[k];
  return out;
}

std::vector<Vec3> per_sample(const DomainMesh& m, std::span<const Vec3> per_vertex) {
  std::vector<Vec3> out(m.ids.size());
  for (std::size_t k = 0; k < m.ids.size(); ++k) out[k] = per_vertex[m.ids[k]];
  return out;
}

void check_n(std::uint32_t n) {
  if (n < 1 || n > 1024) throw InvalidInput(fmt::format("domain map: tessellation n = {} is outside 1..1024", n));
}

}  // namespace

DomainSphereMap gnomonic_domain_map(SphericalDomain domain, std::uint32_t n) {
  check_n(n);
  const DomainImage image(domain, n);
  return {domain, n, domain_positions(image, DomainEmbedding::Sphere)};
}

std::vector<Vec3> sample_domain_map(const DomainSphereMap& map, const DomainImage& image) {
  if (map.domain != image.domain())
    throw InvalidInput(fmt::format("sample_domain_map: a {} map cannot sample a {} image", to_string(map.domain),
                                   to_string(image.domain())));
  const DomainImage table(map.domain, map.n);
  if (map.sphere.size() != table.num_samples())
    throw InvalidInput(fmt::format("sample_domain_map: the {} table at n = {} has {} vectors, expected {}",
                                   to_string(map.domain), map.n, map.sphere.size(), table.num_samples()));
  const double scale = static_cast<double>(map.n) / static_cast<double>(image.n());
  const std::int32_t max_i = cell_columns(table) - 1, max_j = table.height() - 2;
  std::vector<Vec3> out(image.num_samples());
  for (std::size_t k = 0; k < out.size(); ++k) {
    const SampleIndex s = image.sample_at(k);
    const double u = s.i * scale, v = s.j * scale;
    const std::int32_t i0 = std::clamp(static_cast<std::int32_t>(std::floor(u)), 0, max_i);
    const std::int32_t j0 = std::clamp(static_cast<std::int32_t>(std::floor(v)), 0, max_j);
    const double a = u - i0, b = v - j0;
    auto at = [&](std::int32_t di, std::int32_t dj) -> const Vec3& {
      return map.sphere[table.linear_index(table.resolve(s.face, i0 + di, j0 + dj))];
    };
    Vec3 x;
    if (main_diagonal(table, i0, j0))
      x = a >= b ? (1.0 - a) * at(0, 0) + (a - b) * at(1, 0) + b * at(1, 1)
                 : (1.0 - b) * at(0, 0) + a * at(1, 1) + (b - a) * at(0, 1);
    else
      x = a + b <= 1.0 ? (1.0 - a - b) * at(0, 0) + a * at(1, 0) + b * at(0, 1)
                       : (1.0 - b) * at(1, 0) + (a + b - 1.0) * at(1, 1) + (1.0 - a) * at(0, 1);
    out[k] = x.normalized();
  }
  return out;
}

DomainMapStretch domain_map_stretch(const DomainSphereMap& map) {
  const DomainImage image(map.domain, map.n);
  if (map.sphere.size() != image.num_samples())
    throw InvalidInput(fmt::format("domain_map_stretch: {} vectors for {} samples", map.sphere.size(),
                                   image.num_samples()));
  const DomainMesh m = build_domain_mesh(image);
  const std::vector<Vec3> s = per_vertex(m, map.sphere);
  const DomainEnergy energy{&m};
  DomainMapStretch r;
  double integral = 0.0, sphere_area = 0.0;
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    const Face& t = m.faces[f];
    const double e = energy(static_cast<std::uint32_t>(f), s[t[0]], s[t[1]], s[t[2]]);
    if (!std::isfinite(e)) {
      ++r.flipped;
      continue;
    }
    integral += e;
    sphere_area += 0.5 * (s[t[1]] - s[t[0]]).cross(s[t[2]] - s[t[0]]).norm();
  }
  if (r.flipped > 0 || !(sphere_area > 0.0)) return r;
  r.l2 = std::sqrt(integral / sphere_area);
  r.efficiency = (sphere_area / m.domain_area) / (r.l2 * r.l2);
  return r;
}

double domain_to_surface_efficiency(const DomainImage& image, std::span<const Vec3> positions) {
  if (positions.size() != image.num_samples())
    throw InvalidInput(fmt::format("domain_to_surface_efficiency: {} positions for {} samples", positions.size(),
                                   image.num_samples()));
  const DomainMesh m = build_domain_mesh(image);
  const std::vector<Vec3> p = per_vertex(m, positions);
  double integral = 0.0, surface_area = 0.0, domain_area = 0.0;
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    const Face& t = m.faces[f];
    if (!p[t[0]].allFinite() || !p[t[1]].allFinite() || !p[t[2]].allFinite()) continue;
    const auto& uv = m.domain_uv[f];
    const double area = 0.5 * (p[t[1]] - p[t[0]]).cross(p[t[2]] - p[t[0]]).norm();
    const TriangleStretch s = triangle_stretch(uv[0], uv[1], uv[2], p[t[0]], p[t[1]], p[t[2]]);
    integral += s.l2 * s.l2 * area;
    surface_area += area;
    domain_area += 0.5 * (uv[1].x() * uv[2].y() - uv[1].y() * uv[2].x());
  }
  if (!(surface_area > 0.0) || !(integral > 0.0)) return 0.0;
  return (surface_area / domain_area) / (integral / surface_area);
}

DomainSphereMap optimize_domain_map(SphericalDomain domain, std::uint32_t n, const DomainMapOptions& options) {
  check_n(n);
  std::vector<std::uint32_t> levels;
  for (std::uint32_t level = std::max<std::uint32_t>(1, options.coarsest_n); level < n; level *= 2) levels.push_back(level);
  levels.push_back(n);
  DomainSphereMap map = gnomonic_domain_map(domain, levels.front());
  for (std::size_t l = 0; l < levels.size(); ++l) {
    const DomainImage image(domain, levels[l]);
    if (l > 0) map = {domain, levels[l], sample_domain_map(map, image)};
    const DomainMesh m = build_domain_mesh(image);
    std::vector<Vec3> sphere = per_vertex(m, map.sphere);
    const detail::StaticTopology topo(m.faces, m.vertices);
    detail::SphereVertexOptimizer opt(topo, sphere, DomainEnergy{&m}, options.seed + l);
    std::vector<std::uint32_t> all(m.vertices);
    for (std::uint32_t v = 0; v < all.size(); ++v) all[v] = v;
    const std::size_t budget = static_cast<std::size_t>(std::max(1, options.max_sweeps)) * all.size();
    for (std::size_t used = 0; used < budget;) {
      const std::size_t pops = opt.priority_sweep(all, options.tolerance, std::min(all.size(), budget - used));
      used += pops;
      report_progress(options.progress, "domain map",
                      (static_cast<double>(l) + static_cast<double>(used) / static_cast<double>(budget)) /
                          static_cast<double>(levels.size()));
      if (pops < all.size()) break;  // the queue ran dry: converged at this tolerance
    }
    map.sphere = per_sample(m, sphere);
  }
  const DomainMapStretch check = domain_map_stretch(map);
  if (check.flipped != 0)
    throw NumericalError(fmt::format("domain map: {} flipped triangles in the optimized {} map", check.flipped,
                                     to_string(domain)));
  return map;
}

const DomainSphereMap& builtin_domain_map(SphericalDomain domain) {
  static std::once_flag once;
  static std::array<DomainSphereMap, kSphericalDomains.size()> maps;
  std::call_once(once, [] {
    for (const detail::DomainTableData& t : detail::domain_tables()) {
      DomainSphereMap& m = maps[static_cast<std::size_t>(t.domain)];
      m.domain = t.domain;
      m.n = t.n;
      m.sphere.resize(t.xyz.size() / 3);
      for (std::size_t k = 0; k < m.sphere.size(); ++k)
        m.sphere[k] = Vec3(static_cast<double>(t.xyz[3 * k]), static_cast<double>(t.xyz[3 * k + 1]),
                           static_cast<double>(t.xyz[3 * k + 2]))
                          .normalized();
    }
  });
  const DomainSphereMap& m = maps[static_cast<std::size_t>(domain)];
  if (m.n == 0)
    throw InvalidInput(fmt::format("no built-in {} domain map: regenerate kernels/sphere/domain_tables.bin with "
                                   "tools/domain_tables (generate_domain_tables --write)",
                                   to_string(domain)));
  return m;
}

double paper_domain_efficiency(SphericalDomain domain) {
  switch (domain) {
    case SphericalDomain::Tetrahedron: return 0.910;
    case SphericalDomain::Octahedron: return 0.969;
    case SphericalDomain::Cube: return 0.983;
    case SphericalDomain::FlatOctahedron: return 0.896;
  }
  return 0.0;
}

}  // namespace gimforge
