#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <filesystem>
#include <functional>
#include <optional>
#include <set>
#include <span>

#include <fmt/format.h>
#include <png.h>

#include "io/atomic_file.h"
#include "io/gim_archive.h"
#include "io/mcgim_archive.h"
#include "io/png_image.h"
#include "io/relief_archive.h"
#include "io/sphere_archive.h"
#include "io/printable.h"
#include "jobs/cli/commands.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/gim_store.h"
#include "jobs/stored_image.h"
#include "kernels/core/errors.h"
#include "kernels/core/hash.h"
#include "kernels/relief/relief_map.h"

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
  // libpng refuses a side over PNG_USER_WIDTH_MAX / _HEIGHT_MAX ("Invalid IHDR data"): say what and whose.
  if (width > PNG_USER_WIDTH_MAX || height > PNG_USER_HEIGHT_MAX)
    throw InvalidInput(fmt::format("{}: the picture {} would be {} x {} pixels; PNG pictures are at most {} x {} here",
                                   io::printable(options.archive), io::printable(file), width, height, PNG_USER_WIDTH_MAX,
                                   PNG_USER_HEIGHT_MAX));
  io::write_png_rgb(path, width, height, rgb);
  fmt::print("{}\n", io::printable(path.string()));
}

/// Adaptive sampling with a region of interest (an n × n image): which samples lie in it (white), pixel for
/// pixel, as NAME_roi.png; nothing without one.
void preview_roi(const io::Archive& archive, const jobs::ImageRef& ref, const std::string& name, std::uint32_t n,
                 const PreviewOptions& options) {
  const std::optional<h5::Group> group = jobs::image_group(archive, ref);
  if (!group) return;  // an item stacked in a batch output: no region of interest is kept there
  const std::vector<std::uint8_t> inside =
      io::read_roi_mask(*group, archive, jobs::representation(ref.kind), ref.batch ? ref.path() : ref.name, n);
  if (inside.empty()) return;
  std::vector<float> white(3 * inside.size());
  for (std::size_t k = 0; k < white.size(); ++k) white[k] = inside[k / 3] ? 1.0f : 0.0f;
  write_png(options, name + "_roi.png", n, n, to_rgb(white, n, n, Vec3::Zero(), Vec3::Ones()));
}

void preview_gim(const io::Archive& archive, const jobs::ImageRef& ref, const std::string& name,
                 const PreviewOptions& options) {
  const GeometryImage image = jobs::read_gim(archive, ref);
  write_png(options, name + "_geometry.png", image.size, image.size,
            geometry_rgb(image.positions, image.size, image.size));
  if (image.normal_size > 0)
    write_png(options, name + "_normals.png", image.normal_size, image.normal_size,
              to_rgb(image.normals, image.normal_size, image.normal_size, Vec3::Constant(-1.0), Vec3::Constant(0.5)));
  preview_roi(archive, ref, name, image.size, options);
}

/// The spherical image as stored: one picture of (faces·height) rows (the cube's six faces stacked, face 0
/// at the bottom), undefined samples yellow; and its mask (white defined, black undefined).
void preview_sphere(const io::Archive& archive, const jobs::ImageRef& ref, const std::string& name,
                    const PreviewOptions& options) {
  const SphericalImage image = jobs::read_sphere(archive, ref);
  const DomainImage layout = image.layout();
  const auto width = static_cast<std::uint32_t>(layout.width());
  const auto height = static_cast<std::uint32_t>(layout.faces() * layout.height());
  write_png(options, name + "_sphere_geometry.png", width, height, geometry_rgb(image.positions, width, height));
  std::vector<float> mask(3 * image.mask.size());
  for (std::size_t k = 0; k < mask.size(); ++k) mask[k] = static_cast<float>(image.mask[k / 3]);
  write_png(options, name + "_sphere_mask.png", width, height,
            to_rgb(mask, width, height, Vec3::Zero(), Vec3::Ones()));
  if (layout.faces() == 1 && width == height) preview_roi(archive, ref, name, width, options);
}

/// Multi-chart geometry images: the geometry (undefined samples yellow), the normals and the charts (one
/// colour per chart, undefined samples black), row 0 at the bottom as packed.
void preview_mcgim(const io::Archive& archive, const jobs::ImageRef& ref, const std::string& name,
                   const PreviewOptions& options) {
  const MultiChartImage image = jobs::read_mcgim(archive, ref);
  const io::McgimExtras extras = jobs::read_mcgim_extras(archive, ref);
  write_png(options, name + "_mcgim_geometry.png", image.width, image.height,
            geometry_rgb(image.positions, image.width, image.height));
  // A compressed item stores no normals: they are central differences of the positions, recomputed here.
  const std::vector<float> normals = extras.normals.empty() ? multichart_normals(image) : extras.normals;
  write_png(options, name + "_mcgim_normals.png", image.width, image.height,
            to_rgb(normals, image.width, image.height, Vec3::Constant(-1.0), Vec3::Constant(0.5)));
  std::vector<float> colours(3 * image.samples(), 0.0f);
  for (std::size_t s = 0; s < image.samples(); ++s) {
    if (image.chart[s] == kNoChart) continue;
    // A well-spread hue per chart (golden-ratio steps), full saturation.
    const double hue = std::fmod(0.618033988749895 * image.chart[s], 1.0) * 6.0;
    const double f = hue - std::floor(hue);
    const std::array<double, 6 * 3> table{1, f, 0, 1 - f, 1, 0, 0, 1, f, 0, 1 - f, 1, f, 0, 1, 1, 0, 1 - f};
    const auto k = static_cast<std::size_t>(hue) % 6;
    for (std::size_t c = 0; c < 3; ++c) colours[3 * s + c] = static_cast<float>(0.25 + 0.75 * table[3 * k + c]);
  }
  write_png(options, name + "_mcgim_charts.png", image.width, image.height,
            to_rgb(colours, image.width, image.height, Vec3::Zero(), Vec3::Ones()));
}

using Rgb = std::array<std::uint8_t, 3>;

/// Relief previews: lines between the tiles of an atlas, and the cell classes.
constexpr Rgb kSeparatorColour{0, 0, 96};
constexpr Rgb kWhiteCell{255, 255, 255};
constexpr Rgb kBlackCell{0, 0, 0};
constexpr Rgb kBorderGreyCell{176, 176, 176};
constexpr Rgb kInteriorGreyCell{96, 96, 96};
/// Larger pictures are not written (a preview, not an export).
constexpr std::uint64_t kMaxPreviewPixels = std::uint64_t{1} << 26;
/// The grid of the cells picture is rebuilt in memory (N³ bytes) up to this N.
constexpr std::uint32_t kMaxPreviewGrid = 256;

/// `count` square tiles of `tile` pixels, left to right and top to bottom, about as many columns as rows,
/// with 1-pixel separator lines between and around them.
class Atlas {
 public:
  Atlas(std::uint32_t tile, std::size_t count)
      : tile_(tile),
        columns_(static_cast<std::uint32_t>(std::ceil(std::sqrt(static_cast<double>(std::max<std::size_t>(count, 1)))))),
        rows_(static_cast<std::uint32_t>((std::max<std::size_t>(count, 1) + columns_ - 1) / columns_)) {}

  [[nodiscard]] std::uint32_t width() const { return columns_ * (tile_ + 1) + 1; }
  [[nodiscard]] std::uint32_t height() const { return rows_ * (tile_ + 1) + 1; }
  [[nodiscard]] std::uint64_t pixels() const { return std::uint64_t{width()} * height(); }

  /// Allocates the picture, all separator colour.
  void allocate() {
    rgb_.resize(3 * pixels());
    for (std::size_t p = 0; p < rgb_.size(); p += 3) std::copy(kSeparatorColour.begin(), kSeparatorColour.end(), &rgb_[p]);
  }
  /// Pixel (x, y) of tile t, y = 0 the bottom row of the tile.
  void set(std::size_t t, std::uint32_t x, std::uint32_t y, const Rgb& c) {
    const std::size_t px = (t % columns_) * (tile_ + 1) + 1 + x;
    const std::size_t py = (t / columns_) * (tile_ + 1) + 1 + (tile_ - 1 - y);
    std::copy(c.begin(), c.end(), &rgb_[3 * (py * width() + px)]);
  }
  [[nodiscard]] const std::vector<std::uint8_t>& rgb() const { return rgb_; }

 private:
  std::uint32_t tile_;
  std::uint32_t columns_;
  std::uint32_t rows_;
  std::vector<std::uint8_t> rgb_;
};

/// Writes the atlas unless it is too large for a preview (then says so).
void write_atlas(const PreviewOptions& options, const std::string& file, Atlas& atlas, const std::string& what,
                 const std::function<void(Atlas&)>& paint) {
  if (atlas.pixels() > kMaxPreviewPixels) {
    fmt::print("{}: not written: {} would make a {}x{} picture\n", file, what, atlas.width(), atlas.height());
    return;
  }
  atlas.allocate();
  paint(atlas);
  write_png(options, file, atlas.width(), atlas.height(), atlas.rgb());
}

/// One texel map of a relief map as an atlas of its layers; empty texels kUndefinedColour.
void relief_layers_png(const PreviewOptions& options, const std::string& file, const ReliefMap& map,
                       const std::function<Rgb(std::size_t texel)>& colour) {
  Atlas atlas(map.texture, map.num_layers());
  write_atlas(options, file, atlas, fmt::format("{} layers of {}x{} texels", map.num_layers(), map.texture, map.texture),
              [&](Atlas& a) {
                for (std::size_t l = 0; l < map.num_layers(); ++l)
                  for (std::uint32_t j = 0; j < map.texture; ++j)
                    for (std::uint32_t i = 0; i < map.texture; ++i) {
                      const std::size_t t = map.texel_index(l, i, j);
                      a.set(l, i, j, map.distances[t] == kEmptyTexel ? kUndefinedColour : colour(t));
                    }
              });
}

/// Class of every cell of the N³ grid: 0 white, 1 black, 2 border grey, 3 interior grey. White and black
/// are rebuilt from the grey-cell table: non-grey cells connected (face adjacency) to the grid boundary are
/// white, the others black, which is what the flood fill of a watertight mesh decides; `black` returns
/// their count to compare with the stored one.
std::vector<std::uint8_t> cell_classes(const ReliefMap& map, std::size_t& black) {
  const std::size_t n = map.n;
  std::vector<std::uint8_t> cls(n * n * n, 1);
  for (std::size_t g = 0; g < map.cells.size(); ++g) cls[map.cells[g]] = map.external_faces[g] != 0 ? 2 : 3;
  std::deque<std::size_t> queue;
  const auto visit = [&](std::size_t c) {
    if (cls[c] == 1) {
      cls[c] = 0;
      queue.push_back(c);
    }
  };
  for (std::size_t k = 0; k < n; ++k)
    for (std::size_t j = 0; j < n; ++j)
      for (std::size_t i = 0; i < n; ++i)
        if (i == 0 || j == 0 || k == 0 || i + 1 == n || j + 1 == n || k + 1 == n) visit((k * n + j) * n + i);
  while (!queue.empty()) {
    const std::size_t c = queue.front();
    queue.pop_front();
    const std::size_t i = c % n, j = c / n % n, k = c / (n * n);
    if (i > 0) visit(c - 1);
    if (i + 1 < n) visit(c + 1);
    if (j > 0) visit(c - n);
    if (j + 1 < n) visit(c + n);
    if (k > 0) visit(c - n * n);
    if (k + 1 < n) visit(c + n * n);
  }
  black = static_cast<std::size_t>(std::count(cls.begin(), cls.end(), std::uint8_t{1}));
  return cls;
}

/// The N z-slices of the cell grid, k = 0 first; each cell a square of pixels (tiles of at least 64 pixels).
void relief_cells_png(const PreviewOptions& options, const std::string& file, const ReliefMap& map) {
  if (map.n > kMaxPreviewGrid) {
    fmt::print("{}: not written: the grid has N = {} > {} cells per axis\n", file, map.n, kMaxPreviewGrid);
    return;
  }
  std::size_t black = 0;
  const std::vector<std::uint8_t> cls = cell_classes(map, black);
  const std::uint32_t scale = std::max<std::uint32_t>(1, (64 + map.n - 1) / map.n);
  Atlas atlas(map.n * scale, map.n);
  static constexpr std::array<Rgb, 4> kColours{kWhiteCell, kBlackCell, kBorderGreyCell, kInteriorGreyCell};
  write_atlas(options, file, atlas, fmt::format("{} slices of {}x{} cells", map.n, map.n, map.n), [&](Atlas& a) {
    const std::size_t n = map.n;
    for (std::size_t k = 0; k < n; ++k)
      for (std::uint32_t j = 0; j < map.n; ++j)
        for (std::uint32_t i = 0; i < map.n; ++i) {
          const Rgb& c = kColours[cls[(k * n + j) * n + i]];
          for (std::uint32_t y = 0; y < scale; ++y)
            for (std::uint32_t x = 0; x < scale; ++x) a.set(k, i * scale + x, j * scale + y, c);
        }
  });
  if (black != map.black_cells)
    fmt::print("{}: note: {} cells are enclosed by grey cells (drawn black) but the stored inside test found {} "
               "black cells ({})\n",
               file, black, map.black_cells, map.inside_method);
}

/// Relief maps: atlases of the distance, normal and colour maps (one tile per layer) and the cell grid.
void preview_relief(const io::Archive& archive, const jobs::ImageRef& ref, const std::string& name,
                    const PreviewOptions& options) {
  const ReliefMap map = jobs::read_relief(archive, ref);
  std::uint16_t longest = 1;
  for (const std::uint16_t q : map.distances)
    if (q != kEmptyTexel) longest = std::max(longest, q);
  relief_layers_png(options, name + "_relief_distances.png", map, [&](std::size_t t) {
    const std::uint8_t v = to_byte(static_cast<double>(map.distances[t]) / longest);
    return Rgb{v, v, v};
  });
  relief_layers_png(options, name + "_relief_normals.png", map, [&](std::size_t t) {
    Rgb c{};
    for (std::size_t k = 0; k < 3; ++k) c[k] = to_byte((map.normals[3 * t + k] / 127.0 + 1.0) * 0.5);
    return c;
  });
  if (!map.colors.empty())
    relief_layers_png(options, name + "_relief_colors.png", map, [&](std::size_t t) {
      return Rgb{map.colors[3 * t], map.colors[3 * t + 1], map.colors[3 * t + 2]};
    });
  relief_cells_png(options, name + "_relief_cells.png", map);
}

/// The longest suffix a picture's file name gets ("_relief_distances.png").
constexpr std::size_t kLongestPictureSuffix = 21;

/// What the pictures of `ref` are named after, relative to -o: the image's name, or for a batch item
/// OUTPUT/ITEM, the item's name (chair/0001) as folders like the archive's (gim_257/chair/0001_geometry.png).
/// A last part too long for a file name with its suffix and the temporary name's (names reach 255 bytes) is
/// cut, at a character's start, and ends in "~" and 8 hex digits of the whole name's CRC-32, so that
/// names stay apart.
std::string picture_stem(const jobs::ImageRef& ref) {
  std::string stem = ref.batch ? ref.batch->output + "/" + ref.name : ref.name;
  const std::size_t last = stem.rfind('/') == std::string::npos ? 0 : stem.rfind('/') + 1;
  // The picture is written under a temporary name first (io/atomic_file.h: host and process appended).
  const std::size_t room = io::kMaxPathComponent - kLongestPictureSuffix - (io::temporary_path("x").string().size() - 1);
  if (stem.size() - last <= room) return stem;
  const std::uint32_t hash = crc32(reinterpret_cast<const std::uint8_t*>(stem.data()), stem.size());
  std::size_t keep = last + room - 9;
  while (keep > last && (static_cast<unsigned char>(stem[keep]) & 0xC0) == 0x80) --keep;  // not inside a character
  return stem.substr(0, keep) + fmt::format("~{:08x}", hash);
}

/// Whether the image keeps a region of interest (roi_mask, drawn as STEM_roi.png).
bool has_roi(const io::Archive& archive, const jobs::ImageRef& ref) {
  const std::optional<h5::Group> group = jobs::image_group(archive, ref);
  return group && group->exists("roi_mask");
}

/// The pictures preview writes for an image of `kind` named `name`.
std::vector<std::string> picture_names(jobs::Method kind, const std::string& name) {
  switch (kind) {
    case jobs::Method::Gim: return {name + "_geometry.png", name + "_normals.png", name + "_roi.png"};
    case jobs::Method::Sphere: return {name + "_sphere_geometry.png", name + "_sphere_mask.png", name + "_roi.png"};
    case jobs::Method::Relief:
      return {name + "_relief_distances.png", name + "_relief_normals.png", name + "_relief_colors.png",
              name + "_relief_cells.png"};
    case jobs::Method::Mcgim:
      return {name + "_mcgim_geometry.png", name + "_mcgim_normals.png", name + "_mcgim_charts.png"};
  }
  return {};
}

/// The directories preview created for -o, deepest first: removed again, when still empty, if it fails.
struct CreatedDirs {
  std::vector<std::filesystem::path> dirs;
  bool keep{false};
  ~CreatedDirs() {
    if (keep) return;
    std::error_code ec;
    for (const std::filesystem::path& d : dirs)
      if (std::filesystem::is_empty(d, ec) && !ec) std::filesystem::remove(d, ec);
  }
};

/// Before any picture is drawn: -o is a directory (created when missing) where files can be created, and
/// none of the pictures would replace the archive.
void prepare_output_dir(const PreviewOptions& options, const jobs::ImageRef& ref, CreatedDirs& created) {
  const std::filesystem::path dir = options.output_dir;
  std::error_code ec;
  if (std::filesystem::exists(dir, ec) && !std::filesystem::is_directory(dir, ec))
    throw IoError(fmt::format("{}: is not a directory (preview -o takes the directory to write the pictures into)",
                              options.output_dir));
  for (std::filesystem::path d = dir; !d.empty() && !std::filesystem::exists(d, ec); d = d.parent_path()) {
    created.dirs.push_back(d);
    if (d == d.parent_path()) break;
  }
  std::filesystem::create_directories(dir, ec);
  if (ec) throw IoError(fmt::format("{}: cannot create the directory: {}", options.output_dir, ec.message()));
  // The item's name comes from the archive (someone else's file) and becomes part of the pictures' names:
  // every part of it one file name (no "..", nothing absolute), and a batch item's folders created here.
  const std::string stem = picture_stem(ref);
  for (std::size_t start = 0; start <= stem.size();) {
    const std::size_t end = ref.batch ? std::min(stem.find('/', start), stem.size()) : stem.size();
    if (const std::string problem = io::path_component_problem(std::string_view(stem).substr(start, end - start));
        !problem.empty())
      throw FormatError(fmt::format("{}:/{}: the item's name{} {}: it cannot name a picture file", options.archive,
                                    io::printable(ref.path()), ref.batch ? " has a part that" : "", problem));
    start = end + 1;
  }
  if (ref.batch) {
    const std::filesystem::path folder = (dir / stem).parent_path();
    // The item's folders are preview's own: a link in their place would send the pictures outside -o.
    for (std::filesystem::path d = folder; d != dir; d = d.parent_path())
      if (std::filesystem::is_symlink(d, ec))
        throw IoError(fmt::format("{}: is a symbolic link where preview writes the item's folder; remove it or choose "
                                  "another -o",
                                  io::printable(d.string())));
    std::vector<std::filesystem::path> made;
    for (std::filesystem::path d = folder; d != dir && !std::filesystem::exists(d, ec); d = d.parent_path())
      made.push_back(d);
    created.dirs.insert(created.dirs.begin(), made.begin(), made.end());  // deeper than -o: removed first, also on failure
    std::filesystem::create_directories(folder, ec);
    if (ec) throw IoError(fmt::format("{}: cannot create the directory: {}", io::printable(folder.string()), ec.message()));
  }
  for (const std::string& file : picture_names(ref.kind, stem)) {
    io::check_can_create(dir / file);
    jobs::refuse_output_over_inputs(dir / file, {options.archive});
  }
}

}  // namespace

int run_preview(const PreviewOptions& options) {
  const io::Archive archive = io::Archive::open(options.archive);
  // Pictures go into a directory, named after each image: without --name every image is drawn.
  std::vector<jobs::ImageRef> refs;
  if (options.name.empty())
    for (const jobs::Method kind : jobs::kMethods)
      for (const std::string& name : jobs::image_names(archive, kind)) refs.push_back({kind, name});
  if (refs.size() <= 1) refs = {jobs::choose_image(archive, options.name, jobs::BatchItems::kAccepted)};
  std::set<std::string> pictures;  // a gim and a spherical image of one name, both with a ROI: NAME_roi.png twice
  for (const jobs::ImageRef& ref : refs)
    for (const std::string& file : picture_names(ref.kind, picture_stem(ref)))
      if ((!file.ends_with("_roi.png") || has_roi(archive, ref)) &&
          !pictures.insert(file).second)
        throw InvalidInput(fmt::format("{}: two images would write {}; choose one with --name", options.archive,
                                       io::printable(file)));
  CreatedDirs created;
  for (const jobs::ImageRef& ref : refs) prepare_output_dir(options, ref, created);
  for (const jobs::ImageRef& ref : refs) {
    (void)jobs::image_origin(archive, ref);  // not drawn, but checked as every reader checks it
    const std::string stem = picture_stem(ref);
    if (ref.kind == jobs::Method::Gim)
      preview_gim(archive, ref, stem, options);
    else if (ref.kind == jobs::Method::Sphere)
      preview_sphere(archive, ref, stem, options);
    else if (ref.kind == jobs::Method::Mcgim)
      preview_mcgim(archive, ref, stem, options);
    else
      preview_relief(archive, ref, stem, options);
  }
  created.keep = true;
  return kExitOk;
}

}  // namespace gimforge::cli
