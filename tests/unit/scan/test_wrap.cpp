// The closed one-piece wrap of any surface (kernels/scan/wrap.h).
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/core/topology.h"
#include "kernels/scan/wrap.h"

namespace gimforge {
namespace {

/// The largest |distance from the origin − radius| over the vertices.
double radial_error(const TriMesh& m, double radius) {
  double worst = 0.0;
  for (const Vec3& p : m.positions) worst = std::max(worst, std::abs(p.norm() - radius));
  return worst;
}

/// Checks that `m` is one closed, oriented 2-manifold of genus `genus` with outward faces.
void expect_closed_piece(const TriMesh& m, int genus) {
  const TopologyReport t = analyze_topology(m);
  ASSERT_EQ(t.components.size(), 1u);
  EXPECT_TRUE(t.closed);
  EXPECT_TRUE(t.manifold);
  EXPECT_TRUE(t.oriented);
  EXPECT_EQ(t.components[0].genus, genus);
  double volume = 0.0;
  for (const Face& f : m.faces) volume += m.positions[f[0]].dot(m.positions[f[1]].cross(m.positions[f[2]]));
  EXPECT_GT(volume, 0.0);
}

TEST(Wrap, SealsTheHolesOfASphereAndStaysOnIt) {
  TriMesh holed = make_icosphere(1.0, 4);
  std::vector<Face> kept;  // every 7th face out: 732 holes of one triangle, and the sphere stays in one piece
  for (std::size_t f = 0; f < holed.faces.size(); ++f)
    if (f % 7 != 3) kept.push_back(holed.faces[f]);
  holed.faces = kept;
  ASSERT_GT(analyze_topology(holed).boundary_loops, 100u);
  WrapOptions o;
  o.resolution = 64;
  const WrapResult r = wrap_surface(holed, o);
  expect_closed_piece(r.mesh, 0);
  EXPECT_EQ(r.dropped_components, 0u);
  EXPECT_NEAR(r.voxel, 2.0 / 64, 0.05 / 64);
  // Within a voxel of the sphere (the chords of the icosphere are 0.4 % inside it).
  EXPECT_LT(radial_error(r.mesh, 1.0), r.voxel);
}

TEST(Wrap, TheWrapDoesNotDependOnTheMeshsUnits) {
  // A torus in metres, in fractions of a millimetre (voxels of 1e-5 and less, below what OpenVDB's transforms
  // take: it failed) and in kilometres: the same wrap, scaled (OpenVDB works in index space). Powers of two
  // round the voxelization's coordinates alike and give the same faces; another scale (a 5 mm part: 0.0025)
  // may move a wall voxel, but wraps all the same.
  const TriMesh torus = make_torus(1.0, 0.3, 48, 24);
  WrapOptions o;
  o.resolution = 64;
  const WrapResult one = wrap_surface(torus, o);
  TriMesh small = torus;
  for (Vec3& p : small.positions) p *= 0.0025;
  expect_closed_piece(wrap_surface(small, o).mesh, 1);
  for (const double scale : {1.0 / 4096.0, 1.0 / 1048576.0, 1024.0}) {  // powers of two: exact
    TriMesh scaled = torus;
    for (Vec3& p : scaled.positions) p *= scale;
    const WrapResult r = wrap_surface(scaled, o);
    ASSERT_EQ(r.mesh.faces, one.mesh.faces) << scale;
    ASSERT_EQ(r.mesh.positions.size(), one.mesh.positions.size()) << scale;
    double worst = 0.0;
    for (std::size_t i = 0; i < r.mesh.positions.size(); ++i)
      worst = std::max(worst, (r.mesh.positions[i] / scale - one.mesh.positions[i]).norm());
    EXPECT_LT(worst, 1e-9) << scale;
  }
}

TEST(Wrap, KeepsARealHandleAndTheLargestPiece) {
  // A torus (genus 1, tube radius 0.3: 19 voxels) and a small sphere far from it.
  TriMesh torus = make_torus(1.0, 0.3, 48, 24);
  TriMesh ball = make_icosphere(0.1, 2);
  for (Vec3& p : ball.positions) p += Vec3(2.0, 0.0, 0.0);
  WrapOptions o;
  o.resolution = 128;
  const WrapResult r = wrap_surface(concatenate(torus, ball), o);
  expect_closed_piece(r.mesh, 1);
  EXPECT_EQ(r.dropped_components, 1u);
  EXPECT_GT(r.dropped_faces, 0u);
  // The ball's share of the area (0.13 of 11.9 + 0.13) is what the kept piece leaves out.
  EXPECT_NEAR(r.area_left_out, 0.0104, 0.002);
}

TEST(Wrap, SeparateObjectsAreRefusedNotReducedToTheLargest) {
  // A torus beside a sphere of radius 0.8 (40 % of the area): one closed wrap keeps the torus alone, which an
  // image would then show as the whole input (a cow beside a fist kept the fist: 10 dB, exit 0).
  TriMesh ball = make_icosphere(0.8, 3);
  for (Vec3& p : ball.positions) p += Vec3(3.0, 0.0, 0.0);
  WrapOptions o;
  o.resolution = 128;
  try {
    (void)wrap_surface(concatenate(make_torus(1.0, 0.3, 48, 24), ball), o);
    ADD_FAILURE() << "no error";
  } catch (const NumericalError& e) {
    EXPECT_NE(std::string(e.what()).find("% of the mesh's area lies outside its largest piece"), std::string::npos) << e.what();
  }
  o.max_area_left_out = 0.5;  // allowed: the torus, with the ball's share measured
  const WrapResult r = wrap_surface(concatenate(make_torus(1.0, 0.3, 48, 24), ball), o);
  EXPECT_NEAR(r.area_left_out, 0.40, 0.03);
  EXPECT_EQ(r.area_outside, 0.0) << "measured only beyond max_area_left_out";
}

TEST(Wrap, AHollowPartsInnerWallIsSealedInsideNotRefused) {
  // A ball of radius 1 with an inner wall at 0.8 facing in (39 % of the area): the wrap fills the cavity and
  // keeps the outer surface; the inner wall is left out but is no separate object (a review found it refused).
  TriMesh inner = make_icosphere(0.8, 4);
  for (Face& f : inner.faces) std::swap(f[1], f[2]);
  WrapOptions o;
  o.resolution = 64;
  const WrapResult r = wrap_surface(concatenate(make_icosphere(1.0, 4), inner), o);
  expect_closed_piece(r.mesh, 0);
  EXPECT_NEAR(r.area_left_out, 0.39, 0.03);
  EXPECT_LT(r.area_outside, 0.01);
  EXPECT_LT(radial_error(r.mesh, 1.0), 2.0 * r.voxel);
}

TEST(Wrap, ASealedSurfaceLeavesNothingOut) {
  const WrapResult r = wrap_surface(make_torus(1.0, 0.3, 48, 24), WrapOptions{.resolution = 64});
  EXPECT_LT(r.area_left_out, 1e-3);
}

TEST(Wrap, ClosingSealsATunnelNarrowerThanItself) {
  // A slab with one hole of 1 × 1 cell through it (genus 1). At 8 voxels per cell (the slab is 3 cells
  // long, 24 voxels) the hole is 8 voxels wide: a closing of 2 keeps it, a closing of 5 seals it (genus 0).
  const TriMesh slab = make_slab_with_holes(1, 1);
  WrapOptions o;
  o.resolution = 24;
  o.closing = 2;
  expect_closed_piece(wrap_surface(slab, o).mesh, 1);
  o.closing = 5;
  expect_closed_piece(wrap_surface(slab, o).mesh, 0);
}

TEST(Wrap, AHoleWiderThanTheClosingIsAnErrorNotCrumbs) {
  // A sphere without its cap (a hole 38 voxels wide at 64): the outside gets in, the solid is a shell a voxel
  // thick that breaks into crumbs; that is refused, not passed on as the largest crumb.
  TriMesh open_ball = make_icosphere(1.0, 4);
  std::vector<Face> kept;
  for (const Face& f : open_ball.faces)
    if (open_ball.positions[f[0]].z() < 0.8 || open_ball.positions[f[1]].z() < 0.8 || open_ball.positions[f[2]].z() < 0.8)
      kept.push_back(f);
  open_ball.faces = kept;
  WrapOptions o;
  o.resolution = 64;
  try {
    (void)wrap_surface(open_ball, o);
    ADD_FAILURE() << "no error";
  } catch (const NumericalError& e) {
    EXPECT_NE(std::string(e.what()).find("the outside got in"), std::string::npos) << e.what();
  }
}

TEST(Wrap, RefusesBadOptionsAndEmptyMeshes) {
  const TriMesh ball = make_icosphere(1.0, 1);
  WrapOptions o;
  o.resolution = 8;
  EXPECT_THROW((void)wrap_surface(ball, o), InvalidInput);
  o.resolution = 4096;
  EXPECT_THROW((void)wrap_surface(ball, o), InvalidInput);
  o.resolution = 64;
  o.closing = 17;
  EXPECT_THROW((void)wrap_surface(ball, o), InvalidInput);
  EXPECT_THROW((void)wrap_surface(TriMesh{}, WrapOptions{}), InvalidInput);
  TriMesh flat_point;  // one degenerate face: no extent
  flat_point.positions = {Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  flat_point.faces = {{0, 1, 2}};
  EXPECT_THROW((void)wrap_surface(flat_point, WrapOptions{}), InvalidInput);
  o.resolution = 2048;  // a ball at 2048 voxels: 2048³ > 2^30 voxels
  o.closing = 1;
  EXPECT_THROW((void)wrap_surface(ball, o), InvalidInput);
}

}  // namespace
}  // namespace gimforge
