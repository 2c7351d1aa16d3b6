#pragma once
/// \file mesh_render.h
/// The reference renderer of the relief ray caster: the original triangle mesh rendered with Embree from
/// the same camera with the same shading (render_camera.h), and the comparison of two renders (PSNR of the
/// shaded images, silhouette IoU, depth and normal errors).
#include <cstdint>
#include <memory>

#include "kernels/core/embree_device.h"
#include "kernels/core/mesh.h"
#include "kernels/relief/render_camera.h"

namespace gimforge {

/// The reference renderer: closest hit of every primary ray with the triangles of a mesh (Embree, robust
/// scene), shaded with the geometric normal of the hit triangle. The mesh must outlive it.
class MeshRenderer {
 public:
  /// Builds the BVH. Throws InvalidInput for a mesh without faces, LibraryError when Embree fails.
  MeshRenderer(const EmbreeDevice& device, const TriMesh& mesh, double ambient = 0.15);
  ~MeshRenderer();
  MeshRenderer(MeshRenderer&&) noexcept;
  MeshRenderer& operator=(MeshRenderer&&) noexcept;
  MeshRenderer(const MeshRenderer&) = delete;
  MeshRenderer& operator=(const MeshRenderer&) = delete;

  [[nodiscard]] RayHit trace(const Vec3& origin, const Vec3& direction) const;  ///< grey_cell unused (0)
  [[nodiscard]] RenderImage render(const Camera& camera) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Comparison of two renders of the same camera.
struct RenderComparison {
  double mse{0.0};              ///< mean squared difference of the shaded images, over all pixels
  double psnr{0.0};             ///< 10·log10(255² / mse) in dB; +inf for identical images
  double iou{1.0};              ///< |mask_a ∩ mask_b| / |mask_a ∪ mask_b| (1 when both are empty)
  std::uint64_t hits_a{0};
  std::uint64_t hits_b{0};
  std::uint64_t hits_both{0};
  std::uint64_t hits_either{0};
  double depth_mean_abs{0.0};   ///< over pixels hit in both: mean |t_a − t_b| (world units)
  double depth_rms{0.0};
  double depth_p95{0.0};        ///< 95th percentile of |t_a − t_b|
  double normal_mean_deg{0.0};  ///< over pixels hit in both: mean angle between the unit normals, two-sided
};

/// Compares two renders. Throws InvalidInput when their sizes differ.
[[nodiscard]] RenderComparison compare_renders(const RenderImage& a, const RenderImage& b);

}  // namespace gimforge
