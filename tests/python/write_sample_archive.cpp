// write_sample_archive OUT.h5: writes a gimforge archive with known contents for check_archive.py, which
// reads it back with h5py (the layout contract of docs/archive.md, checked by an independent reader).
//
// Contents (all under /sample unless noted):
//   /                     archive root attributes (format, format_version, ..., creation_parameters)
//   image_f32             float32 (5, 4, 3), value i * 0.5 at flat index i, chunked + shuffle + gzip
//   image_u16             uint16 (4, 4), value i * 1000, attributes scale = 0.001, offset = -1.0
//   names                 variable-length UTF-8 strings ["alpha", "beta", "gamma"]
//   nested/deeper         group with attribute depth = 2
//   attributes            label = "Zürich ✓", count = 42, ratio = 0.125, doubles = [0.5, 1.5],
//                         ints = [1, -2, 3]
// and /spherical/sample (io/sphere_archive.h): octahedron, n = 2, a (5, 5, 3) geometry image with value
// i * 0.25 at flat index i except sample 12 (the centre), which is undefined (NaN, mask 0); the
// parametrization of an octahedron (6 input vertices, 8 faces, plus one hole centre); source
// "octahedron.ply", psnr = 80.5.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "io/archive.h"
#include "io/sphere_archive.h"

namespace {

void write_spherical_sample(gimforge::io::Archive& archive) {
  using namespace gimforge;
  SphericalImage image;
  image.domain = SphericalDomain::Octahedron;
  image.n = 2;
  for (std::size_t k = 0; k < 25; ++k) {
    image.mask.push_back(k == 12 ? 0 : 1);
    for (std::size_t c = 0; c < 3; ++c)
      image.positions.push_back(k == 12 ? std::nanf("") : static_cast<float>(3 * k + c) * 0.25f);
  }
  io::SphereParametrization p{.sphere = {Vec3::UnitX(), -Vec3::UnitX(), Vec3::UnitY(), -Vec3::UnitY(), Vec3::UnitZ(),
                                         -Vec3::UnitZ(), Vec3(1, 1, 1).normalized()},
                              .input_vertices = 6,
                              .input_faces = 8};
  io::write_spherical_image(archive, "sample", image, p, {.source = "octahedron.ply", .numbers = {{"psnr", 80.5}}});
}

void write_sample(const std::string& path, const std::string& command_line) {
  using namespace gimforge;
  io::Archive archive =
      io::Archive::create(path, {.creator = command_line, .parameters_json = R"({"sample": true, "size": [5, 4]})"});
  h5::Group sample = archive.root().create_group("sample");

  std::vector<float> rgb(5 * 4 * 3);
  for (std::size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<float>(i) * 0.5f;
  io::write_image(sample, "image_f32", {5, 4, 3}, rgb);

  std::vector<std::uint16_t> quantized(4 * 4);
  for (std::size_t i = 0; i < quantized.size(); ++i) quantized[i] = static_cast<std::uint16_t>(i * 1000);
  io::write_quantized_image(sample, "image_u16", {4, 4}, quantized, 0.001, -1.0);

  sample.write_strings("names", std::vector<std::string>{"alpha", "beta", "gamma"});
  sample.create_group("nested/deeper").set_attribute("depth", 2);

  sample.set_attribute("label", "Zürich ✓");
  sample.set_attribute("count", 42);
  sample.set_attribute("ratio", 0.125);
  sample.set_attribute("doubles", std::vector<double>{0.5, 1.5});
  sample.set_attribute("ints", std::vector<std::int64_t>{1, -2, 3});
  write_spherical_sample(archive);
  archive.close();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: write_sample_archive OUT.h5\n");
    return 2;
  }
  try {
    write_sample(argv[1], std::string(argv[0]) + " " + argv[1]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "write_sample_archive: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
