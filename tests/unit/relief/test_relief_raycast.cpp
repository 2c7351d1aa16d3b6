// Ray casting of relief maps (Apaza & Andújar §3.5.2) against the Embree reference render of the mesh:
// silhouettes, depths and shading of procedural solids (sphere, cube, rotated cube, torus) and of the
// bunny; single rays that must miss or hit; the orbit camera; the comparison; thread independence.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include "io/mesh_io.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/relief/mesh_render.h"
#include "kernels/relief/relief_map.h"
#include "kernels/relief/relief_raycast.h"
#include "tests/unit/test_support.h"

namespace gimforge {
namespace {

/// Axis-aligned cube [-1, 1]³, 12 triangles oriented outwards.
TriMesh make_cube() {
  TriMesh m;
  for (int i = 0; i < 8; ++i) m.positions.emplace_back(i & 1 ? 1.0 : -1.0, i & 2 ? 1.0 : -1.0, i & 4 ? 1.0 : -1.0);
  const std::uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                     {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    m.faces.push_back({q[0], q[1], q[2]});
    m.faces.push_back({q[0], q[2], q[3]});
  }
  return m;
}

/// `mesh` rotated by `angle_deg` about the unit axis `axis`.
TriMesh rotated(TriMesh mesh, const Vec3& axis, double angle_deg) {
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(angle_deg * std::numbers::pi / 180.0, axis.normalized()).toRotationMatrix();
  for (Vec3& p : mesh.positions) p = r * p;
  return mesh;
}

struct ViewResult {
  RenderComparison cmp;
  RenderImage relief;
  RenderImage reference;
};

/// Renders `mesh` and its relief map from `view` with both renderers.
ViewResult render_both(const TriMesh& mesh, const ReliefMap& map, const OrbitView& view, std::uint32_t size,
                       const RaycastOptions& options = {}) {
  const EmbreeDevice device;
  const MeshRenderer reference(device, mesh, options.ambient);
  const Camera camera = orbit_camera(bounding_box(mesh), view, size, size);
  ViewResult r;
  r.relief = ReliefRaycaster(map, options).render(camera);
  r.reference = reference.render(camera);
  r.cmp = compare_renders(r.relief, r.reference);
  return r;
}

/// Checks the agreement of the two renders of `mesh` from several views.
void expect_agreement(const TriMesh& mesh, const ReliefMap& map, double min_iou, double max_mean_depth,
                      double max_p95_depth, double min_psnr, const std::string& what) {
  const double diagonal = bounding_box(mesh).diagonal();
  const OrbitView views[] = {{30.0, 20.0}, {135.0, -35.0}, {250.0, 60.0}, {0.0, 0.0}};
  for (const OrbitView& view : views) {
    SCOPED_TRACE(what + " view " + std::to_string(view.azimuth_deg) + ", " + std::to_string(view.elevation_deg));
    const ViewResult r = render_both(mesh, map, view, 128);
    EXPECT_GT(r.cmp.hits_b, 1000u);
    EXPECT_GT(r.cmp.iou, min_iou);
    EXPECT_LT(r.cmp.depth_mean_abs / diagonal, max_mean_depth);
    EXPECT_LT(r.cmp.depth_p95 / diagonal, max_p95_depth);
    EXPECT_GT(r.cmp.psnr, min_psnr);
    EXPECT_EQ(r.relief.rays, 128u * 128u);
    EXPECT_EQ(r.relief.hits, r.cmp.hits_a);
  }
}

/// Two renders that must be the same pixel for pixel, with the same inside-test count.
void expect_same_render(const RenderImage& a, const RenderImage& b) {
  EXPECT_EQ(a.hits, b.hits);
  EXPECT_EQ(a.mask, b.mask);
  EXPECT_EQ(a.depth, b.depth);
  EXPECT_EQ(a.normal, b.normal);
  EXPECT_EQ(a.shaded, b.shaded);
  EXPECT_EQ(a.samples, b.samples);
}

ReliefMap build(const TriMesh& mesh, std::uint32_t grid, std::uint32_t texture) {
  ReliefOptions o;
  o.grid = grid;
  o.texture = texture;
  return build_relief_map(mesh, o);
}

// ---- agreement with the reference ----

TEST(ReliefRaycast, SphereAgreesWithEmbree) {
  const TriMesh sphere = make_icosphere(1.0, 4);
  for (const std::uint32_t grid : {1u, 4u, 8u}) {
    const ReliefMap map = build(sphere, grid, 64);
    expect_agreement(sphere, map, 0.98, 2e-3, 5e-3, 28.0, "sphere n = " + std::to_string(grid));
  }
}

TEST(ReliefRaycast, SurfaceBoundsMatchTheMesh) {
  const TriMesh sphere = make_icosphere(1.0, 4);
  const BoundingBox mesh_box = bounding_box(sphere);
  const BoundingBox box = relief_surface_bounds(build(sphere, 4, 64));
  ASSERT_FALSE(box.empty());
  EXPECT_LT((box.min - mesh_box.min).cwiseAbs().maxCoeff(), 0.02);
  EXPECT_LT((box.max - mesh_box.max).cwiseAbs().maxCoeff(), 0.02);
}

TEST(ReliefRaycast, CubeAgreesWithEmbree) {
  const TriMesh cube = make_cube();
  // Face-on, the rim pixels see the cube edge inside one texel of an axial cell: their normal blends the two
  // faces (the texel resolution), so the PSNR bound is lower than for smooth shapes.
  expect_agreement(cube, build(cube, 4, 64), 0.98, 2e-3, 5e-3, 20.0, "cube");
  const TriMesh tilted = rotated(make_cube(), Vec3(1.0, 2.0, 0.5), 37.0);
  expect_agreement(tilted, build(tilted, 8, 64), 0.98, 2e-3, 5e-3, 25.0, "rotated cube");
}

TEST(ReliefRaycast, TorusAgreesWithEmbree) {
  const TriMesh torus = make_torus(1.0, 0.35, 96, 48);
  expect_agreement(torus, build(torus, 8, 64), 0.98, 2e-3, 5e-3, 25.0, "torus");
}

TEST(ReliefRaycast, NearestFilterAgreesToo) {
  const TriMesh sphere = make_icosphere(1.0, 4);
  const ReliefMap map = build(sphere, 4, 64);
  RaycastOptions options;
  options.filter = ReliefFilter::Nearest;
  const ViewResult r = render_both(sphere, map, {30.0, 20.0}, 128, options);
  EXPECT_GT(r.cmp.iou, 0.98);
  EXPECT_LT(r.cmp.depth_mean_abs, 5e-3);
}

TEST(ReliefRaycast, BunnyAgreesWithEmbree) {
  const std::filesystem::path path = std::filesystem::path(GIMFORGE_SHARED_MESHES_DIR) / "bunny_closed.ply";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " is not there";
  const TriMesh bunny = io::read_mesh(path);
  // n = 16 has interior grey cells (case 6), whose centres the ray caster must classify.
  const ReliefMap map = build(bunny, 16, 32);
  std::size_t interior = 0;
  for (const std::uint8_t e : map.external_faces) interior += e == 0;
  EXPECT_GT(interior, 0u);
  const double diagonal = bounding_box(bunny).diagonal();
  for (const OrbitView& view : {OrbitView{30.0, 20.0}, OrbitView{210.0, 30.0}}) {
    const ViewResult r = render_both(bunny, map, view, 256);
    EXPECT_GT(r.cmp.iou, 0.98);
    EXPECT_LT(r.cmp.depth_mean_abs / diagonal, 2e-3);
    EXPECT_LT(r.cmp.depth_p95 / diagonal, 5e-3);
    EXPECT_GT(r.cmp.psnr, 28.0);
  }
}

TEST(ReliefRaycast, FineGridUsesTheHashedCellLookup) {
  // n > 160: the grey cells are looked up in a hash instead of a dense n³ table; same agreement.
  const TriMesh sphere = make_icosphere(1.0, 5);
  const ReliefMap map = build(sphere, 192, 4);
  const ViewResult r = render_both(sphere, map, {30.0, 20.0}, 128);
  EXPECT_GT(r.cmp.iou, 0.98);
  EXPECT_LT(r.cmp.depth_mean_abs, 4e-3);
  EXPECT_GT(r.cmp.psnr, 25.0);
}

// ---- single rays ----

TEST(ReliefRaycast, RaysThatMissTheObjectMiss) {
  const TriMesh sphere = make_icosphere(1.0, 4);
  const ReliefMap map = build(sphere, 4, 64);
  const ReliefRaycaster caster(map);
  // Away from the object, beside the bounding cube, and through a corner of the bounding cube (the
  // sphere fills the cube's inscribed ball, so a ray near a corner crosses grey cells but no surface).
  EXPECT_FALSE(caster.trace(Vec3(0, 0, 5), Vec3(0, 0, 1)).hit);
  EXPECT_FALSE(caster.trace(Vec3(3, 0, 5), Vec3(0, 0, -1)).hit);
  EXPECT_FALSE(caster.trace(Vec3(0.95, 0.95, 5), Vec3(0, 0, -1)).hit);
  EXPECT_FALSE(caster.trace(Vec3(-5, 0.9, 0.9), Vec3(1, 0, 0)).hit);
  // The reference agrees.
  const EmbreeDevice device;
  const MeshRenderer reference(device, sphere);
  EXPECT_FALSE(reference.trace(Vec3(0.95, 0.95, 5), Vec3(0, 0, -1)).hit);
}

TEST(ReliefRaycast, RayThroughTheCentreHitsTheSphere) {
  const TriMesh sphere = make_icosphere(1.0, 5);
  for (const std::uint32_t grid : {1u, 2u, 4u, 8u}) {
    SCOPED_TRACE("n = " + std::to_string(grid));
    const ReliefMap map = build(sphere, grid, 64);
    const ReliefRaycaster caster(map);
    for (const Vec3& dir : {Vec3(0, 0, -1), Vec3(1, 1, 1), Vec3(-0.3, 0.8, -0.2)}) {
      const Vec3 d = dir.normalized();
      const RayHit hit = caster.trace(-5.0 * d, 2.0 * d);  // direction need not be unit
      ASSERT_TRUE(hit.hit);
      EXPECT_NEAR(hit.t, 4.0, 5e-3);
      EXPECT_NEAR(hit.position.norm(), 1.0, 5e-3);
      EXPECT_NEAR(std::abs(hit.normal.dot(d)), 1.0, 2e-2);
      EXPECT_LT(hit.grey_cell, map.cells.size());
    }
  }
}

TEST(ReliefRaycast, StartingInsideTheBoundingCube) {
  // The eye inside the bounding cube but outside the object: the walk starts in the eye's cell.
  const TriMesh sphere = make_icosphere(1.0, 4);
  const ReliefMap map = build(sphere, 8, 64);
  const ReliefRaycaster caster(map);
  const RayHit hit = caster.trace(Vec3(0.9, 0.9, 0.0), Vec3(-1, -1, 0));
  ASSERT_TRUE(hit.hit);
  EXPECT_NEAR(hit.position.norm(), 1.0, 5e-3);
  EXPECT_NEAR(hit.t, std::sqrt(2.0) * 0.9 - 1.0, 5e-3);
}

TEST(ReliefRaycast, RejectsBadInput) {
  const TriMesh sphere = make_icosphere(1.0, 2);
  const ReliefMap map = build(sphere, 2, 16);
  RaycastOptions o;
  o.linear_steps = 0;
  EXPECT_THROW(ReliefRaycaster(map, o), InvalidInput);
  o = {};
  o.binary_steps = 33;
  EXPECT_THROW(ReliefRaycaster(map, o), InvalidInput);
  ReliefMap broken = map;
  broken.distances.pop_back();
  EXPECT_THROW(ReliefRaycaster{broken}, InvalidInput);
  const ReliefRaycaster caster(map);
  EXPECT_THROW((void)caster.trace(Vec3::Zero(), Vec3::Zero()), InvalidInput);
  Camera camera;
  camera.width = 0;
  EXPECT_THROW((void)caster.render(camera), InvalidInput);
  EXPECT_THROW((void)orbit_camera(BoundingBox{}, {}, 64, 64), InvalidInput);
  EXPECT_THROW((void)orbit_camera(bounding_box(sphere), OrbitView{0.0, 95.0}, 64, 64), InvalidInput);
}

// ---- camera, comparison, threads ----

TEST(OrbitCamera, LooksAtTheCentreAndFramesTheBoundingSphere) {
  BoundingBox box;
  box.extend(Vec3(1, 2, 3));
  box.extend(Vec3(3, 6, 4));
  const Vec3 centre(2, 4, 3.5);
  const double radius = 0.5 * box.diagonal();
  const Camera c = orbit_camera(box, OrbitView{0.0, 0.0}, 200, 100);
  EXPECT_LT((c.forward - Vec3(0, 0, -1)).norm(), 1e-12);  // up = y, azimuth 0: from +z
  EXPECT_LT((c.up - Vec3(0, 1, 0)).norm(), 1e-12);
  EXPECT_LT((c.right - Vec3(1, 0, 0)).norm(), 1e-12);
  EXPECT_LT((c.eye - centre).normalized().dot(Vec3(0, 0, 1)) - 1.0, 1e-12);
  // The centre pixel looks at the centre; the sphere's angular radius fits the narrower (vertical) half
  // field of view.
  EXPECT_GT(c.ray_direction(99.5, 49.5).dot((centre - c.eye).normalized()), 1.0 - 1e-12);
  const double half = std::atan(c.tan_half_fov);
  EXPECT_LT(std::asin(radius / (c.eye - centre).norm()), half);
  EXPECT_GT(std::asin(radius / (c.eye - centre).norm()), 0.8 * half);
  // Azimuth 90 with up = y looks from +x; up = z, azimuth 90, elevation 90 looks straight down.
  EXPECT_LT((orbit_camera(box, OrbitView{90.0, 0.0}, 64, 64).forward - Vec3(-1, 0, 0)).norm(), 1e-12);
  OrbitView top{90.0, 90.0};
  top.up_axis = 2;
  const Camera t = orbit_camera(box, top, 64, 64);
  EXPECT_LT((t.forward - Vec3(0, 0, -1)).norm(), 1e-12);
  EXPECT_NEAR(t.up.dot(t.forward), 0.0, 1e-12);
  EXPECT_NEAR(t.right.norm(), 1.0, 1e-12);
}

TEST(CompareRenders, IdenticalAndDifferentImages) {
  const TriMesh sphere = make_icosphere(1.0, 3);
  const EmbreeDevice device;
  const MeshRenderer reference(device, sphere);
  const Camera camera = orbit_camera(bounding_box(sphere), {}, 64, 48);
  const RenderImage a = reference.render(camera);
  const RenderComparison same = compare_renders(a, a);
  EXPECT_TRUE(std::isinf(same.psnr));
  EXPECT_EQ(same.iou, 1.0);
  EXPECT_EQ(same.depth_mean_abs, 0.0);
  RenderImage b = a;
  std::size_t changed = 0;
  for (std::size_t p = 0; p < b.mask.size(); ++p)
    if (b.mask[p] && changed < 10) {
      b.mask[p] = 0;
      b.shaded[p] = 0;
      ++changed;
    }
  const RenderComparison diff = compare_renders(b, a);
  EXPECT_EQ(diff.hits_either - diff.hits_both, 10u);
  EXPECT_NEAR(diff.iou, 1.0 - 10.0 / static_cast<double>(diff.hits_either), 1e-12);
  EXPECT_TRUE(std::isfinite(diff.psnr));
  const RenderImage c = reference.render(orbit_camera(bounding_box(sphere), {}, 32, 32));
  EXPECT_THROW((void)compare_renders(a, c), InvalidInput);
  EXPECT_EQ(a.shaded_rgb().size(), 3 * a.shaded.size());
}

TEST(ReliefRaycast, IndependentOfThreadCount) {
  const TriMesh torus = make_torus(1.0, 0.4, 64, 32);
  const ReliefMap map = build(torus, 8, 32);
  const ReliefRaycaster caster(map);
  const Camera camera = orbit_camera(bounding_box(torus), OrbitView{20.0, 50.0}, 96, 80);
  RenderImage one, two;
  {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = caster.render(camera);
  }
  {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    two = caster.render(camera);
  }
  EXPECT_EQ(one.mask, two.mask);
  EXPECT_EQ(one.shaded, two.shaded);
  EXPECT_EQ(one.depth, two.depth);
  EXPECT_EQ(one.samples, two.samples);
}

/// Solids whose relief maps at N = 8 have cells of every projection type: a torus and a rotated cube
/// (parallel, perspective and axial cells) and a tilted plate thinner than a cell (planar ones: two
/// opposite external faces).
struct ProjectionScenes {
  TriMesh torus = make_torus(1.0, 0.4, 64, 32);
  TriMesh tilted = rotated(make_cube(), Vec3(1.0, 2.0, 0.5), 37.0);
  TriMesh plate = make_plate();

  static TriMesh make_plate() {
    TriMesh plate = make_cube();
    for (Vec3& p : plate.positions) p.z() *= 0.04;
    return rotated(plate, Vec3(1.0, 2.0, 0.5), 20.0);
  }
};

TEST(ReliefRaycast, EmptySpaceCullingLeavesTheImageUnchanged) {
  // The cell and face bounds only skip samples they prove to be outside: the same image with fewer inside
  // tests, for every projection type and both filters, from far and from close up.
  const ProjectionScenes scenes;
  const auto& [torus, tilted, plate] = scenes;
  std::array<std::size_t, 4> types{};
  for (const TriMesh* mesh : std::array<const TriMesh*, 3>{&torus, &tilted, &plate}) {
    const ReliefMap map = build(*mesh, 8, 32);
    for (const CellProjection& p : map.projections) ++types[static_cast<std::size_t>(p.type)];
    for (const ReliefFilter filter : {ReliefFilter::Bilinear, ReliefFilter::Nearest}) {
      for (const double margin : {1.05, 0.4}) {
        RaycastOptions culled, full;
        culled.filter = full.filter = filter;
        full.cull_empty_space = false;
        const Camera camera = orbit_camera(bounding_box(*mesh), OrbitView{35.0, 25.0, 45.0, 2, margin}, 96, 96);
        const RenderImage a = ReliefRaycaster(map, culled).render(camera);
        const RenderImage b = ReliefRaycaster(map, full).render(camera);
        EXPECT_GT(a.hits, 1000u);
        EXPECT_EQ(a.mask, b.mask);
        EXPECT_EQ(a.depth, b.depth);
        EXPECT_EQ(a.shaded, b.shaded);
        EXPECT_LT(a.samples, b.samples);
      }
    }
  }
  for (const std::size_t count : types) EXPECT_GT(count, 0u);
}

TEST(ReliefRaycast, VectorizedMarchMatchesTheScalarOne) {
  // The AVX2 march evaluates 8 samples at a time with the scalar operations in the same order: the same
  // pixels, depths and inside-test counts for every projection type, both filters, border and interior
  // cells (the torus at N = 24 has them), with and without empty-space culling and for several
  // refinement depths.
  const ProjectionScenes solids;
  const auto& [torus, tilted, plate] = solids;
  const std::array<std::pair<const TriMesh*, std::uint32_t>, 4> scenes{
      {{&torus, 8}, {&tilted, 8}, {&plate, 8}, {&torus, 24}}};
  {
    const ReliefMap probe_map = build(torus, 8, 32);
    if (!ReliefRaycaster(probe_map).vectorized())
      GTEST_SKIP() << "this CPU has no AVX2: only the scalar march runs here";
  }
  std::array<std::size_t, 4> types{};
  std::size_t interior = 0;
  for (const auto& [mesh, grid] : scenes) {
    const ReliefMap map = build(*mesh, grid, 32);
    for (const CellProjection& p : map.projections) ++types[static_cast<std::size_t>(p.type)];
    for (const std::uint8_t faces : map.external_faces) interior += faces == 0 ? 1 : 0;
    for (const ReliefFilter filter : {ReliefFilter::Bilinear, ReliefFilter::Nearest}) {
      for (const std::uint32_t refine : {0u, 3u, 6u}) {
        for (const bool cull : {true, false}) {
          for (const double margin : {1.05, 0.4}) {
            SCOPED_TRACE(::testing::Message() << "grid " << grid << " filter " << static_cast<int>(filter)
                                              << " refine " << refine << " cull " << cull << " margin " << margin);
            RaycastOptions vector, scalar;
            vector.filter = scalar.filter = filter;
            vector.binary_steps = scalar.binary_steps = refine;
            vector.cull_empty_space = scalar.cull_empty_space = cull;
            scalar.vectorized = false;
            const ReliefRaycaster a_caster(map, vector), b_caster(map, scalar);
            ASSERT_TRUE(a_caster.vectorized());
            ASSERT_FALSE(b_caster.vectorized());
            const Camera camera = orbit_camera(bounding_box(*mesh), OrbitView{35.0, 25.0, 45.0, 2, margin}, 64, 64);
            const RenderImage a = a_caster.render(camera);
            const RenderImage b = b_caster.render(camera);
            EXPECT_GT(a.hits, 400u);
            expect_same_render(a, b);
          }
        }
      }
    }
  }
  for (const std::size_t count : types) EXPECT_GT(count, 0u);
  EXPECT_GT(interior, 0u);
}

TEST(ReliefRaycast, CellOrderRenderMatchesTheWalk) {
  // Drawing the cells front to back (the default) must find, for every pixel, the cell and the hit that
  // the pixel's ray finds by walking the grid: the same image and inside-test count, for every projection
  // type, from far, close up, with the eye inside the grid (cells cut by the plane of the eye), along an
  // axis (an odd image size gives rays with zero components) and with a camera whose axes are degenerate
  // (where the cell order falls back to the walk).
  const ProjectionScenes solids;
  const auto& [torus, tilted, plate] = solids;
  const std::array<std::pair<const TriMesh*, std::uint32_t>, 4> scenes{
      {{&torus, 8}, {&tilted, 8}, {&plate, 8}, {&torus, 24}}};
  std::size_t compared = 0;
  for (const auto& [mesh, grid] : scenes) {
    const ReliefMap map = build(*mesh, grid, 32);
    const BoundingBox box = bounding_box(*mesh);
    std::vector<std::pair<std::string, Camera>> cameras{
        {"far", orbit_camera(box, OrbitView{35.0, 25.0, 45.0, 2, 1.05}, 64, 48)},
        {"close", orbit_camera(box, OrbitView{200.0, -30.0, 45.0, 2, 0.4}, 64, 64)},
        {"axis", orbit_camera(box, OrbitView{0.0, 0.0, 40.0, 2, 0.9}, 65, 65)},
    };
    Camera inside = orbit_camera(box, OrbitView{60.0, 10.0, 90.0, 2, 1.0}, 64, 64);
    inside.eye = 0.5 * (box.min + box.max) + 0.3 * (box.max - box.min).cwiseProduct(Vec3(0.5, -0.4, 0.2));
    cameras.emplace_back("inside", inside);
    Camera degenerate = cameras.front().second;
    degenerate.up = degenerate.right;
    cameras.emplace_back("degenerate", degenerate);
    for (const auto& [name, camera] : cameras) {
      for (const bool vectorized : {true, false}) {
        SCOPED_TRACE(::testing::Message() << "grid " << grid << " camera " << name << " vectorized " << vectorized);
        RaycastOptions cells, walk;
        cells.vectorized = walk.vectorized = vectorized;
        walk.traversal = RenderTraversal::Walk;
        const RenderImage a = ReliefRaycaster(map, cells).render(camera);
        const RenderImage b = ReliefRaycaster(map, walk).render(camera);
        if (name != "degenerate") {
          EXPECT_GT(a.hits, 100u);
        }
        expect_same_render(a, b);
        ++compared;
      }
    }
  }
  EXPECT_EQ(compared, 40u);

  // The eye inside a cube, just inside its surface and 1e-6 cells before a grid plane, looking across the
  // plane: every ray leaves the eye's (grey) cell within 1e-6 cells, but hits the surface there. Cells
  // that reach into the pyramid of visible points nearest the eye must cover the whole image.
  const TriMesh cube = make_cube();
  const ReliefMap map = build(cube, 8, 32);
  const double plane = map.origin.y() + map.cell_size * std::round((0.0 - map.origin.y()) / map.cell_size);
  Camera sliver;
  sliver.eye = Vec3(1.0 - 1e-3, plane - 1e-6 * map.cell_size, 0.1);
  sliver.forward = Vec3(0.0, 1.0, 0.0);
  sliver.up = Vec3(0.0, 0.0, 1.0);
  sliver.right = sliver.forward.cross(sliver.up);
  sliver.width = sliver.height = 32;
  RaycastOptions walk;
  walk.traversal = RenderTraversal::Walk;
  const RenderImage a = ReliefRaycaster(map).render(sliver);
  const RenderImage b = ReliefRaycaster(map, walk).render(sliver);
  EXPECT_EQ(b.hits, 32u * 32u);
  EXPECT_LT(*std::max_element(b.depth.begin(), b.depth.end()), 1e-5 * map.cell_size);
  expect_same_render(a, b);
}

TEST(ShadeGrey, HeadlightLambertPlusAmbient) {
  EXPECT_EQ(shade_grey(Vec3(0, 0, 1), Vec3(0, 0, -1)), 255);
  EXPECT_EQ(shade_grey(Vec3(0, 0, 1), Vec3(0, 0, 1)), 255);  // two-sided
  EXPECT_EQ(shade_grey(Vec3(1, 0, 0), Vec3(0, 0, 1)), 38);   // ambient 0.15 · 255
  EXPECT_EQ(shade_grey(Vec3(1, 0, 0), Vec3(0, 0, 1), 0.0), 0);
}

}  // namespace
}  // namespace gimforge
