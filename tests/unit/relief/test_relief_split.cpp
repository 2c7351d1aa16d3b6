// Relief maps of a mesh whose faces are split into parts (what each rank of `mpirun convert --method relief`
// holds, jobs/brick_relief.h), without MPI: the parts' cell contributions combined by or / xor and finished,
// and their hits replayed in texel and face order, give the grid and the map of the whole mesh bit for bit.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/relief/relief_cells.h"
#include "kernels/relief/relief_map.h"

namespace gimforge {
namespace {

/// Part k of `parts`: every vertex, the faces f with f % parts == k (interleaved, so every cell and every
/// texel meets faces of several parts), and their indices in the whole mesh.
struct Part {
  TriMesh mesh;
  std::vector<std::uint64_t> ids;
};
std::vector<Part> split(const TriMesh& mesh, std::size_t parts) {
  std::vector<Part> out(parts);
  for (Part& p : out) p.mesh.positions = mesh.positions;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    out[f % parts].mesh.faces.push_back(mesh.faces[f]);
    out[f % parts].ids.push_back(f);
  }
  return out;
}

/// A wavy torus (closed: the flood fill decides) or, with a hole cut out and a zero-area face, an open one
/// (parity votes).
TriMesh wavy_torus(bool open) {
  TriMesh t = make_torus(1.0, 0.4, 48, 24);
  for (Vec3& p : t.positions) p += 0.05 * Vec3(std::sin(7 * p.y()), std::cos(5 * p.z()), std::sin(3 * p.x()));
  if (!open) return t;
  t.faces.erase(t.faces.begin() + 100, t.faces.begin() + 160);
  // A zero-area face with three distinct vertices takes part in the classification, not in the sampling.
  t.faces.push_back({0, 1, 1 + 24});
  t.positions[1 + 24] = 0.5 * (t.positions[0] + t.positions[1]);
  return t;
}

/// The map of `mesh` made from `parts` parts, as the ranks of brick_relief make it.
ReliefMap split_map(const TriMesh& mesh, std::size_t parts, const ReliefOptions& options, bool closed) {
  BoundingBox box;
  for (const Face& t : mesh.faces)
    for (std::uint32_t v : t) box.extend(mesh.positions[v]);
  const std::vector<Part> split_parts = split(mesh, parts);
  CellGridOptions co;
  co.n = options.grid;
  co.inside_test = options.inside_test;
  const bool parity = !(closed && options.inside_test == InsideTest::Automatic);
  std::vector<CellFaceParts> contributions;
  for (const Part& p : split_parts) contributions.push_back(cell_face_parts(p.mesh, box, co, parity));
  // What the allreduces do.
  CellFaceParts combined = contributions[0];
  for (std::size_t k = 1; k < parts; ++k) {
    for (std::size_t c = 0; c < combined.grey.size(); ++c) combined.grey[c] |= contributions[k].grey[c];
    for (std::size_t c = 0; c < combined.toggles.size(); ++c) combined.toggles[c] ^= contributions[k].toggles[c];
    for (std::size_t a = 0; a < 3; ++a)
      for (std::size_t r = 0; r < combined.line_parity[a].size(); ++r)
        combined.line_parity[a][r] ^= contributions[k].line_parity[a][r];
  }
  std::vector<ReliefHit> hits;
  ReliefMap map;
  for (std::size_t k = 0; k < parts; ++k) {
    CellFaceParts mine = combined;
    mine.pairs = contributions[k].pairs;  // the pairs stay with their part
    const CellGrid grid = finish_cell_grid(std::move(mine), closed, co);
    set_relief_layout(map, grid, options.texture);
    const std::vector<ReliefHit> h = sample_relief_hits(map, split_parts[k].mesh, grid, split_parts[k].ids);
    hits.insert(hits.end(), h.begin(), h.end());
  }
  std::sort(hits.begin(), hits.end(), [](const ReliefHit& a, const ReliefHit& b) {
    return a.texel != b.texel ? a.texel < b.texel : a.face < b.face;
  });
  const ReliefSampleCounts counts = resolve_relief_hits(map, hits);
  map.levels.push_back({options.grid, map.cells.size(), map.num_layers(), counts.samples, counts.occluded});
  return map;
}

void expect_same_map(const ReliefMap& a, const ReliefMap& b) {
  EXPECT_EQ(a.cells, b.cells);
  EXPECT_EQ(a.external_faces, b.external_faces);
  EXPECT_EQ(a.layer_face, b.layer_face);
  EXPECT_EQ(a.white_cells, b.white_cells);
  EXPECT_EQ(a.black_cells, b.black_cells);
  EXPECT_EQ(a.inside_method, b.inside_method);
  EXPECT_EQ(a.distances, b.distances);
  EXPECT_EQ(a.normals, b.normals);
  ASSERT_FALSE(a.levels.empty());
  ASSERT_FALSE(b.levels.empty());
  EXPECT_EQ(a.levels.back().samples, b.levels.back().samples);
  EXPECT_EQ(a.levels.back().occluded, b.levels.back().occluded);
  EXPECT_GT(a.levels.back().occluded, 0u);  // the replay's counting is exercised
}

TEST(ReliefSplit, ClosedMeshInPartsGivesTheWholeMeshsMap) {
  const TriMesh mesh = wavy_torus(false);
  for (const std::uint32_t n : {1u, 4u, 8u}) {
    ReliefOptions o;
    o.grid = n;
    o.texture = 16;
    const ReliefMap whole = build_relief_map(mesh, o);
    EXPECT_TRUE(whole.watertight_inside_test);
    for (const std::size_t parts : {2u, 3u}) {
      SCOPED_TRACE(testing::Message() << "n = " << n << ", parts = " << parts);
      expect_same_map(split_map(mesh, parts, o, is_closed_edge_manifold(mesh)), whole);
    }
  }
}

TEST(ReliefSplit, OpenMeshInPartsVotesAsTheWholeMesh) {
  const TriMesh mesh = wavy_torus(true);
  ASSERT_FALSE(is_closed_edge_manifold(mesh));
  ReliefOptions o;
  o.grid = 8;
  o.texture = 12;
  const ReliefMap whole = build_relief_map(mesh, o);
  EXPECT_FALSE(whole.watertight_inside_test);
  EXPECT_GT(whole.black_cells, 0u);
  expect_same_map(split_map(mesh, 3, o, false), whole);
  // Requested parity votes on the closed mesh too.
  const TriMesh closed = wavy_torus(false);
  o.inside_test = InsideTest::ParityVotes;
  expect_same_map(split_map(closed, 2, o, true), build_relief_map(closed, o));
}

TEST(ReliefSplit, CellsHoldingMoreTrianglesThanOneLoadReplayAsOneProcess) {
  // Both samplers load a cell's triangles 65,536 at a time: at grid 1 the one cell holds all 92,160.
  const TriMesh mesh = make_torus(1.0, 0.4, 384, 120);
  ReliefOptions o;
  o.grid = 1;
  o.texture = 24;
  const ReliefMap whole = build_relief_map(mesh, o);
  expect_same_map(split_map(mesh, 1, o, true), whole);
}

TEST(ReliefSplit, ResolveRejectsUnsortedHits) {
  const TriMesh mesh = wavy_torus(false);
  ReliefOptions o;
  o.grid = 2;
  o.texture = 8;
  ReliefMap map = build_relief_map(mesh, o);
  std::vector<ReliefHit> hits{{5, 9, 0.5, 1.0, {}, {}}, {5, 3, 0.4, 1.0, {}, {}}};
  EXPECT_THROW((void)resolve_relief_hits(map, hits), InvalidInput);
  hits = {{7, 1, 0.5, 1.0, {}, {}}, {6, 2, 0.4, 1.0, {}, {}}};
  EXPECT_THROW((void)resolve_relief_hits(map, hits), InvalidInput);
  hits = {{map.distances.size(), 1, 0.5, 1.0, {}, {}}};
  EXPECT_THROW((void)resolve_relief_hits(map, hits), InvalidInput);
}

}  // namespace
}  // namespace gimforge
