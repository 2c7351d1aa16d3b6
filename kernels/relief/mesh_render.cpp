// The Embree reference renderer of the original mesh and the comparison of two renders (mesh_render.h).
#include "kernels/relief/mesh_render.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <vector>

#include <embree3/rtcore.h>
#include <fmt/format.h>

#include "kernels/core/embree_scene.h"
#include "kernels/core/errors.h"
#include "kernels/relief/render_detail.h"

namespace gimforge {
using detail::blank_image;
using detail::check_camera;
using detail::render_rows;

struct MeshRenderer::Impl {
  const TriMesh& mesh;
  double ambient;
  detail::EmbreeScene scene;

  Impl(const EmbreeDevice& device, const TriMesh& m, double amb)
      : mesh(m),
        ambient(amb),
        scene(device, (m.faces.empty() ? throw InvalidInput("render: the reference mesh has no faces") : m.positions),
              m.faces, RTC_BUILD_QUALITY_HIGH, "building the reference render BVH") {
    if (!(amb >= 0.0 && amb <= 1.0)) throw InvalidInput(fmt::format("render: ambient {} out of range 0..1", amb));
  }

  RayHit trace(const Vec3& org, const Vec3& dir, RTCIntersectContext& context) const {
    RTCRayHit rh{};
    rh.ray.org_x = static_cast<float>(org.x());
    rh.ray.org_y = static_cast<float>(org.y());
    rh.ray.org_z = static_cast<float>(org.z());
    rh.ray.dir_x = static_cast<float>(dir.x());
    rh.ray.dir_y = static_cast<float>(dir.y());
    rh.ray.dir_z = static_cast<float>(dir.z());
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = std::numeric_limits<float>::infinity();
    rh.ray.mask = 0xffffffffu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene.get(), &context, &rh);
    RayHit out;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return out;
    out.hit = true;
    out.t = static_cast<double>(rh.ray.tfar);
    out.position = org + out.t * dir;
    const Face& f = mesh.faces[rh.hit.primID];
    const Vec3& a = mesh.positions[f[0]];
    const Vec3 nrm = (mesh.positions[f[1]] - a).cross(mesh.positions[f[2]] - a);
    out.normal = nrm.squaredNorm() > 0.0
                     ? nrm.normalized()
                     : Vec3(static_cast<double>(rh.hit.Ng_x), static_cast<double>(rh.hit.Ng_y),
                            static_cast<double>(rh.hit.Ng_z)).normalized();
    if (!out.normal.allFinite()) out.normal = -dir;
    return out;
  }
};

MeshRenderer::MeshRenderer(const EmbreeDevice& device, const TriMesh& mesh, double ambient)
    : impl_(std::make_unique<Impl>(device, mesh, ambient)) {}
MeshRenderer::~MeshRenderer() = default;
MeshRenderer::MeshRenderer(MeshRenderer&&) noexcept = default;
MeshRenderer& MeshRenderer::operator=(MeshRenderer&&) noexcept = default;

RayHit MeshRenderer::trace(const Vec3& origin, const Vec3& direction) const {
  const double len = direction.norm();
  if (!origin.allFinite() || !direction.allFinite() || !(len > 0.0))
    throw InvalidInput("render: ray with a non-finite origin or a zero direction");
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  return impl_->trace(origin, direction / len, context);
}

RenderImage MeshRenderer::render(const Camera& camera) const {
  check_camera(camera);
  RenderImage img = blank_image(camera);
  render_rows(camera, impl_->ambient, img, [&](const Vec3& org, const Vec3& dir, std::uint64_t&) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    return impl_->trace(org, dir, context);
  });
  return img;
}

RenderComparison compare_renders(const RenderImage& a, const RenderImage& b) {
  if (a.width != b.width || a.height != b.height || a.shaded.size() != b.shaded.size() ||
      a.mask.size() != b.mask.size() || a.mask.size() != a.shaded.size())
    throw InvalidInput(fmt::format("render comparison: image sizes differ ({}x{} and {}x{})", a.width, a.height,
                                   b.width, b.height));
  RenderComparison r;
  double se = 0.0;
  std::vector<double> depth_errors;
  double angle_sum = 0.0, depth_sq = 0.0, depth_abs = 0.0;
  for (std::size_t p = 0; p < a.shaded.size(); ++p) {
    const double d = static_cast<double>(a.shaded[p]) - static_cast<double>(b.shaded[p]);
    se += d * d;
    const bool ha = a.mask[p] != 0, hb = b.mask[p] != 0;
    r.hits_a += ha;
    r.hits_b += hb;
    r.hits_both += ha && hb;
    r.hits_either += ha || hb;
    if (ha && hb) {
      const double e = std::abs(static_cast<double>(a.depth[p]) - static_cast<double>(b.depth[p]));
      depth_errors.push_back(e);
      depth_abs += e;
      depth_sq += e * e;
      const double c = std::min(1.0, std::abs(static_cast<double>(a.normal[p].dot(b.normal[p]))));
      angle_sum += std::acos(c) * 180.0 / std::numbers::pi;
    }
  }
  const auto pixels = static_cast<double>(std::max<std::size_t>(a.shaded.size(), 1));
  r.mse = se / pixels;
  r.psnr = r.mse > 0.0 ? 10.0 * std::log10(255.0 * 255.0 / r.mse) : std::numeric_limits<double>::infinity();
  r.iou = r.hits_either == 0 ? 1.0 : static_cast<double>(r.hits_both) / static_cast<double>(r.hits_either);
  if (!depth_errors.empty()) {
    const auto count = static_cast<double>(depth_errors.size());
    r.depth_mean_abs = depth_abs / count;
    r.depth_rms = std::sqrt(depth_sq / count);
    r.normal_mean_deg = angle_sum / count;
    const auto k = static_cast<std::size_t>(std::floor(0.95 * (count - 1.0)));
    std::nth_element(depth_errors.begin(), depth_errors.begin() + static_cast<std::ptrdiff_t>(k), depth_errors.end());
    r.depth_p95 = depth_errors[k];
  }
  return r;
}

}  // namespace gimforge
