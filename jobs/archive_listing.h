#pragma once
/// \file archive_listing.h
/// What an archive holds, for `gimforge ls`: every representation (/gim, /spherical, /relief, /mcgim) and every
/// batch output (/batch/<output>), with its method, sizes, fidelity and provenance. Only attributes and
/// dataset shapes are read (never image data, except the batch PSNR column), so listing a large archive is
/// instant; an item that cannot be read is listed with the reason instead of stopping the listing.
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/archive.h"

namespace gimforge::jobs {

/// One entry of the listing.
struct ListedItem {
  std::string group{};            ///< "gim", "spherical", "relief" or "batch"
  std::string name{};             ///< the representation's or batch output's name
  std::string method{};           ///< "gim", "sphere", "relief" (the `method` attribute)
  std::string shape{};            ///< main dataset's shape, e.g. "257x257x3", or "N items" for a batch;
                                  ///< " adaptive" appended for adaptive geometry images (sample_uv stored)
  std::optional<double> psnr{};   ///< dB; for a batch output the mean over its converted items
  bool coded{false};              ///< quantized or coded by compress: `psnr` is its conversion's, before coding
  std::string source{};           ///< input mesh path (representations)
  std::int64_t count{-1};       ///< batch: converted items (-1 for representations)
  std::int64_t failed{-1};      ///< batch: failed items
  std::string gimforge_version{}; ///< provenance, when recorded on the item
  std::string command_line{};     ///< provenance, when recorded on the item
  std::string problem{};          ///< non-empty when the item could not be read: why
};

/// The archive's root facts and its items, representations first (by group, then name), then batch outputs.
struct ArchiveListing {
  io::ArchiveInfo info{};
  std::vector<ListedItem> items{};
};

/// Lists `archive`. Throws only for errors of the archive as a whole (unreadable root); per-item errors
/// land in ListedItem::problem.
[[nodiscard]] ArchiveListing list_archive(const io::Archive& archive);

/// A table for the terminal: one line per item (names escaped with io::printable) and a header.
[[nodiscard]] std::string listing_text(const ArchiveListing& listing);

/// {"archive": {...root attributes...}, "items": [{...}, ...]}.
[[nodiscard]] nlohmann::json listing_json(const ArchiveListing& listing);

}  // namespace gimforge::jobs
