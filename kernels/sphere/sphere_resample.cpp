#include "kernels/sphere/sphere_resample.h"

#include <cmath>
#include <limits>
#include <optional>

#include <embree3/rtcore.h>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "kernels/core/embree_scene.h"
#include "kernels/core/errors.h"
#include "kernels/sphere/spherical_stretch.h"

namespace gimforge {

struct SphericalLocator::Impl {
  MeshView mesh;
  std::span<const Vec3> sphere;
  std::optional<detail::EmbreeScene> scene;
};

namespace {

/// Barycentric coordinates of the ray from the origin along x in the plane of triangle (a, b, c), in
/// double precision; nullopt-like flag when the ray is parallel to the plane or behind the origin.
bool ray_barycentric(const Vec3& x, const Vec3& a, const Vec3& b, const Vec3& c, Vec3& bary) {
  const Vec3 n = (b - a).cross(c - a);
  const double denom = n.dot(x);
  if (!(std::abs(denom) > 0.0)) return false;
  const double t = n.dot(a) / denom;
  if (!(t > 0.0)) return false;
  const Vec3 y = t * x;
  const double area2 = n.squaredNorm();
  bary.x() = (c - b).cross(y - b).dot(n) / area2;
  bary.y() = (a - c).cross(y - c).dot(n) / area2;
  bary.z() = 1.0 - bary.x() - bary.y();
  return true;
}

}  // namespace

SphericalLocator::SphericalLocator(const EmbreeDevice& device, MeshView mesh, std::span<const Vec3> sphere)
    : impl_(std::make_unique<Impl>()) {
  if (mesh.faces.empty()) throw InvalidInput("SphericalLocator: mesh has no faces");
  check_sphere_points(mesh, sphere, "SphericalLocator");
  impl_->mesh = mesh;
  impl_->sphere = sphere;
  // The planar triangles spanned by the sphere points: a ray from the centre hits the one whose spherical
  // triangle contains its direction.
  impl_->scene.emplace(device, sphere, mesh.faces, RTC_BUILD_QUALITY_MEDIUM, "building the spherical triangulation");
}

SphericalLocator::~SphericalLocator() = default;
SphericalLocator::SphericalLocator(SphericalLocator&&) noexcept = default;
SphericalLocator& SphericalLocator::operator=(SphericalLocator&&) noexcept = default;

SphericalLocator::Location SphericalLocator::locate(const Vec3& x) const {
  // A ray exactly along an edge or vertex may graze past in float: re-aim by a tiny rotation and retry.
  const Vec3 nudges[] = {Vec3::Zero(), Vec3(1e-7, 2e-7, -1.5e-7), Vec3(-2e-7, 1e-7, 1e-7)};
  for (const Vec3& nudge : nudges) {
    const Vec3 d = (x.normalized() + nudge).normalized();
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh{};
    rh.ray.org_x = rh.ray.org_y = rh.ray.org_z = 0.0f;
    rh.ray.dir_x = static_cast<float>(d.x());
    rh.ray.dir_y = static_cast<float>(d.y());
    rh.ray.dir_z = static_cast<float>(d.z());
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = std::numeric_limits<float>::infinity();
    rh.ray.mask = 0xffffffffu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(impl_->scene->get(), &context, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
    const Face& f = impl_->mesh.faces[rh.hit.primID];
    Location loc{rh.hit.primID, Vec3::Zero()};
    // Exact coordinates of the original direction in the hit triangle, clamped onto it (the float hit
    // may sit a rounding error outside).
    if (!ray_barycentric(x, impl_->sphere[f[0]], impl_->sphere[f[1]], impl_->sphere[f[2]], loc.barycentric)) continue;
    loc.barycentric = loc.barycentric.cwiseMax(0.0);
    loc.barycentric /= loc.barycentric.sum();
    return loc;
  }
  throw NumericalError(fmt::format("no spherical triangle contains direction ({}, {}, {}); the sphere map is not "
                                   "an embedding",
                                   x.x(), x.y(), x.z()));
}

Vec3 SphericalLocator::position(const Vec3& x) const {
  const Location loc = locate(x);
  const Face& f = impl_->mesh.faces[loc.face];
  const auto& p = impl_->mesh.positions;
  return loc.barycentric.x() * p[f[0]] + loc.barycentric.y() * p[f[1]] + loc.barycentric.z() * p[f[2]];
}

std::vector<Vec3> resample_spherical_map(const EmbreeDevice& device, MeshView mesh, std::span<const Vec3> sphere,
                                         std::span<const Vec3> directions) {
  const SphericalLocator locator(device, mesh, sphere);
  std::vector<Vec3> out(directions.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, directions.size(), 1024),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i < r.end(); ++i) out[i] = locator.position(directions[i]);
                    });
  return out;
}

}  // namespace gimforge
