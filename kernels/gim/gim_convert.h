#pragma once
/// \file gim_convert.h
/// The whole geometry-image conversion of Gu, Gortler, Hoppe 2002 (§3.2 pseudocode Cut_and_parametrize,
/// then §4 sampling): initial cut, boundary on the square, Floater start, hierarchical stretch
/// optimization, iterated cut augmentation while the stretch improves, regular resampling.
#include <cstdint>

#include "kernels/adaptive/roi_sampling.h"
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

struct GimOptions {
  GeometryImageOptions image{};
  GimSampling sampling{GimSampling::Uniform};
  AdaptStart adapt_start{AdaptStart::Auto};
  AdaptOptions adapt{};              ///< adaptive sampling: rounds and steps (its progress is `progress`)
  /// Adaptive sampling: the region of interest (none by default; roi_sampling.h). The start grid is then the
  /// uniform one (the strips under AdaptStart::Strips).
  RoiSource roi{};
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
  /// With a ROI: which final samples lie in it, its samples on the start grid, after enhancement and at
  /// the end, the figures inside and outside it on the start grid (later rounds: adapt_history).
  RoiSummary roi{};
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
