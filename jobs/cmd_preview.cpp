#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <span>

#include <fmt/format.h>

#include "io/gim_archive.h"
#include "io/png_image.h"
#include "io/sphere_archive.h"
#include "jobs/commands.h"
#include "jobs/exit_codes.h"
#include "jobs/gim_store.h"

namespace gimforge::cli {
namespace {

/// Colour of undefined samples (NaN: in a filled hole), yellow as in Praun & Hoppe's figures.
constexpr std::array<std::uint8_t, 3> kUndefinedColour{255, 255, 0};

std::uint8_t to_byte(double x) { return static_cast<std::uint8_t>(std::clamp(x, 0.0, 1.0) * 255.0 + 0.5); }

/// An image of `height` rows of `width` samples of 3 floats as 8-bit RGB, each channel mapped by
/// (x - lo) * scale, row 0 at the bottom (parameter t grows upwards, as in the papers' figures). Samples
/// with a NaN channel get kUndefinedColour.
std::vector<std::uint8_t> to_rgb(std::span<const float> img, std::uint32_t width, std::uint32_t height, const Vec3& lo,
                                 const Vec3& scale) {
  std::vector<std::uint8_t> rgb(img.size());
  for (std::size_t j = 0; j < height; ++j)
    for (std::size_t i = 0; i < width; ++i) {
      const std::size_t src = (j * width + i) * 3;
      const std::size_t dst = ((height - 1 - j) * width + i) * 3;
      const bool undefined = std::isnan(img[src]) || std::isnan(img[src + 1]) || std::isnan(img[src + 2]);
      for (std::size_t c = 0; c < 3; ++c) {
        const auto k = static_cast<Eigen::Index>(c);
        rgb[dst + c] = undefined ? kUndefinedColour[c] : to_byte((double{img[src + c]} - lo[k]) * scale[k]);
      }
    }
  return rgb;
}

/// Geometry as colour: x, y, z mapped to r, g, b over the bounding box of the defined samples (one scale
/// for all axes keeps proportions).
std::vector<std::uint8_t> geometry_rgb(std::span<const float> img, std::uint32_t width, std::uint32_t height) {
  BoundingBox box;
  for (std::size_t p = 0; p < img.size(); p += 3) {
    const Vec3 x(img[p], img[p + 1], img[p + 2]);
    if (x.allFinite()) box.extend(x);
  }
  const Vec3 lo = box.empty() ? Vec3::Zero() : box.min;
  const double extent = box.empty() ? 1.0 : std::max((box.max - box.min).maxCoeff(), 1e-30);
  return to_rgb(img, width, height, lo, Vec3::Constant(1.0 / extent));
}

/// Writes DIR/FILE as a PNG and prints its path.
void write_png(const PreviewOptions& options, const std::string& file, std::uint32_t width, std::uint32_t height,
               const std::vector<std::uint8_t>& rgb) {
  const auto path = std::filesystem::path(options.output_dir) / file;
  io::write_png_rgb(path, width, height, rgb);
  fmt::print("{}\n", path.string());
}

void preview_gim(const io::Archive& archive, const std::string& name, const PreviewOptions& options) {
  const GeometryImage image = io::read_geometry_image(archive, name);
  write_png(options, name + "_geometry.png", image.size, image.size,
            geometry_rgb(image.positions, image.size, image.size));
  if (image.normal_size > 0)
    write_png(options, name + "_normals.png", image.normal_size, image.normal_size,
              to_rgb(image.normals, image.normal_size, image.normal_size, Vec3::Constant(-1.0), Vec3::Constant(0.5)));
}

/// The spherical image as stored: one picture of (faces·height) rows (the cube's six faces stacked, face 0
/// at the bottom), undefined samples yellow; and its mask (white defined, black undefined).
void preview_sphere(const io::Archive& archive, const std::string& name, const PreviewOptions& options) {
  const SphericalImage image = io::read_spherical_image(archive, name);
  const DomainImage layout = image.layout();
  const auto width = static_cast<std::uint32_t>(layout.width());
  const auto height = static_cast<std::uint32_t>(layout.faces() * layout.height());
  write_png(options, name + "_sphere_geometry.png", width, height, geometry_rgb(image.positions, width, height));
  std::vector<float> mask(3 * image.mask.size());
  for (std::size_t k = 0; k < mask.size(); ++k) mask[k] = static_cast<float>(image.mask[k / 3]);
  write_png(options, name + "_sphere_mask.png", width, height,
            to_rgb(mask, width, height, Vec3::Zero(), Vec3::Ones()));
}

}  // namespace

int run_preview(const PreviewOptions& options) {
  const io::Archive archive = io::Archive::open(options.archive);
  const jobs::ImageRef ref = jobs::choose_image(archive, options.name);
  std::filesystem::create_directories(options.output_dir);
  if (ref.kind == jobs::ImageKind::Geometry)
    preview_gim(archive, ref.name, options);
  else
    preview_sphere(archive, ref.name, options);
  return kExitOk;
}

}  // namespace gimforge::cli
