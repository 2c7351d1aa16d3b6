// Tests of kernels/mcgim/chartify.h: the chartification of multi-chart geometry images (Sander et al. 2003, §4.1)
// on procedural surfaces — every chart a topological disk, extra charts where the disk rule or several components
// need them, convergence or a detected cycle, reproducibility, charts that follow the normals of a cube — and
// the disk test itself.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/mcgim/chartify.h"

namespace gimforge {
namespace {

/// The faces of every chart.
std::vector<std::vector<std::uint32_t>> chart_faces(const Chartification& c) {
  std::vector<std::vector<std::uint32_t>> out(c.num_charts);
  for (std::uint32_t f = 0; f < c.face_chart.size(); ++f) out[c.face_chart[f]].push_back(f);
  return out;
}

/// Checks that `c` partitions the faces of `mesh` into `c.num_charts` non-empty topological disks, seed c
/// lying in chart c, and that the counters agree with the request `requested` and the bound `max_iterations`.
void expect_disk_charts(const TriMesh& mesh, const Chartification& c, std::uint32_t requested,
                        int max_iterations = ChartifyOptions{}.max_iterations) {
  ASSERT_EQ(c.face_chart.size(), mesh.faces.size());
  ASSERT_EQ(c.seeds.size(), c.num_charts);
  const std::uint32_t target = std::min<std::uint32_t>(requested, static_cast<std::uint32_t>(mesh.faces.size()));
  EXPECT_GE(c.num_charts, target);
  EXPECT_EQ(c.extra_seeds, c.num_charts - target);
  // The first seed, one per bootstrap round, the rest from the disk rule or seedless components.
  EXPECT_LE(c.bootstrap_rounds, static_cast<int>(target) - 1);
  EXPECT_LE(1 + static_cast<std::uint32_t>(c.bootstrap_rounds) + c.extra_seeds, c.num_charts);
  for (std::uint32_t f = 0; f < c.face_chart.size(); ++f) ASSERT_LT(c.face_chart[f], c.num_charts) << "face " << f;
  for (std::uint32_t k = 0; k < c.num_charts; ++k) EXPECT_EQ(c.face_chart[c.seeds[k]], k) << "seed of chart " << k;
  const auto charts = chart_faces(c);
  for (std::uint32_t k = 0; k < c.num_charts; ++k) {
    EXPECT_FALSE(charts[k].empty()) << "chart " << k;
    EXPECT_TRUE(is_topological_disk(mesh, charts[k])) << "chart " << k << " of " << c.num_charts;
  }
  EXPECT_TRUE(c.converged || c.cycle || c.fragmenting || c.iterations == max_iterations);
  EXPECT_LE(int{c.converged} + int{c.cycle} + int{c.fragmenting}, 1);
  EXPECT_LE(c.iterations, max_iterations);
}

/// Chartifies `mesh` into `charts` charts with default options and checks the result.
Chartification chartify_checked(const TriMesh& mesh, std::uint32_t charts) {
  ChartifyOptions options;
  options.charts = charts;
  Chartification c = chartify(mesh, options);
  expect_disk_charts(mesh, c, charts);
  return c;
}

/// A box [-stretch/2, stretch/2] × [-0.5, 0.5]² whose six sides are n × n grids of quads split into triangles,
/// oriented outwards (stretch = 1: a cube).
TriMesh make_subdivided_box(int n, double stretch = 1.0) {
  TriMesh m;
  std::map<std::array<int, 3>, std::uint32_t> ids;
  auto vertex = [&](const std::array<int, 3>& p) {
    auto [it, inserted] = ids.try_emplace(p, static_cast<std::uint32_t>(m.positions.size()));
    if (inserted)
      m.positions.emplace_back(stretch * (p[0] / double(n) - 0.5), p[1] / double(n) - 0.5, p[2] / double(n) - 0.5);
    return it->second;
  };
  for (std::size_t a = 0; a < 3; ++a) {
    const std::size_t b = (a + 1) % 3, c = (a + 2) % 3;  // e_b × e_c = e_a
    for (int side : {0, n}) {
      auto at = [&](int u, int v) {
        std::array<int, 3> p{};
        p[a] = side;
        p[b] = u;
        p[c] = v;
        return vertex(p);
      };
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
          const std::uint32_t q0 = at(i, j), q1 = at(i + 1, j), q2 = at(i + 1, j + 1), q3 = at(i, j + 1);
          if (side == n) {  // counter-clockwise seen from +e_a
            m.faces.push_back({q0, q1, q2});
            m.faces.push_back({q0, q2, q3});
          } else {
            m.faces.push_back({q0, q2, q1});
            m.faces.push_back({q0, q3, q2});
          }
        }
    }
  }
  return m;
}

/// Faces of `box` that lie off the main side of their chart (the side holding most of the chart's faces), and
/// the number of distinct main sides.
std::pair<std::size_t, std::size_t> faces_off_main_side(const TriMesh& box, const Chartification& c) {
  std::size_t off_side = 0;
  std::array<char, 6> side_taken{};
  for (const auto& faces : chart_faces(c)) {
    std::array<std::size_t, 6> per_side{};
    for (std::uint32_t f : faces) {
      const Face& t = box.faces[f];
      const Vec3 n = (box.positions[t[1]] - box.positions[t[0]]).cross(box.positions[t[2]] - box.positions[t[0]]);
      Eigen::Index axis = 0;
      n.cwiseAbs().maxCoeff(&axis);
      ++per_side[static_cast<std::size_t>(2 * axis + (n[axis] > 0 ? 1 : 0))];
    }
    const auto best = std::max_element(per_side.begin(), per_side.end());
    side_taken[static_cast<std::size_t>(best - per_side.begin())] = 1;
    off_side += faces.size() - *best;
  }
  return {off_side, static_cast<std::size_t>(std::count(side_taken.begin(), side_taken.end(), 1))};
}

/// A 6 × 6 grid with its middle 2 × 2 quads removed: an annulus.
TriMesh make_annulus() {
  TriMesh g = make_grid(6, 6);
  for (const std::ptrdiff_t q : {3 * 6 + 3, 3 * 6 + 2, 2 * 6 + 3, 2 * 6 + 2})  // quads (i, j) at j * 6 + i
    g.faces.erase(g.faces.begin() + 2 * q, g.faces.begin() + 2 * q + 2);
  return g;
}

/// All face indices of a mesh.
std::vector<std::uint32_t> all_faces(const TriMesh& mesh) {
  std::vector<std::uint32_t> out(mesh.faces.size());
  for (std::uint32_t f = 0; f < out.size(); ++f) out[f] = f;
  return out;
}

TEST(Chartify, IcosphereChartsAreDisks) {
  const TriMesh sphere = make_icosphere(1.0, 3);
  for (std::uint32_t charts : {1u, 2u, 6u, 12u}) {
    SCOPED_TRACE("charts = " + std::to_string(charts));
    const Chartification c = chartify_checked(sphere, charts);
    if (charts == 1) {
      EXPECT_GE(c.num_charts, 2u);  // a closed chart is refused: one chart cannot cover a sphere
      EXPECT_GE(c.extra_seeds, 1u);
    }
  }
}

TEST(Chartify, TorusChartsAreDisks) {
  const TriMesh torus = make_torus(2.0, 0.6, 32, 16);
  for (std::uint32_t charts : {1u, 4u, 10u}) {
    SCOPED_TRACE("charts = " + std::to_string(charts));
    const Chartification c = chartify_checked(torus, charts);
    EXPECT_GE(c.num_charts, 2u);
  }
}

TEST(Chartify, HigherGenusSlabChartsAreDisks) {
  for (int genus : {2, 3}) {
    SCOPED_TRACE("genus = " + std::to_string(genus));
    const TriMesh slab = make_slab_with_holes(genus, 3);
    chartify_checked(slab, 8);
    chartify_checked(slab, 1);
  }
}

TEST(Chartify, GridWithBoundary) {
  const TriMesh grid = make_grid(20, 16);
  const Chartification one = chartify_checked(grid, 1);
  EXPECT_EQ(one.num_charts, 1u);  // a disk is one chart
  EXPECT_EQ(one.extra_seeds, 0u);
  const Chartification four = chartify_checked(grid, 4);
  EXPECT_EQ(four.num_charts, 4u);
  EXPECT_EQ(four.bootstrap_rounds, 3);  // no seed is needed for the disk rule on a flat disk
}

TEST(Chartify, EveryComponentGetsCharts) {
  TriMesh sphere = make_icosphere(1.0, 2);
  for (Vec3& p : sphere.positions) p += Vec3(5.0, 0.0, 0.0);
  const TriMesh torus = make_torus(2.0, 0.6, 16, 8);
  const TriMesh both = concatenate(sphere, torus);
  for (std::uint32_t charts : {1u, 2u, 8u}) {
    SCOPED_TRACE("charts = " + std::to_string(charts));
    const Chartification c = chartify_checked(both, charts);
    std::vector<char> in_sphere(c.num_charts, 0), in_torus(c.num_charts, 0);
    for (std::uint32_t f = 0; f < both.faces.size(); ++f)
      (f < sphere.faces.size() ? in_sphere : in_torus)[c.face_chart[f]] = 1;
    for (std::uint32_t k = 0; k < c.num_charts; ++k) EXPECT_FALSE(in_sphere[k] && in_torus[k]) << "chart " << k;
    EXPECT_GE(std::count(in_sphere.begin(), in_sphere.end(), 1), 2);  // closed: never one chart
    EXPECT_GE(std::count(in_torus.begin(), in_torus.end(), 1), 2);
  }
}

TEST(Chartify, ConvergesOrDetectsCycle) {
  const TriMesh sphere = make_icosphere(1.0, 4);
  ChartifyOptions options;
  options.charts = 10;
  const Chartification c = chartify(sphere, options);
  EXPECT_TRUE(c.converged || c.cycle || c.iterations == options.max_iterations);
  EXPECT_FALSE(c.converged && c.cycle);
  options.max_iterations = 2;
  const Chartification capped = chartify(sphere, options);
  expect_disk_charts(sphere, capped, options.charts, options.max_iterations);
  EXPECT_LE(capped.iterations, 2);
  EXPECT_TRUE(capped.converged || capped.cycle || capped.iterations == 2);
  options.max_iterations = 0;
  const Chartification none = chartify(sphere, options);
  EXPECT_EQ(none.iterations, 0);
  EXPECT_FALSE(none.converged || none.cycle);
  expect_disk_charts(sphere, none, options.charts, options.max_iterations);
}

TEST(Chartify, Reproducible) {
  const TriMesh torus = make_torus(2.0, 0.7, 24, 12);
  ChartifyOptions options;
  options.charts = 7;
  options.seed = 42;
  const Chartification a = chartify(torus, options);
  const Chartification b = chartify(torus, options);
  EXPECT_EQ(a.face_chart, b.face_chart);
  EXPECT_EQ(a.seeds, b.seeds);
  EXPECT_EQ(a.iterations, b.iterations);
  options.seed = 7;
  expect_disk_charts(torus, chartify(torus, options), options.charts);
}

TEST(Chartify, CubeChartsFollowItsSides) {
  const TriMesh cube = make_subdivided_box(8);
  const Chartification c = chartify_checked(cube, 6);
  EXPECT_EQ(c.num_charts, 6u);
  const auto [off_side, sides] = faces_off_main_side(cube, c);
  EXPECT_LE(off_side, cube.faces.size() / 50) << "faces of a chart off its main side";
  EXPECT_EQ(sides, 6u) << "one chart per side";
}

/// On a box four times longer than wide, charts of equal geodesic extent would split the long sides and wrap
/// the ends; the normal term of the growth cost keeps one chart per side.
TEST(Chartify, ElongatedBoxChartsFollowItsSides) {
  const TriMesh box = make_subdivided_box(8, 4.0);
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    SCOPED_TRACE("seed = " + std::to_string(seed));
    ChartifyOptions options;
    options.charts = 6;
    options.seed = seed;
    const Chartification c = chartify(box, options);
    expect_disk_charts(box, c, 6);
    const auto [off_side, sides] = faces_off_main_side(box, c);
    EXPECT_LE(off_side, box.faces.size() / 50) << "faces of a chart off its main side";
    EXPECT_EQ(sides, 6u) << "one chart per side";
  }
}

/// Two triangles glued along all three edges (a closed "pillow"): each must be its own chart.
TEST(Chartify, SmallestClosedSurface) {
  TriMesh pillow;
  pillow.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  pillow.faces = {{0, 1, 2}, {0, 2, 1}};
  const Chartification c = chartify_checked(pillow, 1);
  EXPECT_EQ(c.num_charts, 2u);
  EXPECT_NE(c.face_chart[0], c.face_chart[1]);
}

TEST(Chartify, ClampsChartsToFaces) {
  const TriMesh grid = make_grid(2, 1);  // 4 faces
  const Chartification c = chartify_checked(grid, 100);
  EXPECT_EQ(c.num_charts, 4u);
  EXPECT_EQ(c.extra_seeds, 0u);
}

TEST(Chartify, ReportsProgressAndCancels) {
  const TriMesh sphere = make_icosphere(1.0, 2);
  ChartifyOptions options;
  options.charts = 4;
  int calls = 0;
  double last = -1.0;
  options.progress = [&](std::string_view stage, double fraction) {
    EXPECT_EQ(stage, "chartify");
    EXPECT_GE(fraction, 0.0);
    EXPECT_LE(fraction, 1.0);
    EXPECT_GE(fraction, last);
    last = fraction;
    ++calls;
    return true;
  };
  const Chartification c = chartify(sphere, options);
  EXPECT_GE(calls, c.bootstrap_rounds + c.iterations + 1);
  EXPECT_EQ(last, 1.0);
  options.progress = [](std::string_view, double) { return false; };
  EXPECT_THROW((void)chartify(sphere, options), Cancelled);
}

TEST(Chartify, RejectsBadInput) {
  EXPECT_THROW((void)chartify(TriMesh{}), InvalidInput);
  TriMesh bad = make_grid(2, 2);
  bad.faces[1][2] = static_cast<std::uint32_t>(bad.positions.size());
  EXPECT_THROW((void)chartify(bad), InvalidInput);
  TriMesh repeated = make_grid(2, 2);
  repeated.faces[0][1] = repeated.faces[0][0];
  EXPECT_THROW((void)chartify(repeated), InvalidInput);
  TriMesh fin;  // three triangles on the edge (0, 1)
  fin.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(0, 0, 1)};
  fin.faces = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  EXPECT_THROW((void)chartify(fin), TopologyError);
  TriMesh flipped = make_grid(2, 2);
  std::swap(flipped.faces[0][1], flipped.faces[0][2]);
  EXPECT_THROW((void)chartify(flipped), TopologyError);
  TriMesh nan_vertex = make_grid(2, 2);
  nan_vertex.positions[0].x() = std::nan("");
  EXPECT_THROW((void)chartify(nan_vertex), InvalidInput);
  ChartifyOptions zero;
  zero.charts = 0;
  EXPECT_THROW((void)chartify(make_grid(2, 2), zero), InvalidInput);
  ChartifyOptions negative;
  negative.max_iterations = -1;
  EXPECT_THROW((void)chartify(make_grid(2, 2), negative), InvalidInput);
}

TEST(Chartify, DiskTest) {
  const TriMesh grid = make_grid(4, 4);
  EXPECT_TRUE(is_topological_disk(grid, all_faces(grid)));
  EXPECT_TRUE(is_topological_disk(grid, {0}));
  EXPECT_TRUE(is_topological_disk(grid, {0, 1}));
  EXPECT_FALSE(is_topological_disk(grid, {}));
  const TriMesh annulus = make_annulus();
  EXPECT_FALSE(is_topological_disk(annulus, all_faces(annulus)));
  TriMesh two;  // two separate triangles
  two.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(3, 0, 0), Vec3(4, 0, 0), Vec3(3, 1, 0)};
  two.faces = {{0, 1, 2}, {3, 4, 5}};
  EXPECT_FALSE(is_topological_disk(two, {0, 1}));
  EXPECT_TRUE(is_topological_disk(two, {1}));
  TriMesh bowtie;  // two triangles sharing only a vertex
  bowtie.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(-1, 0, 0), Vec3(0, -1, 0)};
  bowtie.faces = {{0, 1, 2}, {0, 3, 4}};
  EXPECT_FALSE(is_topological_disk(bowtie, {0, 1}));
  const TriMesh sphere = make_icosphere(1.0, 1);
  EXPECT_FALSE(is_topological_disk(sphere, all_faces(sphere)));  // closed
  std::vector<std::uint32_t> open = all_faces(sphere);
  open.pop_back();
  EXPECT_TRUE(is_topological_disk(sphere, open));
  EXPECT_THROW((void)is_topological_disk(grid, {static_cast<std::uint32_t>(grid.faces.size())}), InvalidInput);
}

}  // namespace
}  // namespace gimforge
