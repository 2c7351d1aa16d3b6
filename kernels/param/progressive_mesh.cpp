#include "kernels/param/progressive_mesh.h"

#include <algorithm>
#include <limits>
#include <queue>
#include <string>
#include <tuple>
#include <utility>

#include "kernels/core/errors.h"

namespace gimforge {
namespace {

using Quadric = std::array<double, 10>;
using NeighbourCount = std::pair<std::uint32_t, std::uint32_t>;  // (vertex, incident faces shared with centre)

/// Area-weighted plane quadric of triangle (a, b, c).
Quadric plane_quadric(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 cross = (b - a).cross(c - a);
  const double len = cross.norm();
  Quadric q{};
  if (len <= 0.0) return q;
  const Vec3 n = cross / len;
  const std::array<double, 4> p{n.x(), n.y(), n.z(), -n.dot(a)};
  const double area = 0.5 * len;
  std::size_t k = 0;
  for (std::size_t i = 0; i < 4; ++i)
    for (std::size_t j = i; j < 4; ++j) q[k++] = area * p[i] * p[j];
  return q;
}

/// p^T Q p for the homogeneous point (x, y, z, 1).
double quadric_error(const Quadric& q, const Vec3& x) {
  const std::array<double, 4> p{x.x(), x.y(), x.z(), 1.0};
  double e = 0.0;
  std::size_t k = 0;
  for (std::size_t i = 0; i < 4; ++i)
    for (std::size_t j = i; j < 4; ++j) e += (i == j ? 1.0 : 2.0) * q[k++] * p[i] * p[j];
  return e;
}

/// Neighbours of the centre with the number of its faces each one shares.
void count_neighbours(std::span<const Face> faces, std::span<const std::uint32_t> incident, std::uint32_t centre,
                      std::vector<NeighbourCount>& out) {
  out.clear();
  for (std::uint32_t f : incident)
    for (std::uint32_t c : faces[f]) {
      if (c == centre) continue;
      auto it = std::find_if(out.begin(), out.end(), [c](const NeighbourCount& n) { return n.first == c; });
      if (it == out.end())
        out.emplace_back(c, 1);
      else
        ++it->second;
    }
}

bool face_has(const Face& f, std::uint32_t v) { return f[0] == v || f[1] == v || f[2] == v; }

}  // namespace

ProgressiveMesh::ProgressiveMesh(MeshView mesh, std::span<const char> locked)
    : mesh_(mesh), faces_(mesh.faces.begin(), mesh.faces.end()), face_alive_(mesh.faces.size(), 1),
      vertex_alive_(mesh.positions.size(), 0), locked_(mesh.positions.size(), 0),
      vertex_faces_(mesh.positions.size()) {
  if (!locked.empty() && locked.size() != mesh.positions.size())
    throw InvalidInput("ProgressiveMesh: locked has " + std::to_string(locked.size()) + " entries for " +
                       std::to_string(mesh.positions.size()) + " vertices");
  for (std::size_t f = 0; f < faces_.size(); ++f) {
    if (has_repeated_index(faces_[f])) {
      face_alive_[f] = 0;
      continue;
    }
    for (std::uint32_t c : faces_[f]) vertex_faces_[c].push_back(static_cast<std::uint32_t>(f));
  }
  for (std::size_t v = 0; v < vertex_faces_.size(); ++v) {
    if (!locked.empty()) locked_[v] = locked[v] != 0 ? 1 : 0;
    if (vertex_faces_[v].empty()) continue;
    vertex_alive_[v] = 1;
    ++alive_vertices_;
    if (!locked_[v]) ++alive_free_;
  }
}

void ProgressiveMesh::init_quadrics() {
  quadrics_.assign(mesh_.positions.size(), Quadric{});
  for (std::size_t f = 0; f < faces_.size(); ++f) {
    if (!face_alive_[f]) continue;
    const Face& t = faces_[f];
    const Quadric q = plane_quadric(mesh_.positions[t[0]], mesh_.positions[t[1]], mesh_.positions[t[2]]);
    for (std::uint32_t c : t)
      for (std::size_t k = 0; k < q.size(); ++k) quadrics_[c][k] += q[k];
  }
}

double ProgressiveMesh::collapse_cost(std::uint32_t vertex, std::uint32_t target) const {
  Quadric q = quadrics_[vertex];
  for (std::size_t k = 0; k < q.size(); ++k) q[k] += quadrics_[target][k];
  const double len2 = (mesh_.positions[vertex] - mesh_.positions[target]).squaredNorm();
  return quadric_error(q, mesh_.positions[target]) + 1e-4 * len2 * len2;  // length term breaks ties on flat parts
}

void ProgressiveMesh::neighbours(std::uint32_t v, std::vector<std::uint32_t>& out) const {
  out.clear();
  for (std::uint32_t f : vertex_faces_[v])
    for (std::uint32_t c : faces_[f])
      if (c != v && std::find(out.begin(), out.end(), c) == out.end()) out.push_back(c);
}

bool ProgressiveMesh::on_boundary(std::uint32_t v) const {
  std::vector<NeighbourCount> counts;
  count_neighbours(faces_, vertex_faces_[v], v, counts);
  return std::any_of(counts.begin(), counts.end(), [](const NeighbourCount& n) { return n.second != 2; });
}

bool ProgressiveMesh::can_collapse(std::uint32_t vertex, std::uint32_t target) const {
  if (vertex == target || locked_[vertex] || !vertex_alive_[vertex] || !vertex_alive_[target] || alive_vertices_ <= 4)
    return false;
  std::vector<NeighbourCount> around_v;
  count_neighbours(faces_, vertex_faces_[vertex], vertex, around_v);
  bool adjacent = false;
  for (const NeighbourCount& n : around_v) {
    if (n.second != 2) return false;  // vertex on the boundary (or non-manifold): keep the boundary intact
    adjacent = adjacent || n.first == target;
  }
  if (!adjacent) return false;
  std::vector<std::uint32_t> around_w;
  neighbours(target, around_w);
  std::size_t common = 0;
  for (const NeighbourCount& n : around_v)
    common += static_cast<std::size_t>(std::count(around_w.begin(), around_w.end(), n.first));
  return common == 2;  // link condition for an interior edge
}

void ProgressiveMesh::erase_value(std::vector<std::uint32_t>& list, std::uint32_t value) {
  auto it = std::find(list.begin(), list.end(), value);
  if (it == list.end()) return;
  *it = list.back();
  list.pop_back();
}

void ProgressiveMesh::detach_face(std::uint32_t f, std::uint32_t except) {
  for (std::uint32_t c : faces_[f])
    if (c != except) erase_value(vertex_faces_[c], f);
}

void ProgressiveMesh::collapse(std::uint32_t vertex, std::uint32_t target) {
  VertexSplitRecord rec;
  rec.vertex = vertex;
  rec.target = target;
  for (std::uint32_t f : vertex_faces_[vertex]) {
    if (face_has(faces_[f], target)) {
      face_alive_[f] = 0;
      detach_face(f, vertex);
      rec.removed_faces.push_back(f);
      continue;
    }
    for (std::uint32_t i = 0; i < 3; ++i)
      if (faces_[f][i] == vertex) {
        faces_[f][i] = target;
        rec.moved_corners.push_back(3 * f + i);
      }
    vertex_faces_[target].push_back(f);
  }
  vertex_faces_[vertex].clear();
  if (!quadrics_.empty())
    for (std::size_t k = 0; k < quadrics_[target].size(); ++k) quadrics_[target][k] += quadrics_[vertex][k];
  vertex_alive_[vertex] = 0;
  --alive_vertices_;
  --alive_free_;
  records_.push_back(std::move(rec));
}

std::uint32_t ProgressiveMesh::split() {
  const VertexSplitRecord rec = std::move(records_.back());
  records_.pop_back();
  const std::uint32_t v = rec.vertex;
  for (std::uint32_t f : rec.removed_faces) {
    face_alive_[f] = 1;
    for (std::uint32_t c : faces_[f]) vertex_faces_[c].push_back(f);
  }
  for (std::uint32_t corner : rec.moved_corners) {
    const std::uint32_t f = corner / 3;
    faces_[f][corner % 3] = v;
    erase_value(vertex_faces_[rec.target], f);
    vertex_faces_[v].push_back(f);
  }
  vertex_alive_[v] = 1;
  ++alive_vertices_;
  ++alive_free_;
  return v;
}

std::vector<Face> ProgressiveMesh::alive_faces() const {
  std::vector<Face> out;
  for (std::size_t f = 0; f < faces_.size(); ++f)
    if (face_alive_[f]) out.push_back(faces_[f]);
  return out;
}

std::size_t ProgressiveMesh::simplify(std::size_t target_free, const CollapseFilter& filter,
                                      const ProgressCallback& progress, std::string_view stage) {
  init_quadrics();
  using Entry = std::tuple<double, std::uint32_t, std::uint32_t, std::uint32_t>;  // cost, vertex, target, stamp
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> queue;
  std::vector<std::uint32_t> stamp(mesh_.positions.size(), 0);
  std::vector<std::uint32_t> ring;
  auto push_best = [&](std::uint32_t v) {
    if (locked_[v] || !vertex_alive_[v]) return;
    neighbours(v, ring);
    double best = std::numeric_limits<double>::infinity();
    std::uint32_t best_w = v;
    for (std::uint32_t w : ring) {
      const double cost = collapse_cost(v, w);
      if (cost < best && can_collapse(v, w) && (!filter || filter(*this, v, w))) best = cost, best_w = w;
    }
    if (best_w != v) queue.emplace(best, v, best_w, stamp[v]);
  };
  for (std::uint32_t v = 0; v < mesh_.positions.size(); ++v) push_best(v);
  const std::size_t start_free = alive_free_;
  std::size_t done = 0;
  std::vector<std::uint32_t> affected;
  while (alive_free_ > target_free && !queue.empty()) {
    const auto [cost, v, w, s] = queue.top();
    queue.pop();
    if (s != stamp[v] || !vertex_alive_[v]) continue;
    if (!can_collapse(v, w) || (filter && !filter(*this, v, w))) {
      ++stamp[v];
      push_best(v);
      continue;
    }
    collapse(v, w);
    ++done;
    neighbours(w, affected);  // their links and their costs towards w (whose quadric grew) changed
    affected.push_back(w);
    for (std::uint32_t u : affected) {
      ++stamp[u];
      push_best(u);
    }
    if ((done & 1023u) == 0)
      report_progress(progress, stage,
                      static_cast<double>(done) / static_cast<double>(std::max<std::size_t>(1, start_free - target_free)));
  }
  report_progress(progress, stage, 1.0);
  return done;
}

}  // namespace gimforge
