#pragma once
/// \file batch_item.h
/// Converting one mesh of a batch for one output: load (repair; refuse non-manifold or inconsistently
/// oriented meshes), run the method's kernel, reconstruct and measure the PSNR against the input, and return
/// the channel-first arrays and the figures that the shard and the consolidated archive store.
#include <chrono>
#include <cstddef>
#include <string>

#include "io/batch_types.h"
#include "jobs/batch_job.h"
#include "kernels/core/embree_device.h"

namespace gimforge::jobs {

/// Converts `source` for `output`. Figures in ItemArrays::metrics: psnr, hausdorff_rms, hausdorff_max,
/// bbox_diagonal, input_faces, stretch_efficiency (gim: the parametrization's; sphere: S → M),
/// seconds_convert, seconds_metric, and per method: gim cut_paths, augmentations; sphere
/// domain_efficiency, efficiency_domain_to_mesh, holes_filled, masked_samples.
/// `deadline`: the conversion is cancelled when it passes (Cancelled "timed out after S s"); use
/// time_point::max() for none. Throws the loader's and the kernels' errors, each naming the file.
[[nodiscard]] io::ItemArrays convert_item(const EmbreeDevice& device, const std::string& source, const OutputSpec& output,
                                          std::size_t metric_samples,
                                          std::chrono::steady_clock::time_point deadline);

}  // namespace gimforge::jobs
