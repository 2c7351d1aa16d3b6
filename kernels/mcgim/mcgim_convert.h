#pragma once
/// \file mcgim_convert.h
/// The whole multi-chart geometry-image conversion (Sander, Wood, Gortler, Snyder, Hoppe 2003): chartify
/// (§4.1), parametrize the charts with free boundaries (§4.2), pack them into a rectangle under a sample
/// budget (§4.3), sample them (§4.4), zipper them (§4.5) and, on request, optimize the samples against the
/// input surface (§4.6). Meshes of several components, with holes, of any genus.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "kernels/core/embree_device.h"
#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"
#include "kernels/core/surface_fit.h"
#include "kernels/mcgim/chartify.h"
#include "kernels/mcgim/mcgim_image.h"
#include "kernels/mcgim/pack.h"
#include "kernels/mcgim/zipper.h"
#include "kernels/param/stretch_optimizer.h"

namespace gimforge {

/// The §4.6 optimization's settings for multi-chart images: a light dihedral term (w = 1e-5: zipper
/// degenerates and dilated samples make a heavier one, e.g. the generic 1e-3, stall the descent at its first
/// step — measured on bunny_closed: 1e-3 and 1e-4 moved nothing, 1e-5 gained 4.1 dB in 20 iterations; since
/// slivers are left out of the dihedral term, 1e-3 still stalls the cow, 1e-4 and 1e-5 are within 0.4 dB on
/// cow and bunny_closed) and 60 conjugate-gradient iterations.
[[nodiscard]] inline SurfaceFitOptions default_mcgim_fit() {
  SurfaceFitOptions o;
  o.smoothness = 1e-5;
  o.iterations = 60;
  return o;
}

struct McgimOptions {
  std::size_t samples{65536};  ///< bound on the rectangle's area W·H (the memory cost)
  /// Charts requested; 0 chooses the count by a short search over `auto_charts` (the accuracy "hill" of the
  /// paper's Fig. 13): each candidate is converted and the one whose reconstruction is closest to the input
  /// (symmetric RMS distance over `auto_metric_samples` area samples) wins; a later candidate must be closer
  /// by more than 1 % (the estimate's sampling noise), so near ties go to the earlier (fewer charts).
  std::uint32_t charts{0};
  std::vector<std::uint32_t> auto_charts{32, 48};  ///< docs/multichart.md: why these
  std::size_t auto_metric_samples{50'000};
  bool optimize{false};        ///< geometry-image optimization (§4.6)
  ChartifyOptions chartify{};  ///< its `charts` is set from `charts`
  StretchOptimizerOptions stretch{};
  PackOptions pack{};          ///< its `max_samples` is set from `samples`
  SurfaceFitOptions fit = default_mcgim_fit();
  ProgressCallback progress{};  ///< stages "chartify", "parametrize", "pack", "sample", "zipper", "optimize", "charts auto"
};

struct McgimStats {
  std::uint32_t charts{0};
  int chartify_iterations{0};
  bool chartify_converged{false};
  bool chartify_cycle{false};
  std::uint32_t extra_seeds{0};
  std::size_t smoothed_faces{0};         ///< faces moved to a neighbouring chart by boundary smoothing (chart_smooth.h)
  std::uint32_t split_charts{0};         ///< charts split into pieces (overlapping free boundary, or efficiency < 0.8)
  std::uint32_t enlarged_charts{0};      ///< charts scaled up to get enough boundary samples for their cut-nodes
  std::vector<double> chart_efficiency;  ///< stretch efficiency per chart
  MeshStretch stretch;                   ///< the atlas (efficiency: the paper's total stretch efficiency)
  std::size_t optimizer_fallbacks{0};
  std::size_t boundary_folds{0};         ///< free-boundary crossings narrower than a sample, kept (chart_param.h)
  /// What cutting the input into an oriented 2-manifold changed (manifold_cut.h): edges of more than two
  /// faces and edges whose faces could not agree, made boundaries; faces reversed; vertices split into fans.
  std::size_t cut_nonmanifold_edges{0}, cut_orientation_edges{0}, flipped_faces{0}, split_vertices{0};
  std::size_t arealess_faces{0};  ///< faces of pieces without surface area, left out (no chart can hold them)
  double packing_efficiency{0.0};        ///< defined samples / W·H
  double scale{0.0};                     ///< samples per parameter unit (parameter area = surface area)
  double scale_steps{0.0};               ///< 1 % reductions until the charts fitted (a fraction: refined, pack.h)
  std::size_t defined_samples{0};
  std::size_t unique_vertices{0};
  std::size_t interior_samples{0}, boundary_samples{0}, dilated_samples{0};
  ZipperStats zipper;
  double fit_energy_before{0.0}, fit_energy_after{0.0};  ///< §4.6, when optimized
  std::vector<std::uint32_t> auto_tried;                 ///< charts auto: the counts tried
  std::vector<double> auto_rms;                          ///< ... and their symmetric RMS distances
  /// ... and for each, the earlier count whose chartification it repeated (then it was not converted again
  /// and its distance is that count's), or 0.
  std::vector<std::uint32_t> auto_same_as;
  std::uint32_t auto_kept{0};                            ///< charts auto: the count whose image was kept
  double seconds_chartify{0.0}, seconds_parametrize{0.0}, seconds_pack{0.0}, seconds_sample{0.0},
      seconds_zipper{0.0}, seconds_optimize{0.0};
};

struct McgimResult {
  MultiChartImage image;
  std::vector<float> normals;  ///< height × width × 3 (multichart_normals), NaN where undefined
  McgimStats stats;
};

/// Geometry-image optimization (§4.6) of any grid image in the §3 form: the clusters' representatives are
/// the vertices (unified samples move together, so a watertight image stays watertight), the triangulation
/// is re-chosen from the moved positions (shorter diagonals; pinned quads keep the image's stored
/// zipper_diagonals when it has them), and every defined sample takes its cluster's
/// fitted position. Serves mcgim and, through a full mask and the sideband's glued pixels as clusters,
/// geometry images. Throws as fit_surface does.
SurfaceFitResult optimize_multichart_image(const EmbreeDevice& device, const FitReference& reference, MultiChartImage& image,
                                           const SurfaceFitOptions& options);

/// --charts auto's rule: true when a later candidate count (more charts) with symmetric RMS distance
/// `candidate_rms` replaces the best so far — only when closer by more than the estimate's sampling noise
/// (1 %), so near ties keep fewer charts.
[[nodiscard]] bool auto_count_replaces(double best_rms, double candidate_rms);

/// Converts `mesh` (any triangle mesh without repeated-vertex faces: any number of components, holes, any
/// genus; non-manifold edges and vertices and inconsistent orientations are cut first, cut_to_manifold) to a
/// multi-chart geometry image. Throws InvalidInput for bad options (samples < 64, no face), NumericalError when the budget is too
/// small for the charts (message says to raise --samples), Cancelled via progress.
[[nodiscard]] McgimResult convert_to_multichart(const EmbreeDevice& device, const TriMesh& mesh,
                                                const McgimOptions& options = {});

}  // namespace gimforge
