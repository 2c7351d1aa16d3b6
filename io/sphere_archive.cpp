/// \file sphere_archive.cpp
/// Spherical geometry images in the archive (see sphere_archive.h and docs/archive.md).
#include "io/sphere_archive.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>

#include <fmt/format.h>

#include "io/coded_image.h"
#include "kernels/core/errors.h"

namespace gimforge::io {
namespace {

constexpr const RepresentationKind& kSphere = kSphericalImages;
constexpr const char* kMethod = "sphere";
constexpr const char* kSphereItem = "parametrization/sphere";
constexpr const char* kVertexOrder =
    "one unit vector per vertex of the closed mesh that was parametrized: the input mesh's vertices in their "
    "order, then one centre vertex per filled hole";
/// How far a stored sphere point may be from unit length (they are normalized in double precision).
constexpr double kUnitTolerance = 1e-6;

/// Shape of an image of `layout` with `channels` channels per sample ((S, W) when channels is 0).
h5::Dims image_shape(const DomainImage& layout, std::uint64_t channels) {
  const auto rows = static_cast<std::uint64_t>(layout.faces()) * static_cast<std::uint64_t>(layout.height());
  const auto width = static_cast<std::uint64_t>(layout.width());
  return channels == 0 ? h5::Dims{rows, width} : h5::Dims{rows, width, channels};
}

std::string describe(const DomainImage& layout) {
  return fmt::format("domain {}, n = {}: {} samples", to_string(layout.domain()), layout.n(), layout.num_samples());
}

/// The first disagreement of the mask with itself or the positions ("mask of sample 3 is 2 (expected 0
/// or 1)", "defined sample 3 is not finite", "masked sample 3 is not NaN"); empty when there is none.
/// Precondition: positions hold 3 values per mask entry.
std::string mask_problem(const SphericalImage& image) {
  for (std::size_t k = 0; k < image.mask.size(); ++k) {
    const float* p = &image.positions[3 * k];
    const std::uint8_t m = image.mask[k];
    if (m > 1) return fmt::format("mask of sample {} is {} (expected 0 or 1)", k, m);
    if (m == 1 && !(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])))
      return fmt::format("defined sample {} is not finite", k);
    if (m == 0 && !(std::isnan(p[0]) && std::isnan(p[1]) && std::isnan(p[2])))
      return fmt::format("masked sample {} is not NaN", k);
  }
  return {};
}

/// Throws InvalidInput when the arrays of `image` do not fit its layout, or the mask is not 0/1 or disagrees
/// with the positions.
void check_image(const std::string& name, const SphericalImage& image, const DomainImage& layout) {
  const std::size_t samples = layout.num_samples();
  const auto mismatch = [&](std::string_view what, std::size_t got, std::size_t want) {
    return InvalidInput(fmt::format("spherical geometry image '{}': {} hold {} values, expected {} ({})", name, what,
                                    got, want, describe(layout)));
  };
  if (image.positions.size() != 3 * samples) throw mismatch("positions", image.positions.size(), 3 * samples);
  if (image.mask.size() != samples) throw mismatch("mask", image.mask.size(), samples);
  if (!image.colors.empty() && image.colors.size() != 3 * samples)
    throw mismatch("colors", image.colors.size(), 3 * samples);
  if (!image.sample_uv.empty()) {
    if (layout.domain() != SphericalDomain::FlatOctahedron)
      throw InvalidInput(fmt::format("spherical geometry image '{}': sample positions are for the flat-octa domain, "
                                     "not {}",
                                     name, to_string(layout.domain())));
    if (image.sample_uv.size() != 2 * samples) throw mismatch("sample_uv", image.sample_uv.size(), 2 * samples);
  }
  if (const std::string problem = mask_problem(image); !problem.empty())
    throw InvalidInput(fmt::format("spherical geometry image '{}': {}", name, problem));
}

bool is_unit(const Vec3& s) { return s.allFinite() && std::abs(s.norm() - 1.0) <= kUnitTolerance; }

void check_parametrization(const std::string& name, const SphereParametrization& p) {
  if (p.input_vertices == 0 && p.sphere.empty()) return;  // none (a decompressed item): not written
  if (p.input_vertices == 0 || p.sphere.size() < p.input_vertices)
    throw InvalidInput(fmt::format("spherical geometry image '{}': the parametrization has {} unit vectors for {} "
                                   "input vertices",
                                   name, p.sphere.size(), p.input_vertices));
  const auto bad = std::find_if_not(p.sphere.begin(), p.sphere.end(), is_unit);
  if (bad != p.sphere.end())
    throw InvalidInput(fmt::format("spherical geometry image '{}': vertex {} of the parametrization is not a unit "
                                   "vector",
                                   name, bad - p.sphere.begin()));
}

/// Writes the attributes that identify the domain layout of an image.
void write_layout_attributes(h5::Object& object, const DomainImage& layout) {
  object.set_attribute("domain", to_string(layout.domain()));
  object.set_attribute("n", layout.n());
}

/// The layout named by the `domain` and `n` attributes of the group.
DomainImage read_layout(const h5::Group& g, const Archive& archive, const std::string& name) {
  const auto domain_name = g.attribute<std::string>("domain");
  const auto n = g.attribute<std::int64_t>("n");
  std::vector<std::string_view> known;
  for (const SphericalDomain d : kSphericalDomains) {
    if (to_string(d) == domain_name) {
      if (std::in_range<std::uint32_t>(n)) try {
          return DomainImage(d, static_cast<std::uint32_t>(n));
        } catch (const InvalidInput&) {
          // out of the domain's range: reported below like a negative n
        }
      throw representation_error(archive, kSphere, name, fmt::format("tessellation n = {} is out of range", n));
    }
    known.push_back(to_string(d));
  }
  throw representation_error(archive, kSphere, name,
                             fmt::format("unknown domain '{}' (known: {})", domain_name, fmt::join(known, ", ")));
}

/// Checks that the geometry dataset's own layout attributes agree with the group's.
void check_geometry_attributes(const h5::Dataset& ds, const Archive& archive, const std::string& name,
                               const DomainImage& layout) {
  const auto expect = [&](std::string_view key, std::int64_t want) {
    const auto got = ds.attribute<std::int64_t>(key);
    if (got != want)
      throw representation_error(
          archive, kSphere, name, fmt::format("geometry attribute {} = {} disagrees with {}", key, got, describe(layout)));
  };
  if (ds.attribute<std::string>("domain") != to_string(layout.domain()))
    throw representation_error(archive, kSphere, name,
                               fmt::format("geometry attribute domain = '{}' disagrees with {}",
                                           ds.attribute<std::string>("domain"), describe(layout)));
  expect("n", layout.n());
  expect("faces", layout.faces());
  expect("width", layout.width());
  expect("height", layout.height());
}

}  // namespace

void check_spherical_image(const std::string& name, const SphericalImage& image) {
  check_image(name, image, image.layout());
}

void write_spherical_image(Archive& archive, const std::string& name, const SphericalImage& image,
                           const SphereParametrization& parametrization, const SphereRecord& record) {
  check_representation_name(kSphere, name);
  const DomainImage layout = image.layout();
  check_image(name, image, layout);
  check_parametrization(name, parametrization);
  check_record(record, {"domain", "n"});

  h5::Group g = create_representation(archive, kSphere, name);
  h5::Dataset geometry = write_image(g, "geometry", image_shape(layout, 3), image.positions);
  write_layout_attributes(geometry, layout);
  geometry.set_attribute("faces", layout.faces());
  geometry.set_attribute("width", layout.width());
  geometry.set_attribute("height", layout.height());
  write_image(g, "mask", image_shape(layout, 0), image.mask);
  if (!image.colors.empty()) write_image(g, "colors", image_shape(layout, 3), image.colors);
  if (!image.sample_uv.empty()) write_image(g, "sample_uv", image_shape(layout, 2), image.sample_uv);

  if (!parametrization.sphere.empty()) {
    std::vector<double> flat;
    flat.reserve(3 * parametrization.sphere.size());
    for (const Vec3& s : parametrization.sphere) flat.insert(flat.end(), {s.x(), s.y(), s.z()});
    h5::Group param = g.create_group("parametrization");
    h5::Dataset sphere = param.write_dataset("sphere", {parametrization.sphere.size(), 3}, flat);
    sphere.set_attribute("vertex_order", kVertexOrder);
    sphere.set_attribute("input_vertices", parametrization.input_vertices);
    sphere.set_attribute("input_faces", parametrization.input_faces);
  }

  write_layout_attributes(g, layout);
  write_record(g, kMethod, record);
}

SphericalImage read_spherical_image(const Archive& archive, const std::string& name) {
  return read_spherical_image(archive, open_representation(archive, kSphere, name), name);
}

SphericalImage read_spherical_image(const Archive& archive, const h5::Group& g, const std::string& name) {
  check_method(g, archive, kSphere, name, kMethod);
  const DomainImage layout = read_layout(g, archive, name);
  SphericalImage image;
  image.domain = layout.domain();
  image.n = static_cast<std::uint32_t>(layout.n());

  const h5::Dims shape = image_shape(layout, 3);
  if (!has_coded_positions(g)) {
    const h5::Dataset geometry = open_item(g, archive, kSphere, name, "geometry");
    check_shape(geometry, archive, kSphere, name, "geometry", shape);
    check_geometry_attributes(geometry, archive, name, layout);
  }
  // Octahedral images are coded with their own extension rules (Praun & Hoppe §6); the others only by JPEG 2000.
  const bool octahedral = layout.domain() == SphericalDomain::Octahedron || layout.domain() == SphericalDomain::FlatOctahedron;
  StoredPositions stored = read_positions(g, archive, kSphere, name, shape[0], shape[1],
                                          octahedral ? LatticeExtension::Sphere : LatticeExtension::Mirror);
  image.positions = std::move(stored.xyz);

  if (!g.exists("mask") && has_coded_positions(g)) {
    image.mask.assign(layout.num_samples(), 1);  // a coded item of a closed input stores no mask: all defined
  } else {
    const h5::Dataset mask = open_item(g, archive, kSphere, name, "mask");
    check_shape(mask, archive, kSphere, name, "mask", image_shape(layout, 0));
    if (mask.dtype() != h5::DType::kUInt8) throw representation_error(archive, kSphere, name, "mask is not uint8");
    image.mask = mask.read<std::uint8_t>();
  }
  if (stored.storage != "float32")  // quantized and coded samples are numbers everywhere: the mask says which are not
    for (std::size_t k = 0; k < image.mask.size(); ++k)
      if (image.mask[k] == 0)
        for (std::size_t c = 0; c < 3; ++c) image.positions[3 * k + c] = std::numeric_limits<float>::quiet_NaN();
  if (const std::string problem = mask_problem(image); !problem.empty())
    throw representation_error(archive, kSphere, name, problem);
  require_near_samples(image.positions, image.mask, stored.storage, archive, kSphere, name);

  if (g.exists("colors")) {
    const h5::Dataset colors = open_item(g, archive, kSphere, name, "colors");
    check_shape(colors, archive, kSphere, name, "colors", image_shape(layout, 3));
    image.colors = read_real_image(colors, archive, kSphere, name, "colors");
    // Colours are defined where the geometry is (NaN, like the positions, only at masked samples).
    for (std::size_t k = 0; k < image.colors.size(); ++k)
      if (image.mask[k / 3] == 1 && !std::isfinite(image.colors[k]))
        throw representation_error(archive, kSphere, name, fmt::format("colour of defined sample {} is not finite", k / 3));
  }
  if (g.exists("sample_uv")) {  // adaptive sampling (docs/adaptive.md): the flat-octahedron square only
    if (layout.domain() != SphericalDomain::FlatOctahedron)
      throw representation_error(archive, kSphere, name,
                                 fmt::format("dataset 'sample_uv' belongs to a flat-octa image, not {}", to_string(layout.domain())));
    image.sample_uv = read_sample_uv(g, archive, kSphere, name, static_cast<std::uint64_t>(layout.width()));
    // The square folds at its side midpoints: those stay, and mated samples lie at mirrored points.
    const auto w = static_cast<std::size_t>(layout.width()), last = w - 1, half = last / 2;
    const auto at = [&](std::size_t i, std::size_t j, std::size_t c) { return double{image.sample_uv[2 * (j * w + i) + c]}; };
    for (const auto& [i, j] : {std::pair{half, std::size_t{0}}, {half, last}, {std::size_t{0}, half}, {last, half}})
      if (at(i, j, 0) != static_cast<double>(i) / static_cast<double>(last) || at(i, j, 1) != static_cast<double>(j) / static_cast<double>(last))
        throw representation_error(archive, kSphere, name, "dataset 'sample_uv': a side midpoint moved (it is a seam point)");
    for (std::size_t k = 0; k < w; ++k)
      if (std::abs(at(k, 0, 0) + at(last - k, 0, 0) - 1.0) > 1e-6 || std::abs(at(k, last, 0) + at(last - k, last, 0) - 1.0) > 1e-6 ||
          std::abs(at(0, k, 1) + at(0, last - k, 1) - 1.0) > 1e-6 || std::abs(at(last, k, 1) + at(last, last - k, 1) - 1.0) > 1e-6)
        throw representation_error(archive, kSphere, name,
                                   fmt::format("dataset 'sample_uv': boundary sample {} is not at the mirror of its mate", k));
  }
  return image;
}

void write_sphere_layout(h5::Object& object, const DomainImage& layout, bool image_sizes) {
  write_layout_attributes(object, layout);
  if (!image_sizes) return;
  object.set_attribute("faces", layout.faces());
  object.set_attribute("width", layout.width());
  object.set_attribute("height", layout.height());
}

h5::Dims sphere_image_shape(const DomainImage& layout, std::uint64_t channels) { return image_shape(layout, channels); }

SphereRecord read_spherical_record(const Archive& archive, const std::string& name) {
  return read_record(open_representation(archive, kSphere, name));
}

SphereParametrization read_sphere_parametrization(const Archive& archive, const std::string& name) {
  const h5::Group g = open_representation(archive, kSphere, name);
  const h5::Dataset ds = open_item(g, archive, kSphere, name, kSphereItem);
  const h5::Dims shape = ds.shape();
  if (shape.size() != 2 || shape[1] != 3)
    throw representation_error(archive, kSphere, name,
                               fmt::format("dataset '{}' should have shape (V, 3)", kSphereItem));
  if (ds.dtype() != h5::DType::kFloat64)
    throw representation_error(archive, kSphere, name, fmt::format("dataset '{}' is not float64", kSphereItem));
  const auto input_vertices = ds.attribute<std::int64_t>("input_vertices");
  const auto input_faces = ds.attribute_in_range("input_faces", 1, std::int64_t{1} << 32);
  if (input_vertices < 1 || input_faces < 1 || static_cast<std::uint64_t>(input_vertices) > shape[0])
    throw representation_error(archive, kSphere, name,
                               fmt::format("'{}' has {} rows for input_vertices = {}, input_faces = {}", kSphereItem,
                                           shape[0], input_vertices, input_faces));
  SphereParametrization p;
  p.input_vertices = static_cast<std::size_t>(input_vertices);
  p.input_faces = static_cast<std::size_t>(input_faces);
  const std::vector<double> flat = ds.read<double>();
  p.sphere.reserve(flat.size() / 3);
  for (std::size_t v = 0; v < flat.size() / 3; ++v) {
    const Vec3 s(flat[3 * v], flat[3 * v + 1], flat[3 * v + 2]);
    if (!is_unit(s))
      throw representation_error(archive, kSphere, name,
                                 fmt::format("row {} of '{}' is not a unit vector", v, kSphereItem));
    p.sphere.push_back(s);
  }
  return p;
}

std::vector<std::string> spherical_image_names(const Archive& archive) {
  return representation_names(archive, kSphere);
}

}  // namespace gimforge::io
