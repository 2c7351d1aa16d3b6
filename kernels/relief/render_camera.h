#pragma once
/// \file render_camera.h
/// What the renders of gimforge share: the pinhole camera and the orbit view that places it around a
/// bounding box, the headlight shading, one traced ray (RayHit) and one rendered view (RenderImage). The
/// relief ray caster (relief_raycast.h) and the Embree reference renderer of the original mesh
/// (mesh_render.h) render through the same cameras with the same shading.
///
/// **Images.** Row 0 is the top row; pixel (x, y) looks through the centre of its square. Shading
/// (shade_grey) is a headlight: ambient + (1 − ambient) · |n · d| for the unit normal n and the viewing
/// direction d, two-sided because stored normals face the domain faces and mesh orientation is arbitrary;
/// 0 (black) where the ray misses. The reference renderer shades the geometric normal of the hit triangle
/// with the same function.
#include <cstdint>
#include <vector>

#include "kernels/core/mesh.h"

namespace gimforge {

/// A pinhole camera. Pixel (x, y) (row 0 at the top) looks along
/// normalize(forward + sx · right + sy · up) with sx = ((x + 0.5) / width · 2 − 1) · tan_half_fov · width /
/// height and sy = (1 − (y + 0.5) / height · 2) · tan_half_fov.
struct Camera {
  Vec3 eye{Vec3::Zero()};
  Vec3 forward{0.0, 0.0, -1.0};  ///< unit
  Vec3 right{1.0, 0.0, 0.0};     ///< unit, orthogonal to forward
  Vec3 up{0.0, 1.0, 0.0};        ///< unit, orthogonal to forward and right
  double tan_half_fov{0.2679491924311227};  ///< tan of half the vertical field of view (default 30°)
  std::uint32_t width{512};
  std::uint32_t height{512};

  /// Unit direction of the ray through pixel (x, y) (pixel centres at x + 0.5, y + 0.5).
  [[nodiscard]] Vec3 ray_direction(double x, double y) const;
};

/// An orbit view around a bounding box.
struct OrbitView {
  double azimuth_deg{30.0};    ///< rotation about the up axis (right-handed)
  double elevation_deg{20.0};  ///< above (+) or below (−) the plane normal to the up axis, −90..90
  double fov_deg{30.0};        ///< vertical field of view, 1..170
  int up_axis{1};              ///< 0 = x, 1 = y, 2 = z
  double margin{1.05};         ///< the bounding sphere's radius is scaled by this factor before fitting
                               ///< (> 1: whole model with a border; < 1: a close-up of its centre)
};

/// The camera looking at the centre of `box` from azimuth / elevation at a distance where the bounding
/// sphere of the box (radius = half the diagonal, times view.margin) fits the narrower field of view.
/// With up axis a and the two other axes b = (a + 1) % 3, c = (a + 2) % 3, the eye lies in the direction
/// e[b] = cos(el)·cos(az), e[c] = cos(el)·sin(az), e[a] = sin(el) from the centre: for up = y, azimuth 0
/// looks from +z and azimuth 90 from +x; for up = z, azimuth 0 looks from +x and 90 from +y.
/// Throws InvalidInput for an empty or non-finite box, a size of 0, elevation outside −90..90, field of
/// view outside 1..170, up_axis outside 0..2 or a margin that is not positive.
[[nodiscard]] Camera orbit_camera(const BoundingBox& box, const OrbitView& view, std::uint32_t width,
                                  std::uint32_t height);

/// Headlight shading of both renderers: round(255 · (ambient + (1 − ambient) · |n · d|)), n and d unit.
[[nodiscard]] std::uint8_t shade_grey(const Vec3& normal, const Vec3& direction, double ambient = 0.15);

/// One rendered view. Per pixel (row-major, row 0 at the top): hit mask (1 = hit), ray parameter of the
/// hit (world distance from the eye; +inf where missed), world position and unit normal (zero where
/// missed), and the shaded grey value (0 where missed).
struct RenderImage {
  std::uint32_t width{0};
  std::uint32_t height{0};
  std::vector<std::uint8_t> mask;
  std::vector<float> depth;
  std::vector<Vec3f> position;
  std::vector<Vec3f> normal;
  std::vector<std::uint8_t> shaded;

  double seconds{0.0};       ///< wall time of the render (set-up of the ray caster / BVH not included)
  std::uint64_t rays{0};     ///< primary rays cast (one per pixel)
  std::uint64_t hits{0};
  /// Relief ray casting: inside tests (linear samples + one per halving of the refinement); 0 for the
  /// reference.
  std::uint64_t samples{0};
  [[nodiscard]] double rays_per_second() const { return seconds > 0.0 ? static_cast<double>(rays) / seconds : 0.0; }
  /// The shaded image as 8-bit RGB (grey replicated), for io::write_png_rgb.
  [[nodiscard]] std::vector<std::uint8_t> shaded_rgb() const;
};

/// One traced ray.
struct RayHit {
  bool hit{false};
  double t{0.0};                    ///< world distance along the (unit) direction
  Vec3 position{Vec3::Zero()};
  Vec3 normal{Vec3::Zero()};        ///< unit; faces the domain face the hit projects onto
  std::uint32_t grey_cell{0};       ///< index of the grey cell (into ReliefMap::cells) holding the hit
  /// Relief ray casting: the hit lies more than four texel spacings from the stored surface of its texel,
  /// on a *wall* (a jump of the stored distances, where the surface runs along the projection rays and
  /// the texels hold another surface): its stored normal belongs to that other surface.
  bool discontinuity{false};
};

}  // namespace gimforge
