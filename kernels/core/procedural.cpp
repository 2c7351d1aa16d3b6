#include "kernels/core/procedural.h"

#include <cmath>
#include <array>
#include <map>
#include <numbers>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge {

TriMesh make_icosphere(double radius, int subdivisions) {
  if (!(radius > 0.0) || subdivisions < 0 || subdivisions > 9)
    throw InvalidInput(fmt::format("make_icosphere: need radius > 0 and 0 <= subdivisions <= 9 (got {}, {})", radius,
                                   subdivisions));
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  TriMesh m;
  m.positions = {{-1, t, 0}, {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                 {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  m.faces = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
             {11, 10, 2}, {10, 7, 6}, {7, 1, 8},   {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
             {3, 8, 9},  {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (auto& p : m.positions) p.normalize();
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> midpoint;
    auto mid = [&](std::uint32_t a, std::uint32_t b) {
      const auto key = std::minmax(a, b);
      auto [it, inserted] = midpoint.try_emplace(key, static_cast<std::uint32_t>(m.positions.size()));
      if (inserted) m.positions.push_back((m.positions[a] + m.positions[b]).normalized());
      return it->second;
    };
    std::vector<Face> faces;
    faces.reserve(4 * m.faces.size());
    for (const Face& f : m.faces) {
      const std::uint32_t ab = mid(f[0], f[1]), bc = mid(f[1], f[2]), ca = mid(f[2], f[0]);
      faces.push_back({f[0], ab, ca});
      faces.push_back({f[1], bc, ab});
      faces.push_back({f[2], ca, bc});
      faces.push_back({ab, bc, ca});
    }
    m.faces = std::move(faces);
  }
  for (auto& p : m.positions) p *= radius;
  return m;
}

TriMesh make_torus(double major_radius, double minor_radius, std::size_t nu, std::size_t nv) {
  if (!(major_radius > minor_radius && minor_radius > 0.0) || nu < 3 || nv < 3)
    throw InvalidInput(fmt::format("make_torus: need R > r > 0 and nu, nv >= 3 (got {}, {}, {}, {})", major_radius,
                                   minor_radius, nu, nv));
  TriMesh m;
  const double two_pi = 2.0 * std::numbers::pi;
  for (std::size_t i = 0; i < nu; ++i) {
    const double u = two_pi * static_cast<double>(i) / static_cast<double>(nu);
    for (std::size_t j = 0; j < nv; ++j) {
      const double v = two_pi * static_cast<double>(j) / static_cast<double>(nv);
      const double w = major_radius + minor_radius * std::cos(v);
      m.positions.emplace_back(w * std::cos(u), w * std::sin(u), minor_radius * std::sin(v));
    }
  }
  auto id = [&](std::size_t i, std::size_t j) { return static_cast<std::uint32_t>((i % nu) * nv + (j % nv)); };
  for (std::size_t i = 0; i < nu; ++i) {
    for (std::size_t j = 0; j < nv; ++j) {
      m.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  }
  return m;
}

TriMesh make_grid(std::size_t nx, std::size_t ny, double size) {
  if (nx < 1 || ny < 1 || !(size > 0.0))
    throw InvalidInput(fmt::format("make_grid: need nx, ny >= 1 and size > 0 (got {}, {}, {})", nx, ny, size));
  TriMesh m;
  for (std::size_t j = 0; j <= ny; ++j)
    for (std::size_t i = 0; i <= nx; ++i)
      m.positions.emplace_back(size * static_cast<double>(i) / static_cast<double>(nx),
                               size * static_cast<double>(j) / static_cast<double>(ny), 0.0);
  auto id = [&](std::size_t i, std::size_t j) { return static_cast<std::uint32_t>(j * (nx + 1) + i); };
  for (std::size_t j = 0; j < ny; ++j) {
    for (std::size_t i = 0; i < nx; ++i) {
      m.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  }
  return m;
}

TriMesh make_slab_with_holes(int genus, int s) {
  if (genus < 0 || s < 1)
    throw InvalidInput(fmt::format("make_slab_with_holes: need genus >= 0 and s >= 1 (got {}, {})", genus, s));
  const int nx = (2 * genus + 1) * s, ny = 3 * s;
  auto solid = [&](int i, int j) {
    if (i < 0 || j < 0 || i >= nx || j >= ny) return false;
    return !(j >= s && j < 2 * s && (i / s) % 2 == 1);
  };
  TriMesh m;
  std::map<std::array<int, 3>, std::uint32_t> ids;
  auto vertex = [&](const std::array<int, 3>& p) {
    auto [it, inserted] = ids.try_emplace(p, static_cast<std::uint32_t>(m.positions.size()));
    if (inserted) m.positions.emplace_back(p[0], p[1], p[2]);
    return it->second;
  };
  auto quad = [&](std::array<std::array<int, 3>, 4> p, const Vec3& outward) {
    std::array<std::uint32_t, 4> v{vertex(p[0]), vertex(p[1]), vertex(p[2]), vertex(p[3])};
    const Vec3 n = (m.positions[v[1]] - m.positions[v[0]]).cross(m.positions[v[3]] - m.positions[v[0]]);
    if (n.dot(outward) < 0) std::swap(v[1], v[3]);
    m.faces.push_back({v[0], v[1], v[2]});
    m.faces.push_back({v[0], v[2], v[3]});
  };
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      if (!solid(i, j)) continue;
      quad({{{i, j, 1}, {i + 1, j, 1}, {i + 1, j + 1, 1}, {i, j + 1, 1}}}, {0, 0, 1});
      quad({{{i, j, 0}, {i + 1, j, 0}, {i + 1, j + 1, 0}, {i, j + 1, 0}}}, {0, 0, -1});
      if (!solid(i + 1, j)) quad({{{i + 1, j, 0}, {i + 1, j + 1, 0}, {i + 1, j + 1, 1}, {i + 1, j, 1}}}, {1, 0, 0});
      if (!solid(i - 1, j)) quad({{{i, j, 0}, {i, j + 1, 0}, {i, j + 1, 1}, {i, j, 1}}}, {-1, 0, 0});
      if (!solid(i, j + 1)) quad({{{i, j + 1, 0}, {i + 1, j + 1, 0}, {i + 1, j + 1, 1}, {i, j + 1, 1}}}, {0, 1, 0});
      if (!solid(i, j - 1)) quad({{{i, j, 0}, {i + 1, j, 0}, {i + 1, j, 1}, {i, j, 1}}}, {0, -1, 0});
    }
  }
  return m;
}

TriMesh concatenate(const TriMesh& a, const TriMesh& b) {
  TriMesh m = a;
  const auto offset = static_cast<std::uint32_t>(a.positions.size());
  m.positions.insert(m.positions.end(), b.positions.begin(), b.positions.end());
  for (Face f : b.faces) {
    for (auto& v : f) v += offset;
    m.faces.push_back(f);
  }
  m.colors.clear();
  m.normals.clear();
  return m;
}

}  // namespace gimforge
