#include "jobs/batch_item.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "io/batch_shard.h"
#include "io/input_file.h"
#include "jobs/brick_tasks.h"
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
      c = compress_spherical_image(device, conversion.sphere.value().image, record, conversion.origin, group, options, path,
                                   conversion.sphere.value().stats.roi.inside);
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
  io::write_shard(shard, stamped, item.arrays, item.representation, io::ParentDirectory::kMustExist);
  return item.arrays.metrics;
}

mpi::WorkFunction batch_worker(const EmbreeDevice& device, const std::filesystem::path& work_root, double item_timeout) {
  namespace fs = std::filesystem;
  using nlohmann::json;
  return [&device, work_root, item_timeout](const mpi::WorkItem& item) -> std::string {
    const json p = json::parse(item.payload);
    const OutputSpec output = output_from_json(p.at("output"));
    const io::ItemKey key{output.name, p.at("name").get<std::string>(), p.at("source").get<std::string>(),
                          p.at("label").get<std::string>(), p.at("index").get<std::uint64_t>()};
    const auto deadline = item_timeout > 0.0
                              ? Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                                   std::chrono::duration<double>(item_timeout))
                              : Clock::time_point::max();
    const FidelityOptions fidelity{p.value("metric", true), p.at("metric_samples").get<std::size_t>()};
    const std::string task = p.value("task", "whole");
    const fs::path bricks = task == "whole" ? fs::path() : work_root / p.at("bricks").get<std::string>();
    std::map<std::string, double> metrics;
    try {
      const auto task_start = Clock::now();
      const auto seconds = [&] { return std::chrono::duration<double>(Clock::now() - task_start).count(); };
      if (task == "plan") {
        const BrickPlanSummary plan = plan_brick_tasks(key.source, output.method, bricks);
        spdlog::debug("{} ({}): planned {} bricks in {:.1f} s", key.source, output.name, plan.brick_faces.size(), seconds());
        return json{{"brick_faces", plan.brick_faces}}.dump();
      }
      if (task == "piece") {
        const auto brick = p.at("brick").get<std::size_t>();
        decimate_brick_task(key.source, bricks, brick);
        spdlog::debug("{} ({}): brick {} decimated in {:.1f} s", key.source, output.name, brick, seconds());
        return "ok";
      }
      metrics = convert_item(device, key, output, fidelity, deadline, work_root / p.at("shard").get<std::string>(),
                             task == "finish" ? proxy_from_pieces(key.source, bricks) : ProxyMaker{});
    } catch (const Cancelled&) {
      throw;  // a timeout may pass on a less loaded node
    } catch (const StaleBricks& e) {  // the coordinator plans the item again
      throw IoError(std::string(kStaleBricksReason) + e.what());
    } catch (const FormatError& e) {  // the file does not parse: it never will
      throw FormatError(std::string(e.what()) + std::string(kNotRetried));
    } catch (const InvalidInput& e) {  // refused by the method (topology, options): deterministic
      throw InvalidInput(std::string(e.what()) + std::string(kNotRetried));
    } catch (const NumericalError& e) {  // one thread per rank: the same numbers every time
      throw NumericalError(std::string(e.what()) + std::string(kNotRetried));
    } catch (const Error& e) {  // I/O, and HDF5's own write failures (LibraryError: a chunk written in H5Dwrite)
      if (says_no_space(e.what())) throw IoError(std::string(kNoSpaceReason) + e.what());
      throw;
    } catch (const std::bad_alloc&) {
      throw IoError(fmt::format("{}: out of memory while converting it ({})", key.source, output.name));
    }
    if (const auto psnr = metrics.find("psnr"); psnr != metrics.end())
      spdlog::debug("{} ({}): committed, PSNR {:.2f} dB", key.source, output.name, psnr->second);
    else
      spdlog::debug("{} ({}): committed", key.source, output.name);
    return "ok";
  };
}

}  // namespace gimforge::jobs
