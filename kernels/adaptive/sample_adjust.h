#pragma once
/// \file sample_adjust.h
/// Hausdorff-error-driven adjustment of the samples of a geometry image (adaptive geometry images §3.3,
/// Algorithms 1–3).
///
/// A round visits the faces of both directions whose directed distance is at least `target_fraction` of
/// the largest one, worst first (the paper's Algorithm 1 visits only the worst face; a round of one target
/// is that algorithm). For a face of D1 (original → reconstruction) the samples of its f* move: the
/// vertex, edge or face of f* closest to p* (eq. (5)), along the gradient of the squared point–feature
/// distance (eq. (9), (16), (17)); for a face of D2 (reconstruction → original) the three samples of the
/// face holding p* move (eq. (10), (12), (15)). Samples live on the original surface: the 3D gradient is
/// taken to the parameter square through the Jacobian of the parametrization at each sample, the sample
/// moves there by ρ^k times a first step of half its distance to its nearest grid neighbour, and the surface
/// is resampled at the new parameter point. The first k = 0..step_halvings whose move lowers the largest
/// distance among every entry the move re-measures (both directions) is kept; a move that folds the grid is
/// never kept. A face whose move failed is visited again only after a later move changed its distance.
/// Boundary samples slide along their side with their glued partner (PerimeterGlue); corners and
/// cut-nodes stay. The adjustment stops after `rounds` rounds, at the first round that keeps no move, or at
/// the first round that lowers neither the largest distance nor the RMS by a thousandth.
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "kernels/adaptive/local_hausdorff.h"
#include "kernels/adaptive/roi.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"
#include "kernels/param/stretch.h"

namespace gimforge {

struct AdaptOptions {
  std::uint32_t rounds{12};          ///< K: at most this many rounds (0: measure only)
  std::uint32_t step_halvings{6};    ///< steps ρ^k, k = 0..step_halvings
  double rho{0.5};                   ///< ρ
  double target_fraction{0.5};       ///< a round visits faces with distance >= this × the largest
  LocalHausdorffOptions measure{};
  /// ROI mode (§4, roi.h): the objective is the directed distance from the ROI's reconstruction to the
  /// original (D2 of the reconstruction triangles whose samples' centroid lies in the ROI): a round visits
  /// those within target_fraction of their largest; a move is kept when its target falls, no re-measured
  /// ROI triangle rises above the largest of them before nor above the ROI's largest at the start of the
  /// round, and no entry anywhere rises above the global largest distance; the stop rule watches the ROI's largest D2 and its RMS. Null: the whole surface, both
  /// directions. The mask must outlive the call.
  const RoiMask* roi{nullptr};
  ProgressCallback progress{};       ///< stage "adapt"
};

/// Figures of the faces of one part of the square (ROI mode): original faces by the parameter point of
/// their centroid, reconstruction triangles by their samples' centroid; RMS weighted by area.
struct RegionFigures {
  double max_d1{0.0}, rms_d1{0.0};
  double max_d2{0.0}, rms_d2{0.0};
};

/// Figures after a round (round 0: before any move).
struct AdaptRound {
  std::uint32_t round{0};
  double max_d1{0.0}, max_d2{0.0};   ///< original → reconstruction, reconstruction → original
  double rms_d1{0.0}, rms_d2{0.0};
  std::uint64_t targets{0};          ///< faces visited in the round
  std::uint64_t moves{0};            ///< moves kept
  std::uint64_t folds{0};            ///< trial moves refused because they fold the grid
  RegionFigures roi{};               ///< ROI mode: inside the ROI
  RegionFigures outside{};           ///< ROI mode: outside it
};

struct AdaptResult {
  std::vector<Vec2> sample_uv;       ///< n·n final parameter points
  std::vector<AdaptRound> history;
  double seconds{0.0};
};

/// Where the parametrized surface is at a parameter point: the original face holding it, its position
/// and the Jacobian ∂x/∂(u, v) of the parametrization there.
class ParametrizedSurface {
 public:
  ParametrizedSurface(const EmbreeDevice& device, MeshView surface, std::span<const Vec2> uv);
  ~ParametrizedSurface();
  ParametrizedSurface(const ParametrizedSurface&) = delete;
  ParametrizedSurface& operator=(const ParametrizedSurface&) = delete;
  struct Point {
    std::uint32_t face{0};
    Vec3 position{Vec3::Zero()};
    Eigen::Matrix<double, 3, 2> jacobian{Eigen::Matrix<double, 3, 2>::Zero()};
  };
  [[nodiscard]] Point at(const Vec2& uv) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The figures inside and outside `roi` of a measured field (sample_adjust's ROI mode).
[[nodiscard]] std::pair<RegionFigures, RegionFigures> region_figures(const LocalHausdorff& field, std::span<const Vec2> uv,
                                                                     const RoiMask& roi);

/// Adjusts the samples of an n×n grid over the parametrized surface (`surface`, one parameter point per
/// vertex in `uv`), starting from `sample_uv` with positions `sample_pos`: interior samples move in the
/// square; boundary samples slide along their side only when options.measure.glue says how the sides are
/// glued (all three functions set), and otherwise stay. Throws InvalidInput for mismatched sizes or
/// parameter points outside [0, 1]², Cancelled via progress.
[[nodiscard]] AdaptResult adjust_samples(const EmbreeDevice& device, MeshView surface, std::span<const Vec2> uv,
                                         std::uint32_t n, std::vector<Vec2> sample_uv, std::vector<Vec3> sample_pos,
                                         const AdaptOptions& options = {});

/// Adaptive sampling: the grid the adjustment starts from.
enum class AdaptStart {
  Auto,     ///< whichever of the two below has the smaller symmetric RMS of the local Hausdorff distances
  Uniform,  ///< the regular grid
  Strips,   ///< the vertex-density-equalized strips (adaptive geometry images §3.1)
};

/// The surface points of an n × n grid of parameter points (row-major), as the image's sampler gives
/// them (mates on glued sides bit-equal).
using GridPositions = std::function<std::vector<Vec3>(const std::vector<Vec2>&)>;

/// What sample_adaptively did.
struct AdaptiveSampling {
  std::vector<Vec2> sample_uv;      ///< n·n final parameter points
  std::vector<AdaptRound> history;  ///< round 0: the start grid
  bool started_from_strips{false};
  double rms_uniform_start{0.0};    ///< AdaptStart::Auto: symmetric local RMS of either start grid
  double rms_strips_start{0.0};
};

/// The uniform n × n grid of the unit square, row-major.
[[nodiscard]] std::vector<Vec2> uniform_grid(std::uint32_t n);

/// The start grid (`start`: the uniform one, the vertex-density strips of §3.1, or under AdaptStart::Auto
/// whichever of the two is closer to the surface by the symmetric RMS of the local Hausdorff distances),
/// then adjust_samples from it: the adaptive sampling of every image over a parameter square (geometry
/// images, the flat-octahedron spherical image). `options.roi` must be null. Throws as adjust_samples.
[[nodiscard]] AdaptiveSampling sample_adaptively(const EmbreeDevice& device, MeshView surface, std::span<const Vec2> uv,
                                                 std::uint32_t n, AdaptStart start, const GridPositions& positions_at,
                                                 const AdaptOptions& options);

}  // namespace gimforge
