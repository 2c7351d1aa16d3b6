// The voxel closing of wrap.h. The dense byte grid does the parts OpenVDB has no direct tool for (the
// triangles' voxels, the closing's dilation, the flood fill of the outside, the erosion); OpenVDB turns the
// solid's voxels into a signed distance field and that into a closed mesh. This is the only translation unit
// of scan/ that includes OpenVDB.
#include "kernels/scan/wrap.h"

#include <fmt/format.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetUtil.h>
#include <openvdb/tools/Morphology.h>
#include <openvdb/tools/TopologyToLevelSet.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <span>
#include <vector>

#include "kernels/core/errors.h"

namespace gimforge {
namespace {

constexpr std::uint8_t kWall = 1;      // a voxel the surface (dilated by the closing) passes through
constexpr std::uint8_t kOutside = 2;   // reached from the grid's border without crossing a wall
constexpr std::uint8_t kMarked = 4;    // scratch of a dilation or erosion pass
constexpr std::uint64_t kMaxVoxels = std::uint64_t{1} << 30;  // one byte each
// The solid reaches about a voxel beyond the surface: a voxel counts when the surface passes anywhere through
// it, and the level set lies half a voxel beyond the last such voxel's centre. The mesh is extracted this many
// voxels inside the level set (the raw dragon scan at 512 voxels: mean distance wrap → scan 1.09 voxels at 0,
// 0.18 at 1).
constexpr double kInset = 1.0;

/// The dense grid: dims, index of (x, y, z), the 6 neighbours of an inner voxel.
struct Grid {
  std::array<std::size_t, 3> n{};
  std::vector<std::uint8_t> v;
  [[nodiscard]] std::size_t at(std::size_t x, std::size_t y, std::size_t z) const { return (z * n[1] + y) * n[0] + x; }
  /// Calls f(j) for the 6 face neighbours j of an inner voxel i.
  template <class F>
  void neighbours(std::size_t i, F&& f) const {
    const std::size_t sx = 1, sy = n[0], sz = n[0] * n[1];
    f(i - sx), f(i + sx), f(i - sy), f(i + sy), f(i - sz), f(i + sz);
  }
};

/// The voxel whose centre is nearest to `p` (voxel (i, j, k) has its centre at centre0 + voxel · (i, j, k)).
openvdb::Coord voxel_of(const Vec3& p, const Vec3& centre0, double voxel) {
  const Vec3 q = (p - centre0) / voxel;
  return openvdb::Coord(static_cast<openvdb::Int32>(std::floor(q.x() + 0.5)), static_cast<openvdb::Int32>(std::floor(q.y() + 0.5)),
                        static_cast<openvdb::Int32>(std::floor(q.z() + 0.5)));
}

/// Calls f(point) for points at most `spacing` apart covering face `f`, in rows parallel to its longest edge
/// (so a sliver costs its area, not its longest edge squared); returns how many.
template <class F>
std::size_t for_each_face_point(MeshView mesh, std::size_t f, double spacing, F&& visit) {
  std::array<Vec3, 3> p{mesh.positions[mesh.faces[f][0]], mesh.positions[mesh.faces[f][1]], mesh.positions[mesh.faces[f][2]]};
  int longest = 0;  // the edge p[k] → p[k + 1] that is longest becomes the base p[0] → p[1]
  for (int k = 1; k < 3; ++k)
    if ((p[static_cast<std::size_t>((k + 1) % 3)] - p[static_cast<std::size_t>(k)]).squaredNorm() >
        (p[static_cast<std::size_t>((longest + 1) % 3)] - p[static_cast<std::size_t>(longest)]).squaredNorm())
      longest = k;
  std::rotate(p.begin(), p.begin() + longest, p.end());
  const Vec3 base = p[1] - p[0];
  const double height = base.squaredNorm() > 0.0 ? (p[2] - p[0]).cross(base).norm() / base.norm() : (p[2] - p[0]).norm();
  const auto rows = static_cast<std::size_t>(std::ceil(height / spacing)) + 1;
  std::size_t count = 0;
  for (std::size_t i = 0; i <= rows; ++i) {  // row i: from p0 + t (p2 − p0) to p1 + t (p2 − p1)
    const double t = static_cast<double>(i) / static_cast<double>(rows);
    const Vec3 from = p[0] + t * (p[2] - p[0]), to = p[1] + t * (p[2] - p[1]);
    const auto steps = static_cast<std::size_t>(std::ceil((to - from).norm() / spacing)) + 1;
    for (std::size_t j = 0; j <= steps; ++j, ++count)
      visit(from + (to - from) * (static_cast<double>(j) / static_cast<double>(steps)));
  }
  return count;
}

/// Marks the voxels the triangles pass through: points at most half a voxel apart on every triangle.
void voxelize(MeshView mesh, const Vec3& origin, double voxel, Grid& g, const ProgressCallback& progress) {
  const auto mark = [&](const Vec3& p) {
    const Vec3 q = (p - origin) / voxel;
    g.v[g.at(static_cast<std::size_t>(q.x()), static_cast<std::size_t>(q.y()), static_cast<std::size_t>(q.z()))] = kWall;
  };
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    if (f % 65536 == 0) report_progress(progress, "wrap", 0.15 * static_cast<double>(f) / static_cast<double>(mesh.faces.size()));
    (void)for_each_face_point(mesh, f, 0.5 * voxel, mark);
  }
}

/// One pass of dilation (grow = true: every voxel with value `bit` spreads it to its face neighbours) or
/// erosion (a voxel with `bit` loses it when a face neighbour lacks it). The border layer stays as it is
/// (inner voxels only: their neighbours are in the grid).
void morph(Grid& g, std::uint8_t bit, bool grow) {
  for (std::size_t z = 1; z + 1 < g.n[2]; ++z)
    for (std::size_t y = 1; y + 1 < g.n[1]; ++y)
      for (std::size_t i = g.at(1, y, z), end = g.at(g.n[0] - 1, y, z); i < end; ++i) {
        if (((g.v[i] & bit) != 0) == grow) continue;
        bool hit = false;
        g.neighbours(i, [&](std::size_t j) { hit = hit || (((g.v[j] & bit) != 0) == grow); });
        if (hit) g.v[i] |= kMarked;
      }
  for (std::uint8_t& x : g.v)
    if (x & kMarked) x = static_cast<std::uint8_t>(grow ? (x | bit) & ~kMarked : x & ~(bit | kMarked));
}

/// Marks kOutside every voxel reachable from voxel (0, 0, 0) (in the border layer, which holds no wall and
/// joins every border voxel) through voxels that are not walls: a scanline fill, whose stack holds runs along
/// x rather than voxels.
void flood_outside(Grid& g) {
  struct Run {
    std::size_t x, y, z;
  };
  std::vector<Run> stack{{0, 0, 0}};
  const auto free = [&](std::size_t x, std::size_t y, std::size_t z) { return g.v[g.at(x, y, z)] == 0; };
  while (!stack.empty()) {
    const Run r = stack.back();
    stack.pop_back();
    if (!free(r.x, r.y, r.z)) continue;
    std::size_t x0 = r.x, x1 = r.x;
    while (x0 > 0 && free(x0 - 1, r.y, r.z)) --x0;
    while (x1 + 1 < g.n[0] && free(x1 + 1, r.y, r.z)) ++x1;
    for (std::size_t x = x0; x <= x1; ++x) g.v[g.at(x, r.y, r.z)] = kOutside;
    const auto row = [&](std::size_t y, std::size_t z) {  // push the first voxel of each free run over [x0, x1]
      for (std::size_t x = x0; x <= x1; ++x)
        if (free(x, y, z) && (x == x0 || !free(x - 1, y, z))) stack.push_back({x, y, z});
    };
    if (r.y > 0) row(r.y - 1, r.z);
    if (r.y + 1 < g.n[1]) row(r.y + 1, r.z);
    if (r.z > 0) row(r.y, r.z - 1);
    if (r.z + 1 < g.n[2]) row(r.y, r.z + 1);
  }
}

/// Keeps the piece of `m` with the most faces (pieces: faces joined through shared vertices).
void keep_largest_piece(TriMesh& m, WrapResult& out) {
  std::vector<std::uint32_t> parent(m.positions.size());
  std::iota(parent.begin(), parent.end(), 0u);
  const auto find = [&](std::uint32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  for (const Face& f : m.faces) parent[find(f[0])] = find(f[1]), parent[find(f[1])] = find(f[2]);
  std::vector<std::size_t> faces_of(m.positions.size(), 0);
  for (const Face& f : m.faces) ++faces_of[find(f[0])];
  const auto largest = static_cast<std::uint32_t>(std::max_element(faces_of.begin(), faces_of.end()) - faces_of.begin());
  for (std::size_t r = 0; r < faces_of.size(); ++r)
    if (faces_of[r] > 0 && r != largest) ++out.dropped_components, out.dropped_faces += faces_of[r];
  std::vector<std::uint32_t> index(m.positions.size(), ~0u);
  TriMesh kept;
  for (const Face& f : m.faces) {
    if (find(f[0]) != largest) continue;
    Face g{};
    for (int k = 0; k < 3; ++k) {
      std::uint32_t& i = index[f[static_cast<std::size_t>(k)]];
      if (i == ~0u) i = static_cast<std::uint32_t>(kept.positions.size()), kept.positions.push_back(m.positions[f[static_cast<std::size_t>(k)]]);
      g[static_cast<std::size_t>(k)] = i;
    }
    kept.faces.push_back(g);
  }
  m = std::move(kept);
}

/// The voxels within kNearVoxels (in each axis) of `points`, whose voxel (i, j, k) has its centre at
/// centre0 + voxel · (i, j, k).
openvdb::MaskGrid::Ptr near_voxels(std::span<const Vec3> points, const Vec3& centre0, double voxel) {
  openvdb::MaskGrid::Ptr near = openvdb::MaskGrid::create(false);
  auto access = near->getAccessor();
  for (const Vec3& p : points) access.setValueOn(voxel_of(p, centre0, voxel));
  openvdb::tools::dilateActiveValues(near->tree(), kNearVoxels, openvdb::tools::NN_FACE_EDGE_VERTEX,
                                     openvdb::tools::IGNORE_TILES, /*threaded=*/false);
  return near;
}

/// The share of `mesh`'s area whose points `away(point)` calls away: points every two voxels on each face stand
/// for its area. Blocks of faces run in parallel, each with its own `make_away()`, and are summed in order:
/// the same figure for any number of threads.
template <class MakeAway>
double area_share(MeshView mesh, double voxel, MakeAway&& make_away) {
  constexpr std::size_t kBlock = 16384;
  const std::size_t blocks = (mesh.faces.size() + kBlock - 1) / kBlock;
  std::vector<std::array<double, 2>> sums(blocks, {0.0, 0.0});  // area, area away
  tbb::parallel_for(std::size_t{0}, blocks, [&](std::size_t b) {
    auto away = make_away();
    for (std::size_t f = b * kBlock; f < std::min(mesh.faces.size(), (b + 1) * kBlock); ++f) {
      const double area = triangle_area(mesh, f);
      if (!(area > 0.0)) continue;
      std::size_t far = 0;
      const std::size_t count = for_each_face_point(mesh, f, 2.0 * voxel, [&](const Vec3& p) { if (away(p)) ++far; });
      sums[b][0] += area;
      sums[b][1] += area * static_cast<double>(far) / static_cast<double>(count);
    }
  });
  double total = 0.0, far = 0.0;
  for (const auto& s : sums) total += s[0], far += s[1];
  return total > 0.0 ? far / total : 0.0;
}

/// The share of `mesh`'s area farther than kNearVoxels (in each axis) from every vertex of `kept`.
double area_away_from(MeshView mesh, const TriMesh& kept, const Vec3& centre0, double voxel) {
  const openvdb::MaskGrid::Ptr near = near_voxels(kept.positions, centre0, voxel);
  return area_share(mesh, voxel, [&] {
    return [&, look = near->getConstAccessor()](const Vec3& p) { return !look.isValueOn(voxel_of(p, centre0, voxel)); };
  });
}

/// The share of `mesh`'s area outside the solid of the kept piece: the connected component of `solid` that
/// holds most of `kept`'s vertices, grown by a voxel. Surfaces sealed inside that solid (a hollow part's
/// inner wall) are in it; separate objects, and a part whose holes let the outside in, are not.
double area_outside_kept_solid(MeshView mesh, const openvdb::MaskGrid& solid, const TriMesh& kept, const Vec3& centre0,
                               double voxel) {
  std::vector<openvdb::MaskGrid::Ptr> segments;
  openvdb::tools::segmentActiveVoxels(solid, segments);
  if (segments.empty()) return 1.0;
  std::vector<std::size_t> votes(segments.size(), 0);
  const std::size_t stride = std::max<std::size_t>(1, kept.positions.size() / 4096);
  for (std::size_t v = 0; v < kept.positions.size(); v += stride) {
    const openvdb::Coord c = voxel_of(kept.positions[v], centre0, voxel);
    for (std::size_t s = 0; s < segments.size(); ++s)
      if (segments[s]->tree().isValueOn(c)) {
        ++votes[s];
        break;
      }
  }
  openvdb::MaskGrid::Ptr own = segments[static_cast<std::size_t>(std::max_element(votes.begin(), votes.end()) - votes.begin())];
  segments.clear();
  openvdb::tools::dilateActiveValues(own->tree(), 1, openvdb::tools::NN_FACE_EDGE_VERTEX, openvdb::tools::IGNORE_TILES,
                                     /*threaded=*/false);
  return area_share(mesh, voxel, [&] {
    return [&, look = own->getConstAccessor()](const Vec3& p) { return !look.isValueOn(voxel_of(p, centre0, voxel)); };
  });
}

}  // namespace

WrapResult wrap_surface(MeshView mesh, const WrapOptions& options) {
  if (options.resolution < 16 || options.resolution > 2048)
    throw InvalidInput(fmt::format("wrap: resolution {} is outside [16, 2048] voxels", options.resolution));
  if (options.closing > 16) throw InvalidInput(fmt::format("wrap: closing {} is outside [0, 16] voxels", options.closing));
  const BoundingBox box = bounding_box(mesh);
  const double longest = box.empty() ? 0.0 : (box.max - box.min).maxCoeff();
  if (mesh.faces.empty() || !(longest > 0.0) || !std::isfinite(longest)) throw InvalidInput("wrap: the mesh has no extent");
  WrapResult out;
  out.voxel = longest / options.resolution;
  const auto pad = static_cast<double>(options.closing + 3);
  const Vec3 origin = box.min - Vec3::Constant(pad * out.voxel);
  Grid g;
  std::uint64_t total = 1;
  for (int k = 0; k < 3; ++k) {
    const double cells = std::ceil((box.max[k] - box.min[k]) / out.voxel) + 2.0 * pad + 1.0;
    out.dims[static_cast<std::size_t>(k)] = static_cast<std::uint32_t>(cells);
    g.n[static_cast<std::size_t>(k)] = static_cast<std::size_t>(cells);
    total *= static_cast<std::uint64_t>(cells);
  }
  if (total > kMaxVoxels)
    throw InvalidInput(fmt::format("wrap: {}x{}x{} voxels exceed the {} a wrap may use (one byte each); a resolution of "
                                   "about {} fits this bounding box",
                                   out.dims[0], out.dims[1], out.dims[2], kMaxVoxels,
                                   static_cast<std::uint32_t>(0.98 * options.resolution *
                                                              std::cbrt(static_cast<double>(kMaxVoxels) / static_cast<double>(total)))));
  g.v.assign(static_cast<std::size_t>(total), 0);
  report_progress(options.progress, "wrap", 0.0);
  voxelize(mesh, origin, out.voxel, g, options.progress);
  report_progress(options.progress, "wrap", 0.15);
  for (std::uint32_t i = 0; i < options.closing; ++i) morph(g, kWall, true);
  flood_outside(g);
  for (std::uint8_t& x : g.v) x = x == kOutside ? 0 : kWall;  // the solid: walls and what they enclose
  for (std::uint32_t i = 0; i < options.closing; ++i) morph(g, kWall, false);
  report_progress(options.progress, "wrap", 0.4);
  std::vector<openvdb::Vec3s> points;
  std::vector<openvdb::Vec3I> triangles;
  std::vector<openvdb::Vec4I> quads;
  openvdb::MaskGrid::Ptr solid;  // kept for the area check below
  try {
    openvdb::initialize();
    // OpenVDB works in index space (voxel 1, its world the index): what it does depends on the voxels, never
    // on the mesh's units or position (a 5 mm part in metres has voxels of 1e-5, below what its transforms
    // take). The points come back to the mesh's frame below.
    solid = openvdb::MaskGrid::create(false);
    auto access = solid->getAccessor();
    for (std::size_t z = 0; z < g.n[2]; ++z)
      for (std::size_t y = 0; y < g.n[1]; ++y)
        for (std::size_t x = 0; x < g.n[0]; ++x)
          if (g.v[g.at(x, y, z)])
            access.setValueOn(openvdb::Coord(static_cast<openvdb::Int32>(x), static_cast<openvdb::Int32>(y),
                                             static_cast<openvdb::Int32>(z)));
    g.v = {};
    report_progress(options.progress, "wrap", 0.5);
    const openvdb::FloatGrid::Ptr level = openvdb::tools::topologyToLevelSet(*solid, 3, 0, 0, 1);
    report_progress(options.progress, "wrap", 0.8);
    // One voxel inside the solid's level set: see kInset.
    openvdb::tools::volumeToMesh(*level, points, triangles, quads, -kInset, 0.0);
  } catch (const openvdb::Exception& e) {
    throw LibraryError(fmt::format("OpenVDB: wrap: {}", e.what()));
  }
  TriMesh& m = out.mesh;
  m.positions.reserve(points.size());
  // Index (i, j, k) is the centre of dense voxel (i, j, k).
  const Vec3 centre0 = origin + Vec3::Constant(0.5 * out.voxel);
  for (const openvdb::Vec3s& p : points)
    m.positions.push_back(centre0 + out.voxel * Vec3(static_cast<double>(p.x()), static_cast<double>(p.y()),
                                                      static_cast<double>(p.z())));
  // Split in index space, where ties (a regular grid has many) break alike at any scale.
  const auto vertex = [&](unsigned i) {
    return Vec3(static_cast<double>(points[i].x()), static_cast<double>(points[i].y()), static_cast<double>(points[i].z()));
  };
  for (const openvdb::Vec3I& t : triangles) m.faces.push_back({t.x(), t.y(), t.z()});
  for (const openvdb::Vec4I& q : quads) {  // split on the shorter diagonal
    if ((vertex(q[0]) - vertex(q[2])).squaredNorm() <= (vertex(q[1]) - vertex(q[3])).squaredNorm())
      m.faces.push_back({q[0], q[1], q[2]}), m.faces.push_back({q[0], q[2], q[3]});
    else
      m.faces.push_back({q[0], q[1], q[3]}), m.faces.push_back({q[1], q[2], q[3]});
  }
  if (m.faces.empty())
    throw NumericalError(fmt::format("wrap: no closed surface came out: every part of the mesh is thinner than about "
                                     "two voxels of {:.4g} (a flat or one-sided sheet encloses nothing to wrap; a "
                                     "bounding box stretched by a far outlier makes the voxels large)",
                                     out.voxel));
  keep_largest_piece(m, out);
  // A hole wider than the closing lets the outside in: what is left is a shell a voxel thick, which the inset
  // breaks into crumbs. The largest then holds less than half of the wrap.
  if (out.dropped_faces > m.faces.size())
    throw NumericalError(fmt::format("wrap: the outside got in through a hole wider than the closing of {} voxel(s) "
                                     "(the largest of {} pieces holds {:.1f} % of the wrap): a larger closing C in "
                                     "--wrap R:C, up to 16, or a lower R seals it",
                                     options.closing, out.dropped_components + 1,
                                     100.0 * static_cast<double>(m.faces.size()) /
                                         static_cast<double>(m.faces.size() + out.dropped_faces)));
  try {
    out.area_left_out = area_away_from(mesh, m, centre0, out.voxel);
    // Much of the surface away from the kept piece: sealed inside its solid (a hollow part's inner wall, only
    // reported), or outside it (another object, or a part the outside got into), which one wrap cannot hold.
    if (out.area_left_out > options.max_area_left_out)
      out.area_outside = area_outside_kept_solid(mesh, *solid, m, centre0, out.voxel);
  } catch (const openvdb::Exception& e) {
    throw LibraryError(fmt::format("OpenVDB: wrap: {}", e.what()));
  }
  solid.reset();
  if (out.area_outside > options.max_area_left_out)
    throw NumericalError(fmt::format(
        "wrap: {:.1f} % of the mesh's area lies outside its largest piece: separate objects (one closed wrap keeps "
        "one; --method mcgim or relief, without --wrap, keep every piece), or a part whose holes let the outside in "
        "(a larger closing C in --wrap R:C seals holes up to about 2C voxels)",
        100.0 * out.area_outside));
  double volume = 0.0;  // outward faces give a positive volume
  for (const Face& f : m.faces) volume += m.positions[f[0]].dot(m.positions[f[1]].cross(m.positions[f[2]]));
  if (volume < 0.0)
    for (Face& f : m.faces) std::swap(f[1], f[2]);
  report_progress(options.progress, "wrap", 1.0);
  return out;
}

}  // namespace gimforge
