#pragma once
/// \file chart_param.h
/// Chart parametrization of multi-chart geometry images (Sander et al. 2003, §4.2): every chart of a
/// chartification (chartify.h) is cut out as a mesh of its own, started by its least-squares conformal map
/// (lscm.h) or Floater's map with the boundary on a convex ellipse, whichever is valid and less stretched, and
/// optimized (where the free boundary makes the map overlap itself, the chart is optimized again with its
/// boundary held at a one-to-one start) by the hierarchical L2-stretch minimization of the geometry-image path
/// (stretch_optimizer.h) with a **free boundary**: boundary vertices move under their own open-ring kernel,
/// and the energy is the scale-invariant (Σ L2² A')·(Σ A_param). The charts are then scaled relative to
/// each other by their stretch (Sander et al. 2002): chart i gets parameter area ∝ sqrt(S_i · D_i)
/// (S_i = Σ L2² A', D_i its parameter area), the scaling that minimizes the atlas's L2 stretch for a given
/// total area; the atlas is normalized to parameter area = surface area.
#include <cstdint>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"
#include "kernels/param/stretch.h"
#include "kernels/param/stretch_optimizer.h"

namespace gimforge {

/// One chart as a mesh of its own.
struct ChartMesh {
  TriMesh mesh;                          ///< the chart's faces over its own vertices
  std::vector<std::uint32_t> vertices;   ///< local vertex -> vertex of the input mesh
  std::vector<std::uint32_t> faces;      ///< local face -> face of the input mesh
  std::vector<std::uint32_t> boundary;   ///< the boundary loop (local vertices), the chart on its left
};

/// Cuts the charts out of `mesh`. Precondition: `face_chart` has one entry < num_charts per face and every
/// chart is a topological disk (chartify's guarantee); throws InvalidInput otherwise (naming the chart).
[[nodiscard]] std::vector<ChartMesh> extract_charts(MeshView mesh, const std::vector<std::uint32_t>& face_chart,
                                                    std::uint32_t num_charts);

struct ChartParamOptions {
  StretchOptimizerOptions stretch{};  ///< free_boundary is set by parametrize_charts
  ProgressCallback progress{};        ///< stage "parametrize" (fraction of the charts done)
  /// A free boundary that crosses itself in a loop smaller than this (surface units) is kept: a fold the
  /// sampling cannot see. 0: every crossing holds the boundary (and marks the chart for splitting).
  double fold_tolerance{0.0};
};

/// Below this stretch efficiency a chart is better split (ChartParametrization::split).
inline constexpr double kSplitEfficiency = 0.8;

struct ChartParametrization {
  std::vector<std::vector<Vec2>> uv;  ///< per chart, per local vertex, after the relative scaling
  std::vector<MeshStretch> stretch;   ///< per chart (efficiency is scale-free)
  /// Per chart: 1 when it should be split — its free boundary overlapped itself (the boundary was then
  /// held), or its efficiency is below kSplitEfficiency (e.g. a band the clustering wrapped around a limb).
  std::vector<char> split;
  MeshStretch total;                  ///< the whole atlas after the relative scaling
  std::size_t optimizer_fallbacks{0}; ///< charts where the optimizer failed and its start map is kept
  std::size_t overlap_fallbacks{0};   ///< charts whose free boundary overlapped itself: boundary held instead
  std::size_t floater_starts{0};      ///< charts started from Floater's circle map (the conformal one folded or was worse)
  std::size_t tutte_starts{0};        ///< charts started from Tutte's map (degenerate faces defeated the other two)
  std::size_t small_folds{0};         ///< boundary crossings kept as folds below ChartParamOptions::fold_tolerance
  double seconds{0.0};
};

/// Scales chart c's map by `factor` (> 0) beyond the relative scaling, updating its stretch and the totals:
/// for charts too small to sample (fewer boundary samples than cut-nodes at the atlas's scale).
void enlarge_chart(ChartParametrization& param, const ChartMesh& chart, std::size_t c, double factor);

/// Parametrizes every chart (see the file comment). `reuse`, when given, holds per chart either a
/// parametrization to keep as it is (one uv per chart vertex: a chart unchanged since an earlier call) or
/// nothing (parametrize it). Throws NumericalError when a chart has no valid parametrization at all,
/// Cancelled via progress.
[[nodiscard]] ChartParametrization parametrize_charts(const std::vector<ChartMesh>& charts,
                                                      const ChartParamOptions& options = {},
                                                      const std::vector<std::vector<Vec2>>* reuse = nullptr);

}  // namespace gimforge
