#pragma once
/// \file line_search.h
/// One-dimensional minimization shared by the vertex optimizers (planar and spherical stretch).
#include <cmath>
#include <utility>

namespace gimforge::detail {

/// Brent's minimization of f on [lo, hi] starting from x0 (f(x0) = f0 known); returns (x, f(x)).
template <class F>
std::pair<double, double> brent_minimize(F&& f, double lo, double hi, double x0, double f0, int max_iter) {
  constexpr double kGolden = 0.3819660112501051;
  double x = x0, w = x0, v = x0, fx = f0, fw = f0, fv = f0, d = 0.0, e = 0.0;
  const double tol_interval = 1e-5 * (hi - lo) + 1e-300;
  for (int it = 0; it < max_iter; ++it) {
    const double m = 0.5 * (lo + hi), tol = 1e-6 * std::abs(x) + tol_interval, tol2 = 2.0 * tol;
    if (std::abs(x - m) <= tol2 - 0.5 * (hi - lo)) break;
    bool golden = true;
    if (std::abs(e) > tol) {  // parabolic step through x, w, v
      const double r = (x - w) * (fx - fv), q0 = (x - v) * (fx - fw);
      double p = (x - v) * q0 - (x - w) * r, q = 2.0 * (q0 - r);
      if (q > 0.0) p = -p;
      q = std::abs(q);
      if (std::isfinite(p) && std::abs(p) < std::abs(0.5 * q * e) && p > q * (lo - x) && p < q * (hi - x)) {
        e = d;
        d = p / q;
        golden = false;
        if ((x + d) - lo < tol2 || hi - (x + d) < tol2) d = x < m ? tol : -tol;
      }
    }
    if (golden) {
      e = (x >= m ? lo : hi) - x;
      d = kGolden * e;
    }
    const double u = std::abs(d) >= tol ? x + d : x + (d > 0.0 ? tol : -tol);
    const double fu = f(u);
    if (fu <= fx) {
      (u >= x ? lo : hi) = x;
      v = w, fv = fw, w = x, fw = fx, x = u, fx = fu;
    } else {
      (u < x ? lo : hi) = u;
      if (fu <= fw || w == x) {
        v = w, fv = fw, w = u, fw = fu;
      } else if (fu <= fv || v == x || v == w) {
        v = u, fv = fu;
      }
    }
  }
  return {x, fx};
}

}  // namespace gimforge::detail
