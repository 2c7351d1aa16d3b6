// Tests of the representation groups in the archive: spherical geometry images (io/sphere_archive.h) and
// the geometry images that share the record and naming helpers with them (io/gim_archive.h).
#include <gtest/gtest.h>

#include "io/printable.h"
#include <hdf5.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "io/gim_archive.h"
#include "io/sphere_archive.h"
#include "kernels/core/errors.h"
#include "tests/unit/test_support.h"

namespace fs = std::filesystem;
using namespace gimforge;
using gimforge::test::message_of;

namespace {

class SphereArchiveTest : public gimforge::test::ScratchDirTest {};

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

/// A spherical image of `domain` at tessellation n whose samples are their domain points, with every
/// seventh sample masked (NaN) and, with `colors`, a colour per sample.
SphericalImage sample_image(SphericalDomain domain, std::uint32_t n, bool colors) {
  SphericalImage image;
  image.domain = domain;
  image.n = n;
  const DomainImage layout = image.layout();
  const std::vector<Vec3> points = domain_positions(layout, DomainEmbedding::Polyhedron);
  for (std::size_t k = 0; k < points.size(); ++k) {
    const bool hole = k % 7 == 3;
    image.mask.push_back(hole ? 0 : 1);
    for (int c = 0; c < 3; ++c) {
      image.positions.push_back(hole ? kNaN : static_cast<float>(points[k][c]));
      if (colors) image.colors.push_back(static_cast<float>((k + static_cast<std::size_t>(c)) % 11) / 10.0f);
    }
  }
  return image;
}

/// Unit vectors for `vertices` input vertices plus `holes` hole centres.
io::SphereParametrization sample_parametrization(std::size_t vertices, std::size_t holes) {
  io::SphereParametrization p;
  p.input_vertices = vertices;
  p.input_faces = vertices >= 2 ? 2 * vertices - 4 : 0;
  for (std::size_t v = 0; v < vertices + holes; ++v) {
    const double t = static_cast<double>(v) * 0.7;
    p.sphere.push_back(Vec3(std::cos(t), std::sin(t), 0.3 * static_cast<double>(v % 3)).normalized());
  }
  return p;
}

io::SphereRecord sample_record() {
  return {.source = "meshes/fist.ply",
          .numbers = {{"psnr", 71.25}, {"domain_efficiency", 0.969}, {"holes_filled", 2.0}, {"seconds_total", 1.5}}};
}

/// Positions equal, NaN where expected (NaN != NaN, so compare bit patterns of the finite ones only).
void expect_same_positions(const std::vector<float>& got, const std::vector<float>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    if (std::isnan(want[i]))
      EXPECT_TRUE(std::isnan(got[i])) << "value " << i;
    else
      EXPECT_EQ(got[i], want[i]) << "value " << i;
  }
}

TEST_F(SphereArchiveTest, EveryDomainRoundTripsWithNaNMaskColorsAndParametrization) {
  const fs::path path = file("s.h5");
  {
    io::Archive a = io::Archive::create(path, {});
    for (const SphericalDomain d : kSphericalDomains) {
      const std::string name = std::string(to_string(d)) + "_img";
      io::write_spherical_image(a, name, sample_image(d, 3, d == SphericalDomain::Cube), sample_parametrization(12, 2),
                                sample_record());
    }
    a.close();
  }
  const io::Archive a = io::Archive::open(path);
  EXPECT_EQ(io::spherical_image_names(a),
            (std::vector<std::string>{"cube_img", "flat-octa_img", "octa_img", "tetra_img"}));
  EXPECT_TRUE(io::geometry_image_names(a).empty());
  for (const SphericalDomain d : kSphericalDomains) {
    const std::string name = std::string(to_string(d)) + "_img";
    const SphericalImage want = sample_image(d, 3, d == SphericalDomain::Cube);
    const SphericalImage got = io::read_spherical_image(a, name);
    EXPECT_EQ(got.domain, d);
    EXPECT_EQ(got.n, 3u);
    expect_same_positions(got.positions, want.positions);
    EXPECT_EQ(got.mask, want.mask);
    EXPECT_EQ(got.colors, want.colors);

    // The layout promised by docs/archive.md.
    const DomainImage layout = want.layout();
    const auto rows = static_cast<std::uint64_t>(layout.faces() * layout.height());
    const auto width = static_cast<std::uint64_t>(layout.width());
    const h5::Group g = a.root().open_group("spherical/" + name);
    EXPECT_EQ(g.open_dataset("geometry").shape(), (h5::Dims{rows, width, 3}));
    EXPECT_EQ(g.open_dataset("geometry").dtype(), h5::DType::kFloat32);
    EXPECT_EQ(g.open_dataset("mask").shape(), (h5::Dims{rows, width}));
    EXPECT_EQ(g.open_dataset("mask").dtype(), h5::DType::kUInt8);
    EXPECT_EQ(g.open_dataset("geometry").attribute<std::int64_t>("faces"), layout.faces());
    EXPECT_EQ(g.attribute<std::string>("method"), "sphere");
    EXPECT_EQ(g.attribute<std::string>("domain"), to_string(d));
    EXPECT_EQ(g.attribute<std::int64_t>("n"), 3);

    const io::SphereRecord record = io::read_spherical_record(a, name);
    EXPECT_EQ(record.source, "meshes/fist.ply");
    EXPECT_EQ(record.numbers, sample_record().numbers) << "n and the strings are structural, not record numbers";

    const io::SphereParametrization p = io::read_sphere_parametrization(a, name);
    const io::SphereParametrization want_p = sample_parametrization(12, 2);
    EXPECT_EQ(p.input_vertices, 12u);
    EXPECT_EQ(p.input_faces, 20u);
    ASSERT_EQ(p.sphere.size(), 14u);
    for (std::size_t v = 0; v < p.sphere.size(); ++v) EXPECT_EQ(p.sphere[v], want_p.sphere[v]) << "vertex " << v;
    EXPECT_FALSE(g.open_dataset("parametrization/sphere").attribute<std::string>("vertex_order").empty());
  }
}

TEST_F(SphereArchiveTest, MissingImagesAndNamesAreClearErrors) {
  const fs::path path = file("m.h5");
  {
    io::Archive a = io::Archive::create(path, {});
    io::write_spherical_image(a, "fist", sample_image(SphericalDomain::Octahedron, 2, false),
                              sample_parametrization(6, 0), sample_record());
    a.close();
  }
  const io::Archive a = io::Archive::open(path);
  std::string msg = message_of<FormatError>([&] { (void)io::read_spherical_image(a, "bunny"); });
  EXPECT_EQ(msg, path.string() + ": no spherical geometry image 'bunny' (has: fist)");
  msg = message_of<FormatError>([&] { (void)io::read_sphere_parametrization(a, "bunny"); });
  EXPECT_NE(msg.find("no spherical geometry image 'bunny'"), std::string::npos) << msg;
  msg = message_of<FormatError>([&] { (void)io::read_spherical_record(a, "bunny"); });
  EXPECT_NE(msg.find("no spherical geometry image 'bunny'"), std::string::npos) << msg;
  for (const std::string bad : {"", "a/b", ".", ".."}) {
    msg = message_of<InvalidInput>([&] { (void)io::read_spherical_image(a, bad); });
    EXPECT_EQ(msg, "invalid spherical geometry image name '" + bad + "': it " + io::path_component_problem(bad) +
                       " (non-empty, not '.' or '..', no '/' or control characters, at most 255 bytes)");
  }
  msg = message_of<FormatError>([&] { (void)io::read_geometry_image(a, "fist"); });
  EXPECT_EQ(msg, path.string() + ": no geometry image 'fist' (it holds no geometry image)");
}

TEST_F(SphereArchiveTest, WritingRefusesBadNamesSizesAndTakenNames) {
  io::Archive a = io::Archive::create(file("w.h5"), {});
  const SphericalImage good = sample_image(SphericalDomain::Tetrahedron, 2, false);
  const auto p = sample_parametrization(6, 1);
  EXPECT_THROW(io::write_spherical_image(a, "x/y", good, p, sample_record()), InvalidInput);
  SphericalImage short_mask = good;
  short_mask.mask.pop_back();
  std::string msg =
      message_of<InvalidInput>([&] { io::write_spherical_image(a, "s", short_mask, p, sample_record()); });
  EXPECT_NE(msg.find("mask hold"), std::string::npos) << msg;
  SphericalImage bad_mask = good;
  bad_mask.mask[1] = 2;
  EXPECT_THROW(io::write_spherical_image(a, "s", bad_mask, p, sample_record()), InvalidInput);
  SphericalImage nan_defined = good;
  nan_defined.mask[3] = 1;
  msg = message_of<InvalidInput>([&] { io::write_spherical_image(a, "s", nan_defined, p, sample_record()); });
  EXPECT_EQ(msg, "spherical geometry image 's': defined sample 3 is not finite");
  SphericalImage bad_colors = good;
  bad_colors.colors.assign(5, 0.5f);
  EXPECT_THROW(io::write_spherical_image(a, "s", bad_colors, p, sample_record()), InvalidInput);
  EXPECT_THROW(io::write_spherical_image(a, "s", good, sample_parametrization(0, 2), sample_record()), InvalidInput);
  io::SphereParametrization not_unit = p;
  not_unit.sphere[2] *= 2.0;
  msg = message_of<InvalidInput>([&] { io::write_spherical_image(a, "s", good, not_unit, sample_record()); });
  EXPECT_EQ(msg, "spherical geometry image 's': vertex 2 of the parametrization is not a unit vector");
  io::SphereParametrization too_few = p;
  too_few.input_vertices = 99;
  EXPECT_THROW(io::write_spherical_image(a, "s", good, too_few, sample_record()), InvalidInput);
  EXPECT_FALSE(a.root().exists("spherical")) << "nothing is written for refused input";
  io::SphereRecord clash = sample_record();
  clash.numbers["domain"] = 1.0;
  msg = message_of<InvalidInput>([&] { io::write_spherical_image(a, "clash", good, p, clash); });
  EXPECT_EQ(msg, "record number 'domain' would overwrite the attribute of that name");
  EXPECT_FALSE(a.root().exists("spherical/clash"));
  io::write_spherical_image(a, "s", good, p, sample_record());
  EXPECT_THROW(io::write_spherical_image(a, "s", good, p, sample_record()), LibraryError);
}

/// Writes one valid image "fist", then lets `damage` change the file, and returns the FormatError message of
/// reading the image (or the parametrization, with `parametrization`).
class DamagedArchiveTest : public SphereArchiveTest {
 protected:
  template <class F>
  std::string read_error(F damage, bool parametrization = false) {
    const fs::path path = file("d.h5");
    {
      io::Archive a = io::Archive::create(path, {});
      io::write_spherical_image(a, "fist", sample_image(SphericalDomain::Octahedron, 2, true),
                                sample_parametrization(6, 1), sample_record());
      h5::Group g = a.root().open_group("spherical/fist");
      damage(g);
      a.close();
    }
    const io::Archive a = io::Archive::open(path);
    return message_of<FormatError>([&] {
      if (parametrization)
        (void)io::read_sphere_parametrization(a, "fist");
      else
        (void)io::read_spherical_image(a, "fist");
    });
  }
  static void remove(h5::Group& g, const char* item) { ASSERT_GE(H5Ldelete(g.id(), item, H5P_DEFAULT), 0); }
  /// A damage that replaces image `item` by one of `shape` holding `values`.
  template <class T>
  static auto replace(const char* item, h5::Dims shape, std::vector<T> values) {
    return [=](h5::Group& g) {
      remove(g, item);
      io::write_image(g, item, shape, values);
    };
  }
};

TEST_F(DamagedArchiveTest, MissingDatasetsNameTheArchiveImageAndItem) {
  const std::string prefix = file("d.h5").string() + ": spherical geometry image 'fist': ";
  EXPECT_EQ(read_error([](h5::Group& g) { remove(g, "geometry"); }), prefix + "no dataset 'geometry'");
  EXPECT_EQ(read_error([](h5::Group& g) { remove(g, "mask"); }), prefix + "no dataset 'mask'");
  EXPECT_EQ(read_error([](h5::Group& g) { remove(g, "parametrization/sphere"); }, true),
            prefix + "no dataset 'parametrization/sphere'");
  EXPECT_EQ(read_error([](h5::Group& g) {
              remove(g, "mask");
              g.create_group("mask");
            }),
            prefix + "'mask' is not a dataset");
}

TEST_F(DamagedArchiveTest, InconsistentContentsAreFormatErrors) {
  const std::string prefix = file("d.h5").string() + ": spherical geometry image 'fist': ";
  EXPECT_EQ(read_error(replace("mask", {5, 4}, std::vector<std::uint8_t>(20, 1))),
            prefix + "dataset 'mask' has shape (5, 4), expected (5, 5)");
  EXPECT_EQ(read_error(replace("mask", {5, 5}, std::vector<std::uint8_t>(25, 1))),
            prefix + "defined sample 3 is not finite");
  std::vector<std::uint8_t> mask(25, 1);
  mask[3] = mask[10] = mask[17] = mask[24] = 0;  // the NaN samples of sample_image
  mask[0] = 0;
  EXPECT_EQ(read_error(replace("mask", {5, 5}, mask)), prefix + "masked sample 0 is not NaN");
  mask[0] = 2;
  EXPECT_EQ(read_error(replace("mask", {5, 5}, mask)), prefix + "mask of sample 0 is 2 (expected 0 or 1)");
  EXPECT_EQ(read_error(replace("mask", {5, 5}, std::vector<std::uint16_t>(25, 1))), prefix + "mask is not uint8");
  EXPECT_EQ(read_error(replace("colors", {5, 5}, std::vector<float>(25, 0.5f))),
            prefix + "dataset 'colors' has shape (5, 5), expected (5, 5, 3)");
  EXPECT_EQ(read_error([](h5::Group& g) { g.set_attribute("domain", "dodeca"); }),
            prefix + "unknown domain 'dodeca' (known: octa, tetra, cube, flat-octa)");
  EXPECT_EQ(read_error([](h5::Group& g) { g.set_attribute("n", 0); }), prefix + "tessellation n = 0 is out of range");
  EXPECT_EQ(read_error([](h5::Group& g) { g.set_attribute("n", 3); }),
            prefix + "dataset 'geometry' has shape (5, 5, 3), expected (7, 7, 3)");
  EXPECT_EQ(read_error([](h5::Group& g) { g.set_attribute("method", "gim"); }),
            prefix + "method is 'gim', expected 'sphere'");
  EXPECT_NE(read_error([](h5::Group& g) { g.open_dataset("geometry").set_attribute("faces", 6); }).find("faces = 6"),
            std::string::npos);
  const std::string missing = read_error([](h5::Group& g) { ASSERT_GE(H5Adelete(g.id(), "domain"), 0); });
  EXPECT_NE(missing.find("has no attribute 'domain'"), std::string::npos) << missing;
  EXPECT_EQ(read_error([](h5::Group& g) {
              h5::Dataset s = g.open_dataset("parametrization/sphere");
              s.write(std::vector<double>(21, 0.5));
            }, true),
            prefix + "row 0 of 'parametrization/sphere' is not a unit vector");
  EXPECT_EQ(read_error(
                [](h5::Group& g) { g.open_dataset("parametrization/sphere").set_attribute("input_vertices", 8); }, true),
            prefix + "'parametrization/sphere' has 7 rows for input_vertices = 8, input_faces = 8");
}

TEST_F(SphereArchiveTest, GeometryImagesShareTheRecordAndNaming) {
  GeometryImage image;
  image.size = 65;
  image.positions.resize(65 * 65 * 3);
  for (std::size_t i = 0; i < image.positions.size(); ++i) image.positions[i] = static_cast<float>(i % 97) * 0.25f;
  image.sideband.paths = {{1, 0, 128}, {-1, 128, 128}};
  io::GimRecord record{.source = "kitten.ply", .numbers = {{"psnr", 66.5}, {"cut_edges", 12.0}}};
  {
    io::Archive a = io::Archive::create(file("g.h5"), {});
    io::write_geometry_image(a, "kitten", image, record);
    io::write_spherical_image(a, "kitten", sample_image(SphericalDomain::Cube, 1, false), sample_parametrization(4, 0),
                              sample_record());
    a.close();
  }
  const io::Archive a = io::Archive::open(file("g.h5"));
  EXPECT_EQ(io::geometry_image_names(a), std::vector<std::string>{"kitten"});
  EXPECT_EQ(io::spherical_image_names(a), std::vector<std::string>{"kitten"});
  const GeometryImage got = io::read_geometry_image(a, "kitten");
  EXPECT_EQ(got.size, 65u);
  EXPECT_EQ(got.positions, image.positions);
  EXPECT_EQ(got.normal_size, 0u);
  ASSERT_EQ(got.sideband.paths.size(), 2u);
  EXPECT_EQ(got.sideband.paths[1].label, -1);
  EXPECT_EQ(io::read_gim_record(a, "kitten").numbers, record.numbers);
  EXPECT_EQ(io::read_gim_record(a, "kitten").source, "kitten.ply");
  EXPECT_EQ(io::read_spherical_image(a, "kitten").domain, SphericalDomain::Cube);
}

}  // namespace
