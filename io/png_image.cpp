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

}  // namespace gimforge::io
