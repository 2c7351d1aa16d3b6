#include "kernels/scan/surface_transfer.h"

#include <atomic>
#include <cmath>
#include <limits>
#include <optional>

#include <embree3/rtcore.h>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "kernels/core/embree_scene.h"
#include "kernels/core/errors.h"

namespace gimforge {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Barycentric interpolation of per-vertex vectors over face f, normalized (zero stays zero).
Vec3 interpolate_normal(MeshView mesh, std::span<const Vec3> normals, std::uint32_t f, const Vec3& bary) {
  const Face& face = mesh.faces[f];
  const Vec3 n = bary.x() * normals[face[0]] + bary.y() * normals[face[1]] + bary.z() * normals[face[2]];
  const double len = n.norm();
  if (len > 0.0) return n / len;
  // A vertex fan without area: the face's own normal.
  const Vec3 fn = (mesh.positions[face[1]] - mesh.positions[face[0]]).cross(mesh.positions[face[2]] - mesh.positions[face[0]]);
  return fn.norm() > 0.0 ? Vec3(fn.normalized()) : Vec3::Zero();
}

// The crossing of the line o + t·d with triangle f in double (Möller–Trumbore), barycentric clamped onto the
// triangle: Embree finds the triangle in float, the point is computed from the mesh's own coordinates.
std::optional<std::pair<Vec3, Vec3>> exact_crossing(MeshView mesh, std::uint32_t f, const Vec3& o, const Vec3& d) {
  const Face& face = mesh.faces[f];
  const Vec3& a = mesh.positions[face[0]];
  const Vec3 e1 = mesh.positions[face[1]] - a;
  const Vec3 e2 = mesh.positions[face[2]] - a;
  const Vec3 pv = d.cross(e2);
  const double det = e1.dot(pv);
  if (det == 0.0 || !std::isfinite(det)) return std::nullopt;
  const Vec3 tv = o - a;
  const Vec3 qv = tv.cross(e1);
  Vec3 bary(0.0, tv.dot(pv) / det, d.dot(qv) / det);
  bary = bary.cwiseMax(0.0);
  bary.x() = std::max(0.0, 1.0 - bary.y() - bary.z());
  bary /= bary.sum();
  const Vec3 point = bary.x() * a + bary.y() * mesh.positions[face[1]] + bary.z() * mesh.positions[face[2]];
  return std::make_pair(point, bary);
}

struct Hit {
  std::uint32_t face{kNoFace};
  float t{std::numeric_limits<float>::infinity()};
};

Hit cast(const detail::EmbreeScene& scene, const Vec3& o, const Vec3& d, float tfar) {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh{};
  rh.ray.org_x = static_cast<float>(o.x());
  rh.ray.org_y = static_cast<float>(o.y());
  rh.ray.org_z = static_cast<float>(o.z());
  rh.ray.dir_x = static_cast<float>(d.x());
  rh.ray.dir_y = static_cast<float>(d.y());
  rh.ray.dir_z = static_cast<float>(d.z());
  rh.ray.tnear = 0.0f;
  rh.ray.tfar = tfar;
  rh.ray.mask = 0xffffffffu;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene.get(), &context, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return {};
  return {rh.hit.primID, rh.ray.tfar};
}

}  // namespace

std::vector<Vec3> area_weighted_vertex_normals(MeshView mesh) {
  std::vector<Vec3> normals(mesh.positions.size(), Vec3::Zero());
  for (const Face& f : mesh.faces) {
    // The cross product's length is twice the area: area weighting for free.
    const Vec3 n = (mesh.positions[f[1]] - mesh.positions[f[0]]).cross(mesh.positions[f[2]] - mesh.positions[f[0]]);
    for (const std::uint32_t v : f) normals[v] += n;
  }
  for (Vec3& n : normals) {
    const double len = n.norm();
    n = len > 0.0 ? Vec3(n / len) : Vec3::Zero();
  }
  return normals;
}

struct SurfaceTransfer::Impl {
  Impl(const EmbreeDevice& device, MeshView proxy_mesh, MeshView surface_mesh, const TransferOptions& o)
      : proxy(proxy_mesh),
        surface(surface_mesh),
        options(o),
        proxy_bvh(device, proxy_mesh),
        surface_bvh(device, surface_mesh),
        scene(device, surface_mesh.positions, surface_mesh.faces, RTC_BUILD_QUALITY_MEDIUM,
              "building the full-resolution surface's ray scene"),
        proxy_normals(area_weighted_vertex_normals(proxy_mesh)),
        surface_normals(area_weighted_vertex_normals(surface_mesh)),
        tolerance(1e-9 * bounding_box(proxy_mesh).diagonal()) {}
  MeshView proxy, surface;
  TransferOptions options;
  TriangleBvh proxy_bvh, surface_bvh;
  detail::EmbreeScene scene;
  std::vector<Vec3> proxy_normals, surface_normals;
  double tolerance;
};

namespace {
const TransferOptions& checked(MeshView proxy, MeshView surface, const TransferOptions& options) {
  if (proxy.faces.empty() || surface.faces.empty()) throw InvalidInput("transfer: the proxy or the surface has no face");
  if (!(options.ray_factor >= 1.0)) throw InvalidInput(fmt::format("transfer: ray factor {} is below 1", options.ray_factor));
  return options;
}
}  // namespace

SurfaceTransfer::SurfaceTransfer(const EmbreeDevice& device, MeshView proxy, MeshView surface, const TransferOptions& options)
    : impl_(std::make_unique<Impl>(device, proxy, surface, checked(proxy, surface, options))) {}

SurfaceTransfer::~SurfaceTransfer() = default;

TransferResult transfer_to_surface(const EmbreeDevice& device, MeshView proxy, MeshView surface,
                                   std::span<const Vec3> points, const TransferOptions& options) {
  return SurfaceTransfer(device, proxy, surface, options)(points);
}

TransferResult SurfaceTransfer::operator()(std::span<const Vec3> points) const {
  const Impl& m = *impl_;
  const MeshView proxy = m.proxy, surface = m.surface;
  const TransferOptions& options = m.options;
  const TriangleBvh& proxy_bvh = m.proxy_bvh;
  const TriangleBvh& surface_bvh = m.surface_bvh;
  const detail::EmbreeScene& scene = m.scene;
  const std::vector<Vec3>& proxy_normals = m.proxy_normals;
  const std::vector<Vec3>& surface_normals = m.surface_normals;
  const double tolerance = m.tolerance;
  report_progress(options.progress, "transfer", 0.0);
  TransferResult result;
  result.positions.assign(points.begin(), points.end());
  result.normals.assign(points.size(), Vec3::Constant(kNaN));
  result.faces.assign(points.size(), kNoFace);
  result.barycentric.assign(points.size(), Vec3::Zero());
  std::vector<std::uint8_t> how(points.size(), 0);  // 0 untouched, 1 along the normal, 2 closest point
  std::vector<double> moved(points.size(), 0.0);
  constexpr std::size_t kBlock = 4096;
  const std::size_t blocks = (points.size() + kBlock - 1) / kBlock;
  std::atomic<std::size_t> done{0};
  std::atomic<bool> cancelled{false};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks, 1), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t b = range.begin(); b != range.end() && !cancelled.load(std::memory_order_relaxed); ++b) {
      // Image samples come in scan order: the previous answer's face bounds the next query from above
      // (exact, and usually tight).
      std::uint32_t last_proxy = kNoFace, last_surface = kNoFace;
      for (std::size_t i = b * kBlock; i < std::min(points.size(), (b + 1) * kBlock); ++i) {
        const Vec3& p = points[i];
        if (!p.allFinite()) continue;
        const ClosestPoint on_proxy = proxy_bvh.closest_point(
            p, last_proxy == kNoFace ? std::numeric_limits<double>::infinity() : proxy_bvh.distance_to_face(p, last_proxy));
        const ClosestPoint nearest = surface_bvh.closest_point(
            p, last_surface == kNoFace ? std::numeric_limits<double>::infinity()
                                       : surface_bvh.distance_to_face(p, last_surface));
        if (!on_proxy.found() || !nearest.found())
          throw NumericalError(fmt::format("transfer: no closest point for ({}, {}, {})", p.x(), p.y(), p.z()));
        last_proxy = on_proxy.face;
        last_surface = nearest.face;
        const Vec3 n = interpolate_normal(proxy, proxy_normals, on_proxy.face, on_proxy.barycentric);
        const double limit = options.ray_factor * nearest.distance + tolerance;
        std::uint32_t face = nearest.face;
        Vec3 bary = nearest.barycentric;
        Vec3 q = nearest.point;
        how[i] = 2;
        if (n.squaredNorm() > 0.0) {
          const Hit up = cast(scene, p, n, static_cast<float>(limit));
          const Hit down = cast(scene, p, -n, static_cast<float>(limit));
          const Hit& hit = up.t <= down.t ? up : down;
          if (hit.face != kNoFace) {
            const Vec3 d = &hit == &up ? n : Vec3(-n);
            if (const auto crossing = exact_crossing(surface, hit.face, p, d);
                crossing && (crossing->first - p).norm() <= limit) {
              q = crossing->first;
              bary = crossing->second;
              face = hit.face;
              how[i] = 1;
            }
          }
        }
        result.positions[i] = q;
        result.faces[i] = face;
        result.barycentric[i] = bary;
        result.normals[i] = interpolate_normal(surface, surface_normals, face, bary);
        moved[i] = (q - p).norm();
      }
      // Only the thread that completes a 1/64 step reports; the callback is called from worker threads.
      const std::size_t finished = done.fetch_add(1, std::memory_order_relaxed) + 1;
      if (options.progress && (finished * 64 / blocks) != ((finished - 1) * 64 / blocks) &&
          !options.progress("transfer", static_cast<double>(finished) / static_cast<double>(blocks)))
        cancelled = true;
    }
  });
  if (cancelled) throw Cancelled("transfer: cancelled");
  double sum = 0.0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (how[i] == 0) continue;
    ++result.stats.points;
    ++(how[i] == 1 ? result.stats.along_normal : result.stats.closest);
    result.stats.max_move = std::max(result.stats.max_move, moved[i]);
    sum += moved[i] * moved[i];
  }
  if (result.stats.points > 0) result.stats.rms_move = std::sqrt(sum / static_cast<double>(result.stats.points));
  report_progress(options.progress, "transfer", 1.0);
  return result;
}

}  // namespace gimforge
