#pragma once
/// \file png_image.h
/// Writing 8-bit RGB PNG files (libpng's simplified API), atomically (io::write_atomically: temporary
/// file, fsync, rename).
#include <cstdint>
#include <filesystem>
#include <span>

namespace gimforge::io {

/// Writes `rgb` (height rows of width·3 bytes, top row first) as a PNG. Throws InvalidInput for a size
/// mismatch, IoError naming the path when the file cannot be written (its directory must exist); a failed
/// write leaves no file behind.
void write_png_rgb(const std::filesystem::path& path, std::uint32_t width, std::uint32_t height,
                   std::span<const std::uint8_t> rgb);

}  // namespace gimforge::io
