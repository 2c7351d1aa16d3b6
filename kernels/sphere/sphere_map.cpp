#include "kernels/sphere/sphere_map.h"

#include <chrono>
#include <cmath>
#include <numbers>
#include <unordered_map>

#include <fmt/format.h>

#include "kernels/core/edge_topology.h"
#include "kernels/core/errors.h"
#include "kernels/param/progressive_mesh.h"
#include "kernels/sphere/sphere_vertex_optimizer.h"
#include "kernels/core/topology.h"

namespace gimforge {
namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Shape quality 4√3·area / Σ edge² (1 for an equilateral triangle, 0 for a degenerate one).
double triangle_quality(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double edges = (b - a).squaredNorm() + (c - b).squaredNorm() + (a - c).squaredNorm();
  if (!(edges > 0.0)) return 0.0;
  return 2.0 * std::sqrt(3.0) * (b - a).cross(c - a).norm() / edges;
}

/// Collapse filter of the first simplification pass (§3.5, "favoring triangles with good aspect ratios"):
/// a collapse may not create a triangle of quality below `min_quality` unless it improves on the worst
/// triangle it replaces.
ProgressiveMesh::CollapseFilter keeps_shapes(double min_quality) {
  return [min_quality](const ProgressiveMesh& pm, std::uint32_t v, std::uint32_t w) {
    const auto& p = pm.input().positions;
    double before = 1.0, after = 1.0;
    for (std::uint32_t f : pm.vertex_faces(v)) {
      const Face& t = pm.faces()[f];
      before = std::min(before, triangle_quality(p[t[0]], p[t[1]], p[t[2]]));
      if (t[0] == w || t[1] == w || t[2] == w) continue;  // removed by the collapse
      const std::size_t c = detail::corner_of(t, v);
      Face moved = t;
      moved[c] = w;
      after = std::min(after, triangle_quality(p[moved[0]], p[moved[1]], p[moved[2]]));
    }
    return after >= min_quality || after >= before;
  };
}

void check_topology(MeshView mesh) {
  const TopologyReport t = analyze_topology(mesh);
  const auto hint = "spherical parametrization maps one genus-0 surface (its holes filled first) onto the sphere; "
                    "for another genus use geometry images (--method gim), for several components multi-chart "
                    "geometry images";
  if (t.faces == 0) throw TopologyError("the mesh has no faces");
  if (!t.manifold)
    throw TopologyError(fmt::format("the mesh is not manifold ({} non-manifold edges, {} non-manifold vertices); {}",
                                    t.nonmanifold_edges, t.nonmanifold_vertices, hint));
  if (!t.oriented) throw TopologyError("the mesh is not consistently oriented");
  if (t.components.size() != 1)
    throw TopologyError(fmt::format("the mesh has {} connected components; {}", t.components.size(), hint));
  if (!t.closed)
    throw TopologyError(fmt::format("the mesh has {} boundary loops (fill them first); {}", t.boundary_loops, hint));
  if (t.euler_characteristic != 2)
    throw TopologyError(fmt::format("the surface has genus {} (Euler characteristic {}), not 0; spherical "
                                    "parametrization maps genus-0 surfaces only: for another genus use geometry "
                                    "images or multi-chart geometry images",
                                    t.components.front().genus, t.euler_characteristic));
}

/// Per-face energy of the surface map: stretch + ε (A_M/4π)^(p/2+1) · inverse stretch, scaled for holes.
class SurfaceEnergy {
 public:
  SurfaceEnergy(const ProgressiveMesh& pm, std::span<const char> hole_faces, const SphereMapOptions& o, double area)
      : pm_(&pm), holes_(hole_faces), stretch_(o.stretch), hole_weight_(o.hole_weight),
        inverse_weight_(o.stretch.epsilon * std::pow(area / (4.0 * std::numbers::pi), o.stretch.power / 2.0 + 1.0)) {
    stretch_.max_chord = std::max(o.stretch.max_chord, o.optimize_max_chord);
  }

  double operator()(std::uint32_t f, const Vec3& s0, const Vec3& s1, const Vec3& s2) const {
    const Face& t = pm_->faces()[f];
    const auto& q = pm_->input().positions;
    const SphericalTriangleStretch s = spherical_triangle_stretch(q[t[0]], q[t[1]], q[t[2]], s0, s1, s2, stretch_);
    if (s.flipped) return std::numeric_limits<double>::infinity();
    const double e = s.stretch + inverse_weight_ * s.inverse;
    return !holes_.empty() && holes_[f] ? hole_weight_ * e : e;
  }

 private:
  const ProgressiveMesh* pm_;
  std::span<const char> holes_;
  SphericalStretchOptions stretch_;
  double hole_weight_;
  double inverse_weight_;
};

using Optimizer = detail::SphereVertexOptimizer<ProgressiveMesh, SurfaceEnergy>;

/// Maps the base tetrahedron onto the regular tetrahedron inscribed in the sphere, positively oriented.
void place_base(const ProgressiveMesh& pm, std::vector<Vec3>& sphere) {
  const std::vector<Face> faces = pm.alive_faces();
  if (faces.size() != 4 || pm.alive_vertices() != 4)
    throw NumericalError(fmt::format("spherical parametrization: simplification stopped at {} vertices and {} faces "
                                     "instead of a tetrahedron",
                                     pm.alive_vertices(), faces.size()));
  const double k = 1.0 / std::sqrt(3.0);
  const Vec3 t[4] = {Vec3(k, k, k), Vec3(k, -k, -k), Vec3(-k, k, -k), Vec3(-k, -k, k)};  // (t0,t1,t2) positive
  const Face& f = faces.front();
  std::uint32_t d = f[0];
  for (const Face& g : faces)
    for (std::uint32_t c : g)
      if (c != f[0] && c != f[1] && c != f[2]) d = c;
  sphere[f[0]] = t[0];
  sphere[f[1]] = t[1];
  sphere[f[2]] = t[2];
  sphere[d] = t[3];
}

/// The two ring neighbours a, b that flank the edge (vertex, target) of a split, so that the faces removed
/// by the collapse were (vertex, target, a) and (vertex, b, target).
std::pair<std::uint32_t, std::uint32_t> flanking(const ProgressiveMesh& pm, const VertexSplitRecord& rec) {
  std::uint32_t a = rec.target, b = rec.target;
  for (std::uint32_t f : rec.removed_faces) {
    const Face& t = pm.faces()[f];
    const std::size_t c = detail::corner_of(t, rec.vertex);
    const std::uint32_t x = t[(c + 1) % 3], y = t[(c + 2) % 3];
    if (x == rec.target) a = y;
    if (y == rec.target) b = x;
  }
  return {a, b};
}

/// A point inside the kernel of a re-inserted vertex's ring: the normalized ring centroid when it is
/// inside, else a point just off the target in the sector that the split re-opens (valid for small enough
/// steps because the coarser map was an embedding).
bool initial_inside(const ProgressiveMesh& pm, const Optimizer& opt, const std::vector<Vec3>& sphere,
                    const VertexSplitRecord& rec, std::vector<std::uint32_t>& ring, Vec3& out) {
  const std::uint32_t v = rec.vertex, w = rec.target;
  pm.neighbours(v, ring);
  Vec3 sum = Vec3::Zero();
  for (std::uint32_t u : ring) sum += sphere[u];
  if (sum.norm() > 1e-12 && opt.valid_at(v, sum.normalized())) {
    out = sum.normalized();
    return true;
  }
  const auto [a, b] = flanking(pm, rec);
  if (a == w || b == w) return false;
  const Vec3& sw = sphere[w];
  const auto [e1, e2] = detail::tangent_frame(sw);
  // Copies, not a capture of the bindings themselves: clang before 16 cannot capture structured bindings.
  auto tangent = [t1 = e1, t2 = e2](const Vec3& s) { return Vec2(s.dot(t1), s.dot(t2)).normalized(); };
  const Vec2 ua = tangent(sphere[a]), ub = tangent(sphere[b]);
  double theta = std::atan2(ua.x() * ub.y() - ua.y() * ub.x(), ua.dot(ub));
  if (theta <= 0.0) theta += 2.0 * std::numbers::pi;
  const double half = theta / 2.0;
  const Vec2 dir(ua.x() * std::cos(half) - ua.y() * std::sin(half), ua.x() * std::sin(half) + ua.y() * std::cos(half));
  const Vec3 d3 = dir.x() * e1 + dir.y() * e2;
  double step = 0.5 * std::min((sphere[a] - sw).norm(), (sphere[b] - sw).norm());
  for (int i = 0; i < 80; ++i, step *= 0.5) {
    const Vec3 x = (sw + step * d3).normalized();
    if (opt.valid_at(v, x)) {
      out = x;
      return true;
    }
  }
  return false;
}

std::vector<std::uint32_t> alive_vertices(const ProgressiveMesh& pm) {
  std::vector<std::uint32_t> out;
  for (std::uint32_t v = 0; v < pm.input().positions.size(); ++v)
    if (pm.vertex_alive(v)) out.push_back(v);
  return out;
}

/// Debug builds verify the embedding after every stage (the final check runs always).
void debug_check_embedding([[maybe_unused]] const ProgressiveMesh& pm, [[maybe_unused]] std::span<const Vec3> sphere,
                           [[maybe_unused]] const char* stage) {
#ifndef NDEBUG
  const std::vector<Face> faces = pm.alive_faces();
  const std::size_t flipped = count_flipped_spherical(MeshView(pm.input().positions, faces), sphere);
  if (flipped != 0)
    throw NumericalError(fmt::format("spherical parametrization: {} flipped spherical triangles after {}", flipped,
                                     stage));
#endif
}

}  // namespace

std::size_t count_flipped_spherical(MeshView mesh, std::span<const Vec3> sphere) {
  if (sphere.size() != mesh.positions.size())
    throw InvalidInput(fmt::format("count_flipped_spherical: {} sphere points for {} vertices", sphere.size(),
                                   mesh.positions.size()));
  std::size_t flipped = 0;
  for (const Face& f : mesh.faces)
    if (!(sphere[f[0]].dot(sphere[f[1]].cross(sphere[f[2]])) > 0.0)) ++flipped;
  return flipped;
}

FilledMesh fill_holes(const TriMesh& mesh) {
  FilledMesh out;
  out.mesh = mesh;
  out.hole_face.assign(mesh.faces.size(), 0);
  const EdgeTopology topo = build_edge_topology(mesh);
  // The boundary halfedges, by tail vertex (a manifold boundary has one per boundary vertex).
  std::unordered_map<std::uint32_t, std::size_t> outgoing;
  std::vector<std::size_t> boundary;
  for (std::size_t e = 0; e < topo.num_edges(); ++e) {
    if (topo.valence(e) != 1) continue;
    const std::size_t h = topo.edge_halfedges[topo.edge_offsets[e]];
    if (!outgoing.emplace(halfedge_tail(mesh, h), h).second)
      throw TopologyError(fmt::format("fill holes: vertex {} lies on two boundary loops (a pinched boundary)",
                                      halfedge_tail(mesh, h)));
    boundary.push_back(h);
  }
  std::vector<char> used(mesh.faces.size() * 3, 0);
  for (std::size_t start : boundary) {
    if (used[start]) continue;
    std::vector<std::uint32_t> loop;
    for (std::size_t h = start; !used[h];) {
      used[h] = 1;
      loop.push_back(halfedge_tail(mesh, h));
      const auto next = outgoing.find(halfedge_head(mesh, h));
      if (next == outgoing.end())
        throw TopologyError(fmt::format("fill holes: the boundary at vertex {} does not close",
                                        halfedge_head(mesh, h)));
      h = next->second;
    }
    Vec3 centre = Vec3::Zero();
    for (std::uint32_t v : loop) centre += mesh.positions[v];
    const auto c = static_cast<std::uint32_t>(out.mesh.positions.size());
    out.mesh.positions.push_back(centre / static_cast<double>(loop.size()));
    if (!out.mesh.colors.empty()) out.mesh.colors.push_back(Vec3f(0.5f, 0.5f, 0.5f));
    if (!out.mesh.normals.empty()) out.mesh.normals.push_back(Vec3f::Zero());
    for (std::size_t i = 0; i < loop.size(); ++i) {
      // The boundary runs a → b in its face; the hole face runs b → a.
      out.mesh.faces.push_back({loop[(i + 1) % loop.size()], loop[i], c});
      out.hole_face.push_back(1);
    }
    ++out.holes;
  }
  return out;
}

SphereMapResult spherical_parametrization(MeshView mesh, std::span<const char> hole_faces,
                                          const SphereMapOptions& options) {
  if (!hole_faces.empty() && hole_faces.size() != mesh.faces.size())
    throw InvalidInput(fmt::format("spherical_parametrization: {} hole flags for {} faces", hole_faces.size(),
                                   mesh.faces.size()));
  if (!(options.refine_factor > 1.0) || !(options.tolerance > 0.0) || !(options.hole_weight > 0.0))
    throw InvalidInput("spherical_parametrization: refine_factor must be > 1, tolerance and hole_weight > 0");
  check_topology(mesh);
  SphereMapResult result;
  result.sphere.assign(mesh.positions.size(), Vec3::UnitZ());

  auto t0 = std::chrono::steady_clock::now();
  ProgressiveMesh pm(mesh, {});
  pm.simplify(4, keeps_shapes(options.simplify_min_quality), options.progress, "simplify");
  if (pm.alive_vertices() > 4) pm.simplify(4, {}, options.progress, "simplify");
  result.seconds_simplify = seconds_since(t0);

  t0 = std::chrono::steady_clock::now();
  double area = 0.0;
  for (const Face& f : mesh.faces)
    area += 0.5 * (mesh.positions[f[1]] - mesh.positions[f[0]]).cross(mesh.positions[f[2]] - mesh.positions[f[0]]).norm();
  place_base(pm, result.sphere);
  Optimizer opt(pm, result.sphere, SurfaceEnergy(pm, hole_faces, options, area), options.seed);
  std::vector<std::uint32_t> ring;
  std::vector<std::uint32_t> alive = alive_vertices(pm);
  opt.priority_sweep(alive, options.tolerance, 200);
  debug_check_embedding(pm, result.sphere, "the base");

  const std::size_t total = pm.pending_splits();
  double next_sweep = static_cast<double>(pm.alive_vertices()) * options.refine_factor;
  for (std::size_t done = 0; pm.pending_splits() > 0; ++done) {
    const VertexSplitRecord rec = pm.next_split();
    const std::uint32_t v = pm.split();
    Vec3 inside;
    if (!initial_inside(pm, opt, result.sphere, rec, ring, inside))
      throw NumericalError(fmt::format("spherical parametrization: no valid position for re-inserted vertex {} (the "
                                       "map degenerated, as it does for shapes too elongated or thin for one sphere "
                                       "map: --method mcgim or relief convert them)", v));
    result.sphere[v] = opt.kernel_centroid(v, inside);
    opt.optimize(v);
    pm.neighbours(v, ring);
    for (std::uint32_t u : ring) opt.optimize(u);
    if (static_cast<double>(pm.alive_vertices()) >= next_sweep && pm.pending_splits() > 0) {
      alive = alive_vertices(pm);
      opt.priority_sweep(alive, options.tolerance, static_cast<std::size_t>(options.sweep_budget * static_cast<double>(alive.size())));
      next_sweep *= options.refine_factor;
      debug_check_embedding(pm, result.sphere, "a sweep");
    }
    if ((done & 1023u) == 0)
      report_progress(options.progress, "refine", static_cast<double>(done) / static_cast<double>(std::max<std::size_t>(1, total)));
  }
  report_progress(options.progress, "refine", 1.0);
  result.vertex_splits = total;
  alive = alive_vertices(pm);
  for (int i = 0; i < options.final_sweeps; ++i) {
    report_progress(options.progress, "sweep", static_cast<double>(i) / std::max(1, options.final_sweeps));
    opt.priority_sweep(alive, options.tolerance, alive.size());
  }
  report_progress(options.progress, "sweep", 1.0);
  result.seconds_optimize = seconds_since(t0);

  result.flipped = count_flipped_spherical(mesh, result.sphere);
  if (result.flipped != 0)
    throw NumericalError(fmt::format("spherical parametrization: {} spherical triangles flipped or degenerate",
                                     result.flipped));
  result.stretch = spherical_stretch(mesh, result.sphere, options.stretch);
  return result;
}

}  // namespace gimforge
