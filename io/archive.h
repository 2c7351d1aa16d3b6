#pragma once
/// \file archive.h
/// The versioned gimforge archive: an HDF5 file whose root group carries attributes that identify it
/// (`format` = "gimforge", `format_version`), record who made it and with which parameters, and under
/// which later representations add their groups (e.g. /gim/<name>/geometry). docs/archive.md describes
/// the layout and conventions.
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <utility>

#include "io/hdf5.h"

namespace gimforge::io {

/// Value of the root attribute `format` of every gimforge archive.
inline constexpr std::string_view kArchiveFormat = "gimforge";
/// The archive format version this build writes and the newest it reads.
inline constexpr std::int64_t kArchiveFormatVersion = 2;

/// What Archive::create records in the root attributes.
/// With MPI-IO every rank must pass identical values: give `created` explicitly (taken on rank 0 and
/// broadcast) rather than letting each rank read its own clock.
struct CreationInfo {
  /// The command line that created the archive (`creator`).
  std::string creator{};
  /// The creation parameters as serialized JSON text (`creation_parameters`); empty means "{}".
  std::string parameters_json = "{}";
  /// ISO-8601 UTC creation time (`created`); empty means now (utc_timestamp()).
  std::string created{};
};

/// The identifying root attributes of an archive, as read back.
struct ArchiveInfo {
  std::string format;               ///< "gimforge"
  std::int64_t format_version = 0;  ///< layout version, <= kArchiveFormatVersion
  std::string gimforge_version;     ///< gimforge::kVersion of the writer
  std::string created;              ///< ISO-8601 UTC, e.g. "2024-05-01T12:34:56Z"
  std::string creator;              ///< command line
  std::string creation_parameters;  ///< JSON text
};

/// An open gimforge archive. Move-only; the file closes with the object (or with close()).
class Archive {
 public:
  /// Creates the archive at `path` and writes the root attributes (format, format_version,
  /// gimforge_version, created, creator, creation_parameters). `access` may be an MPI-IO FileAccess
  /// (mpi/hdf5_mpio.h), which makes the call collective.
  /// Throws InvalidInput when `info.parameters_json` is not valid JSON, IoError when the file cannot be
  /// created (exists with kExclusive, directory missing, ...), LibraryError for other HDF5 failures.
  [[nodiscard]] static Archive create(const std::filesystem::path& path, const CreationInfo& info,
                                      h5::CreateMode mode = h5::CreateMode::kTruncate,
                                      const h5::FileAccess& access = {});
  /// Opens an existing archive and checks it is one this build can read. Throws IoError when the file is
  /// missing or not HDF5; FormatError (an IoError) "PATH: not a gimforge archive (no 'format'
  /// attribute)" (or with another reason) for an HDF5 file that is not a gimforge archive; IoError
  /// "PATH: archive format_version 7 is newer than this gimforge (2)" for a newer layout.
  [[nodiscard]] static Archive open(const std::filesystem::path& path, h5::OpenMode mode = h5::OpenMode::kReadOnly,
                                    const h5::FileAccess& access = {});
  /// Opens a file gimforge wrote that is not an archive (a batch shard) read-only, without the root checks,
  /// so that the representation readers can read a group in it (their messages name `path`).
  [[nodiscard]] static Archive open_unchecked(const std::filesystem::path& path);

  /// The root group ("/"), where representations add their groups. Valid until close().
  [[nodiscard]] h5::File& root() noexcept { return file_; }
  /// The root group ("/"), read-only access.
  [[nodiscard]] const h5::File& root() const noexcept { return file_; }
  /// The path the archive was created or opened with.
  [[nodiscard]] const std::filesystem::path& path() const noexcept { return path_; }
  /// Reads the identifying root attributes. Throws FormatError when one is missing or mistyped.
  [[nodiscard]] ArchiveInfo info() const;
  /// Flushes and closes the file, reporting failures (IoError). The archive is unusable afterwards.
  void close();

 private:
  Archive(std::filesystem::path path, h5::File file) noexcept : path_(std::move(path)), file_(std::move(file)) {}

  std::filesystem::path path_;
  h5::File file_;
};

/// The current UTC time as ISO-8601 with seconds, e.g. "2024-05-01T12:34:56Z".
[[nodiscard]] std::string utc_timestamp();

/// Storage of an image dataset. Defaults: chunks of up to 256 x 256 pixels with all channels, shuffle +
/// gzip level 4. `chunk` overrides the chunk shape (same rank as the image).
struct ImageOptions {
  h5::Dims chunk{};
  int deflate = 4;
  bool shuffle = true;
};

/// Writes a float32 image `name` under `parent`: `shape` is (H, W) or (H, W, C) and `pixels` holds
/// H*W*C values, row-major (pixel (y, x) channel c at (y*W + x)*C + c). Used for geometry images.
/// In a file opened with MPI-IO every rank calls it with the same arguments and a collective `xfer`
/// (mpi/hdf5_mpio.h): parallel HDF5 writes compressed datasets only collectively.
/// Throws InvalidInput for a bad rank or value count, LibraryError when HDF5 fails (e.g. name taken).
h5::Dataset write_image(h5::Group& parent, std::string_view name, const h5::Dims& shape, std::span<const float> pixels,
                        const ImageOptions& options = {}, const h5::DataTransfer& xfer = {});

/// Writes a uint16 image `name` under `parent` (shape, layout and MPI-IO use as for the float32 overload).
h5::Dataset write_image(h5::Group& parent, std::string_view name, const h5::Dims& shape,
                        std::span<const std::uint16_t> pixels, const ImageOptions& options = {},
                        const h5::DataTransfer& xfer = {});

/// Writes a uint8 image `name` under `parent` (shape, layout and MPI-IO use as for the float32 overload); used
/// for masks (1 = defined, 0 = undefined).
h5::Dataset write_image(h5::Group& parent, std::string_view name, const h5::Dims& shape,
                        std::span<const std::uint8_t> pixels, const ImageOptions& options = {},
                        const h5::DataTransfer& xfer = {});

/// Writes a quantized uint16 image and its dequantization attributes `scale` and `offset` (float64):
/// the real value of a stored q is `offset + scale * q`. Throws as write_image does.
h5::Dataset write_quantized_image(h5::Group& parent, std::string_view name, const h5::Dims& shape,
                                  std::span<const std::uint16_t> pixels, double scale, double offset,
                                  const ImageOptions& options = {}, const h5::DataTransfer& xfer = {});

}  // namespace gimforge::io
