#pragma once
/// \file batch_item.h
/// Converting one mesh of a batch for one output: load (repaired; what the method needs of its input,
/// jobs/method.h), run the one conversion pipeline (jobs/pipeline.h) and commit the item's shard (the image,
/// or the representation group of a relief map, and Conversion::numbers plus input_faces as its metrics).
#include <chrono>
#include <cstddef>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>

#include "io/batch_types.h"
#include "jobs/batch_job.h"
#include "jobs/load_mesh.h"
#include "jobs/pipeline.h"
#include "kernels/core/embree_device.h"
#include "mpi/scheduler.h"

namespace gimforge::jobs {

/// Throws InvalidInput "PATH: no faces left after repair (the file's N faces were all degenerate or
/// duplicates)" when the repairs of load_mesh removed every face: no method can convert that, and saying so
/// beats a kernel's "0 connected components".
void check_faces_left(const LoadedMesh& m);

/// How a worker reports that the work directory's file system is full (ENOSPC, EDQUOT, or the file-size
/// limit: EFBIG): not the item's fault, and every item after it would fail the same way, so the coordinator
/// stops the batch instead of spending the item's attempts; what is done stays in the journal for --resume.
inline constexpr std::string_view kNoSpaceReason = "no space for results: ";

/// Whether an error message's cause is one of those: ": No space left on device" as the error texts end with
/// it; a path that merely contains the words does not count.
[[nodiscard]] bool says_no_space(std::string_view message);

/// Appended to the reason of a failure that cannot go away on a retry (the file does not parse, the mesh
/// is refused by the method): such items are not tried again, in this run or a resumed one.
inline constexpr std::string_view kNotRetried = " (not retried: the same input fails the same way)";

/// The work function of every rank of a batch (mpi/scheduler.h): one task of batch_run's coordinator (a
/// whole item, or a huge item's plan, piece or finish, jobs/brick_tasks.h) from its JSON payload; a
/// conversion commits its shard under `work_root` and is cancelled after `item_timeout` seconds (0: never).
/// Failures are rethrown tagged for the coordinator: kNotRetried, kNoSpaceReason, kStaleBricksReason.
[[nodiscard]] mpi::WorkFunction batch_worker(const EmbreeDevice& device, const std::filesystem::path& work_root,
                                             double item_timeout);

/// Converts `key.source` for `output` and writes its shard to `shard` (atomically, io/batch_shard.h).
/// Returns the item's metrics. `deadline`: the conversion is cancelled when it passes (Cancelled "timed
/// out after S s"); use time_point::max() for none. Throws the loader's and the kernels' errors, each
/// naming the file. `proxy_maker`: how the proxy of a huge input is made (ConversionRequest::proxy_maker).
std::map<std::string, double> convert_item(const EmbreeDevice& device, const io::ItemKey& key, const OutputSpec& output,
                                           const FidelityOptions& fidelity,
                                           std::chrono::steady_clock::time_point deadline,
                                           const std::filesystem::path& shard, const ProxyMaker& proxy_maker = {});

}  // namespace gimforge::jobs
