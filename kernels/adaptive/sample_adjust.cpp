#include "kernels/adaptive/sample_adjust.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <tuple>

#include <fmt/format.h>

#include "kernels/adaptive/point_triangle.h"
#include "kernels/adaptive/strip_sampling.h"
#include "kernels/core/errors.h"

namespace gimforge {

struct ParametrizedSurface::Impl {
  MeshView surface;
  std::vector<Vec2> uv;
  std::vector<Vec3> flat;
  TriangleBvh bvh;
  Impl(const EmbreeDevice& device, MeshView s, std::span<const Vec2> u)
      : surface(s), uv(u.begin(), u.end()), flat(make_flat(u)), bvh(device, MeshView(flat, s.faces)) {}
  static std::vector<Vec3> make_flat(std::span<const Vec2> u) {
    std::vector<Vec3> out(u.size());
    for (std::size_t i = 0; i < u.size(); ++i) out[i] = Vec3(u[i].x(), u[i].y(), 0.0);
    return out;
  }
};

ParametrizedSurface::ParametrizedSurface(const EmbreeDevice& device, MeshView surface, std::span<const Vec2> uv) {
  if (uv.size() != surface.positions.size())
    throw InvalidInput(fmt::format("parametrized surface: {} parameter points for {} vertices", uv.size(),
                                   surface.positions.size()));
  impl_ = std::make_unique<Impl>(device, surface, uv);
}
ParametrizedSurface::~ParametrizedSurface() = default;

ParametrizedSurface::Point ParametrizedSurface::at(const Vec2& p) const {
  const Impl& m = *impl_;
  const ClosestPoint cp = m.bvh.closest_point(Vec3(p.x(), p.y(), 0.0));
  if (!cp.found()) throw NumericalError(fmt::format("parameter point ({}, {}) is not on the surface", p.x(), p.y()));
  const Face& f = m.surface.faces[cp.face];
  Point out;
  out.face = cp.face;
  for (int k = 0; k < 3; ++k) out.position += cp.barycentric[k] * m.surface.positions[f[static_cast<std::size_t>(k)]];
  Eigen::Matrix<double, 3, 2> dx;
  dx.col(0) = m.surface.positions[f[1]] - m.surface.positions[f[0]];
  dx.col(1) = m.surface.positions[f[2]] - m.surface.positions[f[0]];
  Eigen::Matrix2d du;
  du.col(0) = m.uv[f[1]] - m.uv[f[0]];
  du.col(1) = m.uv[f[2]] - m.uv[f[0]];
  const double det = du.determinant();
  if (std::abs(det) > 1e-300) out.jacobian = dx * du.inverse();
  return out;
}

namespace {

double triangle_area(const Vec3& a, const Vec3& b, const Vec3& c) { return 0.5 * (b - a).cross(c - a).norm(); }

/// Whether reconstruction triangle t lies in the ROI (its samples' centroid).
bool triangle_in(const LocalHausdorff& field, const RoiMask& roi, std::uint32_t t) {
  const Face tri = field.triangle(t);
  const std::vector<Vec2>& uv = field.sample_uv();
  return roi.contains((uv[tri[0]] + uv[tri[1]] + uv[tri[2]]) / 3.0);
}

}  // namespace

std::pair<RegionFigures, RegionFigures> region_figures(const LocalHausdorff& field, std::span<const Vec2> uv,
                                                       const RoiMask& roi) {
  // Per part (0 inside, 1 outside) and direction: max, Σ area·mean², Σ area.
  std::array<std::array<double, 3>, 4> acc{};
  const MeshView original = field.original();
  for (std::uint32_t f = 0; f < field.faces(Direction::OriginalToGrid); ++f) {
    const Face& o = original.faces[f];
    const std::size_t part = roi.contains((uv[o[0]] + uv[o[1]] + uv[o[2]]) / 3.0) ? 0 : 1;
    const FaceDistance& d = field.face(Direction::OriginalToGrid, f);
    const double area = triangle_area(original.positions[o[0]], original.positions[o[1]], original.positions[o[2]]);
    acc[2 * part][0] = std::max(acc[2 * part][0], d.distance);
    acc[2 * part][1] += area * d.mean_squared;
    acc[2 * part][2] += area;
  }
  const std::vector<Vec3>& pos = field.sample_pos();
  for (std::uint32_t t = 0; t < field.faces(Direction::GridToOriginal); ++t) {
    const Face tri = field.triangle(t);
    const std::size_t part = triangle_in(field, roi, t) ? 0 : 1;
    const FaceDistance& d = field.face(Direction::GridToOriginal, t);
    const double area = triangle_area(pos[tri[0]], pos[tri[1]], pos[tri[2]]);
    acc[2 * part + 1][0] = std::max(acc[2 * part + 1][0], d.distance);
    acc[2 * part + 1][1] += area * d.mean_squared;
    acc[2 * part + 1][2] += area;
  }
  const auto rms = [](const std::array<double, 3>& a) { return a[2] > 0.0 ? std::sqrt(a[1] / a[2]) : 0.0; };
  const RegionFigures inside{acc[0][0], rms(acc[0]), acc[1][0], rms(acc[1])};
  const RegionFigures outside{acc[2][0], rms(acc[2]), acc[3][0], rms(acc[3])};
  return {inside, outside};
}

namespace {

class Adjuster {
 public:
  Adjuster(const EmbreeDevice& device, MeshView surface, std::span<const Vec2> uv, std::uint32_t n,
           std::vector<Vec2> sample_uv, std::vector<Vec3> sample_pos, const AdaptOptions& options)
      : surface_(surface), uv_(uv), n_(n), options_(options), param_(device, surface, uv),
        field_(device, surface, uv, n, std::move(sample_uv), std::move(sample_pos), options.measure) {
    failed_at_[0].assign(field_.faces(Direction::OriginalToGrid), -1.0);
    failed_at_[1].assign(field_.faces(Direction::GridToOriginal), -1.0);
  }

  AdaptResult run() {
    const auto start = std::chrono::steady_clock::now();
    AdaptResult result;
    field_.verify(0.0);
    result.history.push_back(figures(0));
    for (std::uint32_t r = 1; r <= options_.rounds; ++r) {
      report_progress(options_.progress, "adapt", static_cast<double>(r - 1) / options_.rounds);
      AdaptRound round = one_round(r);
      const AdaptRound f = figures(r);
      round.max_d1 = f.max_d1, round.max_d2 = f.max_d2, round.rms_d1 = f.rms_d1, round.rms_d2 = f.rms_d2;
      round.roi = f.roi, round.outside = f.outside;
      const AdaptRound last = result.history.back();  // a copy: push_back may move the history
      result.history.push_back(round);
      if (round.moves == 0) break;
      // Moves that only trade small errors between neighbours: stop when a round lowered neither the
      // largest distance nor the RMS by a thousandth.
      // In ROI mode: the ROI's directed distance, the objective.
      const bool roi = options_.roi != nullptr;
      const auto largest = [roi](const AdaptRound& a) { return roi ? a.roi.max_d2 : std::max(a.max_d1, a.max_d2); };
      const auto rms = [roi](const AdaptRound& a) {
        return roi ? a.roi.rms_d2 * a.roi.rms_d2 : a.rms_d1 * a.rms_d1 + a.rms_d2 * a.rms_d2;
      };
      if (largest(round) > (1.0 - 1e-3) * largest(last) && rms(round) > (1.0 - 2e-3) * rms(last)) break;
    }
    report_progress(options_.progress, "adapt", 1.0);
    result.sample_uv = field_.sample_uv();
    result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
  }

 private:
  AdaptRound figures(std::uint32_t round) const {
    AdaptRound a;
    a.round = round;
    const DirectedSummary s1 = field_.summary(Direction::OriginalToGrid);
    const DirectedSummary s2 = field_.summary(Direction::GridToOriginal);
    a.max_d1 = s1.max, a.rms_d1 = s1.rms, a.max_d2 = s2.max, a.rms_d2 = s2.rms;
    if (options_.roi != nullptr) std::tie(a.roi, a.outside) = region_figures(field_, uv_, *options_.roi);
    return a;
  }

  static constexpr std::uint32_t kNoSample = std::numeric_limits<std::uint32_t>::max();

  /// The side (0 bottom, 1 right, 2 top, 3 left; −1 for a corner or an interior sample) of a boundary
  /// sample and its perimeter coordinate now (sides, counter-clockwise from (0, 0)).
  [[nodiscard]] std::pair<int, double> perimeter_of(std::uint32_t s) const {
    const std::uint32_t i = s % n_, j = s / n_, last = n_ - 1;
    const Vec2& p = field_.sample_uv()[s];
    const bool corner = (i == 0 || i == last) && (j == 0 || j == last);
    if (corner || interior(s)) return {-1, 0.0};
    if (j == 0) return {0, p.x()};
    if (i == last) return {1, 1.0 + p.y()};
    if (j == last) return {2, 2.0 + (1.0 - p.x())};
    return {3, 3.0 + (1.0 - p.y())};
  }
  /// The perimeter coordinate of a boundary pixel on the uniform grid.
  [[nodiscard]] double uniform_coordinate(std::uint32_t s) const {
    const std::uint32_t i = s % n_, j = s / n_, last = n_ - 1;
    const double h = 1.0 / last;
    if (j == 0) return i * h;
    if (i == last) return 1.0 + j * h;
    if (j == last) return 2.0 + (last - i) * h;
    return 3.0 + (last - j) * h;
  }
  /// The two neighbours of a boundary sample along its side.
  [[nodiscard]] std::array<std::uint32_t, 2> along_side(std::uint32_t s) const {
    const std::uint32_t j = s / n_;
    if (j == 0 || j == n_ - 1) return {s - 1, s + 1};
    return {s - n_, s + n_};
  }
  /// The boundary pixel whose uniform perimeter position is nearest to coordinate c: a glued partner keeps
  /// its pixel (the sideband glues by index) wherever it slides.
  [[nodiscard]] std::uint32_t pixel_at(double c) const {
    c = std::fmod(c, 4.0);
    if (c < 0.0) c += 4.0;
    const auto g = static_cast<std::uint32_t>(std::lround(c * (n_ - 1))) % (4 * (n_ - 1));
    const std::uint32_t side = g / (n_ - 1), k = g % (n_ - 1), last = n_ - 1;
    switch (side) {
      case 0: return k;
      case 1: return k * n_ + last;
      case 2: return last * n_ + (last - k);
      default: return (last - k) * n_;
    }
  }
  [[nodiscard]] bool interior(std::uint32_t s) const {
    const std::uint32_t i = s % n_, j = s / n_;
    return i > 0 && j > 0 && i + 1 < n_ && j + 1 < n_;
  }

  AdaptRound one_round(std::uint32_t r) {
    AdaptRound round;
    round.round = r;
    field_.verify(options_.target_fraction * std::max(field_.summary(Direction::OriginalToGrid).max,
                                                      field_.summary(Direction::GridToOriginal).max));
    global_largest_ = std::max(field_.summary(Direction::OriginalToGrid).max, field_.summary(Direction::GridToOriginal).max);
    std::vector<std::tuple<double, Direction, std::uint32_t>> targets;
    double largest = 0.0;
    if (options_.roi != nullptr) {
      // ROI mode: the reconstruction triangles of the ROI (D2).
      for (std::uint32_t t = 0; t < field_.faces(Direction::GridToOriginal); ++t)
        if (triangle_in(field_, *options_.roi, t)) {
          const double dist = field_.face(Direction::GridToOriginal, t).distance;
          largest = std::max(largest, dist);
          targets.emplace_back(dist, Direction::GridToOriginal, t);
        }
    } else {
      largest = std::max(field_.summary(Direction::OriginalToGrid).max, field_.summary(Direction::GridToOriginal).max);
      for (Direction d : {Direction::OriginalToGrid, Direction::GridToOriginal})
        for (std::uint32_t f = 0; f < field_.faces(d); ++f) targets.emplace_back(field_.face(d, f).distance, d, f);
    }
    roi_largest_ = largest;
    const double threshold = options_.target_fraction * largest;
    std::erase_if(targets, [&](const auto& t) { return !(std::get<0>(t) >= threshold && std::get<0>(t) > 0.0); });
    std::sort(targets.begin(), targets.end(), [](const auto& a, const auto& b) { return std::get<0>(a) > std::get<0>(b); });
    for (std::size_t k = 0; k < targets.size(); ++k) {
      if (k % 256 == 255)
        report_progress(options_.progress, "adapt",
                        (r - 1 + static_cast<double>(k) / static_cast<double>(targets.size())) / options_.rounds);
      const auto [d0, d, f] = targets[k];
      const double now = field_.face(d, f).distance;
      if (now < threshold) continue;  // an earlier move fixed it
      // A face whose move failed is tried again only once its distance has changed (a move nearby).
      double& failed = failed_at_[d == Direction::OriginalToGrid ? 0 : 1][f];
      if (failed == now) continue;
      ++round.targets;
      if (improve(d, f, round.folds))
        ++round.moves;
      else
        failed = now;
    }
    return round;
  }

  /// One move for face f of direction d (Algorithms 2 and 3). True when a move was kept.
  /// One move for face f of direction d: the paper's gradient move, and where it failed, the nearest
  /// interior corner of the reconstruction triangle involved (f* for D1, f for D2) moved onto p*'s parameter
  /// point, all the way or 1/2, 1/4, 1/8 of it (a sample on the peak: where a sharp feature lies between
  /// samples the gradient cannot reach it). True when a move was kept.
  bool improve(Direction d, std::uint32_t f, std::uint64_t& folds) {
    return gradient_move(d, f, folds) || snap_move(d, f, folds);
  }

  bool snap_move(Direction d, std::uint32_t f, std::uint64_t& folds) {
    const FaceDistance& fd = field_.face(d, f);
    const double before = fd.distance;
    const std::vector<Vec2>& uv = field_.sample_uv();
    Vec2 peak;
    Face corners;
    if (d == Direction::OriginalToGrid) {
      const Face& of = surface_.faces[f];
      peak = fd.bary[0] * uv_[of[0]] + fd.bary[1] * uv_[of[1]] + fd.bary[2] * uv_[of[2]];
      corners = field_.triangle(fd.target);
    } else {
      // p* on the reconstruction: a sample at its parameter point puts the reconstruction on the surface there.
      corners = field_.triangle(f);
      peak = fd.bary[0] * uv[corners[0]] + fd.bary[1] * uv[corners[1]] + fd.bary[2] * uv[corners[2]];
    }
    std::uint32_t s = kNoSample;
    for (std::uint32_t c : corners)
      if (interior(c) && (s == kNoSample || (uv[c] - peak).norm() < (uv[s] - peak).norm())) s = c;
    if (s == kNoSample) return false;
    const std::vector<std::uint32_t> moved{s};
    for (double t = 1.0; t >= 0.125; t *= 0.5) {
      const std::vector<Vec2> to{uv[s] + t * (peak - uv[s])};
      const std::vector<Vec3> at{param_.at(to[0]).position};
      if (try_move(moved, to, at, d, f, before, folds)) return true;
    }
    return false;
  }

  /// Applies one trial move and keeps it when face f of direction d fell below `before` and no re-measured
  /// entry rose above the largest of them before the move; otherwise undoes it (a fold counts in `folds`).
  bool try_move(std::span<const std::uint32_t> samples, std::span<const Vec2> uv, std::span<const Vec3> pos,
                Direction d, std::uint32_t f, double before, std::uint64_t& folds) {
    const LocalHausdorff::Change change = field_.move(samples, uv, pos);
    if (change.folded) {
      ++folds;
      return false;
    }
    if (field_.face(d, f).distance < before && accepts(change)) return true;
    field_.undo(change);
    return false;
  }

  /// Whether a move's re-measured entries allow it (the target's fall is checked by the caller).
  [[nodiscard]] bool accepts(const LocalHausdorff::Change& change) const {
    if (options_.roi == nullptr) return change.max_after <= change.max_before;
    // ROI mode: no ROI triangle above the largest of them before, nor above the ROI's largest at the start
    // of the round (a triangle the move brings into the ROI brings its old distance from outside along:
    // the local figure alone would let it in), and nothing above the global largest.
    double roi_before = 0.0, roi_after = 0.0;
    for (std::size_t k = 0; k < change.entries.size(); ++k) {
      const auto [d, f] = change.entries[k];
      if (d != Direction::GridToOriginal || !triangle_in(field_, *options_.roi, f)) continue;
      roi_before = std::max(roi_before, change.old_values[k].distance);
      roi_after = std::max(roi_after, field_.face(d, f).distance);
    }
    return roi_after <= std::min(roi_before, roi_largest_) &&
           change.max_after <= std::max(change.max_before, global_largest_);
  }

  bool gradient_move(Direction d, std::uint32_t f, std::uint64_t& folds) {
    const FaceDistance& fd = field_.face(d, f);
    const double before = fd.distance;
    const std::vector<Vec3>& pos = field_.sample_pos();
    Face movers{};
    std::array<Vec3, 3> grad;
    if (d == Direction::OriginalToGrid) {
      // p* on the original face, f* a reconstruction triangle: move the closest feature of f*.
      const Face& of = surface_.faces[f];
      const Vec3 p = fd.bary[0] * surface_.positions[of[0]] + fd.bary[1] * surface_.positions[of[1]] +
                     fd.bary[2] * surface_.positions[of[2]];
      movers = field_.triangle(fd.target);
      const FeatureHit hit = closest_feature(p, pos[movers[0]], pos[movers[1]], pos[movers[2]]);
      grad = gradient_wrt_feature(p, hit);
    } else {
      // p* on the reconstruction triangle f, f* an original face: move the corners of f.
      movers = field_.triangle(f);
      const Vec3 p = fd.bary[0] * pos[movers[0]] + fd.bary[1] * pos[movers[1]] + fd.bary[2] * pos[movers[2]];
      const Face& of = surface_.faces[fd.target];
      const FeatureHit hit =
          closest_feature(p, surface_.positions[of[0]], surface_.positions[of[1]], surface_.positions[of[2]]);
      grad = gradient_wrt_container(p, fd.bary, hit.closest);
    }
    // Movers: interior samples move in the square; boundary samples slide along their side (their glued
    // partner, across the cut, slides with them to the mirrored point), cut-nodes and corners stay.
    struct Mover {
      std::uint32_t sample;
      Vec2 step;                                 // interior: in the square
      double c{0.0}, dc{0.0};                    // boundary: perimeter coordinate and its step
      std::uint32_t partner{kNoSample};
    };
    std::vector<Mover> movers_list;
    double scale = std::numeric_limits<double>::infinity();
    const std::vector<Vec2>& uv = field_.sample_uv();
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint32_t s = movers[k];
      if (grad[k].squaredNorm() == 0.0) continue;
      if (std::any_of(movers_list.begin(), movers_list.end(), [&](const Mover& m) { return m.sample == s || m.partner == s; }))
        continue;
      if (interior(s)) {
        const Vec2 delta = -(param_.at(uv[s]).jacobian.transpose() * grad[k]);
        const double len = delta.norm();
        if (!(len > 0.0) || !std::isfinite(len)) continue;
        double spacing = std::numeric_limits<double>::infinity();
        for (const std::uint32_t nb : {s - 1, s + 1, s - n_, s + n_}) spacing = std::min(spacing, (uv[nb] - uv[s]).norm());
        scale = std::min(scale, 0.5 * spacing / len);
        movers_list.push_back({s, delta});
        continue;
      }
      const PerimeterGlue& glue = options_.measure.glue;
      if (!glue.position || !glue.mate || !glue.node) continue;
      const auto [side, c] = perimeter_of(s);
      if (side < 0 || glue.node(c)) continue;  // a corner or a cut-node
      const double eps = 1e-4 / (n_ - 1);
      const Vec3 tangent = (glue.position(c + eps) - glue.position(c - eps)) / (2.0 * eps);
      const double dc = -grad[k].dot(tangent);
      if (!(std::abs(dc) > 0.0) || !std::isfinite(dc)) continue;
      // Half the distance to the nearer neighbour along the side.
      const std::array<std::uint32_t, 2> along = along_side(s);
      double spacing = std::numeric_limits<double>::infinity();
      for (std::uint32_t nb : along) spacing = std::min(spacing, (uv[nb] - uv[s]).norm());
      scale = std::min(scale, 0.5 * spacing / std::abs(dc));
      Mover m{s, Vec2::Zero(), c, dc, kNoSample};
      // The partner by the sample's own (uniform) place: the sideband glues pixels, wherever they slid.
      const double mate = glue.mate(uniform_coordinate(s));
      if (std::isfinite(mate)) m.partner = pixel_at(mate);
      // A cut-path may turn round a corner of the square: its partner is then the corner pixel, which stays.
      if (m.partner == s || (m.partner != kNoSample && perimeter_of(m.partner).first < 0)) continue;
      movers_list.push_back(m);
    }
    if (movers_list.empty() || !std::isfinite(scale)) return false;
    std::vector<std::uint32_t> samples;
    for (const Mover& m : movers_list) {
      samples.push_back(m.sample);
      if (m.partner != kNoSample) samples.push_back(m.partner);
    }
    std::vector<Vec2> new_uv(samples.size());
    std::vector<Vec3> new_pos(samples.size());
    double t = scale;
    for (std::uint32_t k = 0; k <= options_.step_halvings; ++k, t *= options_.rho) {
      std::size_t i = 0;
      bool valid = true;
      for (const Mover& m : movers_list) {
        if (m.partner == kNoSample && m.dc == 0.0) {
          new_uv[i] = uv[m.sample] + t * m.step;
          new_pos[i] = param_.at(new_uv[i]).position;
          ++i;
          continue;
        }
        const double c = m.c + t * m.dc;
        if (std::floor(c) != std::floor(m.c)) valid = false;  // it would leave its side
        new_uv[i] = square_perimeter_point(c);
        new_pos[i] = options_.measure.glue.position(c);
        ++i;
        if (m.partner != kNoSample) {
          new_uv[i] = square_perimeter_point(options_.measure.glue.mate(c));
          new_pos[i] = new_pos[i - 1];
          ++i;
        }
      }
      if (valid && try_move(samples, new_uv, new_pos, d, f, before, folds)) return true;
    }
    return false;
  }

  MeshView surface_;
  std::span<const Vec2> uv_;
  std::uint32_t n_;
  AdaptOptions options_;
  ParametrizedSurface param_;
  LocalHausdorff field_;
  std::array<std::vector<double>, 2> failed_at_;  ///< per direction and face: its distance when a move failed
  double global_largest_{0.0};  ///< the largest distance of both directions at the start of the round
  double roi_largest_{0.0};     ///< ROI mode: the ROI's largest D2 at the start of the round
};

}  // namespace

AdaptResult adjust_samples(const EmbreeDevice& device, MeshView surface, std::span<const Vec2> uv, std::uint32_t n,
                           std::vector<Vec2> sample_uv, std::vector<Vec3> sample_pos, const AdaptOptions& options) {
  if (n < 3) throw InvalidInput(fmt::format("sample adjustment: grid size {} is below 3", n));
  if (!(options.rho > 0.0 && options.rho < 1.0))
    throw InvalidInput(fmt::format("sample adjustment: rho {} is outside (0, 1)", options.rho));
  if (!(options.target_fraction > 0.0 && options.target_fraction <= 1.0))
    throw InvalidInput(fmt::format("sample adjustment: target fraction {} is outside (0, 1]", options.target_fraction));
  Adjuster adjuster(device, surface, uv, n, std::move(sample_uv), std::move(sample_pos), options);
  return adjuster.run();
}

std::vector<Vec2> uniform_grid(std::uint32_t n) {
  std::vector<Vec2> grid(static_cast<std::size_t>(n) * n);
  for (std::uint32_t j = 0; j < n; ++j)
    for (std::uint32_t i = 0; i < n; ++i)
      grid[std::size_t{j} * n + i] = Vec2(static_cast<double>(i) / (n - 1), static_cast<double>(j) / (n - 1));
  return grid;
}

AdaptiveSampling sample_adaptively(const EmbreeDevice& device, MeshView surface, std::span<const Vec2> uv, std::uint32_t n,
                                   AdaptStart start, const GridPositions& positions_at, const AdaptOptions& options) {
  if (options.roi != nullptr) throw InvalidInput("sample_adaptively: the ROI adjustment has its own start (roi.h)");
  AdaptiveSampling out;
  std::vector<Vec2> grid;
  switch (start) {
    case AdaptStart::Uniform: grid = uniform_grid(n); break;
    case AdaptStart::Strips:
      grid = strip_sample_grid(equalized_strips(uv, n));
      out.started_from_strips = true;
      break;
    case AdaptStart::Auto: {
      std::vector<Vec2> uniform = uniform_grid(n), strips = strip_sample_grid(equalized_strips(uv, n));
      const auto rms = [&](const std::vector<Vec2>& g) {
        LocalHausdorff field(device, surface, uv, n, g, positions_at(g), options.measure);
        field.verify(0.0);
        const DirectedSummary a = field.summary(Direction::OriginalToGrid), b = field.summary(Direction::GridToOriginal);
        return std::sqrt(0.5 * (a.rms * a.rms + b.rms * b.rms));
      };
      out.rms_uniform_start = rms(uniform);
      out.rms_strips_start = rms(strips);
      out.started_from_strips = out.rms_strips_start < out.rms_uniform_start;
      grid = out.started_from_strips ? std::move(strips) : std::move(uniform);
      break;
    }
  }
  std::vector<Vec3> positions = positions_at(grid);
  AdaptResult adjusted = adjust_samples(device, surface, uv, n, std::move(grid), std::move(positions), options);
  out.sample_uv = std::move(adjusted.sample_uv);
  out.history = std::move(adjusted.history);
  return out;
}

}  // namespace gimforge
