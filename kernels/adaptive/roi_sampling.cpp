#include "kernels/adaptive/roi_sampling.h"

#include <algorithm>
#include <tuple>

#include <fmt/format.h>

#include "kernels/adaptive/local_hausdorff.h"
#include "kernels/adaptive/strip_sampling.h"
#include "kernels/core/errors.h"

namespace gimforge {

RoiMask resolve_roi_mask(const EmbreeDevice& device, MeshView disk, std::span<const Vec2> uv, std::uint32_t n,
                         const RoiSource& source, std::span<const std::uint8_t> face_in) {
  const std::uint32_t raster = roi_raster_size(n);
  RoiMask mask;
  switch (source.kind) {
    case RoiSource::Kind::Auto: {
      const ParametrizedSurface surface(device, disk, uv);
      mask = roi_auto(surface, disk, n, source.auto_fraction, raster);
      break;
    }
    case RoiSource::Kind::Vertices: mask = roi_from_faces(disk, uv, face_in, raster); break;
    case RoiSource::Kind::Picture:
      mask = roi_from_picture(source.picture_width, source.picture_height, source.picture, raster);
      break;
    case RoiSource::Kind::None: throw InvalidInput("region of interest: none given");
  }
  if (mask.area_cells() == 0)
    throw InvalidInput("the region of interest is empty: it covers no part of the parametrized surface");
  return mask;
}

RoiSampling sample_roi_adaptively(const EmbreeDevice& device, MeshView disk, std::span<const Vec2> uv, std::uint32_t n,
                                  AdaptStart start_kind, const GridPositions& positions_at, const RoiMask& mask,
                                  const RoiEnhanceOptions& enhance, AdaptOptions adapt,
                                  std::span<const std::uint32_t> glued) {
  RoiSampling out;
  out.started_from_strips = start_kind == AdaptStart::Strips;
  std::vector<Vec2> start = out.started_from_strips ? strip_sample_grid(equalized_strips(uv, n)) : uniform_grid(n);
  RoiSummary& s = out.summary;
  AdaptRound start_round;  // the start grid's figures, as a round of the history
  {
    LocalHausdorff field(device, disk, uv, n, start, positions_at(start), adapt.measure);
    field.verify(0.0);
    std::tie(s.roi_start, s.outside_start) = region_figures(field, uv, mask);
    const DirectedSummary d1 = field.summary(Direction::OriginalToGrid), d2 = field.summary(Direction::GridToOriginal);
    start_round.max_d1 = d1.max, start_round.rms_d1 = d1.rms, start_round.max_d2 = d2.max, start_round.rms_d2 = d2.rms;
    start_round.roi = s.roi_start, start_round.outside = s.outside_start;
  }
  RoiEnhanceResult enhanced = enhance_roi(uv, n, start, mask, enhance);
  s.samples_start = enhanced.samples_before;
  s.samples_enhanced = enhanced.samples_after;
  s.weight = enhanced.roi_weight;
  s.iterations = enhanced.iterations;
  adapt.roi = &mask;
  std::vector<Vec3> positions = positions_at(enhanced.sample_uv);
  AdaptResult adjusted = adjust_samples(device, disk, uv, n, std::move(enhanced.sample_uv), std::move(positions), adapt);
  out.history = std::move(adjusted.history);
  if (out.history.back().roi.max_d2 > s.roi_start.max_d2) {
    // Worse in the ROI than where it started: the start grid serves the ROI (and the rest) better.
    s.kept_start = true;
    s.rejected_max_d2 = out.history.back().roi.max_d2;
    adjusted.sample_uv = std::move(start);
    out.history = {start_round};
  }
  s.inside.resize(adjusted.sample_uv.size());
  for (std::size_t k = 0; k < adjusted.sample_uv.size(); ++k) s.inside[k] = mask.contains(adjusted.sample_uv[k]) ? 1 : 0;
  if (!glued.empty()) glue_flags(s.inside, glued);
  s.samples_final = static_cast<std::uint64_t>(std::count(s.inside.begin(), s.inside.end(), std::uint8_t{1}));
  out.sample_uv = std::move(adjusted.sample_uv);
  return out;
}

}  // namespace gimforge
