#pragma once
/// \file gim_convert.h
/// The whole geometry-image conversion of Gu, Gortler, Hoppe 2002 (§3.2 pseudocode Cut_and_parametrize,
/// then §4 sampling): initial cut, boundary on the square, Floater start, hierarchical stretch
/// optimization, iterated cut augmentation while the stretch improves, regular resampling.
#include <cstdint>

#include "kernels/adaptive/sample_adjust.h"
#include "kernels/core/embree_device.h"
#include "kernels/gim/geometry_image.h"
#include "kernels/core/progress.h"
#include "kernels/param/stretch_optimizer.h"

namespace gimforge {

/// Where the samples of the image lie in the parameter square.
enum class GimSampling {
  Uniform,   ///< the regular grid (Gu et al. 2002)
  Adaptive,  ///< vertex-density-equalized strips, then Hausdorff-driven adjustment (kernels/adaptive)
};

/// Adaptive sampling with a region of interest (adaptive geometry images §4, kernels/adaptive/roi.h):
/// the ROI gets more samples (enhance_roi), then the adjustment minimizes the directed distance from the
/// ROI's reconstruction to the original (AdaptOptions::roi). The start grid is the uniform one (the
/// strips under AdaptStart::Strips).
struct GimRoi {
  enum class Kind {
    None,      ///< no ROI: the adjustment of the whole surface
    Auto,      ///< roi_auto on the normal image, `auto_fraction` of the square
    Vertices,  ///< the faces touching the flagged vertices (`vertices`, one flag per vertex of the mesh)
    Picture,   ///< a picture over the square (`picture`, row 0 the top, roi_from_picture)
  };
  Kind kind{Kind::None};
  double auto_fraction{0.1};
  std::vector<std::uint8_t> vertices;
  std::uint32_t picture_width{0};
  std::uint32_t picture_height{0};
  std::vector<std::uint8_t> picture;
  RoiEnhanceOptions enhance{};
};

struct GimOptions {
  GeometryImageOptions image{};
  GimSampling sampling{GimSampling::Uniform};
  AdaptStart adapt_start{AdaptStart::Auto};
  AdaptOptions adapt{};              ///< adaptive sampling: rounds and steps (its progress is `progress`)
  GimRoi roi{};                      ///< adaptive sampling: the region of interest (none by default)
  std::uint32_t units_per_side{64};  ///< cut-nodes on the grid of the (units_per_side+1)² level
  int max_augmentations{6};          ///< iterations of cut augmentation (0: keep the initial cut)
  StretchOptimizerOptions stretch{};
  ProgressCallback progress{};       ///< stages "cut", "parametrize", "augment", "adapt", "sample"
};

/// Figures of a conversion, for the archive and reports.
struct GimStats {
  std::size_t cut_edges{0};         ///< edges of the final cut ρ (original boundary edges included)
  std::size_t cut_paths{0};         ///< cut-paths on ρ'
  int augmentations{0};             ///< accepted augmentation steps
  std::size_t corner_splits{0};
  std::size_t side_splits{0};
  MeshStretch floater;              ///< Floater start of the final cut
  MeshStretch stretch;              ///< final parametrization
  bool optimizer_fallback{false};   ///< the stretch optimizer failed on the final cut: its Floater map is used
  double seconds_cut{0.0};
  double seconds_parametrize{0.0};  ///< all parametrizations, augmentation trials included
  double seconds_sample{0.0};
  std::vector<AdaptRound> adapt_history;  ///< adaptive sampling: figures per round (round 0: the start grid)
  bool adapt_started_from_strips{false};  ///< adaptive sampling: the start grid was the strips
  double adapt_rms_uniform_start{0.0};    ///< AdaptStart::Auto: symmetric local RMS of either start grid
  double adapt_rms_strips_start{0.0};
  double seconds_adapt{0.0};              ///< adaptive sampling: start grids, measurement and adjustment
  /// With a ROI: per final sample (n·n, row-major) whether it lies in the ROI; the ROI's samples on the
  /// start grid, after enhancement and at the end; the figures inside and outside the ROI on the start
  /// grid (those after enhancement and after each round are in adapt_history).
  std::vector<std::uint8_t> roi_samples;
  std::uint64_t roi_samples_start{0};
  std::uint64_t roi_samples_enhanced{0};
  std::uint64_t roi_samples_final{0};
  RegionFigures roi_start{};
  RegionFigures outside_start{};
  double roi_weight{0.0};       ///< the ROI's weight when enhancement stopped
  std::uint32_t roi_iterations{0};  ///< enhancement: fixed-point iterations
};

struct GimResult {
  GeometryImage image;
  GimStats stats;
};

/// Converts a mesh to a geometry image. The mesh must be one connected, manifold, orientable surface
/// (any genus, any number of boundaries); otherwise TopologyError says what was found (several components:
/// use the multi-chart method). Throws InvalidInput for bad options, Cancelled via progress.
[[nodiscard]] GimResult convert_to_geometry_image(const EmbreeDevice& device, const TriMesh& mesh,
                                                  const GimOptions& options = {});

}  // namespace gimforge
