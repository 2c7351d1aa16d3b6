#include "kernels/param/floater.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include <Eigen/Sparse>
#include <Eigen/SparseLU>

#include "kernels/core/errors.h"
#include "kernels/param/vertex_rings.h"

namespace gimforge {
namespace {

using Weights = FloaterOptions::Weights;

double cross2(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

/// tan(α/2) of the angle α between e1 and e2, computed stably as |e1×e2| / (|e1||e2| + e1·e2).
double half_angle_tan(const Vec3& e1, const Vec3& e2) {
  const double denom = e1.norm() * e2.norm() + e1.dot(e2);
  const double num = e1.cross(e2).norm();
  return denom > 1e-300 ? num / denom : 1e300;
}

/// Mean-value weights (Floater 2003) of centre x over its ordered ring (open or closed).
void mean_value_weights(MeshView mesh, std::uint32_t v, std::span<const std::uint32_t> ring, bool open,
                        std::vector<double>& w) {
  const std::size_t d = ring.size();
  const std::size_t wedges = open ? d - 1 : d;
  const Vec3& x = mesh.positions[v];
  w.assign(d, 0.0);
  for (std::size_t k = 0; k < wedges; ++k) {
    const std::size_t k1 = (k + 1) % d;
    const double t = half_angle_tan(mesh.positions[ring[k]] - x, mesh.positions[ring[k1]] - x);
    w[k] += t;
    w[k1] += t;
  }
  for (std::size_t k = 0; k < d; ++k) w[k] /= std::max((mesh.positions[ring[k]] - x).norm(), 1e-300);
}

/// The ring flattened by the local geodesic polar map: lengths kept, angles scaled to sum to 2π.
std::vector<Vec2> polar_map(MeshView mesh, std::uint32_t v, std::span<const std::uint32_t> ring) {
  const std::size_t d = ring.size();
  const Vec3& x = mesh.positions[v];
  std::vector<double> angle(d);
  double total = 0.0;
  for (std::size_t k = 0; k < d; ++k) {
    const Vec3 e1 = mesh.positions[ring[k]] - x, e2 = mesh.positions[ring[(k + 1) % d]] - x;
    angle[k] = std::atan2(e1.cross(e2).norm(), e1.dot(e2));
    total += angle[k];
  }
  std::vector<Vec2> p(d);
  double phi = 0.0;
  for (std::size_t k = 0; k < d; ++k) {
    const double r = (mesh.positions[ring[k]] - x).norm();
    p[k] = Vec2(r * std::cos(phi), r * std::sin(phi));
    phi += total > 0.0 ? 2.0 * std::numbers::pi * angle[k] / total : 2.0 * std::numbers::pi / static_cast<double>(d);
  }
  return p;
}

/// Shape-preserving weights (Floater 1997) of a closed ring: for each neighbour l, the barycentric
/// coordinates of the centre in the triangle (p_l, p_k, p_k+1) containing it, averaged over l.
void shape_preserving_weights(MeshView mesh, std::uint32_t v, std::span<const std::uint32_t> ring,
                              std::vector<double>& w) {
  const std::size_t d = ring.size();
  const std::vector<Vec2> p = polar_map(mesh, v, ring);
  w.assign(d, 0.0);
  for (std::size_t l = 0; l < d; ++l) {
    double best = -std::numeric_limits<double>::infinity();
    std::array<double, 3> mu{};
    std::size_t best_k = d;
    for (std::size_t k = 0; k < d; ++k) {
      const std::size_t k1 = (k + 1) % d;
      if (k == l || k1 == l) continue;
      const double det = cross2(p[k] - p[l], p[k1] - p[l]);
      if (std::abs(det) < 1e-300) continue;
      const std::array<double, 3> m{cross2(p[k], p[k1]) / det, cross2(p[k1], p[l]) / det, cross2(p[l], p[k]) / det};
      const double worst = std::min({m[0], m[1], m[2]});
      if (worst > best) best = worst, mu = m, best_k = k;
    }
    if (best_k == d) continue;
    w[l] += mu[0];
    w[best_k] += mu[1];
    w[(best_k + 1) % d] += mu[2];
  }
}

/// Convex weights of vertex v over its ring, normalized to sum 1. Open rings (free vertices on the mesh
/// boundary) get mean-value weights unless uniform ones were asked for.
void ring_weights(MeshView mesh, std::uint32_t v, std::span<const std::uint32_t> ring, bool open, Weights kind,
                  std::vector<double>& w) {
  if (kind == Weights::Uniform || ring.size() < 2)
    w.assign(ring.size(), 1.0);
  else if (kind == Weights::ShapePreserving && !open && ring.size() >= 3)
    shape_preserving_weights(mesh, v, ring, w);
  else
    mean_value_weights(mesh, v, ring, open, w);
  double sum = 0.0;
  for (double x : w) sum += x;
  if (!(sum > 0.0) || !std::isfinite(sum)) {
    w.assign(ring.size(), 1.0);
    sum = static_cast<double>(ring.size());
  }
  for (double& x : w) x /= sum;
}

void check_arguments(MeshView mesh, std::span<const std::uint32_t> fixed_vertices, std::span<const Vec2> fixed_uv) {
  if (fixed_vertices.size() != fixed_uv.size())
    throw InvalidInput("floater_parametrization: " + std::to_string(fixed_vertices.size()) + " fixed vertices but " +
                       std::to_string(fixed_uv.size()) + " fixed positions");
  if (fixed_vertices.size() < 3) throw InvalidInput("floater_parametrization: fewer than 3 fixed vertices");
  for (const Face& t : mesh.faces)
    for (std::uint32_t c : t)
      if (c >= mesh.positions.size()) throw InvalidInput("floater_parametrization: face index out of range");
}

}  // namespace

std::vector<Vec2> floater_parametrization(MeshView mesh, std::span<const std::uint32_t> fixed_vertices,
                                          std::span<const Vec2> fixed_uv, const FloaterOptions& options) {
  check_arguments(mesh, fixed_vertices, fixed_uv);
  const std::size_t n = mesh.positions.size();
  std::vector<Vec2> uv(n, Vec2::Zero());
  std::vector<std::int64_t> index(n, -1);  // unknown index of a free vertex; -2 for fixed
  for (std::size_t i = 0; i < fixed_vertices.size(); ++i) {
    const std::uint32_t v = fixed_vertices[i];
    if (v >= n || index[v] == -2)
      throw InvalidInput("floater_parametrization: fixed vertex " + std::to_string(v) + " out of range or repeated");
    index[v] = -2;
    uv[v] = fixed_uv[i];
  }
  const VertexRings rings = build_vertex_rings(mesh);
  std::vector<std::uint32_t> free_vertices;
  for (std::size_t v = 0; v < n; ++v)
    if (index[v] == -1 && !rings.ring(v).empty()) {
      index[v] = static_cast<std::int64_t>(free_vertices.size());
      free_vertices.push_back(static_cast<std::uint32_t>(v));
    }
  if (free_vertices.empty()) return uv;

  const auto m = static_cast<Eigen::Index>(free_vertices.size());
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(rings.neighbours.size() + free_vertices.size());
  Eigen::MatrixX2d rhs = Eigen::MatrixX2d::Zero(m, 2);
  std::vector<double> w;
  for (Eigen::Index row = 0; row < m; ++row) {
    const std::uint32_t v = free_vertices[static_cast<std::size_t>(row)];
    const auto ring = rings.ring(v);
    ring_weights(mesh, v, ring, rings.open[v] != 0, options.weights, w);
    triplets.emplace_back(row, row, 1.0);
    for (std::size_t k = 0; k < ring.size(); ++k) {
      if (index[ring[k]] >= 0)
        triplets.emplace_back(row, static_cast<Eigen::Index>(index[ring[k]]), -w[k]);
      else
        rhs.row(row) += w[k] * uv[ring[k]].transpose();
    }
  }
  Eigen::SparseMatrix<double> a(m, m);
  a.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SparseLU<Eigen::SparseMatrix<double>, Eigen::COLAMDOrdering<int>> solver;
  solver.compute(a);
  if (solver.info() != Eigen::Success)
    throw NumericalError("floater_parametrization: factorization failed (is every component anchored?)");
  const Eigen::MatrixX2d x = solver.solve(rhs);
  if (solver.info() != Eigen::Success || !x.allFinite())
    throw NumericalError("floater_parametrization: linear solve failed");
  for (Eigen::Index row = 0; row < m; ++row) uv[free_vertices[static_cast<std::size_t>(row)]] = x.row(row).transpose();
  return uv;
}

std::vector<Vec2> circle_boundary(MeshView mesh, std::span<const std::uint32_t> loop) {
  if (loop.size() < 3) throw InvalidInput("circle_boundary: the loop has fewer than 3 vertices");
  for (std::uint32_t v : loop)
    if (v >= mesh.positions.size()) throw InvalidInput("circle_boundary: vertex " + std::to_string(v) + " out of range");
  std::vector<double> arc(loop.size() + 1, 0.0);
  for (std::size_t i = 0; i < loop.size(); ++i)
    arc[i + 1] = arc[i] + (mesh.positions[loop[(i + 1) % loop.size()]] - mesh.positions[loop[i]]).norm();
  const double total = arc.back();
  std::vector<Vec2> uv(loop.size());
  for (std::size_t i = 0; i < loop.size(); ++i) {
    const double t = total > 0.0 ? arc[i] / total : static_cast<double>(i) / static_cast<double>(loop.size());
    const double phi = 2.0 * std::numbers::pi * t;
    uv[i] = Vec2(std::cos(phi), std::sin(phi));
  }
  return uv;
}

}  // namespace gimforge
