#include "kernels/core/embree_scene.h"

#include <utility>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge::detail {

EmbreeScene::EmbreeScene(const EmbreeDevice& device, std::span<const Vec3> positions, std::span<const Face> faces,
                         RTCBuildQuality quality, const char* what, const Vec3& origin) {
  auto* rtc = static_cast<RTCDevice>(device.native());
  RTCGeometry geom = rtcNewGeometry(rtc, RTC_GEOMETRY_TYPE_TRIANGLE);
  device.check(what);
  if (!geom) throw LibraryError(fmt::format("Embree: {}: cannot create a geometry", what));
  auto* vertices = static_cast<float*>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), positions.size()));
  auto* indices = static_cast<std::uint32_t*>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(std::uint32_t), faces.size()));
  if (!vertices || !indices) {
    rtcReleaseGeometry(geom);
    device.check(what);
    throw LibraryError(fmt::format("Embree: {}: cannot allocate geometry buffers", what));
  }
  for (std::size_t v = 0; v < positions.size(); ++v)
    for (int i = 0; i < 3; ++i) vertices[3 * v + static_cast<std::size_t>(i)] = static_cast<float>(positions[v][i] - origin[i]);
  // Degenerate faces are handed over as they are: rays ignore them, and exact callbacks measure them.
  for (std::size_t f = 0; f < faces.size(); ++f)
    for (std::size_t i = 0; i < 3; ++i) indices[3 * f + i] = faces[f][i];
  rtcSetGeometryBuildQuality(geom, quality);
  rtcCommitGeometry(geom);
  scene_ = rtcNewScene(rtc);
  rtcSetSceneBuildQuality(scene_, quality);
  rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_ROBUST);  // watertight: rays through edges still hit a triangle
  rtcAttachGeometry(scene_, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(scene_);
  device.check(what);
}

EmbreeScene::~EmbreeScene() {
  if (scene_) rtcReleaseScene(scene_);
}

EmbreeScene& EmbreeScene::operator=(EmbreeScene&& other) noexcept {
  std::swap(scene_, other.scene_);
  return *this;
}

}  // namespace gimforge::detail
