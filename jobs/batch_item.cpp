#include "jobs/batch_item.h"

#include <fmt/format.h>

#include "io/batch_shard.h"
#include "jobs/load_mesh.h"
#include "jobs/roi.h"
#include "jobs/pipeline.h"
#include "kernels/core/errors.h"

namespace gimforge::jobs {
namespace {

using Clock = std::chrono::steady_clock;

/// A progress callback that cancels the conversion once the deadline has passed.
ProgressCallback deadline_callback(Clock::time_point deadline, Clock::time_point start) {
  if (deadline == Clock::time_point::max()) return {};
  return [deadline, start](std::string_view, double) {
    if (Clock::now() <= deadline) return true;
    throw Cancelled(fmt::format("timed out after {:.0f} s", std::chrono::duration<double>(deadline - start).count()));
  };
}

}  // namespace

void check_faces_left(const LoadedMesh& m) {
  if (m.mesh.num_faces() == 0)
    throw InvalidInput(fmt::format("{}: no faces left after repair (the file's {} face(s) were all degenerate or "
                                   "duplicates)",
                                   m.path.string(), m.file_faces));
}

std::map<std::string, double> convert_item(const EmbreeDevice& device, const io::ItemKey& key, const OutputSpec& output,
                                           const FidelityOptions& fidelity, Clock::time_point deadline,
                                           const std::filesystem::path& shard, const ProxyMaker& proxy_maker) {
  const auto start = Clock::now();
  const LoadedMesh m = load_mesh(key.source, load_policy(output.method.method, /*warn=*/false));
  check_faces_left(m);
  ConversionRequest request;
  request.source = key.source;
  request.method = output.method;
  request.method.normal_size = 0;  // the consolidated archive stacks positions only
  request.fidelity = fidelity;
  request.progress = deadline_callback(deadline, start);
  request.proxy_maker = proxy_maker;
  request.roi = resolve_roi(request.method, m);
  const Conversion conversion = convert_mesh(device, m.mesh, request);
  const BatchItem item = batch_item(conversion);
  io::write_shard(shard, key, item.arrays, item.representation);
  return item.arrays.metrics;
}

}  // namespace gimforge::jobs
