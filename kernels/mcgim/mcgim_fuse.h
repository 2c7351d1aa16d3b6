#pragma once
/// \file mcgim_fuse.h
/// Fusing a lossily decoded multi-chart geometry image: the zipper of Sander et al. (2003, §4.5) unifies
/// boundary samples of neighbouring charts into clusters that hold one position, which is what makes the
/// reconstruction watertight. An image coder reconstructs the members of a cluster differently. As Gu et al.
/// (2002, §5) do with the cut of a geometry image, fusing replaces every cluster by its average, and error
/// diffusion spreads each fused sample's displacement into its chart, so that the average leaves no step
/// next to the chart boundary.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/mcgim/mcgim_image.h"

namespace gimforge {

struct ZipperFuseStats {
  std::size_t clusters{0};       ///< clusters of more than one sample
  double max_displacement{0.0};  ///< the largest move of a clustered sample
};

/// Averages every cluster of `image.unified` in `image.positions`, in place: the members' values become
/// bit-identical (the representative's). `displacement` receives the move of every sample (zero for samples
/// that are alone in their cluster, and for undefined ones). Undefined samples are left as they are. Throws
/// InvalidInput for sizes that disagree.
ZipperFuseStats fuse_zipper(MultiChartImage& image, std::vector<Vec3>& displacement);

/// Floats per chart in chart_planes: the chart's centre (column, row), then for x, y and z the coefficients of
/// 1, dx, dy, dx², dx·dy, dy² (dx, dy: column and row minus the centre).
inline constexpr std::size_t kPlaneFloats = 2 + 3 * 6;

/// The least-squares quadratic map of every chart over its samples' (column, row), kPlaneFloats per chart
/// (float32, so that an encoder and a decoder that store it agree bit for bit). A packed image puts unrelated
/// charts next to each other, one sample apart: an image coder spends its bits on those steps. Coding the
/// positions minus their chart's map leaves only what the quadric does not hold, small on both sides of a
/// gutter. A chart of fewer than twelve samples, or one whose fit is singular, gets its mean as a constant
/// map. `charts` is the number of charts (every defined sample's chart id is below it).
[[nodiscard]] std::vector<float> chart_planes(const MultiChartImage& image, std::uint32_t charts);

/// Adds (`sign` +1) or subtracts (−1) every defined sample's chart map to or from `positions`
/// (width·height·3 floats, in double precision, rounded to float once). Throws InvalidInput for sizes that
/// disagree, a chart id beyond the planes, or a sum that leaves float32.
void apply_chart_planes(std::vector<float>& positions, const MultiChartImage& image, const std::vector<float>& planes,
                        int sign);

/// What a reader does with positions decoded from a lossy code of the positions minus their chart maps
/// (`planes`, chart_planes): undefined samples back to NaN, the maps added back, every zipper cluster fused
/// (fuse_zipper) and the fusing diffused into the charts (diffuse_zipper_fusing). The encoder runs the same
/// to measure what readers will get. Throws InvalidInput as those do.
void restore_decoded_multichart(MultiChartImage& image, const std::vector<float>& planes);

/// Error diffusion: every defined sample that is alone in its cluster and lies within `band` − 1 steps
/// (4-neighbours inside its chart, over such samples) of a fused sample receives the displacement of the
/// nearest one, weighted (1 − d/band)² by the step count d: the ramp Gu et al. diffuse along a geometry
/// image's rows and columns, in a breadth-first walk linear in the samples. Clustered samples keep their
/// fused values, so clusters stay identical. `band` 0 chooses max(2, round(s / 8)),
/// s the side of a chart of mean size: the square root of defined samples per chart.
void diffuse_zipper_fusing(MultiChartImage& image, const std::vector<Vec3>& displacement, std::uint32_t band = 0);

}  // namespace gimforge
