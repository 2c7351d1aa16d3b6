#pragma once
/// \file png_image.h
/// Writing 8-bit RGB PNG files (libpng's simplified API), atomically (io::write_atomically: temporary
/// file, fsync, rename); reading a PNG as a mask.
#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

namespace gimforge::io {

/// Writes `rgb` (height rows of width·3 bytes, top row first) as a PNG. Throws InvalidInput for a size
/// mismatch, IoError naming the path when the file cannot be written (its directory must exist); a failed
/// write leaves no file behind.
void write_png_rgb(const std::filesystem::path& path, std::uint32_t width, std::uint32_t height,
                   std::span<const std::uint8_t> rgb);

/// A two-level picture: width × height flags, row-major, top row first.
struct PngMask {
  std::uint32_t width{0};
  std::uint32_t height{0};
  std::vector<std::uint8_t> inside;
};

/// Largest side read_png_mask accepts.
inline constexpr std::uint32_t kMaxPngMaskSide = 8192;  ///< 128 MiB of grey and alpha at most

/// Reads any PNG (grey, palette, RGB, with or without alpha, 8 or 16 bits) as a mask: a pixel is inside when
/// its grey level (libpng's conversion of colour) is at least half of white and it is at least half opaque.
/// Throws IoError (missing, unreadable) or FormatError (not a PNG, damaged, a side above kMaxPngMaskSide),
/// each one line starting with the path.
[[nodiscard]] PngMask read_png_mask(const std::filesystem::path& path);

}  // namespace gimforge::io
