#pragma once
// Disk-like test meshes and boundary layouts shared by the parametrization tests.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/core/procedural.h"
#include "kernels/param/stretch.h"

namespace gimforge::test {

/// The boundary loop of a disk, following the boundary halfedges (interior on the left).
inline std::vector<std::uint32_t> boundary_loop(const TriMesh& mesh) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> halfedges;
  for (const Face& f : mesh.faces)
    for (std::size_t i = 0; i < 3; ++i) halfedges[{f[i], f[(i + 1) % 3]}] = 1;
  std::map<std::uint32_t, std::uint32_t> next;
  for (const auto& [h, unused] : halfedges)
    if (!halfedges.contains({h.second, h.first})) next[h.first] = h.second;
  std::vector<std::uint32_t> loop;
  if (next.empty()) return loop;
  std::uint32_t v = next.begin()->first;
  do {
    loop.push_back(v);
    v = next.at(v);
  } while (v != loop.front() && loop.size() <= next.size());
  return loop;
}

/// Keeps the faces whose centroid satisfies z > z_min, dropping unreferenced vertices.
inline TriMesh clip_below(const TriMesh& mesh, double z_min) {
  TriMesh out;
  std::vector<std::uint32_t> remap(mesh.positions.size(), 0xffffffffu);
  for (const Face& f : mesh.faces) {
    const Vec3 c = (mesh.positions[f[0]] + mesh.positions[f[1]] + mesh.positions[f[2]]) / 3.0;
    if (c.z() <= z_min) continue;
    Face g{};
    for (std::size_t i = 0; i < 3; ++i) {
      if (remap[f[i]] == 0xffffffffu) {
        remap[f[i]] = static_cast<std::uint32_t>(out.positions.size());
        out.positions.push_back(mesh.positions[f[i]]);
      }
      g[i] = remap[f[i]];
    }
    out.faces.push_back(g);
  }
  return out;
}

/// Upper hemisphere of an icosphere (a disk).
inline TriMesh make_hemisphere(int subdivisions) { return clip_below(make_icosphere(1.0, subdivisions), 0.0); }

/// Grid over [0,1]² with z = 0.3 sin(3x) cos(2y).
inline TriMesh make_bumpy_grid(std::size_t n) {
  TriMesh m = make_grid(n, n, 1.0);
  for (Vec3& p : m.positions) p.z() = 0.3 * std::sin(3.0 * p.x()) * std::cos(2.0 * p.y());
  return m;
}

/// Maps a boundary loop onto the perimeter of the unit square [0,1]², proportionally to arc length between
/// four corner positions corners[0..3] (indices into loop, increasing), which land on (0,0),(1,0),(1,1),(0,1).
inline std::vector<Vec2> square_boundary(const TriMesh& mesh, const std::vector<std::uint32_t>& loop,
                                         const std::array<std::size_t, 4>& corners) {
  const std::array<Vec2, 4> c{Vec2(0, 0), Vec2(1, 0), Vec2(1, 1), Vec2(0, 1)};
  std::vector<Vec2> uv(loop.size());
  const std::size_t n = loop.size();
  for (std::size_t side = 0; side < 4; ++side) {
    const std::size_t begin = corners[side], end = corners[(side + 1) % 4] + (side == 3 ? n : 0);
    std::vector<double> arc{0.0};
    for (std::size_t i = begin; i < end; ++i)
      arc.push_back(arc.back() + (mesh.positions[loop[(i + 1) % n]] - mesh.positions[loop[i % n]]).norm());
    for (std::size_t i = begin; i < end; ++i) {
      const double t = arc[i - begin] / arc.back();
      uv[i % n] = (1.0 - t) * c[side] + t * c[(side + 1) % 4];
    }
  }
  return uv;
}

/// Position in `loop` of the vertex nearest to (x, y) in the xy plane.
inline std::size_t nearest_in_loop(const TriMesh& mesh, const std::vector<std::uint32_t>& loop, double x, double y) {
  std::size_t best = 0;
  for (std::size_t i = 1; i < loop.size(); ++i)
    if ((mesh.positions[loop[i]].head<2>() - Vec2(x, y)).norm() <
        (mesh.positions[loop[best]].head<2>() - Vec2(x, y)).norm())
      best = i;
  return best;
}

/// Grid corners of a (possibly bumpy) grid over [0,1]², as loop positions in loop order, rotated to start at 0.
inline std::array<std::size_t, 4> grid_corners(const TriMesh& mesh, const std::vector<std::uint32_t>& loop) {
  std::array<std::size_t, 4> c{nearest_in_loop(mesh, loop, 0, 0), nearest_in_loop(mesh, loop, 1, 0),
                               nearest_in_loop(mesh, loop, 1, 1), nearest_in_loop(mesh, loop, 0, 1)};
  std::sort(c.begin(), c.end());
  return c;
}

/// Number of faces with non-positive parameter area.
inline std::size_t count_flipped(const TriMesh& mesh, const std::vector<Vec2>& uv) {
  std::size_t flipped = 0;
  for (const Face& f : mesh.faces)
    if (!(triangle_stretch(uv[f[0]], uv[f[1]], uv[f[2]], mesh.positions[f[0]], mesh.positions[f[1]],
                           mesh.positions[f[2]])
              .parametric_area > 0.0))
      ++flipped;
  return flipped;
}

}  // namespace gimforge::test
