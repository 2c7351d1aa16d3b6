// Adaptive geometry images (kernels/adaptive): the §3.1 strips, the λ regions and gradients of §3.3, the
// local Hausdorff distances of §3.2 against the metric, and the sample adjustment.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "kernels/adaptive/local_hausdorff.h"
#include "kernels/adaptive/point_triangle.h"
#include "kernels/adaptive/sample_adjust.h"
#include "kernels/adaptive/strip_sampling.h"
#include "kernels/core/closest_point.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/procedural.h"
#include "kernels/core/topology.h"
#include "kernels/gim/gim_convert.h"

using namespace gimforge;

namespace {

/// Points in the unit square with density growing towards x = 0 and y = 1 (x = u², y = 1 − v²).
std::vector<Vec2> skewed_points(std::size_t count) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.001, 0.999);
  std::vector<Vec2> points;
  for (std::size_t i = 0; i < count; ++i) {
    const double a = u(rng), b = u(rng);
    points.emplace_back(a * a, 1.0 - b * b);
  }
  return points;
}

/// Counts of coordinates per strip.
std::vector<std::size_t> counts(const std::vector<double>& lines, const std::vector<Vec2>& points, int axis) {
  std::vector<std::size_t> c(lines.size() - 1, 0);
  for (const Vec2& p : points) {
    const auto it = std::upper_bound(lines.begin(), lines.end(), p[axis]);
    const auto k = static_cast<std::size_t>(std::clamp<std::ptrdiff_t>(it - lines.begin() - 1, 0,
                                                                      static_cast<std::ptrdiff_t>(c.size()) - 1));
    ++c[k];
  }
  return c;
}

double cross2(const Vec2& o, const Vec2& a, const Vec2& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

/// A parametrized height field over the unit square: the mesh, its parameter points and a sample grid of
/// n × n points on it (uniform, positions interpolated on the mesh).
struct HeightField {
  TriMesh mesh;
  std::vector<Vec2> uv;
  explicit HeightField(std::size_t cells) : mesh(make_grid(cells, cells, 1.0)) {
    for (Vec3& p : mesh.positions) {
      uv.emplace_back(p.x(), p.y());
      p.z() = 0.15 * std::sin(5.0 * p.x()) * std::cos(4.0 * p.y()) + 0.05 * std::exp(-40.0 * (p - Vec3(0.6, 0.3, p.z())).squaredNorm());
    }
  }
};

std::pair<std::vector<Vec2>, std::vector<Vec3>> uniform_samples(const EmbreeDevice& device, const HeightField& h,
                                                                std::uint32_t n) {
  const ParametrizedSurface surface(device, h.mesh, h.uv);
  std::vector<Vec2> uv;
  std::vector<Vec3> pos;
  for (std::uint32_t j = 0; j < n; ++j)
    for (std::uint32_t i = 0; i < n; ++i) {
      uv.emplace_back(static_cast<double>(i) / (n - 1), static_cast<double>(j) / (n - 1));
      pos.push_back(surface.at(uv.back()).position);
    }
  return {uv, pos};
}

TriMesh grid_mesh(const LocalHausdorff& field) {
  TriMesh m;
  m.positions = field.sample_pos();
  for (std::uint32_t t = 0; t < field.triangles(); ++t) m.faces.push_back(field.triangle(t));
  return m;
}

}  // namespace

TEST(StripSampling, ExactlyNMinusOneStripsPerAxis) {
  const std::vector<Vec2> points = skewed_points(20000);
  for (std::uint32_t n : {3u, 65u, 129u, 193u}) {
    const StripLines lines = equalized_strips(points, n);
    for (const auto* axis : {&lines.x, &lines.y}) {
      ASSERT_EQ(axis->size(), n);
      EXPECT_EQ(axis->front(), 0.0);
      EXPECT_EQ(axis->back(), 1.0);
      for (std::size_t k = 0; k + 1 < n; ++k) EXPECT_LT((*axis)[k], (*axis)[k + 1]);
    }
  }
  EXPECT_THROW((void)equalized_strips(points, 2), InvalidInput);
}

TEST(StripSampling, EqualizesVertexCounts) {
  const std::vector<Vec2> points = skewed_points(40000);
  const std::uint32_t n = 65;
  std::vector<double> uniform(n);
  for (std::uint32_t k = 0; k < n; ++k) uniform[k] = static_cast<double>(k) / (n - 1);
  const StripLines lines = equalized_strips(points, n);
  const double mean = static_cast<double>(points.size()) / (n - 1);
  for (int axis : {0, 1}) {
    const auto before = counts(uniform, points, axis);
    const auto after = counts(axis == 0 ? lines.x : lines.y, points, axis);
    const double max_before = static_cast<double>(*std::max_element(before.begin(), before.end()));
    const double max_after = static_cast<double>(*std::max_element(after.begin(), after.end()));
    EXPECT_GT(max_before, 3.0 * mean) << "axis " << axis << ": the test's points are not skewed enough";
    // Splitting the fullest strip in halves leaves no strip holding more than about twice the mean.
    EXPECT_LT(max_after, 2.2 * mean) << "axis " << axis;
  }
}

TEST(StripSampling, GridKeepsTheBoundaryUniformAndNeverFolds) {
  const std::uint32_t n = 129;
  const StripLines lines = equalized_strips(skewed_points(30000), n);
  const std::vector<Vec2> grid = strip_sample_grid(lines);
  ASSERT_EQ(grid.size(), std::size_t{n} * n);
  for (std::uint32_t k = 0; k < n; ++k) {
    const double u = static_cast<double>(k) / (n - 1);
    EXPECT_EQ(grid[k], Vec2(u, 0.0));
    EXPECT_EQ(grid[std::size_t{n - 1} * n + k], Vec2(u, 1.0));
    EXPECT_EQ(grid[std::size_t{k} * n], Vec2(0.0, u));
    EXPECT_EQ(grid[std::size_t{k} * n + n - 1], Vec2(1.0, u));
  }
  // The interior follows the strips (pulled less where these very uneven strips would fold the band).
  const Vec2 centre = grid[std::size_t{n / 2} * n + n / 2];
  const double u = 0.5, pull = (centre.x() - u) / (lines.x[n / 2] - u);
  EXPECT_GT(pull, 0.0);
  EXPECT_LE(pull, 1.0);
  EXPECT_NEAR(centre.y() - u, pull * (lines.y[n / 2] - u), 1e-12);
  std::vector<Vec2> mild;
  for (const Vec2& p : skewed_points(30000)) mild.emplace_back(std::pow(std::sqrt(p.x()), 1.2), std::sqrt(1.0 - p.y()));
  const StripLines gentle = equalized_strips(mild, n);
  EXPECT_EQ(strip_sample_grid(gentle)[std::size_t{n / 2} * n + n / 2], Vec2(gentle.x[n / 2], gentle.y[n / 2]));
  for (std::uint32_t j = 0; j + 1 < n; ++j)
    for (std::uint32_t i = 0; i + 1 < n; ++i) {
      const std::array<Vec2, 4> q{grid[std::size_t{j} * n + i], grid[std::size_t{j} * n + i + 1],
                                  grid[std::size_t{j + 1} * n + i + 1], grid[std::size_t{j + 1} * n + i]};
      for (std::size_t e = 0; e < 4; ++e) ASSERT_GT(cross2(q[e], q[(e + 1) % 4], q[(e + 2) % 4]), 0.0) << i << "," << j;
    }
}

TEST(PointTriangle, LambdaRegionsGiveTheClosestFeature) {
  std::mt19937 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  auto random_point = [&] { return Vec3(g(rng), g(rng), g(rng)); };
  std::array<int, 3> seen{};
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec3 a = random_point(), b = random_point(), c = random_point(), p = 2.0 * random_point();
    const FeatureHit hit = closest_feature(p, a, b, c);
    const TrianglePoint brute = closest_point_on_triangle(p, a, b, c);
    const double d2 = (brute.point - p).squaredNorm();
    ASSERT_NEAR(hit.squared_distance, d2, 1e-9 * (1.0 + d2)) << trial;
    ASSERT_NEAR((hit.closest - brute.point).norm(), 0.0, 1e-7) << trial;
    // The feature, where the brute force's barycentric coordinates name it unambiguously.
    const Vec3 w = brute.barycentric;
    int zeros = 0, clear = 0;
    for (int k = 0; k < 3; ++k) {
      zeros += w[k] < 1e-12 ? 1 : 0;
      clear += w[k] < 1e-12 || w[k] > 1e-6 ? 1 : 0;
    }
    if (clear < 3) continue;
    const DistanceType want = zeros == 0 ? DistanceType::PointFace : zeros == 1 ? DistanceType::PointEdge : DistanceType::PointPoint;
    ASSERT_EQ(hit.type, want) << trial << " weights " << w.transpose();
    ++seen[static_cast<std::size_t>(want)];
    EXPECT_NEAR(hit.weights.sum(), 1.0, 1e-9);
  }
  for (int count : seen) EXPECT_GT(count, 500);  // every type was exercised
}

TEST(PointTriangle, GradientsMatchFiniteDifferences) {
  std::mt19937 rng(5);
  std::normal_distribution<double> g(0.0, 1.0);
  auto random_point = [&] { return Vec3(g(rng), g(rng), g(rng)); };
  const double h = 1e-6;
  for (int trial = 0; trial < 300; ++trial) {
    std::array<Vec3, 3> t{random_point(), random_point(), random_point()};
    const Vec3 p = 2.0 * random_point();
    const FeatureHit hit = closest_feature(p, t[0], t[1], t[2]);
    const auto grad = gradient_wrt_feature(p, hit);
    for (std::size_t k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) {
        auto plus = t, minus = t;
        plus[k][c] += h;
        minus[k][c] -= h;
        const double fd = (squared_distance_to_triangle(p, plus[0], plus[1], plus[2]) -
                           squared_distance_to_triangle(p, minus[0], minus[1], minus[2])) / (2 * h);
        ASSERT_NEAR(grad[k][c], fd, 1e-5 * (1.0 + std::abs(fd))) << trial << " corner " << k;
      }
    // The point of a moving triangle against a fixed one (eq. (10), (12), (15)).
    std::array<Vec3, 3> s{random_point(), random_point(), random_point()};
    std::uniform_real_distribution<double> u(0.05, 1.0);
    Vec3 bary(u(rng), u(rng), u(rng));
    bary /= bary.sum();
    const auto at = [&](const std::array<Vec3, 3>& v) { return Vec3(bary[0] * v[0] + bary[1] * v[1] + bary[2] * v[2]); };
    const Vec3 q = at(s);
    const FeatureHit target = closest_feature(q, t[0], t[1], t[2]);
    const auto gc = gradient_wrt_container(q, bary, target.closest);
    for (std::size_t k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) {
        auto plus = s, minus = s;
        plus[k][c] += h;
        minus[k][c] -= h;
        const double fd = (squared_distance_to_triangle(at(plus), t[0], t[1], t[2]) -
                           squared_distance_to_triangle(at(minus), t[0], t[1], t[2])) / (2 * h);
        ASSERT_NEAR(gc[k][c], fd, 1e-5 * (1.0 + std::abs(fd))) << trial << " corner " << k;
      }
  }
}

TEST(LocalHausdorff, AgreesWithTheMetric) {
  const EmbreeDevice device;
  const HeightField h(40);
  const std::uint32_t n = 33;
  auto [uv, pos] = uniform_samples(device, h, n);
  LocalHausdorff field(device, h.mesh, h.uv, n, uv, pos);
  field.verify(0.0);
  const HausdorffResult metric = symmetric_hausdorff(device, h.mesh, grid_mesh(field), {200000});
  const DirectedSummary d1 = field.summary(Direction::OriginalToGrid), d2 = field.summary(Direction::GridToOriginal);
  // The lattices see the largest distance within a face to about a tenth (the metric samples 200,000 points
  // at random and every vertex); the RMS is an integral both estimate.
  EXPECT_NEAR(d1.max, metric.ab.max, 0.12 * metric.ab.max);
  EXPECT_NEAR(d2.max, metric.ba.max, 0.12 * metric.ba.max);
  EXPECT_NEAR(d1.rms, metric.ab.rms, 0.08 * metric.ab.rms);
  EXPECT_NEAR(d2.rms, metric.ba.rms, 0.08 * metric.ba.rms);
  // p* and f* of the worst face of each direction reproduce its distance.
  const FaceDistance& w1 = field.face(Direction::OriginalToGrid, field.argmax(Direction::OriginalToGrid));
  const Face& of = h.mesh.faces[field.argmax(Direction::OriginalToGrid)];
  const Vec3 p = w1.bary[0] * h.mesh.positions[of[0]] + w1.bary[1] * h.mesh.positions[of[1]] + w1.bary[2] * h.mesh.positions[of[2]];
  const Face rt = field.triangle(w1.target);
  EXPECT_NEAR(std::sqrt(squared_distance_to_triangle(p, pos[rt[0]], pos[rt[1]], pos[rt[2]])), d1.max, 1e-12);
}

TEST(LocalHausdorff, MovesAreExactAndUndone) {
  const EmbreeDevice device;
  const HeightField h(30);
  const std::uint32_t n = 17;
  auto [uv, pos] = uniform_samples(device, h, n);
  LocalHausdorff field(device, h.mesh, h.uv, n, uv, pos);
  const ParametrizedSurface surface(device, h.mesh, h.uv);
  const DirectedSummary before1 = field.summary(Direction::OriginalToGrid), before2 = field.summary(Direction::GridToOriginal);
  const std::uint32_t s = 8 * n + 8;
  const std::vector<std::uint32_t> moved{s};
  const std::vector<Vec2> to{uv[s] + Vec2(0.3, 0.2) / (n - 1)};
  const std::vector<Vec3> at{surface.at(to[0]).position};
  const LocalHausdorff::Change change = field.move(moved, to, at);
  ASSERT_FALSE(change.folded);
  // The incremental state equals a fresh measurement of the moved grid.
  LocalHausdorff fresh(device, h.mesh, h.uv, n, field.sample_uv(), field.sample_pos());
  for (Direction d : {Direction::OriginalToGrid, Direction::GridToOriginal}) {
    EXPECT_DOUBLE_EQ(field.summary(d).max, fresh.summary(d).max);
    EXPECT_NEAR(field.summary(d).rms, fresh.summary(d).rms, 1e-15);
  }
  field.undo(change);
  EXPECT_EQ(field.sample_uv()[s], uv[s]);
  EXPECT_DOUBLE_EQ(field.summary(Direction::OriginalToGrid).max, before1.max);
  EXPECT_DOUBLE_EQ(field.summary(Direction::GridToOriginal).rms, before2.rms);
  // A move past the next sample folds the grid: refused, nothing changed.
  const std::vector<Vec2> across{uv[s] + Vec2(1.5, 0.0) / (n - 1)};
  const std::vector<Vec3> across_at{surface.at(across[0]).position};
  const LocalHausdorff::Change fold = field.move(moved, across, across_at);
  EXPECT_TRUE(fold.folded);
  EXPECT_EQ(field.sample_uv()[s], uv[s]);
  EXPECT_DOUBLE_EQ(field.summary(Direction::GridToOriginal).rms, before2.rms);
}

TEST(LocalHausdorff, AQuadAlreadyTurnedDoesNotFreezeItsSamples) {
  const EmbreeDevice device;
  const HeightField h(30);
  const std::uint32_t n = 17;
  auto [uv, pos] = uniform_samples(device, h, n);
  // Reconstruction triangles of the quads around sample s turned against their quad's normal (the cross
  // product of its diagonals), as on a quad laid across a crease.
  const auto turned_around = [n](const LocalHausdorff& field, std::uint32_t s) {
    const std::vector<Vec3>& p = field.sample_pos();
    int count = 0;
    const std::uint32_t i = s % n, j = s / n;
    for (std::uint32_t qj = j - 1; qj <= j; ++qj)
      for (std::uint32_t qi = i - 1; qi <= i; ++qi) {
        const std::uint32_t a = qj * n + qi, b = a + 1, c = a + n + 1, d = a + n;
        const Vec3 normal = (p[c] - p[a]).cross(p[d] - p[b]);
        const std::uint32_t q = qj * (n - 1) + qi;
        for (std::uint32_t t = 2 * q; t < 2 * q + 2; ++t) {
          const Face tri = field.triangle(t);
          if (!((p[tri[1]] - p[tri[0]]).cross(p[tri[2]] - p[tri[0]]).dot(normal) > 0.0)) ++count;
        }
      }
    return count;
  };
  const std::uint32_t s = 8 * n + 8;
  const double h3 = 1.0 / (n - 1);
  // Sample s lifted across its neighbours in 3D: some triangle around it turns.
  pos[s] += Vec3(-1.5 * h3, 0.0, 0.0);
  LocalHausdorff field(device, h.mesh, h.uv, n, uv, pos);
  const int before = turned_around(field, s);
  ASSERT_GT(before, 0);
  // A small move that turns no other triangle is allowed (it used to be refused, which froze the samples
  // of such quads: kitten's largest distances sat there).
  const std::vector<std::uint32_t> moved{s};
  const std::vector<Vec2> to{uv[s] + Vec2(0.05, 0.0) * h3};
  const std::vector<Vec3> at{pos[s] + Vec3(0.05 * h3, 0.0, 0.0)};
  const LocalHausdorff::Change change = field.move(moved, to, at);
  EXPECT_FALSE(change.folded);
  EXPECT_EQ(turned_around(field, s), before);
  field.undo(change);
  // A move that turns a triangle that was not turned is still refused.
  const std::uint32_t far = 3 * n + 3;
  const std::vector<std::uint32_t> other{far};
  const std::vector<Vec2> other_to{uv[far]};
  const std::vector<Vec3> other_at{pos[far] + Vec3(-1.5 * h3, 0.0, 0.0)};
  EXPECT_TRUE(field.move(other, other_to, other_at).folded);
  EXPECT_EQ(field.sample_pos()[far], pos[far]);
}

TEST(SampleAdjust, TheLargestDistanceNeverGrowsAndFalls) {
  const EmbreeDevice device;
  const HeightField h(24);
  const std::uint32_t n = 17;
  auto [uv, pos] = uniform_samples(device, h, n);
  AdaptOptions options;
  options.rounds = 5;
  const AdaptResult r = adjust_samples(device, h.mesh, h.uv, n, uv, pos, options);
  ASSERT_GE(r.history.size(), 2u);
  double previous = std::numeric_limits<double>::infinity();
  for (const AdaptRound& round : r.history) {
    const double largest = std::max(round.max_d1, round.max_d2);
    EXPECT_LE(largest, previous) << "round " << round.round;
    previous = largest;
  }
  const AdaptRound& first = r.history.front();
  const AdaptRound& last = r.history.back();
  EXPECT_LT(std::max(last.max_d1, last.max_d2), 0.8 * std::max(first.max_d1, first.max_d2));
  EXPECT_LT(last.rms_d1 * last.rms_d1 + last.rms_d2 * last.rms_d2, first.rms_d1 * first.rms_d1 + first.rms_d2 * first.rms_d2);
  // Boundary samples stay; the metric confirms the gain.
  for (std::uint32_t k = 0; k < n; ++k) EXPECT_EQ(r.sample_uv[k], uv[k]);
  const ParametrizedSurface surface(device, h.mesh, h.uv);
  std::vector<Vec3> moved_pos;
  for (const Vec2& p : r.sample_uv) moved_pos.push_back(surface.at(p).position);
  const LocalHausdorff before(device, h.mesh, h.uv, n, uv, pos);
  const LocalHausdorff after(device, h.mesh, h.uv, n, r.sample_uv, moved_pos);
  const HausdorffResult m0 = symmetric_hausdorff(device, h.mesh, grid_mesh(before), {100000});
  const HausdorffResult m1 = symmetric_hausdorff(device, h.mesh, grid_mesh(after), {100000});
  EXPECT_LT(m1.max, m0.max);
  EXPECT_GT(m1.psnr, m0.psnr);
}

TEST(SampleAdjust, RefusesBadOptions) {
  const EmbreeDevice device;
  const HeightField h(8);
  auto [uv, pos] = uniform_samples(device, h, 9);
  AdaptOptions bad;
  bad.rho = 1.0;
  EXPECT_THROW((void)adjust_samples(device, h.mesh, h.uv, 9, uv, pos, bad), InvalidInput);
  EXPECT_THROW((void)adjust_samples(device, h.mesh, h.uv, 9, uv, {}, {}), InvalidInput);
  EXPECT_THROW((void)adjust_samples(device, h.mesh, h.uv, 2, {}, {}, {}), InvalidInput);
}

TEST(GluedPerimeter, MatesMapToEachOtherAndBoundaryToNothing) {
  Sideband sb;
  sb.units_per_side = 4;
  sb.paths = {{1, 0, 3}, {-1, 3, 3}, {0, 6, 10}};
  sb.check();
  // Coordinate 0.25 side (1 unit into path +1) is glued to 1 unit before the end of path −1.
  EXPECT_NEAR(glued_perimeter_coordinate(sb, 0.25), 5.0 / 4.0, 1e-12);
  EXPECT_NEAR(glued_perimeter_coordinate(sb, 5.0 / 4.0), 0.25, 1e-12);
  EXPECT_TRUE(std::isnan(glued_perimeter_coordinate(sb, 2.5)));
}

TEST(AdaptiveGim, ClosedSurfacesStayWatertight) {
  for (int genus : {0, 1}) {
    const TriMesh mesh = genus == 0 ? make_icosphere(1.0, 3) : make_slab_with_holes(1);
    const EmbreeDevice device;
    GimOptions opt;
    opt.image = {65, 0, {}};
    opt.max_augmentations = 2;
    opt.sampling = GimSampling::Adaptive;
    opt.adapt.rounds = 3;
    for (AdaptStart start : {genus == 0 ? AdaptStart::Strips : AdaptStart::Auto}) {
      opt.adapt_start = start;
      const GimResult r = convert_to_geometry_image(device, mesh, opt);
      ASSERT_EQ(r.image.sample_uv.size(), 65u * 65u * 2u);
      EXPECT_EQ(r.stats.adapt_started_from_strips, start == AdaptStart::Strips ? true : r.stats.adapt_rms_strips_start < r.stats.adapt_rms_uniform_start);
      ASSERT_FALSE(r.stats.adapt_history.empty());
      const TriMesh recon = reconstruct_geometry_image(r.image.positions, r.image.size, &r.image.sideband);
      const TopologyReport t = analyze_topology(recon);
      EXPECT_EQ(t.boundary_edges, 0u) << "genus " << genus;
      EXPECT_EQ(t.nonmanifold_edges, 0u) << "genus " << genus;
      EXPECT_EQ(t.components.size(), 1u);
      const auto& last = r.stats.adapt_history.back();
      const auto& first = r.stats.adapt_history.front();
      EXPECT_LE(std::max(last.max_d1, last.max_d2), std::max(first.max_d1, first.max_d2));
    }
  }
}
