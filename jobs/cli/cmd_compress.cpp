// `gimforge compress`: image representations of an archive quantized or coded into a new archive (issue #19).
#include <cmath>
#include <filesystem>
#include <memory>
#include <set>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "io/atomic_file.h"
#include "io/coded_image.h"
#include "io/hdf5.h"
#include "io/representation.h"
#include "io/printable.h"
#include "jobs/cli/commands.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/compress.h"
#include "jobs/gim_store.h"
#include "jobs/pipeline.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"

namespace gimforge::cli {
namespace {

std::string kib(std::uint64_t bytes) {
  return bytes >= 10'000'000 ? fmt::format("{:.1f} MB", static_cast<double>(bytes) / 1e6)
                             : fmt::format("{} bytes", bytes);
}

nlohmann::json number_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

}  // namespace

int run_compress(const CompressCmdOptions& options) {
  jobs::CompressOptions co;
  co.codec = jobs::parse_codec(options.codec);
  co.bytes = options.bytes;
  co.psnr = options.psnr;
  co.lossless = options.lossless;
  co.measure = !options.no_metric;
  co.metric_samples = options.metric_samples;
  jobs::check_compress_options(co);
  // Before any work: the output can be created, is not the input, and no other writer has it.
  io::check_can_create(jobs::output_target(options.output));
  jobs::refuse_output_over_inputs(options.output, {options.archive});
  const std::unique_ptr<io::WriterLock> lock = jobs::lock_archive(options.output, options.wait);
  const io::Archive in = io::Archive::open(options.archive);
  std::vector<jobs::ImageRef> refs;
  if (options.name.empty()) {
    for (const jobs::Method kind : {jobs::Method::Gim, jobs::Method::Sphere, jobs::Method::Mcgim})
      for (const std::string& name : jobs::image_names(in, kind)) refs.push_back({kind, name});
    // Said, not silently dropped: the output holds the coded images only.
    if (const std::size_t reliefs = jobs::image_names(in, jobs::Method::Relief).size(); reliefs > 0)
      spdlog::warn("{}: {} relief map{} not copied: compress codes images of positions only (relief maps are "
                   "quantized already: 2 B per distance)", io::printable(options.archive), reliefs, reliefs == 1 ? " is" : "s are");
    if (refs.empty())
      throw InvalidInput(fmt::format("{}: holds no geometry images, spherical or multi-chart geometry images to compress{}",
                                     io::printable(options.archive),
                                     in.root().exists("batch")
                                         ? " (a batch's stacked items are compressed as the batch writes them: batch "
                                           "--codec)"
                                         : ""));
  } else {
    refs.push_back(jobs::choose_image(in, options.name));
  }
  for (const jobs::ImageRef& ref : refs) jobs::refuse_taken_name(options.output, ref.kind, ref.name, /*renamable=*/false);

  const EmbreeDevice device;
  std::vector<jobs::CompressedItem> items;
  const nlohmann::json parameters = {{"command", "compress"}, {"codec", options.codec}, {"bytes", options.bytes},
                                     {"psnr", options.psnr},   {"lossless", options.lossless}};
  jobs::add_to_archive(options.output, jobs::command_line(), parameters.dump(), [&](io::Archive& out) {
    for (const jobs::ImageRef& ref : refs) {
      // Progress over several items (one item's refusal is then its one line).
      if (!options.json && refs.size() > 1)
        spdlog::info("compressing {}:/{} ...", io::printable(options.archive), io::printable(ref.path()));
      try {
        items.push_back(jobs::compress_item(device, in, ref, out, co));
      } catch (const Cancelled&) {
        throw;
      } catch (const Error& e) {  // one line that names the item, whatever stage refused it
        const std::string item = ref.path(), what = e.what();
        // Named by its path alone (the coder's wording): the archive goes in front, as on the success line.
        if (what.starts_with(item + ": "))
          throw InvalidInput(fmt::format("{}:/{}", io::printable(options.archive), what));
        // Already named: by its path in the archive, or by the archive and the item (the readers' wording).
        if (what.find(item) != std::string::npos ||
            (what.starts_with(options.archive + ":") && what.find("'" + ref.name + "'") != std::string::npos))
          throw;
        throw InvalidInput(fmt::format("{}:/{}: {}", io::printable(options.archive), io::printable(item), what));
      }
    }
  });

  if (options.json) {
    nlohmann::json list = nlohmann::json::array();
    for (const jobs::CompressedItem& item : items) {
      nlohmann::json trials = nlohmann::json::array();
      for (const jobs::CodecTrial& t : item.trials)
        trials.push_back({{"codec", t.codec}, {"payload_bytes", t.payload_bytes}, {"image_psnr", number_or_null(t.image_psnr)},
                          {"surface_psnr", number_or_null(t.surface_psnr)}, {"normal_psnr", number_or_null(t.normal_psnr)}});
      list.push_back({{"item", item.path}, {"codec", item.codec}, {"bytes_before", item.bytes_before},
                      {"geometry_bytes_before", item.geometry_bytes_before},
                      {"bytes", item.bytes_after}, {"image_psnr", number_or_null(item.image_psnr)},
                      {"surface_psnr", number_or_null(item.surface_psnr)}, {"seam_gap", item.seam_gap},
                      {"roi_image_psnr", number_or_null(item.roi_image_psnr)}, {"seconds", item.seconds},
                      {"trials", trials}});
    }
    fmt::print("{}\n", nlohmann::json({{"archive", options.output}, {"items", list}}).dump(2, ' ', false, nlohmann::json::error_handler_t::replace));
    return kExitOk;
  }
  for (const jobs::CompressedItem& item : items) {
    std::string tried;
    for (const jobs::CodecTrial& t : item.trials)
      if (t.codec != item.codec || item.trials.size() > 1)
        tried += std::isfinite(t.surface_psnr)
                     ? fmt::format("{}{} {:.1f} dB", tried.empty() ? " (tried: " : ", ", t.codec, t.surface_psnr)
                     : fmt::format("{}{} {:.1f} dB along the normals", tried.empty() ? " (tried: " : ", ", t.codec,
                                   t.normal_psnr);
    if (!tried.empty()) tried += ")";
    fmt::print("{}:/{}: {}, {}{} -> {}, PSNR {} (samples {:.1f} dB){}{}, {:.1f} s\n", io::printable(options.output),
               io::printable(item.path),
               options.lossless ? item.codec + " lossless (of the 16-bit quantized planes, not the float32 image)"
                                : item.codec,
               kib(item.bytes_before), item.dropped_bytes > 0 ? fmt::format(" (positions {}; normal map and colours, {}, dropped)",
                                                    kib(item.geometry_bytes_before), kib(item.dropped_bytes))
                                      : std::string(),
               kib(item.bytes_after),
               std::isfinite(item.surface_psnr) ? fmt::format("{:.1f} dB against the stored surface", item.surface_psnr)
                                                : std::string("not measured"),
               item.image_psnr,
               item.path.starts_with("spherical/") ? fmt::format(", seam gap {:.3g}", item.seam_gap)
               : std::isfinite(item.roi_image_psnr) ? fmt::format(", ROI samples {:.1f} dB", item.roi_image_psnr)
                                                     : std::string(),
               tried, item.seconds);
  }
  return kExitOk;
}

int run_decompress(const DecompressCmdOptions& options) {
  io::check_can_create(jobs::output_target(options.output));
  jobs::refuse_output_over_inputs(options.output, {options.archive});
  const std::unique_ptr<io::WriterLock> lock = jobs::lock_archive(options.output, options.wait);
  const io::Archive in = io::Archive::open(options.archive);
  std::vector<jobs::ImageRef> refs;
  std::vector<jobs::BatchCodedItem> batch;  // the items of batch --codec outputs
  if (options.name.empty()) {
    for (const jobs::Method kind : {jobs::Method::Gim, jobs::Method::Sphere, jobs::Method::Mcgim})
      for (const std::string& name : jobs::image_names(in, kind)) refs.push_back({kind, name});
    batch = jobs::coded_batch_items(in);
    if (refs.empty() && batch.empty())
      throw InvalidInput(fmt::format("{}: holds no geometry images, spherical or multi-chart geometry images, or outputs of batch --codec",
                                     io::printable(options.archive)));
  } else {
    refs.push_back(jobs::choose_image(in, options.name));
  }
  // Every name is checked before any work: taken in the output, or twice among these.
  std::set<std::string> names;
  const auto claim = [&](jobs::Method kind, const std::string& name) {
    jobs::refuse_taken_name(options.output, kind, name, /*renamable=*/false);
    const std::string path = jobs::ImageRef{kind, name}.path();
    if (!names.insert(path).second)
      throw InvalidInput(fmt::format("{}: two items would be written as {}; decompress them one at a time with --name",
                                     io::printable(options.archive), io::printable(path)));
  };
  for (const jobs::ImageRef& ref : refs) claim(ref.kind, ref.name);
  for (const jobs::BatchCodedItem& item : batch) claim(item.kind, item.name);
  // Items neither coded nor quantized are copied as they are: said, not silently (an archive never compressed).
  std::size_t plain = 0;
  for (const jobs::ImageRef& ref : refs) {
    const h5::Group g = io::open_representation(in, jobs::representation(ref.kind), ref.name);
    plain += !io::has_coded_positions(g) && g.exists("geometry") &&
             g.open_dataset("geometry").dtype() == h5::DType::kFloat32;
  }
  const nlohmann::json parameters = {{"command", "decompress"}};
  std::vector<std::string> written;
  jobs::add_to_archive(options.output, jobs::command_line(), parameters.dump(), [&](io::Archive& out) {
    for (const jobs::ImageRef& ref : refs) {
      jobs::decompress_item(in, ref, out);
      written.push_back(ref.path());
    }
    for (const jobs::BatchCodedItem& item : batch) {
      jobs::decompress_batch_item(in, item, out);
      written.push_back(jobs::ImageRef{item.kind, item.name}.path());
    }
  });
  for (const std::string& path : written)
    fmt::print("{} -> {}:/{} (float32)\n", io::printable(options.archive), io::printable(options.output), io::printable(path));
  if (plain > 0)  // after the copy, which may still refuse a damaged image (then its one line alone)
    spdlog::warn("{}: {} of its {} images {} neither coded nor quantized (not written by compress): copied as stored",
                 io::printable(options.archive), plain, refs.size(), plain == 1 ? "is" : "are");
  return kExitOk;
}

}  // namespace gimforge::cli
