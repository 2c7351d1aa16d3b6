#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/core/surface_fit.h"
#include "kernels/core/surface_fit_detail.h"
#include "kernels/core/surface_sampling.h"

using namespace gimforge;

namespace {

/// An n × n grid of vertices (index j·n + i), each quad split along its shorter diagonal.
Triangulator grid_triangulator(std::size_t n) {
  return [n](std::span<const Vec3> x) {
    std::vector<Face> faces;
    faces.reserve(2 * (n - 1) * (n - 1));
    auto id = [n](std::size_t i, std::size_t j) { return static_cast<std::uint32_t>(j * n + i); };
    for (std::size_t j = 0; j + 1 < n; ++j) {
      for (std::size_t i = 0; i + 1 < n; ++i) {
        const std::uint32_t a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
        if ((x[a] - x[c]).squaredNorm() <= (x[b] - x[d]).squaredNorm()) {
          faces.push_back({a, b, c});
          faces.push_back({a, c, d});
        } else {
          faces.push_back({a, b, d});
          faces.push_back({b, c, d});
        }
      }
    }
    return faces;
  };
}

/// The triangulator that ignores the positions.
Triangulator fixed_triangulator(std::vector<Face> faces) {
  return [faces = std::move(faces)](std::span<const Vec3>) { return faces; };
}

/// A uniform value in [-1, 1).
double noise(std::uint64_t seed, std::uint64_t stream) { return 2.0 * uniform01(seed, stream) - 1.0; }

/// The vertices of an n × n grid over [0,1]² lifted off the plane by noise of `amplitude` (and moved in the
/// plane by a quarter of it).
std::vector<Vec3> noisy_grid(std::size_t n, double amplitude, std::uint64_t seed = 7) {
  const TriMesh grid = make_grid(n - 1, n - 1, 1.0);
  std::vector<Vec3> x = grid.positions;
  for (std::size_t v = 0; v < x.size(); ++v)
    x[v] += Vec3(0.25 * amplitude * noise(seed, 3 * v), 0.25 * amplitude * noise(seed, 3 * v + 1),
                 amplitude * noise(seed, 3 * v + 2));
  return x;
}

double mean_radius(std::span<const Vec3> x) {
  double s = 0.0;
  for (const Vec3& p : x) s += p.norm();
  return s / static_cast<double>(x.size());
}

double max_abs_z(std::span<const Vec3> x) {
  double m = 0.0;
  for (const Vec3& p : x) m = std::max(m, std::abs(p.z()));
  return m;
}

/// The largest |dihedral angle| of the mesh (x, faces), in radians.
double max_dihedral(std::span<const Vec3> x, std::span<const Face> faces) {
  double m = 0.0;
  for (const detail::DihedralEdge& e : detail::build_edges(faces).dihedral)
    m = std::max(m, detail::dihedral_energy(x, std::span(&e, 1), 1, {}));
  return m;
}

/// Checks `gradient` against central differences of `energy` at every coordinate of `x`.
template <class F>
void expect_gradient_matches(std::vector<Vec3> x, std::span<const Vec3> gradient, F&& energy, double h, double tol) {
  double scale = 0.0;
  for (const Vec3& g : gradient) scale = std::max(scale, g.cwiseAbs().maxCoeff());
  ASSERT_GT(scale, 0.0) << "a zero gradient checks nothing";
  for (std::size_t v = 0; v < x.size(); ++v) {
    for (int k = 0; k < 3; ++k) {
      const double keep = x[v][k];
      x[v][k] = keep + h;
      const double up = energy(x);
      x[v][k] = keep - h;
      const double down = energy(x);
      x[v][k] = keep;
      EXPECT_NEAR((up - down) / (2 * h), gradient[v][k], tol * scale) << "vertex " << v << " coordinate " << k;
    }
  }
}

}  // namespace

TEST(SurfaceFit, EdgesOfGridAndSphere) {
  const TriMesh grid = make_grid(2, 2);
  const detail::EdgeSet g = detail::build_edges(grid.faces);
  EXPECT_EQ(g.edges.size(), 16u);
  EXPECT_EQ(g.dihedral.size(), 8u);  // 16 edges, 8 of them on the boundary
  const TriMesh sphere = make_icosphere(1.0, 1);
  const detail::EdgeSet s = detail::build_edges(sphere.faces);
  EXPECT_EQ(s.edges.size(), 3 * sphere.faces.size() / 2);
  EXPECT_EQ(s.dihedral.size(), s.edges.size());
  // A flat mesh has no dihedral energy; an icosphere has some.
  EXPECT_EQ(detail::dihedral_energy(grid.positions, g.dihedral, 4, {}), 0.0);
  EXPECT_GT(detail::dihedral_energy(sphere.positions, s.dihedral, 4, {}), 0.0);
}

TEST(SurfaceFit, DihedralAngleIgnoresStoredOrientation) {
  // Two triangles over the edge (0, 1), the second stored with the opposite orientation.
  const std::vector<Vec3> x{{0, 0, 0}, {1, 0, 0}, {0.5, 1, 0}, {0.5, -1, 0}};
  for (const std::vector<Face>& faces :
       {std::vector<Face>{{0, 1, 2}, {1, 0, 3}}, std::vector<Face>{{0, 1, 2}, {0, 1, 3}}}) {
    const detail::EdgeSet e = detail::build_edges(faces);
    ASSERT_EQ(e.dihedral.size(), 1u);
    EXPECT_NEAR(detail::dihedral_energy(x, e.dihedral, 2, {}), 0.0, 1e-30);
    // Folding vertex 2 up by 90 degrees about the edge: θ = π/2 either way.
    std::vector<Vec3> folded = x;
    folded[2] = Vec3(0.5, 0, 1);
    EXPECT_NEAR(detail::dihedral_energy(folded, e.dihedral, 2, {}), std::pow(std::acos(0.0), 2), 1e-12);
  }
}

TEST(SurfaceFit, DihedralAngleSkipsSliversOverTheEdge) {
  // The same fold by 90 degrees, with the folded triangle's height over the edge at 0.5 % and at 5 % of the
  // edge length: the sliver's angle is ill-conditioned and skipped, the thin but proper triangle counts.
  const std::vector<Face> faces{{0, 1, 2}, {1, 0, 3}};
  const detail::EdgeSet e = detail::build_edges(faces);
  ASSERT_EQ(e.dihedral.size(), 1u);
  for (const double height : {0.005, 0.05}) {
    const std::vector<Vec3> x{{0, 0, 0}, {1, 0, 0}, {0.5, 0, height}, {0.5, -1, 0}};
    std::vector<Vec3> gradient(x.size(), Vec3::Zero());
    const double energy = detail::dihedral_energy(x, e.dihedral, 2, gradient);
    if (height < 0.01) {
      EXPECT_EQ(energy, 0.0);
      for (const Vec3& g : gradient) EXPECT_EQ(g.norm(), 0.0);
    } else {
      EXPECT_NEAR(energy, std::pow(std::acos(0.0), 2), 1e-12);
    }
  }
}

TEST(SurfaceFit, DihedralGradientMatchesFiniteDifferences) {
  TriMesh mesh = make_icosphere(1.0, 1);
  for (std::size_t v = 0; v < mesh.positions.size(); ++v)
    mesh.positions[v] += 0.1 * Vec3(noise(3, 3 * v), noise(3, 3 * v + 1), noise(3, 3 * v + 2));
  TriMesh grid = make_grid(3, 3);
  for (std::size_t v = 0; v < grid.positions.size(); ++v) grid.positions[v].z() = 0.2 * noise(5, v);
  for (const TriMesh* m : {&mesh, &grid}) {
    const detail::EdgeSet edges = detail::build_edges(m->faces);
    for (int p : {2, 3, 4}) {
      std::vector<Vec3> gradient(m->positions.size(), Vec3::Zero());
      const double scale = 0.7;
      detail::dihedral_energy(m->positions, edges.dihedral, p, gradient, scale);
      expect_gradient_matches(
          m->positions, gradient,
          [&](const std::vector<Vec3>& x) { return scale * detail::dihedral_energy(x, edges.dihedral, p, {}); }, 1e-6,
          1e-6);
    }
  }
}

TEST(SurfaceFit, FitGradientMatchesFiniteDifferences) {
  const EmbreeDevice device;
  TriMesh remesh = make_icosphere(0.9, 1);
  for (std::size_t v = 0; v < remesh.positions.size(); ++v)
    remesh.positions[v] += 0.05 * Vec3(noise(11, 3 * v), noise(11, 3 * v + 1), noise(11, 3 * v + 2));
  const TriMesh reference = make_icosphere(1.0, 3);
  const SurfaceSamples samples = sample_surface(reference, {400, 17});
  std::vector<Vec3> gradient(remesh.positions.size(), Vec3::Zero());
  std::vector<std::uint32_t> hints(samples.points.size(), kNoFace);
  const double e = detail::fit_energy(device, samples.points, remesh, gradient, hints);
  EXPECT_GT(e, 0.0);
  // The hints now hold each sample's face: the same energy follows from them.
  EXPECT_NEAR(detail::fit_energy(device, samples.points, remesh, {}, hints), e, 1e-15);
  expect_gradient_matches(
      remesh.positions, gradient,
      [&](const std::vector<Vec3>& x) {
        return detail::fit_energy(device, samples.points, MeshView(x, remesh.faces), {});
      },
      1e-6, 1e-5);
}

TEST(SurfaceFit, NoisyGridReturnsToThePlane) {
  const EmbreeDevice device;
  const std::size_t n = 17;
  const TriMesh reference = make_grid(8, 8, 1.0);
  const std::vector<Vec3> input = noisy_grid(n, 0.03);
  SurfaceFitOptions options;
  options.reference_samples = 20'000;
  options.iterations = 60;
  int calls = 0;
  const Triangulator counted = [&calls, tri = grid_triangulator(n)](std::span<const Vec3> x) {
    ++calls;
    return tri(x);
  };
  const SurfaceFitResult r = fit_surface(device, reference, input, counted, {}, options);
  ASSERT_EQ(r.positions.size(), input.size());
  EXPECT_GT(calls, r.iterations) << "the triangulation is re-chosen at every evaluation";
  EXPECT_GT(r.fit_before, 0.0);
  // The plane is reached up to rounding; thresholds stay loose so that other line searches pass too.
  EXPECT_LT(r.fit_after, 1e-3 * r.fit_before) << "fit " << r.fit_before << " -> " << r.fit_after;
  EXPECT_LT(r.energy_after, 1e-3 * r.energy_before);
  EXPECT_LT(max_abs_z(r.positions), 0.05 * max_abs_z(input));
  // Flat again: the noise had folded some quads by more than a radian.
  EXPECT_GT(max_dihedral(input, grid_triangulator(n)(input)), 1.0);
  EXPECT_LT(max_dihedral(r.positions, grid_triangulator(n)(r.positions)), 0.05);
  EXPECT_GT(r.iterations, 0);
  EXPECT_GE(r.seconds, 0.0);
}

TEST(SurfaceFit, CoarseSphereGrowsToTheReference) {
  const EmbreeDevice device;
  const TriMesh coarse = make_icosphere(0.9, 2);
  const TriMesh reference = make_icosphere(1.0, 4);
  SurfaceFitOptions options;
  options.reference_samples = 30'000;
  options.iterations = 40;
  const SurfaceFitResult r =
      fit_surface(device, reference, coarse.positions, fixed_triangulator(coarse.faces), {}, options);
  EXPECT_LT(r.energy_after, 0.01 * r.energy_before);
  const double before = mean_radius(coarse.positions), after = mean_radius(r.positions);
  EXPECT_NEAR(before, 0.9, 1e-12);
  // The best fit of a coarse polyhedron has its vertices slightly outside the sphere (here about 1.01).
  EXPECT_GT(after, 1.0);
  EXPECT_LT(after, 1.02);
  // Still a convex polyhedron without folds (the icosphere's own dihedral angles are about 0.2 rad).
  EXPECT_LT(max_dihedral(r.positions, coarse.faces), 0.3);
}

TEST(SurfaceFit, LockedVerticesStayPut) {
  const EmbreeDevice device;
  const std::size_t n = 13;
  const TriMesh reference = make_grid(4, 4, 1.0);
  const std::vector<Vec3> input = noisy_grid(n, 0.04, 9);
  std::vector<char> locked(input.size(), 0);
  for (std::size_t v = 0; v < locked.size(); v += 3) locked[v] = 1;
  SurfaceFitOptions options;
  options.reference_samples = 10'000;
  options.iterations = 20;
  const SurfaceFitResult r = fit_surface(device, reference, input, grid_triangulator(n), locked, options);
  std::size_t moved = 0;
  for (std::size_t v = 0; v < input.size(); ++v) {
    if (locked[v]) {
      EXPECT_EQ(r.positions[v], input[v]) << "locked vertex " << v << " moved";
    } else if ((r.positions[v] - input[v]).norm() > 1e-3) {
      ++moved;
    }
  }
  EXPECT_GT(moved, input.size() / 3) << "the free vertices should move";
  EXPECT_LT(r.energy_after, r.energy_before);
}

TEST(SurfaceFit, NeverRaisesTheEnergy) {
  const EmbreeDevice device;
  const std::size_t n = 9;
  const TriMesh reference = make_grid(8, 8, 1.0);
  SurfaceFitOptions options;
  options.reference_samples = 5'000;
  // Already optimal: a flat grid on the flat reference.
  const TriMesh flat = make_grid(n - 1, n - 1, 1.0);
  const SurfaceFitResult exact = fit_surface(device, reference, flat.positions, grid_triangulator(n), {}, options);
  EXPECT_LE(exact.energy_after, exact.energy_before);
  EXPECT_LT(exact.energy_before, 1e-20);
  // No iterations: the input comes back.
  options.iterations = 0;
  const std::vector<Vec3> noisy = noisy_grid(n, 0.05, 4);
  const SurfaceFitResult none = fit_surface(device, reference, noisy, grid_triangulator(n), {}, options);
  EXPECT_EQ(none.positions, noisy);
  EXPECT_EQ(none.energy_after, none.energy_before);
  EXPECT_EQ(none.iterations, 0);
  EXPECT_GT(none.energy_before, none.fit_before);  // the dihedral term counts
  // A tangled start (vertices scattered over the square and far off it), a few iterations.
  std::vector<Vec3> tangled(n * n);
  for (std::size_t v = 0; v < tangled.size(); ++v)
    tangled[v] = Vec3(uniform01(21, 3 * v), uniform01(21, 3 * v + 1), noise(21, 3 * v + 2));
  for (int iterations : {1, 3, 10}) {
    options.iterations = iterations;
    const SurfaceFitResult r = fit_surface(device, reference, tangled, grid_triangulator(n), {}, options);
    EXPECT_LE(r.energy_after, r.energy_before) << iterations << " iterations";
    EXPECT_LE(r.iterations, iterations);
  }
}

TEST(SurfaceFit, EnergyIsScaleFree) {
  // Scaling everything by 10 scales both terms by 100: the smoothness weight means the same at any scale.
  const EmbreeDevice device;
  const std::size_t n = 9;
  TriMesh reference = make_icosphere(1.0, 3);
  std::vector<Vec3> x = noisy_grid(n, 0.2, 5);
  SurfaceFitOptions options;
  options.reference_samples = 5'000;
  options.iterations = 0;
  options.smoothness = 1.0;
  const SurfaceFitResult a = fit_surface(device, reference, x, grid_triangulator(n), {}, options);
  for (Vec3& p : reference.positions) p *= 10.0;
  for (Vec3& p : x) p *= 10.0;
  const SurfaceFitResult b = fit_surface(device, reference, x, grid_triangulator(n), {}, options);
  EXPECT_NEAR(b.fit_before / a.fit_before, 100.0, 1e-6);
  EXPECT_NEAR((b.energy_before - b.fit_before) / (a.energy_before - a.fit_before), 100.0, 1e-6);
  EXPECT_GT(a.energy_before - a.fit_before, 1e-3 * a.fit_before);  // the dihedral term is not negligible
}

TEST(SurfaceFit, SamplesDrawnBeforehandFitAsTheMeshTheyComeFrom) {
  // A FitReference of points (what ranks draw on their slices of a huge mesh, or one process of the full
  // surface behind a proxy) fits exactly as the mesh they were drawn from, with the fit's own count and seed.
  const EmbreeDevice device;
  const std::size_t n = 9;
  const TriMesh reference = make_icosphere(1.0, 3);
  SurfaceFitOptions options;
  options.reference_samples = 3'000;
  options.iterations = 5;
  const std::vector<Vec3> x = noisy_grid(n, 0.2, 5);
  const SurfaceFitResult from_mesh = fit_surface(device, reference, x, grid_triangulator(n), {}, options);
  const std::vector<Vec3> points =
      sample_surface(reference, {std::max(options.reference_samples, 4 * x.size()), options.seed}).points;
  const SurfaceFitResult from_points =
      fit_surface(device, FitReference::samples(points), x, grid_triangulator(n), {}, options);
  EXPECT_EQ(from_points.energy_before, from_mesh.energy_before);
  EXPECT_EQ(from_points.energy_after, from_mesh.energy_after);
  EXPECT_EQ(from_points.positions, from_mesh.positions);
  EXPECT_LT(from_points.energy_after, from_points.energy_before);
  std::vector<Vec3> bad = points;
  bad[7].y() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW((void)fit_surface(device, FitReference::samples(bad), x, grid_triangulator(n), {}, options), InvalidInput);
}

TEST(SurfaceFit, ReportsProgressAndCancels) {
  const EmbreeDevice device;
  const std::size_t n = 9;
  const TriMesh reference = make_grid(4, 4, 1.0);
  SurfaceFitOptions options;
  options.reference_samples = 2'000;
  options.iterations = 5;
  int calls = 0;
  options.progress = [&](std::string_view stage, double fraction) {
    EXPECT_EQ(stage, "optimize");
    EXPECT_GE(fraction, 0.0);
    EXPECT_LE(fraction, 1.0);
    ++calls;
    return true;
  };
  (void)fit_surface(device, reference, noisy_grid(n, 0.05), grid_triangulator(n), {}, options);
  EXPECT_GE(calls, 2);
  options.progress = [](std::string_view, double fraction) { return fraction < 0.1; };
  EXPECT_THROW((void)fit_surface(device, reference, noisy_grid(n, 0.05), grid_triangulator(n), {}, options), Cancelled);
}

TEST(SurfaceFit, RejectsBadInput) {
  const EmbreeDevice device;
  const std::size_t n = 5;
  const TriMesh reference = make_grid(4, 4, 1.0);
  const std::vector<Vec3> x = noisy_grid(n, 0.05);
  const Triangulator tri = grid_triangulator(n);
  SurfaceFitOptions options;
  options.reference_samples = 1'000;
  options.iterations = 2;
  auto fit = [&](MeshView ref, std::vector<Vec3> pos, const Triangulator& t, std::span<const char> locked,
                 const SurfaceFitOptions& o) { return fit_surface(device, ref, std::move(pos), t, locked, o); };
  EXPECT_THROW((void)fit(reference, {}, tri, {}, options), InvalidInput);
  std::vector<Vec3> nan = x;
  nan[3].y() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW((void)fit(reference, nan, tri, {}, options), InvalidInput);
  std::vector<Vec3> inf = x;
  inf[0].x() = std::numeric_limits<double>::infinity();
  EXPECT_THROW((void)fit(reference, inf, tri, {}, options), InvalidInput);
  const std::vector<char> short_locks(x.size() - 1, 0);
  EXPECT_THROW((void)fit(reference, x, tri, short_locks, options), InvalidInput);
  const Triangulator out_of_range = [&](std::span<const Vec3> p) {
    std::vector<Face> f = tri(p);
    f.push_back({0, 1, static_cast<std::uint32_t>(p.size())});
    return f;
  };
  EXPECT_THROW((void)fit(reference, x, out_of_range, {}, options), InvalidInput);
  const Triangulator degenerate = [](std::span<const Vec3>) { return std::vector<Face>{{0, 0, 1}, {2, 2, 2}}; };
  EXPECT_THROW((void)fit(reference, x, degenerate, {}, options), InvalidInput);
  const Triangulator nothing = [](std::span<const Vec3>) { return std::vector<Face>{}; };
  EXPECT_THROW((void)fit(reference, x, nothing, {}, options), InvalidInput);
  EXPECT_THROW((void)fit(TriMesh{}, x, tri, {}, options), InvalidInput);
  TriMesh bad_reference = reference;
  bad_reference.faces[0][1] = 1000;
  EXPECT_THROW((void)fit(bad_reference, x, tri, {}, options), InvalidInput);
  TriMesh flat_reference = reference;
  for (Vec3& p : flat_reference.positions) p = Vec3(p.x(), 0.0, 0.0);  // no area
  EXPECT_THROW((void)fit(flat_reference, x, tri, {}, options), InvalidInput);
  SurfaceFitOptions bad = options;
  bad.smoothness = -1.0;
  EXPECT_THROW((void)fit(reference, x, tri, {}, bad), InvalidInput);
  bad = options;
  bad.exponent = 0;
  EXPECT_THROW((void)fit(reference, x, tri, {}, bad), InvalidInput);
  bad = options;
  bad.iterations = -1;
  EXPECT_THROW((void)fit(reference, x, tri, {}, bad), InvalidInput);
  // Faces repeating a vertex are ignored, not rejected.
  const Triangulator with_degenerate = [&](std::span<const Vec3> p) {
    std::vector<Face> f = tri(p);
    f.push_back({1, 1, 2});
    return f;
  };
  EXPECT_NO_THROW((void)fit(reference, x, with_degenerate, {}, options));
}
