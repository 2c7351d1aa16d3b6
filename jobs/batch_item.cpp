#include "jobs/batch_item.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>

#include <fmt/format.h>

#include "io/batch_shard.h"
#include "io/input_file.h"
#include "jobs/compress.h"
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
    const double seconds = std::chrono::duration<double>(deadline - start).count();
    throw Cancelled(fmt::format("timed out after {:g} s", std::max(0.0, std::round(seconds * 1000.0) / 1000.0)));
  };
}

/// `batch --codec C --rate B`: the item becomes a compressed representation group (jobs/compress.h) instead
/// of a stacked image. The writer runs inside write_shard, before the shard's metrics are written, and adds
/// the compression's figures to them (`item` must outlive write_shard).
void compressed(const EmbreeDevice& device, const Conversion& conversion, const MethodOptions& method,
                const FidelityOptions& fidelity, const std::string& name, BatchItem& item) {
  CompressOptions options;
  options.codec = parse_codec(method.codec);
  options.bytes = method.rate;
  options.bytes_option = "--rate";
  options.measure = fidelity.enabled;
  options.metric_samples = std::max<std::size_t>(1000, fidelity.samples);  // as the item's own PSNR
  const io::RepresentationRecord record{conversion.source, conversion.numbers};
  std::map<std::string, double> metrics = std::move(item.arrays.metrics);
  item.arrays = io::ItemArrays{};
  item.arrays.metrics = std::move(metrics);
  item.representation = [&device, &conversion, options, record, &item, name](h5::Group& group) {
    const std::string path = fmt::format("item '{}'", name);
    CompressedItem c;
    if (conversion.method == Method::Gim)
      c = compress_gim_image(device, conversion.gim.value().image, record, conversion.origin, group, options, path,
                             conversion.gim.value().stats.roi.inside);
    else if (conversion.method == Method::Mcgim)
      c = compress_multichart_image(device, conversion.mcgim.value().image, conversion.mcgim.value().stats.chart_efficiency,
                                    record, conversion.origin, group, options, path);
    else
      c = compress_spherical_image(device, conversion.sphere.value().image, record, conversion.origin, group, options, path);
    item.arrays.metrics["compressed_bytes"] = static_cast<double>(c.bytes_after);
    item.arrays.metrics["compressed_image_psnr"] = c.image_psnr;
    item.arrays.metrics["compressed_psnr"] = c.surface_psnr;
  };
}

}  // namespace

bool says_no_space(std::string_view message) {
  for (const int code : {ENOSPC, EDQUOT, EFBIG})
    if (message.find(fmt::format(": {}", std::strerror(code))) != std::string_view::npos) return true;
  return false;
}

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
  io::ItemKey stamped = key;
  stamped.source_stamp = io::file_stamp(key.source);  // before reading: a file rewritten meanwhile is redone
  LoadedMesh m = load_mesh(key.source, load_policy(output.method, /*warn=*/false));
  check_faces_left(m);
  ConversionRequest request;
  request.source = key.source;
  request.method = output.method;
  request.method.normal_size = 0;  // the consolidated archive stacks positions only
  request.fidelity = fidelity;
  request.progress = deadline_callback(deadline, start);
  request.proxy_maker = proxy_maker;
  request.roi = resolve_roi(request.method, m);
  const Conversion conversion = convert_mesh(device, std::move(m.mesh), request);  // not needed after: no copy
  BatchItem item = batch_item(conversion);
  if (!output.method.codec.empty()) compressed(device, conversion, output.method, fidelity, key.name, item);
  io::write_shard(shard, stamped, item.arrays, item.representation);
  return item.arrays.metrics;
}

}  // namespace gimforge::jobs
