/// \file archive.cpp
/// The gimforge archive root (see archive.h and docs/archive.md).
#include "io/archive.h"

#include <fmt/format.h>

#include <algorithm>
#include <ctime>
#include <nlohmann/json.hpp>

#include "gimforge_version.h"
#include "kernels/core/errors.h"

namespace gimforge::io {
namespace {

/// Validates `text` as JSON and returns its compact form ("{}" for empty text).
std::string normalized_json(const std::string& text) {
  if (text.empty()) return "{}";
  try {
    return nlohmann::json::parse(text).dump();
  } catch (const nlohmann::json::parse_error& e) {
    throw InvalidInput(fmt::format("archive creation parameters are not valid JSON: {}", e.what()));
  }
}

/// Throws FormatError "PATH: not a gimforge archive (REASON)".
[[noreturn]] void throw_not_archive(const std::filesystem::path& path, std::string_view reason) {
  throw FormatError(fmt::format("{}: not a gimforge archive ({})", path.string(), reason));
}

/// Checks the identifying root attributes of an opened file.
void check_identity(const std::filesystem::path& path, const h5::File& file) {
  for (const char* key : {"format", "format_version"})
    if (!file.has_attribute(key)) throw_not_archive(path, fmt::format("no '{}' attribute", key));
  const auto format = file.attribute<std::string>("format");
  if (format != kArchiveFormat) throw_not_archive(path, fmt::format("format is '{}'", format));
  const auto version = file.attribute<std::int64_t>("format_version");
  if (version < 1) throw FormatError(fmt::format("{}: invalid archive format_version {}", path.string(), version));
  if (version > kArchiveFormatVersion)
    throw IoError(fmt::format("{}: archive format_version {} is newer than this gimforge ({})", path.string(), version,
                              kArchiveFormatVersion));
}

/// Image storage: chunked (default up to 256 x 256 pixels x all channels), shuffled, deflated.
h5::DatasetOptions image_storage(const h5::Dims& shape, const ImageOptions& options) {
  constexpr std::uint64_t kTile = 256;
  h5::DatasetOptions storage{options.chunk, options.deflate, options.shuffle, false};
  const bool has_zero = std::find(shape.begin(), shape.end(), 0u) != shape.end();
  if (storage.chunk.empty() && !has_zero) {  // an empty image is stored contiguous (see h5::DatasetOptions)
    storage.chunk = shape;
    storage.chunk[0] = std::min(shape[0], kTile);
    storage.chunk[1] = std::min(shape[1], kTile);
  }
  return storage;
}

template <class T>
h5::Dataset write_image_impl(h5::Group& parent, std::string_view name, const h5::Dims& shape, std::span<const T> pixels,
                             const ImageOptions& options, const h5::DataTransfer& xfer) {
  if (shape.size() != 2 && shape.size() != 3)
    throw InvalidInput(fmt::format("{}:{}: image '{}' needs shape (H, W) or (H, W, C), got rank {}", parent.file_name(),
                                   parent.path(), name, shape.size()));
  return parent.write_dataset(name, shape, pixels, image_storage(shape, options), xfer);
}

}  // namespace

Archive Archive::create(const std::filesystem::path& path, const CreationInfo& info, h5::CreateMode mode,
                        const h5::FileAccess& access) {
  const std::string parameters = normalized_json(info.parameters_json);
  h5::File file = h5::File::create(path, mode, access);
  file.set_attribute("format", kArchiveFormat);
  file.set_attribute("format_version", kArchiveFormatVersion);
  file.set_attribute("gimforge_version", kVersion);
  file.set_attribute("created", info.created.empty() ? utc_timestamp() : info.created);
  file.set_attribute("creator", info.creator);
  file.set_attribute("creation_parameters", parameters);
  return Archive(path, std::move(file));
}

Archive Archive::open(const std::filesystem::path& path, h5::OpenMode mode, const h5::FileAccess& access) {
  h5::File file = h5::File::open(path, mode, access);
  check_identity(path, file);
  return Archive(path, std::move(file));
}

Archive Archive::open_unchecked(const std::filesystem::path& path) {
  return Archive(path, h5::File::open(path, h5::OpenMode::kReadOnly));
}

ArchiveInfo Archive::info() const {
  ArchiveInfo out;
  out.format = file_.attribute<std::string>("format");
  out.format_version = file_.attribute<std::int64_t>("format_version");
  out.gimforge_version = file_.attribute<std::string>("gimforge_version");
  out.created = file_.attribute<std::string>("created");
  out.creator = file_.attribute<std::string>("creator");
  out.creation_parameters = file_.attribute<std::string>("creation_parameters");
  return out;
}

void Archive::close() {
  file_.flush();
  file_.close();
}

std::string utc_timestamp() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char buf[32] = {};
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return buf;
}

h5::Dataset write_image(h5::Group& parent, std::string_view name, const h5::Dims& shape, std::span<const float> pixels,
                        const ImageOptions& options, const h5::DataTransfer& xfer) {
  return write_image_impl(parent, name, shape, pixels, options, xfer);
}

h5::Dataset write_image(h5::Group& parent, std::string_view name, const h5::Dims& shape,
                        std::span<const std::uint16_t> pixels, const ImageOptions& options,
                        const h5::DataTransfer& xfer) {
  return write_image_impl(parent, name, shape, pixels, options, xfer);
}

h5::Dataset write_image(h5::Group& parent, std::string_view name, const h5::Dims& shape,
                        std::span<const std::uint8_t> pixels, const ImageOptions& options,
                        const h5::DataTransfer& xfer) {
  return write_image_impl(parent, name, shape, pixels, options, xfer);
}

h5::Dataset write_quantized_image(h5::Group& parent, std::string_view name, const h5::Dims& shape,
                                  std::span<const std::uint16_t> pixels, double scale, double offset,
                                  const ImageOptions& options, const h5::DataTransfer& xfer) {
  h5::Dataset ds = write_image_impl(parent, name, shape, pixels, options, xfer);
  ds.set_attribute("scale", scale);
  ds.set_attribute("offset", offset);
  return ds;
}

}  // namespace gimforge::io
