#pragma once
/// \file render_detail.h
/// Internal to kernels/relief/: what the relief ray caster (relief_raycast.cpp) and the reference renderer
/// (mesh_render.cpp) share: the image set-up, the pixel rays (both renderers cast exactly the same rays),
/// the recording of hits, the row-parallel render loop and the wall normals. Generic code only: not for
/// raycast_avx2.cpp (compiled with -mavx2), as these inline functions have external linkage. The
/// translation units that include it are compiled with -ffp-contract=off, as the march is.
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "kernels/core/mesh.h"
#include "kernels/relief/render_camera.h"

namespace gimforge::detail {

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

/// Rows per task of a render.
constexpr std::uint32_t kRowGrain = 4;

/// Throws InvalidInput for an empty or too large image or a camera with non-finite values
/// (render_camera.cpp).
void check_camera(const Camera& camera);

/// An image of the camera's size with every pixel missed (render_camera.cpp).
[[nodiscard]] RenderImage blank_image(const Camera& camera);

/// Replaces the normals of wall hits (flagged in `walls`) by the normal of the rendered surface itself,
/// from the world positions of the neighbouring pixels (central differences where both neighbours are
/// hits on the same surface, else one-sided), and shades them again. Neighbours across a depth jump of
/// more than kWallDepthPixels pixel footprints are not used; without usable neighbours on both axes the
/// stored normal stays (render_camera.cpp).
void fix_wall_normals(const Camera& camera, double ambient, const std::vector<std::uint8_t>& walls, RenderImage& img);

/// The part of the ray directions of pixel row y that the row shares: forward + sy · up.
inline Vec3 pixel_row(const Camera& camera, std::uint32_t y) {
  const double sy = (1.0 - (y + 0.5) / camera.height * 2.0) * camera.tan_half_fov;
  return camera.forward + sy * camera.up;
}

/// The unit direction of the ray through pixel x of a row (Camera::ray_direction up to rounding). Every
/// renderer computes it in this order, so that the traversals of a relief render cast the same rays.
inline Vec3 pixel_direction(const Camera& camera, const Vec3& row, std::uint32_t x) {
  const double aspect = static_cast<double>(camera.width) / camera.height;
  const double sx = ((x + 0.5) / camera.width * 2.0 - 1.0) * camera.tan_half_fov * aspect;
  const double d[3] = {row[0] + sx * camera.right[0], row[1] + sx * camera.right[1], row[2] + sx * camera.right[2]};
  const double norm = std::sqrt((d[0] * d[0] + d[1] * d[1]) + d[2] * d[2]);
  return Vec3(d[0] / norm, d[1] / norm, d[2] / norm);
}

/// Writes the hit of pixel p, whose ray has the unit direction dir, into the image (and flags walls).
inline void record_hit(RenderImage& img, std::vector<std::uint8_t>* walls, std::size_t p, const RayHit& hit,
                       const Vec3& dir, double ambient) {
  img.mask[p] = 1;
  img.depth[p] = static_cast<float>(hit.t);
  img.position[p] = hit.position.cast<float>();
  img.normal[p] = hit.normal.cast<float>();
  img.shaded[p] = shade_grey(hit.normal, dir, ambient);
  if (walls) (*walls)[p] = hit.discontinuity ? 1 : 0;
}

/// Renders with `trace(origin, unit direction, samples) -> RayHit`, rows in parallel.
template <class Trace>
void render_rows(const Camera& camera, double ambient, RenderImage& img, const Trace& trace,
                 std::vector<std::uint8_t>* walls = nullptr) {
  std::atomic<std::uint64_t> hits{0}, samples{0};
  const auto t0 = Clock::now();
  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, camera.height, kRowGrain),
                    [&](const tbb::blocked_range<std::uint32_t>& rows) {
                      std::uint64_t h = 0, s = 0;
                      for (std::uint32_t y = rows.begin(); y != rows.end(); ++y) {
                        const Vec3 row = pixel_row(camera, y);
                        for (std::uint32_t x = 0; x < camera.width; ++x) {
                          const Vec3 dir = pixel_direction(camera, row, x);
                          const RayHit hit = trace(camera.eye, dir, s);
                          if (!hit.hit) continue;
                          ++h;
                          record_hit(img, walls, static_cast<std::size_t>(y) * camera.width + x, hit, dir, ambient);
                        }
                      }
                      hits += h;
                      samples += s;
                    });
  img.seconds = seconds_since(t0);
  img.hits = hits.load();
  img.samples = samples.load();
}

}  // namespace gimforge::detail
