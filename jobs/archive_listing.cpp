#include "jobs/archive_listing.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "io/batch_archive.h"
#include "io/coded_image.h"
#include "io/hdf5.h"
#include "io/hdf5_storage.h"
#include "io/printable.h"
#include "kernels/core/errors.h"

namespace gimforge::jobs {
namespace {

constexpr std::array<std::string_view, 4> kRepresentationGroups{"gim", "spherical", "relief", "mcgim"};

std::string shape_text(const h5::Dims& dims) {
  std::string out;
  for (std::size_t i = 0; i < dims.size(); ++i) {
    if (i > 0) out += 'x';
    out += std::to_string(dims[i]);
  }
  return out.empty() ? "scalar" : out;
}

std::string string_attribute(const h5::Object& object, std::string_view name) {
  return object.has_attribute(name) ? object.attribute<std::string>(name) : std::string{};
}

std::optional<double> double_attribute(const h5::Object& object, std::string_view name) {
  if (!object.has_attribute(name)) return std::nullopt;
  const double value = object.attribute<double>(name);
  return std::isfinite(value) ? std::optional<double>(value) : std::nullopt;
}

void read_provenance(const h5::Group& group, ListedItem& item) {
  item.gimforge_version = string_attribute(group, "gimforge_version");
  item.command_line = string_attribute(group, "command_line");
}

/// The dataset whose shape describes a representation: the image, or the relief distances (L, T, T).
std::string_view main_dataset(std::string_view group) { return group == "relief" ? "distances" : "geometry"; }

ListedItem list_representation(const h5::Group& parent, std::string_view group_name, const std::string& name) {
  ListedItem item{.group = std::string(group_name), .name = name};
  try {
    const h5::Group group = parent.open_group(name);
    item.method = string_attribute(group, "method");
    item.source = string_attribute(group, "source");
    item.psnr = double_attribute(group, "psnr");
    read_provenance(group, item);
    const std::string_view data = main_dataset(group_name);
    if (group.exists(data)) {
      const h5::Dataset ds = group.open_dataset(data);
      const h5::Dims shape = ds.shape();
      item.shape = shape_text(shape);
      if (h5::Dataset::product(shape) > 0) {  // decodes: its first and last values (readers decode all of it)
        h5::Dims last = shape;
        for (std::uint64_t& d : last) --d;
        (void)ds.read_slab<double>(h5::Dims(shape.size(), 0), h5::Dims(shape.size(), 1));
        (void)ds.read_slab<double>(last, h5::Dims(shape.size(), 1));
      }
      if (ds.has_attribute("bits")) item.shape += fmt::format(" {}-bit", ds.attribute<std::int64_t>("bits"));
      item.coded = group_name != "relief" && ds.has_attribute("bits");
    } else if (group.exists("geometry_code")) {  // compressed (docs/archive.md, "Compressed items")
      const h5::Dataset code = group.open_dataset("geometry_code");
      const h5::Dims dims = code.shape();
      // Both counts: compress's (everything the item stores, which --bytes bounds) and the payload's.
      item.shape = fmt::format("{} {} B stored (payload {} B)", string_attribute(code, "codec"), io::stored_bytes(group),
                               dims.empty() ? 0 : dims[0]);
      item.coded = true;
    } else {  // what every reader of the item refuses first
      throw FormatError(fmt::format("{}: {}: no dataset '{}'", group.file_name(), group.path(), data));
    }
    // Every dataset of the item stored whole (an index lookup per chunk, nothing read): a chunk never written
    // reads as fill values, and every reader refuses it.
    h5::require_stored(group);
    // A decoded item (decompress) keeps compress's figures: its surface is the decoded one.
    item.coded = item.coded || group.has_attribute("compressed_psnr");
    if (group.exists("sample_uv")) item.shape += " adaptive";  // docs/adaptive.md
    if (group.exists("roi_mask")) item.shape += " roi";  // gim and flat-octa spherical images
    if (group_name == "relief" && group.has_attribute("n"))
      item.shape = fmt::format("grid {}, {} layers", group.attribute<std::int64_t>("n"),
                               item.shape.empty() ? "no" : item.shape);
  } catch (const Error& e) {
    item.problem = e.what();
  }
  return item;
}

ListedItem list_batch_output(const io::Archive& archive, const h5::Group& batch, const std::string& name) {
  ListedItem item{.group = "batch", .name = name};
  try {
    // Checked as the readers check it (count, the shape of 'data', the item groups, the columns): an output
    // they refuse is listed as unreadable, never with an absurd count.
    const io::BatchOutputSummary summary = io::read_batch_output(archive, name);
    const h5::Group group = batch.open_group(name);
    item.method = string_attribute(group, "method");
    item.count = static_cast<std::int64_t>(summary.count);
    item.failed = static_cast<std::int64_t>(summary.failed_names.size());
    read_provenance(group, item);
    // As for a representation, the output's own datasets; each of its item groups is checked when it is read.
    h5::require_stored(group, "items");
    if (group.exists("data")) {
      const h5::Dims dims = group.open_dataset("data").shape();
      item.shape = shape_text(dims);
    } else if (group.exists("items")) {
      item.shape = fmt::format("{} item groups", group.open_group("items").children().size());
    }
    if (group.exists("sample_uv")) item.shape += " adaptive";
    if (group.exists("metrics/roi_samples_before")) item.shape += " roi";
    item.coded = group.has_attribute("codec");  // batch --codec: the items' psnr is their conversions'
    if (group.exists("metrics/psnr")) {
      const h5::Dataset psnr = group.open_dataset("metrics/psnr");
      const h5::Dims dims = psnr.shape();
      // One float64 per item: bounded by the item count the file declares, never by an absurd extent.
      if (dims.size() == 1 && dims[0] <= (std::uint64_t{1} << 28)) {
        double sum = 0;
        std::size_t n = 0;
        for (double v : psnr.read<double>())
          if (std::isfinite(v)) sum += v, ++n;
        if (n > 0) item.psnr = sum / static_cast<double>(n);
      }
    }
  } catch (const Error& e) {
    item.problem = e.what();
  }
  return item;
}

}  // namespace

ArchiveListing list_archive(const io::Archive& archive) {
  ArchiveListing listing{.info = archive.info()};
  const h5::File& root = archive.root();
  for (std::string_view group_name : kRepresentationGroups) {
    if (!root.exists(group_name)) continue;
    const h5::Group group = root.open_group(group_name);
    for (const std::string& name : group.children()) listing.items.push_back(list_representation(group, group_name, name));
  }
  if (root.exists("batch")) {
    const h5::Group batch = root.open_group("batch");
    for (const std::string& name : batch.children()) listing.items.push_back(list_batch_output(archive, batch, name));
  }
  return listing;
}

std::string listing_text(const ArchiveListing& listing) {
  const io::ArchiveInfo& info = listing.info;
  std::string out = fmt::format("archive format {}, written by gimforge {}, created {}\n", info.format_version,
                                io::printable(info.gimforge_version), io::printable(info.created));
  if (listing.items.empty()) return out + "no items\n";
  std::size_t size_width = 24;  // wider when a shape is (a coded item's two byte counts)
  for (const ListedItem& item : listing.items) size_width = std::max(size_width, io::printable(item.shape).size());
  out += fmt::format("{:<28} {:<7} {:<{}} {:>9}  {}\n", "item", "method", "size", size_width, "PSNR dB", "source");
  for (const ListedItem& item : listing.items) {
    const std::string label = io::printable(item.group + "/" + item.name);
    if (!item.problem.empty()) {
      out += fmt::format("{:<28} unreadable: {}\n", label, io::printable(item.problem));
      continue;
    }
    const std::string psnr = item.psnr ? fmt::format("{:.2f}{}", *item.psnr, item.coded ? "*" : "") : "-";
    std::string source = io::printable(item.source);
    if (item.count >= 0) source = fmt::format("{} converted, {} failed", item.count, std::max<std::int64_t>(item.failed, 0));
    out += fmt::format("{:<28} {:<7} {:<{}} {:>9}  {}\n", label, io::printable(item.method), io::printable(item.shape),
                       size_width, psnr, source);
  }
  if (std::any_of(listing.items.begin(), listing.items.end(), [](const ListedItem& i) { return i.coded && i.psnr; }))
    out += "* a quantized, coded or decoded item: the PSNR of its conversion, before coding (compress measured the "
           "coded surface against the stored one: compressed_psnr)\n";
  return out;
}

nlohmann::json listing_json(const ArchiveListing& listing) {
  const io::ArchiveInfo& info = listing.info;
  nlohmann::json items = nlohmann::json::array();
  for (const ListedItem& item : listing.items) {
    nlohmann::json j{{"group", item.group}, {"name", item.name}};
    if (!item.problem.empty()) {
      j["problem"] = item.problem;
    } else {
      j["method"] = item.method;
      j["shape"] = item.shape;
      j["psnr"] = item.psnr ? nlohmann::json(*item.psnr) : nlohmann::json(nullptr);
      j["coded"] = item.coded;
      if (item.count >= 0) {
        j["count"] = item.count;
        j["failed"] = std::max<std::int64_t>(item.failed, 0);
      } else {
        j["source"] = item.source;
      }
      if (!item.gimforge_version.empty()) j["gimforge_version"] = item.gimforge_version;
      if (!item.command_line.empty()) j["command_line"] = item.command_line;
    }
    items.push_back(std::move(j));
  }
  nlohmann::json out{{"archive",
                      {{"format_version", info.format_version},
                       {"gimforge_version", info.gimforge_version},
                       {"created", info.created},
                       {"creator", info.creator}}},
                     {"items", std::move(items)}};
  return out;
}

}  // namespace gimforge::jobs
