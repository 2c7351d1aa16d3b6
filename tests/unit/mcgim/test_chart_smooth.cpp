// Tests of kernels/mcgim/chart_smooth.h: the boundary smoothing after chartification — teeth and sharp
// corners move to the neighbouring chart, every chart stays a non-empty topological disk, the boundary only
// gets shorter, a straight boundary stays where it is.
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "kernels/core/procedural.h"
#include "kernels/mcgim/chart_smooth.h"
#include "kernels/mcgim/chartify.h"

namespace gimforge {
namespace {

/// Total 3D length of the edges whose two faces lie in different charts.
double boundary_length(const TriMesh& mesh, const std::vector<std::uint32_t>& face_chart) {
  double length = 0.0;
  for (std::uint32_t f = 0; f < mesh.faces.size(); ++f)
    for (std::uint32_t g = f + 1; g < mesh.faces.size(); ++g) {
      if (face_chart[f] == face_chart[g]) continue;
      int shared = 0;
      std::uint32_t ends[2] = {0, 0};
      for (std::uint32_t a : mesh.faces[f])
        for (std::uint32_t b : mesh.faces[g])
          if (a == b && shared < 2) ends[shared++] = a;
      if (shared == 2) length += (mesh.positions[ends[0]] - mesh.positions[ends[1]]).norm();
    }
  return length;
}

/// Checks that every one of `charts` charts is a non-empty topological disk.
void expect_disks(const TriMesh& mesh, const std::vector<std::uint32_t>& face_chart, std::uint32_t charts) {
  std::vector<std::vector<std::uint32_t>> faces(charts);
  for (std::uint32_t f = 0; f < face_chart.size(); ++f) {
    ASSERT_LT(face_chart[f], charts);
    faces[face_chart[f]].push_back(f);
  }
  for (std::uint32_t c = 0; c < charts; ++c) {
    EXPECT_FALSE(faces[c].empty()) << "chart " << c;
    EXPECT_TRUE(is_topological_disk(mesh, faces[c])) << "chart " << c;
  }
}

/// The centroid of face f.
Vec3 centroid(const TriMesh& mesh, std::uint32_t f) {
  const Face& t = mesh.faces[f];
  return (mesh.positions[t[0]] + mesh.positions[t[1]] + mesh.positions[t[2]]) / 3.0;
}

TEST(ChartSmooth, StraightBoundaryStays) {
  const TriMesh grid = make_grid(12, 12);
  std::vector<std::uint32_t> face_chart(grid.faces.size());
  for (std::uint32_t f = 0; f < grid.faces.size(); ++f) face_chart[f] = centroid(grid, f).x() < 0.5 ? 0 : 1;
  const std::vector<std::uint32_t> before = face_chart;
  const BoundarySmoothing s = smooth_chart_boundaries(grid, face_chart);
  EXPECT_EQ(face_chart, before);
  EXPECT_EQ(s.teeth + s.fan_faces, 0u);
  EXPECT_EQ(s.passes, 1);
}

TEST(ChartSmooth, ThinPeninsulaErodes) {
  // Chart 0: the left half plus a spike one quad high reaching across chart 1 almost to the right border
  // (a spike with right-angled corners and a flat tip, two quads high, would stay: no move shortens it).
  const TriMesh grid = make_grid(16, 16);
  std::vector<std::uint32_t> face_chart(grid.faces.size());
  const auto in_spike = [](const Vec3& p) { return p.x() < 0.9 && p.y() > 0.5 && p.y() < 0.5 + 1.0 / 16.0; };
  std::uint32_t spike_faces = 0;
  for (std::uint32_t f = 0; f < grid.faces.size(); ++f) {
    const Vec3 p = centroid(grid, f);
    face_chart[f] = p.x() < 0.5 || in_spike(p) ? 0 : 1;
    if (p.x() >= 0.5 && in_spike(p)) ++spike_faces;
  }
  expect_disks(grid, face_chart, 2);
  const double length_before = boundary_length(grid, face_chart);
  const BoundarySmoothing s = smooth_chart_boundaries(grid, face_chart);
  expect_disks(grid, face_chart, 2);
  EXPECT_LT(boundary_length(grid, face_chart), length_before);
  EXPECT_GT(s.fan_faces, 0u);
  std::uint32_t left = 0;  // spike faces still in chart 0
  for (std::uint32_t f = 0; f < grid.faces.size(); ++f) {
    const Vec3 p = centroid(grid, f);
    if (p.x() >= 0.5 && in_spike(p) && face_chart[f] == 0) ++left;
  }
  EXPECT_LT(left, spike_faces / 4) << "of " << spike_faces << " spike faces";
}

TEST(ChartSmooth, ZigzagTeethMove) {
  // A boundary with one-quad teeth: every other row of chart 0 reaches one quad further right.
  const TriMesh grid = make_grid(12, 12);
  std::vector<std::uint32_t> face_chart(grid.faces.size());
  for (std::uint32_t f = 0; f < grid.faces.size(); ++f) {
    const Vec3 p = centroid(grid, f);
    const int row = static_cast<int>(p.y() * 12.0);
    face_chart[f] = p.x() < (row % 2 == 0 ? 6.0 : 7.0) / 12.0 ? 0 : 1;
  }
  const double length_before = boundary_length(grid, face_chart);
  const BoundarySmoothing s = smooth_chart_boundaries(grid, face_chart);
  expect_disks(grid, face_chart, 2);
  EXPECT_GT(s.teeth + s.fan_faces, 0u);
  EXPECT_LT(boundary_length(grid, face_chart), length_before);
}

TEST(ChartSmooth, ChartifiedSurfacesStayDisks) {
  // Real chartifications of closed surfaces of genus 0 and 1: the smoothing keeps every chart a non-empty
  // disk, never lengthens the boundary, and leaves a mesh no moves are possible on unchanged when rerun.
  for (const TriMesh& mesh : {make_icosphere(1.0, 4), make_torus(2.0, 0.6, 48, 24)}) {
    ChartifyOptions options;
    options.charts = 12;
    const Chartification c = chartify(mesh, options);
    std::vector<std::uint32_t> face_chart = c.face_chart;
    const double length_before = boundary_length(mesh, face_chart);
    const BoundarySmoothing s = smooth_chart_boundaries(mesh, face_chart);
    expect_disks(mesh, face_chart, c.num_charts);
    EXPECT_LE(boundary_length(mesh, face_chart), length_before);
    if (s.teeth + s.fan_faces > 0) {
      EXPECT_LT(boundary_length(mesh, face_chart), length_before);
    }
    const std::vector<std::uint32_t> settled = face_chart;
    const BoundarySmoothing again = smooth_chart_boundaries(mesh, face_chart);
    EXPECT_EQ(face_chart, settled);
    EXPECT_EQ(again.teeth + again.fan_faces, 0u);
  }
}

}  // namespace
}  // namespace gimforge
