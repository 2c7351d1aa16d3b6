// The cameras, the shading and the image helpers of the renders (render_camera.h, render_detail.h), and
// the bounds of a relief map's surface samples that orbit_camera frames.
#include "kernels/relief/render_camera.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "kernels/core/errors.h"
#include "kernels/relief/relief_raycast.h"
#include "kernels/relief/render_detail.h"

namespace gimforge {

namespace detail {

void check_camera(const Camera& camera) {
  if (camera.width == 0 || camera.height == 0)
    throw InvalidInput(fmt::format("render: image size {}x{} is empty", camera.width, camera.height));
  if (static_cast<std::uint64_t>(camera.width) * camera.height > (std::uint64_t{1} << 28))
    throw InvalidInput(fmt::format("render: image size {}x{} is too large", camera.width, camera.height));
  if (!camera.eye.allFinite() || !camera.forward.allFinite() || !camera.right.allFinite() || !camera.up.allFinite() ||
      !(camera.tan_half_fov > 0.0) || !std::isfinite(camera.tan_half_fov))
    throw InvalidInput("render: camera with non-finite position, axes or field of view");
}

RenderImage blank_image(const Camera& camera) {
  RenderImage img;
  img.width = camera.width;
  img.height = camera.height;
  const std::size_t n = static_cast<std::size_t>(camera.width) * camera.height;
  img.mask.assign(n, 0);
  img.depth.assign(n, std::numeric_limits<float>::infinity());
  img.position.assign(n, Vec3f::Zero());
  img.normal.assign(n, Vec3f::Zero());
  img.shaded.assign(n, 0);
  img.rays = n;
  return img;
}

void fix_wall_normals(const Camera& camera, double ambient, const std::vector<std::uint8_t>& walls, RenderImage& img) {
  constexpr double kWallDepthPixels = 8.0;
  constexpr std::int64_t kWallReach = 1;
  const double footprint = 2.0 * camera.tan_half_fov / camera.height;  // per unit depth
  const std::uint32_t W = camera.width, H = camera.height;
  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, H, 16), [&](const tbb::blocked_range<std::uint32_t>& rows) {
    for (std::uint32_t y = rows.begin(); y != rows.end(); ++y) {
      for (std::uint32_t x = 0; x < W; ++x) {
        const std::size_t p = static_cast<std::size_t>(y) * W + x;
        if (!walls[p]) continue;
        const double limit = kWallDepthPixels * footprint * static_cast<double>(img.depth[p]);
        auto usable = [&](std::int64_t xx, std::int64_t yy) {
          if (xx < 0 || yy < 0 || xx >= W || yy >= H) return false;
          const std::size_t q = static_cast<std::size_t>(yy) * W + static_cast<std::size_t>(xx);
          return img.mask[q] != 0 &&
                 std::abs(static_cast<double>(img.depth[q]) - static_cast<double>(img.depth[p])) <= limit;
        };
        auto pos = [&](std::int64_t xx, std::int64_t yy) {
          return img.position[static_cast<std::size_t>(yy) * W + static_cast<std::size_t>(xx)].cast<double>();
        };
        // The difference of the positions of the nearest usable (hit, no depth jump) pixels within
        // kWallReach on either side along (dx, dy), or the pixel itself on one side.
        auto difference = [&](int dx, int dy, Vec3& out) {
          const auto xi = static_cast<std::int64_t>(x), yi = static_cast<std::int64_t>(y);
          std::int64_t fwd = 0, bwd = 0;
          for (std::int64_t k = 1; k <= kWallReach && fwd == 0; ++k)
            if (usable(xi + k * dx, yi + k * dy)) fwd = k;
          for (std::int64_t k = 1; k <= kWallReach && bwd == 0; ++k)
            if (usable(xi - k * dx, yi - k * dy)) bwd = k;
          if (fwd == 0 && bwd == 0) return false;
          const Vec3 a = fwd ? pos(xi + fwd * dx, yi + fwd * dy) : pos(xi, yi);
          const Vec3 b = bwd ? pos(xi - bwd * dx, yi - bwd * dy) : pos(xi, yi);
          out = a - b;
          return true;
        };
        Vec3 du, dv;
        if (!difference(1, 0, du) || !difference(0, 1, dv)) continue;
        const Vec3 nrm = du.cross(dv);
        if (!(nrm.squaredNorm() > 0.0) || !nrm.allFinite()) continue;
        const Vec3 unit = nrm.normalized();
        img.normal[p] = unit.cast<float>();
        img.shaded[p] = shade_grey(unit, camera.ray_direction(x, y), ambient);
      }
    }
  });
}

}  // namespace detail

Vec3 Camera::ray_direction(double x, double y) const {
  const double aspect = static_cast<double>(width) / static_cast<double>(height);
  const double sx = ((x + 0.5) / width * 2.0 - 1.0) * tan_half_fov * aspect;
  const double sy = (1.0 - (y + 0.5) / height * 2.0) * tan_half_fov;
  return (forward + sx * right + sy * up).normalized();
}

Camera orbit_camera(const BoundingBox& box, const OrbitView& view, std::uint32_t width, std::uint32_t height) {
  if (box.empty() || !box.min.allFinite() || !box.max.allFinite())
    throw InvalidInput("render: the bounding box to frame is empty or not finite");
  if (width == 0 || height == 0) throw InvalidInput(fmt::format("render: image size {}x{} is empty", width, height));
  if (!(view.elevation_deg >= -90.0 && view.elevation_deg <= 90.0))
    throw InvalidInput(fmt::format("render: elevation {} out of range -90..90", view.elevation_deg));
  if (!std::isfinite(view.azimuth_deg)) throw InvalidInput("render: azimuth is not finite");
  if (!(view.fov_deg >= 1.0 && view.fov_deg <= 170.0))
    throw InvalidInput(fmt::format("render: field of view {} out of range 1..170", view.fov_deg));
  if (view.up_axis < 0 || view.up_axis > 2)
    throw InvalidInput(fmt::format("render: up axis {} out of range 0..2", view.up_axis));
  if (!(view.margin > 0.0) || !std::isfinite(view.margin))
    throw InvalidInput(fmt::format("render: margin {} must be positive", view.margin));
  const double deg = std::numbers::pi / 180.0;
  const double az = view.azimuth_deg * deg, el = view.elevation_deg * deg;
  const int a = view.up_axis, b = (a + 1) % 3, c = (a + 2) % 3;
  Vec3 e, tangent;  // eye direction from the centre and its derivative in elevation (screen up)
  e[b] = std::cos(el) * std::cos(az);
  e[c] = std::cos(el) * std::sin(az);
  e[a] = std::sin(el);
  tangent[b] = -std::sin(el) * std::cos(az);
  tangent[c] = -std::sin(el) * std::sin(az);
  tangent[a] = std::cos(el);
  const Vec3 centre = 0.5 * (box.min + box.max);
  double radius = 0.5 * box.diagonal() * view.margin;
  if (!(radius > 0.0)) radius = 1e-6 * std::max(1.0, centre.norm());
  Camera cam;
  cam.width = width;
  cam.height = height;
  cam.tan_half_fov = std::tan(0.5 * view.fov_deg * deg);
  const double tan_narrow = cam.tan_half_fov * std::min(1.0, static_cast<double>(width) / height);
  const double distance = radius / std::sin(std::atan(tan_narrow));
  cam.eye = centre + distance * e;
  cam.forward = -e.normalized();
  cam.up = tangent.normalized();
  cam.right = cam.forward.cross(cam.up).normalized();
  return cam;
}

BoundingBox relief_surface_bounds(const ReliefMap& map) {
  const std::uint32_t T = map.texture;
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, map.num_layers(), 16), BoundingBox{},
      [&](const tbb::blocked_range<std::size_t>& range, BoundingBox box) {
        for (std::size_t l = range.begin(); l != range.end(); ++l)
          for (std::uint32_t j = 0; j < T; ++j)
            for (std::uint32_t i = 0; i < T; ++i)
              if (map.distances[map.texel_index(l, i, j)] != kEmptyTexel) box.extend(map.texel_surface_point(l, i, j));
        return box;
      },
      [](BoundingBox x, const BoundingBox& y) {
        x.min = x.min.cwiseMin(y.min);
        x.max = x.max.cwiseMax(y.max);
        return x;
      });
}

std::uint8_t shade_grey(const Vec3& normal, const Vec3& direction, double ambient) {
  const double lambert = std::min(1.0, std::abs(normal.dot(direction)));
  return static_cast<std::uint8_t>(std::lround(std::clamp(255.0 * (ambient + (1.0 - ambient) * lambert), 0.0, 255.0)));
}

std::vector<std::uint8_t> RenderImage::shaded_rgb() const {
  std::vector<std::uint8_t> rgb(3 * shaded.size());
  for (std::size_t p = 0; p < shaded.size(); ++p) rgb[3 * p] = rgb[3 * p + 1] = rgb[3 * p + 2] = shaded[p];
  return rgb;
}

}  // namespace gimforge
