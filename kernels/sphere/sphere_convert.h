#pragma once
/// \file sphere_convert.h
/// The whole spherical geometry-image conversion of Praun & Hoppe 2003: fill holes (§5, faces marked
/// "hole"), parametrize the closed genus-0 mesh onto the sphere (§3, sphere_map.h), sample the domain's
/// stretch-optimized map D → S at tessellation n (§4.2, domain_map.h), locate every sample direction in the
/// spherical triangulation and interpolate the surface (§4, I → D → S → M).
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/embree_device.h"
#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"
#include "kernels/core/surface_fit.h"
#include "kernels/adaptive/roi_sampling.h"
#include "kernels/adaptive/sample_adjust.h"
#include "kernels/sphere/sphere_map.h"
#include "kernels/sphere/spherical_domain.h"

namespace gimforge {

struct SphereOptions {
  SphericalDomain domain{SphericalDomain::Octahedron};
  std::uint32_t n{128};      ///< tessellation number (octahedron: a (2n+1)² image)
  SphereMapOptions map{};    ///< the S → M optimizer (its progress callback is replaced by `progress`)
  /// Adaptive sampling (sphere_adapt.h): the flat-octahedron domain only, closed meshes only (a filled
  /// hole's samples are undefined, which the adjustment does not model).
  bool adaptive{false};
  AdaptStart adapt_start{AdaptStart::Auto};
  AdaptOptions adapt{};      ///< rounds and steps (its progress callback is replaced by `progress`)
  RoiSource roi{};           ///< adaptive sampling: the region of interest (none by default; roi_sampling.h)
  ProgressCallback progress{};  ///< stages "simplify", "refine", "sweep", "sample"
};

/// A spherical geometry image: one sample per stored image sample of DomainImage(domain, n), laid out as
/// DomainImage::linear_index, i.e. an array of shape (faces·height, width, 3).
struct SphericalImage {
  SphericalDomain domain{SphericalDomain::Octahedron};
  std::uint32_t n{0};
  std::vector<float> positions;  ///< num_samples·3; NaN where the sample is undefined (in a hole)
  std::vector<std::uint8_t> mask;  ///< num_samples; 1 = defined, 0 = the sample lies in a hole face
  std::vector<float> colors;     ///< num_samples·3 in [0,1] when the mesh has colours, else empty
  /// Adaptive sampling: num_samples·2 parameter points of the samples in the image's square (sample
  /// (i, j) of the uniform image lies at (i, j)/(width − 1)); empty: uniform.
  std::vector<float> sample_uv;

  [[nodiscard]] DomainImage layout() const { return DomainImage(domain, n); }
};

struct SphereStats {
  std::size_t holes_filled{0};       ///< boundary loops closed with hole faces
  std::size_t hole_faces{0};         ///< faces added (energy scaled by SphereMapOptions::hole_weight)
  std::size_t masked_samples{0};     ///< samples in hole faces (NaN in the image)
  /// Filled holes no sample fell into (narrower than the sample spacing): the image closes them over, so its
  /// reconstruction has fewer boundary loops than the input.
  std::size_t holes_without_samples{0};
  SphericalStretch map_stretch;      ///< S → M on the input faces (hole faces excluded)
  double domain_efficiency{0.0};     ///< L2 stretch efficiency of the D → S map used (paper Table 2)
  double efficiency_domain_to_mesh{0.0};  ///< L2 stretch efficiency of D → M, measured on the sampled image
  std::size_t base_vertices{4};
  std::size_t vertex_splits{0};
  double seconds_simplify{0.0};
  double seconds_optimize{0.0};      ///< base placement, vertex insertion and sweeps
  double seconds_sample{0.0};
  std::vector<AdaptRound> adapt_history;  ///< adaptive sampling: figures per round (round 0: the start grid)
  bool adapt_started_from_strips{false};
  double adapt_rms_uniform_start{0.0};    ///< AdaptStart::Auto: symmetric local RMS of either start grid
  double adapt_rms_strips_start{0.0};
  std::size_t adapt_disk_faces{0};        ///< the cut disk (octa_disk.h) and its faces turned over
  std::size_t adapt_disk_flipped{0};
  RoiSummary roi{};                       ///< with a ROI: its samples and figures (later rounds: adapt_history)
  double seconds_adapt{0.0};
};

struct SphereResult {
  SphericalImage image;
  /// Unit vector of every vertex of the closed mesh that was parametrized: the input vertices first (same
  /// order), then one centre vertex per filled hole (in the order fill_holes creates them).
  std::vector<Vec3> sphere;
  SphereStats stats;
};

/// Converts a genus-0 mesh (closed, or with holes that are filled) into a spherical geometry image.
/// Throws TopologyError when the surface is not one connected genus-0 surface after filling holes (the
/// message names the geometry-image and multi-chart methods, which handle any genus), InvalidInput for bad
/// options, NumericalError when the parametrization is not an embedding, Cancelled via progress.
[[nodiscard]] SphereResult convert_to_spherical_image(const EmbreeDevice& device, const TriMesh& mesh,
                                                      const SphereOptions& options = {});

/// convert_to_spherical_image with the sphere map given instead of optimized (e.g. read back from an
/// archive, to resample another domain or n): `sphere` as in SphereResult. Stats as there, with
/// vertex_splits 0 and no simplify/optimize time. Throws as resample_spherical_image.
[[nodiscard]] SphereResult convert_with_sphere_map(const EmbreeDevice& device, const TriMesh& mesh,
                                                   std::span<const Vec3> sphere, const SphereOptions& options = {});

/// Resamples a stored spherical parametrization without re-optimizing: `sphere` as in SphereResult
/// (input vertices, then hole centres; holes are filled again the same way). Throws InvalidInput when
/// `sphere` does not fit the mesh, NumericalError when it is not an embedding.
[[nodiscard]] SphericalImage resample_spherical_image(const EmbreeDevice& device, const TriMesh& mesh,
                                                      std::span<const Vec3> sphere, SphericalDomain domain,
                                                      std::uint32_t n, ProgressCallback progress = {});

/// Reconstructs the mesh of a spherical geometry image at LOD `level` (reconstruct_spherical_image):
/// closed and manifold when every sample is defined; faces touching undefined samples are dropped (and
/// unused vertices removed), leaving the holes open. Throws InvalidInput for bad sizes or levels.
[[nodiscard]] TriMesh reconstruct_spherical_geometry(const SphericalImage& image, std::uint32_t level = 0);

/// Geometry-image optimization (Sander et al. 2003, §4.6, core/surface_fit.h) of a spherical geometry
/// image: the vertices are the image's domain points (samples that are the same point of D move together,
/// so the image stays closed), the triangles those of reconstruct_spherical_image (the domain's own
/// connectivity for the tetrahedron and octahedron, shorter diagonals re-chosen as the samples move for the
/// cube and flattened octahedron), without faces that touch undefined samples, which stay undefined.
/// Rewrites image.positions. Throws as fit_surface, InvalidInput for an image of the wrong size.
[[nodiscard]] SurfaceFitResult optimize_spherical_image(const EmbreeDevice& device, const FitReference& reference,
                                                        SphericalImage& image, const SurfaceFitOptions& options);

}  // namespace gimforge
