#include "kernels/scan/surface_transfer.h"

#include <atomic>
#include <cmath>
#include <limits>
#include <optional>

#include <embree3/rtcore.h>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "kernels/core/errors.h"

namespace gimforge {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

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

Hit cast(RTCScene scene, const Vec3& o, const Vec3& d, float tfar) {
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
  rtcIntersect1(scene, &context, &rh);
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
  Impl(const EmbreeDevice& device, MeshView proxy_mesh, MeshView surface_mesh, std::span<const std::uint8_t> query,
       const TransferOptions& o)
      : proxy(proxy_mesh),
        surface(surface_mesh),
        options(o),
        proxy_bvh(device, proxy_mesh),
        proxy_normals(area_weighted_vertex_normals(proxy_mesh)),
        surface_normals(area_weighted_vertex_normals(surface_mesh)),
        tolerance(1e-9 * bounding_box(proxy_mesh).diagonal()) {
    if (!query.empty()) {  // without a filter the queries see the surface's own faces (no copy of them)
      for (std::size_t f = 0; f < surface_mesh.faces.size(); ++f)
        if (query[f] != 0) {
          own_faces.push_back(surface_mesh.faces[f]);
          surface_face_ids.push_back(static_cast<std::uint32_t>(f));
        }
    }
    const std::span<const Face> faces = query.empty() ? surface_mesh.faces : std::span<const Face>(own_faces);
    if (faces.empty()) return;
    queried = MeshView(surface_mesh.positions, faces);
    // One BVH for both queries: the closest-point BVH's scene also answers the rays.
    surface_bvh.emplace(device, queried);
  }
  MeshView proxy, surface;
  TransferOptions options;
  TriangleBvh proxy_bvh;
  std::vector<Vec3> proxy_normals, surface_normals;
  double tolerance;
  std::vector<Face> own_faces;                  ///< the `query` faces (empty without a filter)
  MeshView queried;                             ///< the faces queries see (surface's, or own_faces); none: empty
  std::vector<std::uint32_t> surface_face_ids;  ///< their index in `surface` (empty: the identity)
  std::optional<TriangleBvh> surface_bvh;
};

namespace {
const TransferOptions& checked(MeshView proxy, MeshView surface, std::span<const std::uint8_t> query,
                               const TransferOptions& options) {
  if (proxy.faces.empty() || (surface.faces.empty() && query.empty()))
    throw InvalidInput("transfer: the proxy or the surface has no face");
  if (!query.empty() && query.size() != surface.faces.size())
    throw InvalidInput(fmt::format("transfer: {} query flags for {} faces", query.size(), surface.faces.size()));
  if (!(options.ray_factor >= 1.0)) throw InvalidInput(fmt::format("transfer: ray factor {} is below 1", options.ray_factor));
  return options;
}
}  // namespace

SurfaceTransfer::SurfaceTransfer(const EmbreeDevice& device, MeshView proxy, MeshView surface, const TransferOptions& options,
                                 std::span<const std::uint8_t> query_faces)
    : impl_(std::make_unique<Impl>(device, proxy, surface, query_faces, checked(proxy, surface, query_faces, options))) {}

SurfaceTransfer::~SurfaceTransfer() = default;

TransferResult transfer_to_surface(const EmbreeDevice& device, MeshView proxy, MeshView surface,
                                   std::span<const Vec3> points, const TransferOptions& options) {
  return SurfaceTransfer(device, proxy, surface, options)(points);
}

TransferCandidates SurfaceTransfer::candidates(std::span<const Vec3> points) const {
  const Impl& m = *impl_;
  const TransferOptions& options = m.options;
  TransferCandidates out;
  out.closest.resize(points.size());
  out.crossing.resize(points.size());
  if (m.queried.faces.empty()) return out;  // nothing held: every distance stays infinite
  const MeshView query = m.queried;
  report_progress(options.progress, "transfer", 0.0);
  constexpr std::size_t kBlock = 4096;
  const std::size_t blocks = (points.size() + kBlock - 1) / kBlock;
  std::atomic<std::size_t> done{0};
  std::atomic<bool> cancelled{false};
  const auto candidate = [&](std::uint32_t face, const Vec3& point, const Vec3& bary, double distance) {
    const std::uint32_t f = m.surface_face_ids.empty() ? face : m.surface_face_ids[face];
    return TransferCandidate{distance, point, interpolate_normal(m.surface, m.surface_normals, f, bary), f, bary};
  };
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks, 1), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t b = range.begin(); b != range.end() && !cancelled.load(std::memory_order_relaxed); ++b) {
      // Image samples come in scan order: the previous answer's face bounds the next query from above
      // (exact, and usually tight).
      std::uint32_t last_proxy = kNoFace, last_surface = kNoFace;
      for (std::size_t i = b * kBlock; i < std::min(points.size(), (b + 1) * kBlock); ++i) {
        const Vec3& p = points[i];
        if (!p.allFinite()) continue;
        const ClosestPoint on_proxy = m.proxy_bvh.closest_point(
            p, last_proxy == kNoFace ? kInf : m.proxy_bvh.distance_to_face(p, last_proxy));
        const ClosestPoint nearest = m.surface_bvh->closest_point(
            p, last_surface == kNoFace ? kInf : m.surface_bvh->distance_to_face(p, last_surface));
        if (!on_proxy.found())
          throw NumericalError(fmt::format("transfer: no closest point on the proxy for ({}, {}, {})", p.x(), p.y(), p.z()));
        last_proxy = on_proxy.face;
        if (!nearest.found()) continue;  // only degenerate faces here: another process's answer, or assemble's error
        last_surface = nearest.face;
        out.closest[i] = candidate(nearest.face, nearest.point, nearest.barycentric, nearest.distance);
        const Vec3 n = interpolate_normal(m.proxy, m.proxy_normals, on_proxy.face, on_proxy.barycentric);
        if (n.squaredNorm() == 0.0) continue;
        // The nearer crossing of the two rays along ±n, measured exactly.
        for (const Vec3& d : {n, Vec3(-n)}) {
          const Hit hit = cast(static_cast<RTCScene>(m.surface_bvh->native_scene()), p, d,
                               std::numeric_limits<float>::infinity());
          if (hit.face == kNoFace) continue;
          if (const auto crossing = exact_crossing(query, hit.face, p, d)) {
            const double distance = (crossing->first - p).norm();
            if (distance < out.crossing[i].distance)
              out.crossing[i] = candidate(hit.face, crossing->first, crossing->second, distance);
          }
        }
      }
      // Only the thread that completes a 1/64 step reports; the callback is called from worker threads.
      const std::size_t finished = done.fetch_add(1, std::memory_order_relaxed) + 1;
      if (options.progress && (finished * 64 / blocks) != ((finished - 1) * 64 / blocks) &&
          !options.progress("transfer", static_cast<double>(finished) / static_cast<double>(blocks)))
        cancelled = true;
    }
  });
  if (cancelled) throw Cancelled("transfer: cancelled");
  return out;
}

TransferResult SurfaceTransfer::assemble(std::span<const Vec3> points, const TransferCandidates& candidates) const {
  const Impl& m = *impl_;
  TransferResult result;
  result.positions.assign(points.begin(), points.end());
  result.normals.assign(points.size(), Vec3::Constant(kNaN));
  result.faces.assign(points.size(), kNoFace);
  result.barycentric.assign(points.size(), Vec3::Zero());
  double sum = 0.0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) continue;
    const TransferCandidate& closest = candidates.closest.at(i);
    const TransferCandidate& crossing = candidates.crossing.at(i);
    if (closest.face == kNoFace)
      throw NumericalError(fmt::format("transfer: no closest point for point {}", i));
    const bool along = crossing.distance <= m.options.ray_factor * closest.distance + m.tolerance;
    const TransferCandidate& c = along ? crossing : closest;
    result.positions[i] = c.point;
    result.normals[i] = c.normal;
    result.faces[i] = c.face;
    result.barycentric[i] = c.barycentric;
    ++result.stats.points;
    ++(along ? result.stats.along_normal : result.stats.closest);
    result.stats.max_move = std::max(result.stats.max_move, c.distance);
    sum += c.distance * c.distance;
  }
  if (result.stats.points > 0) result.stats.rms_move = std::sqrt(sum / static_cast<double>(result.stats.points));
  report_progress(m.options.progress, "transfer", 1.0);
  return result;
}

TransferResult SurfaceTransfer::operator()(std::span<const Vec3> points) const {
  return assemble(points, candidates(points));
}

}  // namespace gimforge
