#pragma once
/// \file roi_sampling.h
/// Adaptive sampling with a region of interest (adaptive geometry images §4) over any image whose samples
/// lie in a parametrized square: the ROI's mask from what the user gave (RoiSource, resolved on the
/// parametrized surface), the figures inside and outside it on the start grid, enhancement (roi.h,
/// enhance_roi: the ROI gets more of the samples), then the adjustment of the ROI's directed distance
/// (sample_adjust.h, AdaptOptions::roi). The geometry image (gim_convert.h) and the flat-octahedron
/// spherical image (sphere_adapt.h) both sample through it.
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/adaptive/roi.h"
#include "kernels/adaptive/sample_adjust.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/mesh.h"

namespace gimforge {

/// The region of interest as the user gave it, resolved against the input mesh.
struct RoiSource {
  enum class Kind {
    None,      ///< no ROI: the adjustment of the whole surface
    Auto,      ///< roi_auto on the normal image, `auto_fraction` of the square
    Vertices,  ///< the faces touching the flagged vertices (`vertices`, one flag per vertex of the input mesh)
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

/// What the ROI got and what it measured (empty `inside`: no ROI).
struct RoiSummary {
  std::vector<std::uint8_t> inside;    ///< per final sample (row-major), whether it lies in the ROI
  std::uint64_t samples_start{0};      ///< samples in the ROI on the start grid
  std::uint64_t samples_enhanced{0};   ///< ... after enhancement
  std::uint64_t samples_final{0};      ///< ... at the end
  RegionFigures roi_start{};           ///< figures inside the ROI on the start grid (later: the history's rounds)
  RegionFigures outside_start{};       ///< ... outside it
  double weight{0.0};                  ///< the ROI's weight when enhancement stopped
  std::uint32_t iterations{0};         ///< enhancement: fixed-point iterations
  /// The ROI's largest distance ended above the start grid's (a ROI larger than the image can feed, a high
  /// gain, a tiny image: enhancement stretched the triangles next to the fixed sides): the start grid was
  /// kept, and `inside`, `samples_final` and the history describe it.
  bool kept_start{false};
  double rejected_max_d2{0.0};  ///< kept_start: the ROI's largest distance on the grid that was not kept
};

struct RoiSampling {
  std::vector<Vec2> sample_uv;      ///< n·n final parameter points
  bool started_from_strips{false};  ///< the start grid was the vertex-density strips (AdaptStart::Strips)
  std::vector<AdaptRound> history;  ///< round 0: the enhanced grid (the start grid's figures are in `summary`)
  RoiSummary summary;
};

/// The mask of `source` (kind other than None) over the square of the parametrized surface `disk` (`uv`
/// one point per vertex) for an n × n image. `face_in` flags the faces of `disk` that touch a vertex of
/// source.vertices (the caller maps the input's vertices through its cut; read for Kind::Vertices only).
/// Throws InvalidInput for an empty ROI or mismatched sizes.
[[nodiscard]] RoiMask resolve_roi_mask(const EmbreeDevice& device, MeshView disk, std::span<const Vec2> uv, std::uint32_t n,
                                       const RoiSource& source, std::span<const std::uint8_t> face_in);

/// Adaptive sampling with a ROI: the figures on the start grid (the strips of §3.1 under AdaptStart::Strips,
/// the uniform grid otherwise), enhancement, then adjust_samples of the ROI's
/// directed distance (`adapt.roi` is set here). When the ROI's largest distance (D2) ends above the start
/// grid's, the start grid is returned instead (summary.kept_start; the history is then its one round).
/// `positions_at` gives the surface points of a grid as the image's sampler does. `glued` (n·n, or empty):
/// each sample's class representative (glue_flags): glued samples are one surface point, so the returned
/// flags (summary.inside, samples_final) put them in the ROI together. Throws as resolve_roi_mask and
/// adjust_samples.
[[nodiscard]] RoiSampling sample_roi_adaptively(const EmbreeDevice& device, MeshView disk, std::span<const Vec2> uv,
                                                std::uint32_t n, AdaptStart start,
                                                const GridPositions& positions_at, const RoiMask& mask,
                                                const RoiEnhanceOptions& enhance, AdaptOptions adapt,
                                                std::span<const std::uint32_t> glued = {});

}  // namespace gimforge
