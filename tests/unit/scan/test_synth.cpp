// Synthetic scans (kernels/scan/synth.h) and the streamed PLY writer (io/ply_stream.h): sizes, topology,
// exact sharing of edge vertices, determinism, translation, and errors.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "io/mesh_io.h"
#include "io/ply_stream.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/core/topology.h"
#include "kernels/scan/synth.h"

namespace gimforge {
namespace {

TriMesh materialize(const SubdividedScan& scan) {
  TriMesh m;
  scan.vertices(0, scan.num_vertices(), m.positions);
  for (std::size_t f = 0; f < scan.num_base_faces(); ++f) scan.faces_of(f, m.faces);
  return m;
}

TriMesh materialize(const TerrainScan& scan, std::uint32_t ny) {
  TriMesh m;
  for (std::uint32_t y = 0; y <= ny; ++y) scan.vertex_row(y, m.positions);
  for (std::uint32_t y = 0; y < ny; ++y) scan.face_row(y, m.faces);
  return m;
}

TEST(SubdividedScan, KeepsTopologyAndCountsForEverySegmentCount) {
  const TriMesh torus = make_torus(2.0, 0.7, 12, 8);
  for (const std::uint32_t n : {1u, 2u, 3u, 5u}) {
    SubdivideOptions o;
    o.segments = n;
    const SubdividedScan scan(torus, o);
    const TriMesh m = materialize(scan);
    EXPECT_EQ(m.positions.size(), scan.num_vertices()) << n;
    EXPECT_EQ(m.faces.size(), torus.faces.size() * n * n) << n;
    // Euler: V − E + F stays 0 (genus 1); every vertex used; closed and manifold.
    const TopologyReport t = analyze_topology(m);
    EXPECT_TRUE(t.closed) << n;
    EXPECT_TRUE(t.manifold) << n;
    EXPECT_EQ(t.euler_characteristic, 0) << n;
    ASSERT_EQ(t.components.size(), 1u);
    EXPECT_EQ(t.components[0].genus, 1.0);
    EXPECT_EQ(t.referenced_vertices, t.vertices) << n;
    EXPECT_TRUE(t.oriented) << n;
  }
}

TEST(SubdividedScan, FlatSubdivisionLiesOnTheBaseAndDisplacementMovesIt) {
  const TriMesh sphere = make_icosphere(1.0, 1);
  SubdivideOptions o;
  o.segments = 4;
  o.amplitude = 0.0;
  const TriMesh flat = materialize(SubdividedScan(sphere, o));
  for (std::size_t v = 0; v < sphere.positions.size(); ++v) EXPECT_EQ(flat.positions[v], sphere.positions[v]);
  for (const Vec3& p : flat.positions) EXPECT_LE(p.norm(), 1.0 + 1e-12);  // on the base triangles: inside the sphere
  o.amplitude = 0.01;
  const TriMesh bumpy = materialize(SubdividedScan(sphere, o));
  double moved = 0.0;
  for (std::size_t v = 0; v < flat.positions.size(); ++v) moved = std::max(moved, (bumpy.positions[v] - flat.positions[v]).norm());
  EXPECT_GT(moved, 0.005);   // up to √6 · amplitude · diagonal (diagonal 2√3)
  EXPECT_LT(moved, 0.01 * 2.0 * std::sqrt(3.0) * 2.5);
}

TEST(SubdividedScan, PiecesAgreeWithTheWholeAndSeedsDiffer) {
  const TriMesh sphere = make_icosphere(1.0, 1);
  SubdivideOptions o;
  o.segments = 6;
  const SubdividedScan scan(sphere, o);
  std::vector<Vec3> whole, pieces;
  scan.vertices(0, scan.num_vertices(), whole);
  for (std::uint64_t first = 0; first < scan.num_vertices(); first += 37) scan.vertices(first, 37, pieces);
  ASSERT_EQ(whole.size(), pieces.size());
  for (std::size_t i = 0; i < whole.size(); ++i) EXPECT_EQ(whole[i], pieces[i]) << i;
  o.seed = 2;
  std::vector<Vec3> other;
  SubdividedScan(sphere, o).vertices(0, scan.num_vertices(), other);
  EXPECT_NE(other, whole);
}

TEST(SubdividedScan, TranslatedBaseGivesTheTranslatedScan) {
  TriMesh sphere = make_icosphere(1.0, 1);
  SubdivideOptions o;
  o.segments = 3;
  const TriMesh at_origin = materialize(SubdividedScan(sphere, o));
  const Vec3 shift(512000.0, 4100000.0, 250.0);
  for (Vec3& p : sphere.positions) p += shift;
  const TriMesh far = materialize(SubdividedScan(sphere, o));
  for (std::size_t v = 0; v < far.positions.size(); ++v) EXPECT_LT((far.positions[v] - shift - at_origin.positions[v]).norm(), 1e-9);
  o.offset = shift;
  sphere = make_icosphere(1.0, 1);
  const TriMesh offset = materialize(SubdividedScan(sphere, o));
  for (std::size_t v = 0; v < far.positions.size(); ++v) EXPECT_LT((offset.positions[v] - far.positions[v]).norm(), 1e-9);
}

TEST(SubdividedScan, RefusesBadInput) {
  const TriMesh sphere = make_icosphere(1.0, 0);
  SubdivideOptions o;
  o.segments = 0;
  EXPECT_THROW(SubdividedScan(sphere, o), InvalidInput);
  o = {};
  o.amplitude = -1.0;
  EXPECT_THROW(SubdividedScan(sphere, o), InvalidInput);
  o = {};
  o.wavelength = 0.0;
  EXPECT_THROW(SubdividedScan(sphere, o), InvalidInput);
  o = {};
  o.segments = 20000;  // 20 · 4·10⁸ faces
  EXPECT_THROW(SubdividedScan(sphere, o), InvalidInput);
  EXPECT_THROW(SubdividedScan(TriMesh{}, SubdivideOptions{}), InvalidInput);
  TriMesh bad = sphere;
  bad.faces[3][1] = 999;
  EXPECT_THROW(SubdividedScan(bad, SubdivideOptions{}), InvalidInput);
}

TEST(TerrainScan, OpenManifoldWithOneLoopPerHole) {
  for (const std::uint64_t seed : {1u, 2u, 3u, 4u, 5u}) {
    TerrainOptions o;
    o.nx = 90;
    o.ny = 70;
    o.holes = 3;
    o.hole_radius = 0.05;
    o.seed = seed;
    const TerrainScan scan(o);
    const TriMesh m = materialize(scan, o.ny);
    EXPECT_EQ(m.positions.size(), scan.num_vertices());
    EXPECT_EQ(m.faces.size(), scan.num_faces());
    EXPECT_LT(m.faces.size(), 2u * o.nx * o.ny);
    const TopologyReport t = analyze_topology(m);
    EXPECT_TRUE(t.manifold) << seed;
    EXPECT_EQ(t.referenced_vertices, t.vertices) << seed;
    EXPECT_TRUE(t.oriented) << seed;
    EXPECT_FALSE(t.closed);
    // Holes apart from each other and from the border give 1 + holes loops; overlapping ones fewer.
    EXPECT_GE(t.boundary_loops, 2u) << seed;
    EXPECT_LE(t.boundary_loops, 1u + o.holes) << seed;
  }
  TerrainOptions none;
  none.nx = 10;
  none.ny = 4;
  none.holes = 0;
  const TerrainScan plain(none);
  EXPECT_EQ(plain.num_faces(), 80u);
  EXPECT_EQ(plain.num_vertices(), 55u);
}

TEST(TerrainScan, RefusesBadInput) {
  TerrainOptions o;
  o.nx = 0;
  EXPECT_THROW(TerrainScan{o}, InvalidInput);
  o = {};
  o.spacing = 0.0;
  EXPECT_THROW(TerrainScan{o}, InvalidInput);
  o = {};
  o.noise = -0.1;
  EXPECT_THROW(TerrainScan{o}, InvalidInput);
  o = {};
  o.nx = o.ny = 70000;
  EXPECT_THROW(TerrainScan{o}, InvalidInput);
}

TEST(PlyStream, WritesWhatTheReaderReadsAndCommitsOnlyComplete) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("gf_plystream_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  TerrainOptions o;
  o.nx = 20;
  o.ny = 12;
  o.offset = Vec3(500000.0, 4100000.0, 30.0);
  const TerrainScan scan(o);
  const TriMesh m = materialize(scan, o.ny);
  const std::filesystem::path path = dir / "t.ply";
  io::write_ply_streamed(path, {m.positions.size(), m.faces.size(), true, "test"}, [&](io::PlyStreamWriter& w) {
    w.add_vertices({m.positions.data(), 7});
    w.add_vertices({m.positions.data() + 7, m.positions.size() - 7});
    w.add_faces(m.faces);
  });
  const TriMesh back = io::read_mesh(path);
  EXPECT_EQ(back.positions, m.positions);  // doubles: exact, far from the origin too
  EXPECT_EQ(back.faces, m.faces);
  // Too few faces, too many vertices, a bad index: an error and no file.
  const std::filesystem::path bad = dir / "bad.ply";
  EXPECT_THROW(io::write_ply_streamed(bad, {m.positions.size(), m.faces.size(), false, ""},
                                      [&](io::PlyStreamWriter& w) { w.add_vertices(m.positions); }),
               Error);
  EXPECT_THROW(io::write_ply_streamed(bad, {1, 0, false, ""}, [&](io::PlyStreamWriter& w) { w.add_vertices(m.positions); }),
               Error);
  EXPECT_THROW(io::write_ply_streamed(bad, {3, 1, false, ""},
                                      [&](io::PlyStreamWriter& w) {
                                        w.add_vertices({m.positions.data(), 3});
                                        w.add_faces(std::vector<Face>{{0, 1, 3}});
                                      }),
               InvalidInput);
  EXPECT_THROW(io::write_ply_streamed(bad, {0, 0, false, "two\nlines"}, [](io::PlyStreamWriter&) {}), InvalidInput);
  EXPECT_FALSE(std::filesystem::exists(bad));
  std::size_t files = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 1u);  // t.ply only: no temporary left behind
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace gimforge
