#include "kernels/core/surface_fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>
#include <limits>
#include <optional>
#include <utility>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "kernels/core/errors.h"
#include "kernels/core/surface_fit_detail.h"
#include "kernels/core/surface_sampling.h"

namespace gimforge {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// x^n for a small non-negative integer n (exact repeated products, faster than std::pow).
double int_pow(double x, int n) {
  double r = 1.0;
  for (int i = 0; i < n; ++i) r *= x;
  return r;
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------
// The energy terms (surface_fit_detail.h)

namespace detail {

EdgeSet build_edges(std::span<const Face> faces) {
  // Half-edges keyed by their vertex pair, sorted so that the faces of an edge are adjacent.
  std::vector<std::pair<std::uint64_t, std::uint64_t>> half;  // (edge key, 3 * face + local edge)
  half.reserve(3 * faces.size());
  for (std::size_t f = 0; f < faces.size(); ++f) {
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint32_t a = faces[f][k], b = faces[f][(k + 1) % 3];
      half.emplace_back((std::uint64_t{std::min(a, b)} << 32) | std::max(a, b), 3 * f + k);
    }
  }
  std::sort(half.begin(), half.end());
  EdgeSet out;
  out.edges.reserve(half.size() / 2 + 1);
  out.dihedral.reserve(half.size() / 2 + 1);
  for (std::size_t i = 0; i < half.size();) {
    std::size_t j = i + 1;
    while (j < half.size() && half[j].first == half[i].first) ++j;
    out.edges.emplace_back(static_cast<std::uint32_t>(half[i].first >> 32),
                           static_cast<std::uint32_t>(half[i].first & 0xffffffffu));
    if (j - i == 2) {
      const Face& t1 = faces[half[i].second / 3];
      const Face& t2 = faces[half[i + 1].second / 3];
      const std::size_t k1 = half[i].second % 3, k2 = half[i + 1].second % 3;
      const DihedralEdge e{t1[k1], t1[(k1 + 1) % 3], t1[(k1 + 2) % 3], t2[(k2 + 2) % 3]};
      if (e.c != e.d) out.dihedral.push_back(e);
    }
    i = j;
  }
  return out;
}

double dihedral_energy(std::span<const Vec3> positions, std::span<const DihedralEdge> edges, int exponent,
                       std::span<Vec3> gradient, double gradient_scale) {
  constexpr double kMinRelativeHeight = 1e-2;  // surface_fit_detail.h
  double sum = 0.0;
  for (const DihedralEdge& e : edges) {
    const Vec3& xa = positions[e.a];
    const Vec3& xb = positions[e.b];
    const Vec3& xc = positions[e.c];
    const Vec3& xd = positions[e.d];
    const Vec3 edge = xb - xa;
    // Area-weighted normals of (a, b, c) and (b, a, d): |n| = |edge| · height.
    const Vec3 n1 = edge.cross(xc - xa);
    const Vec3 n2 = (xd - xb).cross(edge);
    const double len2 = edge.squaredNorm();
    const double n1sq = n1.squaredNorm(), n2sq = n2.squaredNorm();
    const double floor = kMinRelativeHeight * kMinRelativeHeight * len2 * len2;
    if (!(len2 > 0.0) || !(n1sq > floor) || !(n2sq > floor)) continue;
    const double len = std::sqrt(len2);
    // Signed angle between the normals, with the sign convention of Bridson et al., whose gradient follows.
    const double theta = std::atan2(n2.cross(n1).dot(edge) / len, n1.dot(n2));
    const double magnitude = std::abs(theta);
    sum += int_pow(magnitude, exponent);
    if (gradient.empty() || theta == 0.0) continue;
    const double sign = theta > 0.0 ? 1.0 : -1.0;
    const double coef = gradient_scale * exponent * int_pow(magnitude, exponent - 1) * sign;
    const Vec3 m1 = n1 / n1sq, m2 = n2 / n2sq;
    gradient[e.c] += (coef * len) * m1;
    gradient[e.d] += (coef * len) * m2;
    gradient[e.a] += coef * ((xc - xb).dot(edge) / len * m1 + (xd - xb).dot(edge) / len * m2);
    gradient[e.b] -= coef * ((xc - xa).dot(edge) / len * m1 + (xd - xa).dot(edge) / len * m2);
  }
  return sum;
}

double fit_energy(const EmbreeDevice& device, std::span<const Vec3> samples, MeshView remesh,
                  std::span<Vec3> gradient, std::span<std::uint32_t> hints) {
  const TriangleBvh bvh(device, remesh);
  const std::size_t n = samples.size();
  if (n == 0) return 0.0;
  const std::size_t nf = remesh.faces.size();
  std::vector<ClosestPoint> answers(n);
  // Fixed blocks summed in order: the result does not depend on the thread count.
  constexpr std::size_t kBlock = 1024;
  const std::size_t blocks = (n + kBlock - 1) / kBlock;
  std::vector<double> partial(blocks, 0.0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks, 1), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t blk = range.begin(); blk < range.end(); ++blk) {
      const std::size_t first = blk * kBlock, last = std::min(n, first + kBlock);
      double sum = 0.0;
      std::uint32_t previous = kNoFace;
      for (std::size_t i = first; i < last; ++i) {
        // The sample's last face (or the previous sample's answer) bounds the search from above.
        std::uint32_t hint = hints.empty() ? previous : hints[i];
        if (hint >= nf) hint = previous;
        ClosestPoint cp = bvh.closest_point(samples[i], hint < nf ? bvh.distance_to_face(samples[i], hint) : kInf);
        if (!cp.found() && hint < nf) cp = bvh.closest_point(samples[i]);  // the bound was rounded too tight
        if (!cp.found()) {
          sum = kInf;
          continue;
        }
        previous = cp.face;
        if (!hints.empty()) hints[i] = cp.face;
        sum += (samples[i] - cp.point).squaredNorm();
        answers[i] = cp;
      }
      partial[blk] = sum;
    }
  });
  double total = 0.0;
  for (double s : partial) total += s;
  if (!std::isfinite(total)) return kInf;
  if (!gradient.empty()) {
    const double coef = -2.0 / static_cast<double>(n);
    for (std::size_t i = 0; i < n; ++i) {
      const Face& t = remesh.faces[answers[i].face];
      const Vec3 r = samples[i] - answers[i].point;
      for (int k = 0; k < 3; ++k) gradient[t[static_cast<std::size_t>(k)]] += (coef * answers[i].barycentric[k]) * r;
    }
  }
  return total / static_cast<double>(n);
}

}  // namespace detail

// ---------------------------------------------------------------------------------------------------------
// The optimization

namespace {

/// E and its gradient at one set of positions.
struct Evaluation {
  double fit{kInf};
  double smooth{0.0};
  double total{kInf};
  std::vector<Vec3> gradient;
  std::vector<Face> faces;  ///< the triangulation it was measured on
};

/// The energy of §4.6 for one fit: the reference samples, the triangulator and the per-sample hints.
class FitProblem {
 public:
  FitProblem(const EmbreeDevice& device, std::span<const Vec3> samples, const Triangulator& triangulate,
             std::span<const char> locked, int exponent)
      : device_(device),
        samples_(samples),
        triangulate_(triangulate),
        locked_(locked),
        exponent_(exponent),
        hints_(samples_.size(), kNoFace) {}

  /// Re-chooses the triangulation for `x` (faces repeating a vertex dropped); the edges are recomputed
  /// only when the faces changed. Throws InvalidInput for an index out of range or no usable face.
  void triangulate(std::span<const Vec3> x) {
    std::vector<Face> faces = triangulate_(x);
    std::size_t kept = 0;
    for (std::size_t f = 0; f < faces.size(); ++f) {
      for (std::uint32_t v : faces[f])
        if (v >= x.size())
          throw InvalidInput(fmt::format(
              "fit_surface: face {} of the triangulation references vertex {} (only {} vertices)", f, v, x.size()));
      if (!has_repeated_index(faces[f])) faces[kept++] = faces[f];
    }
    faces.resize(kept);
    if (faces.empty()) throw InvalidInput("fit_surface: the triangulation has no face with three distinct vertices");
    if (faces != faces_) {
      faces_ = std::move(faces);
      edges_ = detail::build_edges(faces_);
    }
  }

  [[nodiscard]] const detail::EdgeSet& edges() const { return edges_; }
  void set_smoothness_weight(double weight) { weight_ = weight; }

  /// E(x) = fit + weight · Σ|θ|^p and its gradient (zero at locked vertices); total = +∞ when not finite.
  Evaluation evaluate(std::span<const Vec3> x) {
    triangulate(x);
    Evaluation e;
    e.gradient.assign(x.size(), Vec3::Zero());
    e.fit = detail::fit_energy(device_, samples_, MeshView(x, faces_), e.gradient, hints_);
    if (weight_ > 0.0)
      e.smooth = weight_ * detail::dihedral_energy(x, edges_.dihedral, exponent_, e.gradient, weight_);
    e.total = e.fit + e.smooth;
    if (!std::isfinite(e.total)) e.total = kInf;
    e.faces = faces_;
    if (!locked_.empty())
      for (std::size_t v = 0; v < x.size(); ++v)
        if (locked_[v] != 0) e.gradient[v].setZero();
    return e;
  }

 private:
  const EmbreeDevice& device_;
  std::span<const Vec3> samples_;  ///< the caller's: not copied (a huge image's samples are gigabytes)
  const Triangulator& triangulate_;
  std::span<const char> locked_;
  int exponent_;
  double weight_{0.0};
  std::vector<std::uint32_t> hints_;
  std::vector<Face> faces_;
  detail::EdgeSet edges_;
};

/// Positions x + alpha·d and E there.
struct Trial {
  std::vector<Vec3> x;
  Evaluation eval;
  double alpha{0.0};
};

Trial try_step(FitProblem& problem, std::span<const Vec3> x, std::span<const Vec3> d, double alpha) {
  Trial t;
  t.alpha = alpha;
  t.x.resize(x.size());
  for (std::size_t v = 0; v < x.size(); ++v) t.x[v] = x[v] + alpha * d[v];
  t.eval = problem.evaluate(t.x);
  return t;
}

double dot(std::span<const Vec3> a, std::span<const Vec3> b) {
  double s = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) s += a[i].dot(b[i]);
  return s;
}

double max_norm(std::span<const Vec3> a) {
  double m = 0.0;
  for (const Vec3& v : a) m = std::max(m, v.squaredNorm());
  return std::sqrt(m);
}

/// The face rotated so that its smallest index comes first (same orientation).
Face canonical(const Face& f) {
  const std::size_t k = f[0] < f[1] ? (f[0] < f[2] ? 0 : 2) : (f[1] < f[2] ? 1 : 2);
  return {f[k], f[(k + 1) % 3], f[(k + 2) % 3]};
}

/// The vertices of the faces that are in one triangulation and not in the other (e.g. of the quads whose
/// diagonal flipped), whatever order the faces come in.
std::vector<std::uint32_t> changed_vertices(std::span<const Face> a, std::span<const Face> b) {
  auto sorted = [](std::span<const Face> faces) {
    std::vector<Face> out(faces.size());
    std::transform(faces.begin(), faces.end(), out.begin(), canonical);
    std::sort(out.begin(), out.end());
    return out;
  };
  const std::vector<Face> sa = sorted(a), sb = sorted(b);
  std::vector<Face> differ;
  std::set_symmetric_difference(sa.begin(), sa.end(), sb.begin(), sb.end(), std::back_inserter(differ));
  std::vector<std::uint32_t> vertices;
  for (const Face& f : differ) vertices.insert(vertices.end(), f.begin(), f.end());
  return vertices;
}

/// The outcome of a line search: the lowest trial (nothing when no step satisfied the Armijo condition)
/// and the direction it was taken along.
struct Search {
  std::optional<Trial> trial;
  std::vector<Vec3> direction;
};

/// Line search from x (energy and gradient `current`) along the descent direction d, first trying step
/// `alpha`. The energy jumps where the triangulation changes: when the first trial fails the Armijo
/// condition on another triangulation, the vertices of the faces that changed are held for this step (their
/// components of d zeroed, up to kFreezes times), so that one quad at its flipping point cannot stall every
/// other vertex. Then, while the Armijo condition fails, the step shrinks to the minimizer of the quadratic
/// through E, the slope and the last trial (clamped to [0.1, 0.5] of it); when the first trial succeeds, the
/// step expands (to that minimizer, at most 4 times the step) while E keeps falling.
Search line_search(FitProblem& problem, std::span<const Vec3> x, const Evaluation& current,
                   std::vector<Vec3> d, double alpha) {
  constexpr double kArmijo = 1e-4;
  constexpr int kFreezes = 3, kBacktracks = 12, kExpansions = 4;
  const double energy = current.total;
  double slope = dot(current.gradient, d);
  auto armijo = [&](const Trial& t) { return t.eval.total <= energy + kArmijo * t.alpha * slope; };
  auto quadratic_minimizer = [&](double a, double e) {
    const double curvature = e - energy - slope * a;
    return curvature > 0.0 ? -slope * a * a / (2.0 * curvature) : kInf;
  };
  Search out;
  Trial t = try_step(problem, x, d, alpha);
  for (int k = 0; k < kFreezes && !armijo(t) && t.eval.faces != current.faces; ++k) {
    const std::vector<std::uint32_t> changed = changed_vertices(current.faces, t.eval.faces);
    if (changed.empty()) break;
    for (std::uint32_t v : changed) d[v].setZero();
    slope = dot(current.gradient, d);
    if (!(slope < 0.0)) return out;
    t = try_step(problem, x, d, alpha);
  }
  int backtracks = 0;
  while (!armijo(t)) {
    if (++backtracks > kBacktracks) return out;
    const double q = std::isfinite(t.eval.total) ? quadratic_minimizer(t.alpha, t.eval.total) : 0.1 * t.alpha;
    t = try_step(problem, x, d, std::clamp(q, 0.1 * t.alpha, 0.5 * t.alpha));
  }
  if (backtracks == 0) {
    for (int k = 0; k < kExpansions; ++k) {
      const double q = quadratic_minimizer(t.alpha, t.eval.total);
      if (!(q > 1.5 * t.alpha)) break;
      Trial u = try_step(problem, x, d, std::min(q, 4.0 * t.alpha));
      if (!(u.eval.total < t.eval.total)) break;
      t = std::move(u);
    }
  }
  out.trial = std::move(t);
  out.direction = std::move(d);
  return out;
}

void validate(const FitReference& reference, std::span<const Vec3> positions, std::span<const char> locked,
              const SurfaceFitOptions& options) {
  if (positions.empty()) throw InvalidInput("fit_surface: the remesh has no vertices");
  for (std::size_t v = 0; v < positions.size(); ++v)
    if (!positions[v].allFinite())
      throw InvalidInput(fmt::format("fit_surface: remesh vertex {} is not finite", v));
  if (!locked.empty() && locked.size() != positions.size())
    throw InvalidInput(fmt::format("fit_surface: {} lock flags for {} vertices (need none or one per vertex)",
                                   locked.size(), positions.size()));
  for (std::size_t i = 0; i < reference.points.size(); ++i)
    if (!reference.points[i].allFinite())
      throw InvalidInput(fmt::format("fit_surface: reference sample {} is not finite", i));
  const MeshView mesh = reference.mesh;
  if (reference.points.empty() && (mesh.positions.empty() || mesh.faces.empty()))
    throw InvalidInput("fit_surface: the reference mesh is empty");
  for (std::size_t v = 0; v < mesh.positions.size(); ++v)
    if (!mesh.positions[v].allFinite())
      throw InvalidInput(fmt::format("fit_surface: reference vertex {} is not finite", v));
  for (std::size_t f = 0; f < mesh.faces.size(); ++f)
    for (std::uint32_t v : mesh.faces[f])
      if (v >= mesh.positions.size())
        throw InvalidInput(fmt::format("fit_surface: reference face {} references vertex {} (only {} vertices)", f, v,
                                       mesh.positions.size()));
  if (!(options.smoothness >= 0.0) || !std::isfinite(options.smoothness))
    throw InvalidInput(fmt::format("fit_surface: smoothness must be finite and >= 0 (got {})", options.smoothness));
  if (options.exponent < 1 || options.exponent > 16)
    throw InvalidInput(fmt::format("fit_surface: exponent must be in [1, 16] (got {})", options.exponent));
  if (options.iterations < 0)
    throw InvalidInput(fmt::format("fit_surface: iterations must be >= 0 (got {})", options.iterations));
  if (!(options.tolerance >= 0.0) || !std::isfinite(options.tolerance))
    throw InvalidInput(fmt::format("fit_surface: tolerance must be finite and >= 0 (got {})", options.tolerance));
}

}  // namespace

SurfaceFitResult fit_surface(const EmbreeDevice& device, const FitReference& reference, std::vector<Vec3> positions,
                             const Triangulator& triangulate, std::span<const char> locked,
                             const SurfaceFitOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  validate(reference, positions, locked, options);
  report_progress(options.progress, "optimize", 0.0);

  std::vector<Vec3> drawn;
  if (reference.points.empty())
    drawn = sample_surface(reference.mesh, {std::max(options.reference_samples, 4 * positions.size()), options.seed}).points;
  const std::span<const Vec3> samples = reference.points.empty() ? std::span<const Vec3>(drawn) : reference.points;
  BoundingBox reference_box;
  for (const Vec3& p : samples) reference_box.extend(p);
  FitProblem problem(device, samples, triangulate, locked, options.exponent);

  // Scales fixed from the input: the mean (squared) edge length and the number of dihedral edges.
  problem.triangulate(positions);
  double sum_len = 0.0, sum_len2 = 0.0;
  for (const auto& [a, b] : problem.edges().edges) {
    const double l2 = (positions[a] - positions[b]).squaredNorm();
    sum_len += std::sqrt(l2);
    sum_len2 += l2;
  }
  const double n_edges = static_cast<double>(problem.edges().edges.size());
  const double n_dihedral = static_cast<double>(problem.edges().dihedral.size());
  const double mean_len = sum_len / n_edges;
  if (n_dihedral > 0.0) problem.set_smoothness_weight(options.smoothness * (sum_len2 / n_edges) / n_dihedral);
  // Largest vertex displacement of the first trial step: 10% of an edge (or of the reference's size).
  const double step_cap = mean_len > 0.0 ? mean_len : 1e-2 * reference_box.diagonal();
  double step = 0.1 * step_cap;

  Evaluation current = problem.evaluate(positions);
  if (!std::isfinite(current.total))
    throw InvalidInput("fit_surface: the energy of the input remesh is not finite");
  SurfaceFitResult result;
  result.energy_before = current.total;
  result.fit_before = current.fit;

  std::vector<Vec3> direction(positions.size());
  for (std::size_t v = 0; v < positions.size(); ++v) direction[v] = -current.gradient[v];
  int since_restart = 0;
  for (int it = 0; it < options.iterations; ++it) {
    report_progress(options.progress, "optimize", static_cast<double>(it) / options.iterations);
    const double g2 = dot(current.gradient, current.gradient);
    if (!(g2 > 0.0)) break;
    bool steepest = since_restart == 0;
    if (!(dot(current.gradient, direction) < 0.0)) {  // not a descent direction: restart
      for (std::size_t v = 0; v < positions.size(); ++v) direction[v] = -current.gradient[v];
      steepest = true;
      since_restart = 0;
    }
    const double reach = max_norm(direction);
    if (!(reach > 0.0)) break;
    result.iterations = it + 1;
    Search search = line_search(problem, positions, current, direction, step / reach);
    if (!search.trial) {
      if (steepest) break;  // no progress even downhill: converged
      for (std::size_t v = 0; v < positions.size(); ++v) direction[v] = -current.gradient[v];
      since_restart = 0;
      continue;
    }
    std::optional<Trial>& trial = search.trial;
    direction = std::move(search.direction);
    step = std::clamp(trial->alpha * reach, 1e-12 * step_cap, step_cap);
    const double decrease = (current.total - trial->eval.total) / current.total;
    // Polak–Ribière+ with a restart every kRestart iterations.
    constexpr int kRestart = 20;
    double beta = 0.0;
    if (++since_restart < kRestart) {
      double num = 0.0;
      for (std::size_t v = 0; v < positions.size(); ++v)
        num += trial->eval.gradient[v].dot(trial->eval.gradient[v] - current.gradient[v]);
      beta = std::max(0.0, num / g2);
    } else {
      since_restart = 0;
    }
    positions = std::move(trial->x);
    current = std::move(trial->eval);
    if (!(decrease >= options.tolerance)) {
      if (steepest) break;  // stalled even downhill: converged
      beta = 0.0;           // stalled along a conjugate direction: one more try downhill
      since_restart = 0;
    }
    for (std::size_t v = 0; v < positions.size(); ++v) direction[v] = -current.gradient[v] + beta * direction[v];
  }
  report_progress(options.progress, "optimize", 1.0);

  result.positions = std::move(positions);
  result.energy_after = current.total;
  result.fit_after = current.fit;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace gimforge
