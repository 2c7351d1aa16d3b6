#pragma once
/// \file embree_scene.h
/// Internal to kernels/: an owned, committed Embree scene of one triangle geometry. Shared by the
/// closest-point BVH (embree_device.cpp) and the spherical locator (sphere_resample.cpp). Not part of the
/// public API: it exposes Embree types.
#include <span>

#include <embree3/rtcore.h>

#include "kernels/core/embree_device.h"
#include "kernels/core/mesh.h"

namespace gimforge::detail {

/// Move-only owner of an RTCScene.
class EmbreeScene {
 public:
  /// Builds and commits a robust (watertight) scene of `faces` over `positions` − `origin` (converted to
  /// float: an origin near the mesh keeps its precision). Throws LibraryError naming `what` when Embree fails.
  EmbreeScene(const EmbreeDevice& device, std::span<const Vec3> positions, std::span<const Face> faces,
              RTCBuildQuality quality, const char* what, const Vec3& origin = Vec3::Zero());
  ~EmbreeScene();
  EmbreeScene(EmbreeScene&& other) noexcept : scene_(other.scene_) { other.scene_ = nullptr; }
  EmbreeScene& operator=(EmbreeScene&& other) noexcept;
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  [[nodiscard]] RTCScene get() const { return scene_; }

 private:
  RTCScene scene_{nullptr};
};

}  // namespace gimforge::detail
