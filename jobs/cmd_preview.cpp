#include <algorithm>
#include <filesystem>

#include <fmt/format.h>

#include "io/gim_archive.h"
#include "io/png_image.h"
#include "jobs/commands.h"
#include "jobs/exit_codes.h"
#include "jobs/gim_store.h"

namespace gimforge::cli {
namespace {

std::uint8_t to_byte(double x) { return static_cast<std::uint8_t>(std::clamp(x, 0.0, 1.0) * 255.0 + 0.5); }

/// An (n, n, 3) float image as 8-bit RGB, each channel mapped by (x - lo) * scale, row 0 at the bottom
/// (parameter t grows upwards, as in the paper's figures).
std::vector<std::uint8_t> to_rgb(const std::vector<float>& img, std::uint32_t n, const Vec3& lo, const Vec3& scale) {
  std::vector<std::uint8_t> rgb(img.size());
  for (std::uint32_t j = 0; j < n; ++j)
    for (std::uint32_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) {
        const std::size_t src = (static_cast<std::size_t>(j) * n + i) * 3 + static_cast<std::size_t>(c);
        const std::size_t dst = (static_cast<std::size_t>(n - 1 - j) * n + i) * 3 + static_cast<std::size_t>(c);
        rgb[dst] = to_byte((double{img[src]} - lo[c]) * scale[c]);
      }
  return rgb;
}

}  // namespace

int run_preview(const PreviewOptions& options) {
  const io::Archive archive = io::Archive::open(options.archive);
  const std::string name = jobs::choose_geometry_image(archive, options.name);
  const GeometryImage image = io::read_geometry_image(archive, name);
  std::filesystem::create_directories(options.output_dir);
  // Geometry: x, y, z mapped to r, g, b over the bounding box (one scale for all axes keeps proportions).
  Vec3 lo = Vec3::Constant(INFINITY), hi = Vec3::Constant(-INFINITY);
  for (std::size_t p = 0; p < image.positions.size(); p += 3)
    for (int c = 0; c < 3; ++c) {
      lo[c] = std::min(lo[c], double{image.positions[p + static_cast<std::size_t>(c)]});
      hi[c] = std::max(hi[c], double{image.positions[p + static_cast<std::size_t>(c)]});
    }
  const double extent = std::max((hi - lo).maxCoeff(), 1e-30);
  const auto geometry_png = std::filesystem::path(options.output_dir) / (name + "_geometry.png");
  io::write_png_rgb(geometry_png, image.size, image.size, to_rgb(image.positions, image.size, lo, Vec3::Constant(1.0 / extent)));
  fmt::print("{}\n", geometry_png.string());
  if (image.normal_size > 0) {
    const auto normals_png = std::filesystem::path(options.output_dir) / (name + "_normals.png");
    io::write_png_rgb(normals_png, image.normal_size, image.normal_size,
                      to_rgb(image.normals, image.normal_size, Vec3::Constant(-1.0), Vec3::Constant(0.5)));
    fmt::print("{}\n", normals_png.string());
  }
  return kExitOk;
}

}  // namespace gimforge::cli
