#pragma once
/// \file embree_device.h
/// RAII wrappers over Embree 3: one explicit device (make one per rank and pass it down; no hidden global)
/// and a triangle BVH answering exact closest-point queries through rtcPointQuery.
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>

#include "kernels/core/mesh.h"

namespace gimforge {

/// An Embree device. Errors reported by Embree on this device throw LibraryError from the call that
/// caused them. Move-only.
class EmbreeDevice {
 public:
  /// `config` is Embree's device configuration string (e.g. "threads=2"); empty for defaults.
  explicit EmbreeDevice(const std::string& config = {});
  ~EmbreeDevice();
  EmbreeDevice(EmbreeDevice&&) noexcept;
  EmbreeDevice& operator=(EmbreeDevice&&) noexcept;
  EmbreeDevice(const EmbreeDevice&) = delete;
  EmbreeDevice& operator=(const EmbreeDevice&) = delete;

  /// The underlying RTCDevice (opaque pointer, to keep embree headers out of this header).
  [[nodiscard]] void* native() const;
  /// Throws LibraryError if Embree recorded an error on this device since the last check.
  void check(const char* what) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Face index meaning "no face".
inline constexpr std::uint32_t kNoFace = 0xffffffffu;

/// Closest point on a mesh: the point, its distance, the face and the barycentric coordinates there.
struct ClosestPoint {
  Vec3 point{Vec3::Zero()};
  double distance{std::numeric_limits<double>::infinity()};
  std::uint32_t face{kNoFace};
  Vec3 barycentric{Vec3::Zero()};
  [[nodiscard]] bool found() const { return face != kNoFace; }
};

/// A BVH over the triangles of a mesh for exact closest-point queries.
/// Embree traverses its float BVH; every candidate triangle is then measured exactly in double
/// precision against the mesh's own coordinates, and the traversal radius carries a margin larger than
/// the float rounding of the bounds, so the answer is the exact closest point (up to double rounding).
/// The mesh storage must outlive the BVH. Queries are thread-safe. Degenerate faces are skipped.
class TriangleBvh {
 public:
  /// Builds the BVH. Throws InvalidInput for an empty mesh, LibraryError on Embree failures.
  TriangleBvh(const EmbreeDevice& device, MeshView mesh);
  ~TriangleBvh();
  TriangleBvh(TriangleBvh&&) noexcept;
  TriangleBvh& operator=(TriangleBvh&&) noexcept;
  TriangleBvh(const TriangleBvh&) = delete;
  TriangleBvh& operator=(const TriangleBvh&) = delete;

  /// Closest point on the mesh to p. `upper_bound` is a distance known to be at least the true answer
  /// (e.g. the distance to some triangle); it speeds up the search and does not change the result.
  /// Returns a ClosestPoint with found() == false when nothing lies within `upper_bound`.
  [[nodiscard]] ClosestPoint closest_point(const Vec3& p,
                                           double upper_bound = std::numeric_limits<double>::infinity()) const;

  /// Exact distance from p to face f (for computing upper bounds from a neighbouring query's answer).
  [[nodiscard]] double distance_to_face(const Vec3& p, std::uint32_t f) const;

  [[nodiscard]] MeshView mesh() const;

  /// Its committed, robust Embree scene (an RTCScene) of the mesh's triangles, primitive i = face i: ray
  /// queries over the same triangles need no second BVH (kernels/scan/surface_transfer.cpp).
  [[nodiscard]] void* native_scene() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gimforge
