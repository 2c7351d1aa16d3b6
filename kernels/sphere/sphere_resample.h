#pragma once
/// \file sphere_resample.h
/// Resampling a spherically parametrized mesh (Praun & Hoppe 2003, §4, step I→D→S→M): a point x on the
/// unit sphere lies in the spherical triangle whose planar triangle (spanned by its vertices' sphere
/// points) the ray from the centre through x hits; the inverse of the spherical triangle map is that
/// ray's barycentric coordinates, which interpolate the mesh (../shared/notes/parametrization.md).
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "kernels/core/embree_device.h"
#include "kernels/core/mesh.h"

namespace gimforge {

/// Locates unit-sphere points in a spherical triangulation with Embree rays from the origin.
/// The sphere points (one unit vector per mesh vertex) must form an embedding (no flipped spherical
/// triangles): then every direction hits exactly one planar triangle. Thread-safe queries.
class SphericalLocator {
 public:
  /// Throws InvalidInput for a size mismatch, an empty mesh or a non-unit sphere point.
  SphericalLocator(const EmbreeDevice& device, MeshView mesh, std::span<const Vec3> sphere);
  ~SphericalLocator();
  SphericalLocator(SphericalLocator&&) noexcept;
  SphericalLocator& operator=(SphericalLocator&&) noexcept;
  SphericalLocator(const SphericalLocator&) = delete;
  SphericalLocator& operator=(const SphericalLocator&) = delete;

  /// Face and barycentric coordinates (double precision, summing to 1) of direction `x` (any length > 0).
  /// Throws NumericalError when no triangle is hit even after re-aiming (the map is not an embedding).
  struct Location {
    std::uint32_t face;
    Vec3 barycentric;
  };
  [[nodiscard]] Location locate(const Vec3& x) const;

  /// The mesh point at direction `x`.
  [[nodiscard]] Vec3 position(const Vec3& x) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The mesh points at each of `directions` (multi-threaded).
[[nodiscard]] std::vector<Vec3> resample_spherical_map(const EmbreeDevice& device, MeshView mesh,
                                                       std::span<const Vec3> sphere,
                                                       std::span<const Vec3> directions);

}  // namespace gimforge
