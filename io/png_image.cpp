#include "io/png_image.h"

#include <png.h>

#include <cstring>

#include <fmt/format.h>

#include "io/atomic_file.h"
#include "kernels/core/errors.h"

namespace gimforge::io {

void write_png_rgb(const std::filesystem::path& path, std::uint32_t width, std::uint32_t height,
                   std::span<const std::uint8_t> rgb) {
  if (width == 0 || height == 0 || rgb.size() != static_cast<std::size_t>(width) * height * 3)
    throw InvalidInput(fmt::format("{}: {} bytes are not a {}x{} RGB image", path.string(), rgb.size(), width, height));
  write_atomically(
      path,
      [&](const std::filesystem::path& tmp) {
        png_image image;
        std::memset(&image, 0, sizeof image);
        image.version = PNG_IMAGE_VERSION;
        image.width = width;
        image.height = height;
        image.format = PNG_FORMAT_RGB;
        if (!png_image_write_to_file(&image, tmp.c_str(), 0, rgb.data(), static_cast<png_int_32>(width * 3),
                                     nullptr))
          throw IoError(fmt::format("{}: cannot write PNG ({})", path.string(), image.message));
      },
      ParentDirectory::kMustExist);
}

PngMask read_png_mask(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw IoError(fmt::format("{}: no such file (a PNG mask was expected)", path.string()));
  png_image image;
  std::memset(&image, 0, sizeof image);
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, path.c_str()))
    throw FormatError(fmt::format("{}: not a readable PNG ({})", path.string(), image.message));
  if (image.width == 0 || image.height == 0 || image.width > kMaxPngMaskSide || image.height > kMaxPngMaskSide) {
    png_image_free(&image);
    throw FormatError(fmt::format("{}: a {} × {} picture (each side must be 1..{})", path.string(), image.width,
                                  image.height, kMaxPngMaskSide));
  }
  image.format = PNG_FORMAT_GA;
  PngMask mask{image.width, image.height, {}};
  std::vector<std::uint8_t> ga;
  try {
    ga.resize(std::size_t{image.width} * image.height * 2);
  } catch (...) {
    png_image_free(&image);
    throw;
  }
  if (!png_image_finish_read(&image, nullptr, ga.data(), static_cast<png_int_32>(image.width * 2), nullptr)) {
    png_image_free(&image);
    throw FormatError(fmt::format("{}: damaged PNG ({})", path.string(), image.message));
  }
  mask.inside.resize(ga.size() / 2);
  for (std::size_t p = 0; p < mask.inside.size(); ++p) mask.inside[p] = ga[2 * p] >= 128 && ga[2 * p + 1] >= 128 ? 1 : 0;
  return mask;
}

}  // namespace gimforge::io
