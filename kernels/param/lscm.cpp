#include "kernels/param/lscm.h"

#include <cmath>
#include <string>

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include "kernels/core/errors.h"

namespace gimforge {

std::vector<Vec2> lscm_parametrization(MeshView mesh, std::span<const std::uint32_t> boundary) {
  const std::size_t n = mesh.positions.size();
  if (boundary.size() < 2) throw InvalidInput("lscm_parametrization: the boundary has fewer than 2 vertices");
  for (std::uint32_t v : boundary)
    if (v >= n) throw InvalidInput("lscm_parametrization: boundary vertex " + std::to_string(v) + " out of range");
  // Pins: a boundary vertex far from the first, then the boundary vertex farthest from that one.
  const auto farthest = [&](std::uint32_t from) {
    std::uint32_t best = from;
    double d = -1.0;
    for (std::uint32_t v : boundary)
      if (const double e = (mesh.positions[v] - mesh.positions[from]).squaredNorm(); e > d) d = e, best = v;
    return best;
  };
  const std::uint32_t p0 = farthest(boundary.front()), p1 = farthest(p0);
  if (p0 == p1) throw InvalidInput("lscm_parametrization: the boundary has no extent");
  const double span = (mesh.positions[p1] - mesh.positions[p0]).norm();
  // Unknowns: u, v of every vertex but the pins (2 per vertex, column 2i and 2i + 1).
  std::vector<int> column(n, -1);
  int unknowns = 0;
  for (std::size_t v = 0; v < n; ++v)
    if (v != p0 && v != p1) column[v] = unknowns, unknowns += 2;
  const Vec2 pin_uv[2] = {Vec2(0.0, 0.0), Vec2(span, 0.0)};
  std::vector<Eigen::Triplet<double>> triplets;
  std::vector<double> rhs;
  int row = 0;
  for (const Face& f : mesh.faces) {
    const Vec3 &a = mesh.positions[f[0]], &b = mesh.positions[f[1]], &c = mesh.positions[f[2]];
    const Vec3 e1 = b - a;
    const Vec3 normal = e1.cross(c - a);
    const double area2 = normal.norm();
    if (!(area2 > 0.0) || !(e1.norm() > 0.0)) continue;  // degenerate: no constraint
    const Vec3 x = e1.normalized(), y = normal.normalized().cross(x);
    const Vec2 z[3] = {Vec2(0.0, 0.0), Vec2(e1.norm(), 0.0), Vec2((c - a).dot(x), (c - a).dot(y))};
    const double w = 1.0 / std::sqrt(area2);
    double r_re = 0.0, r_im = 0.0;
    for (int k = 0; k < 3; ++k) {
      // W_k = z_{k+2} − z_{k+1} (complex); the row is Σ W_k U_k = 0 with U_k = u_k + i v_k.
      const Vec2 wk = (z[(k + 2) % 3] - z[(k + 1) % 3]) * w;
      const std::uint32_t v = f[static_cast<std::size_t>(k)];
      if (column[v] < 0) {
        const Vec2& p = pin_uv[v == p0 ? 0 : 1];
        r_re -= wk.x() * p.x() - wk.y() * p.y();
        r_im -= wk.y() * p.x() + wk.x() * p.y();
        continue;
      }
      triplets.emplace_back(row, column[v], wk.x());
      triplets.emplace_back(row, column[v] + 1, -wk.y());
      triplets.emplace_back(row + 1, column[v], wk.y());
      triplets.emplace_back(row + 1, column[v] + 1, wk.x());
    }
    rhs.push_back(r_re);
    rhs.push_back(r_im);
    row += 2;
  }
  Eigen::SparseMatrix<double> m(row, unknowns);
  m.setFromTriplets(triplets.begin(), triplets.end());
  const Eigen::VectorXd b = Eigen::Map<const Eigen::VectorXd>(rhs.data(), static_cast<Eigen::Index>(rhs.size()));
  Eigen::SparseMatrix<double> normal_matrix = m.transpose() * m;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(normal_matrix);
  if (solver.info() != Eigen::Success) throw NumericalError("lscm_parametrization: factorization failed");
  const Eigen::VectorXd x = solver.solve(m.transpose() * b);
  if (solver.info() != Eigen::Success || !x.allFinite()) throw NumericalError("lscm_parametrization: solve failed");
  std::vector<Vec2> uv(n, Vec2::Zero());
  for (std::size_t v = 0; v < n; ++v)
    uv[v] = column[v] < 0 ? pin_uv[v == p0 ? 0 : 1] : Vec2(x[column[v]], x[column[v] + 1]);
  // The conformal energy's minimizer keeps the orientation of the row convention; if it came out mirrored,
  // mirror it back.
  double signed_area = 0.0;
  for (const Face& f : mesh.faces) {
    const Vec2 e = uv[f[1]] - uv[f[0]], g = uv[f[2]] - uv[f[0]];
    signed_area += e.x() * g.y() - e.y() * g.x();
  }
  if (signed_area < 0.0)
    for (Vec2& p : uv) p.y() = -p.y();
  return uv;
}

}  // namespace gimforge
