// write_xdmf_sample OUT.h5: writes an archive with one item of every structured layout docs/archive.md
// describes and its XDMF sidecar OUT.xmf (io/xdmf.h), for check_xdmf.py, which resolves every HDF5
// reference of the sidecar with h5py and checks it describes the datasets exactly.
//
// Contents (float32 positions, value = flat position, so a slab's values identify where it came from):
//   /gim/a           geometry (5, 5, 3), colors (5, 5, 3)
//   /spherical/oct   geometry (5, 5, 3), mask (5, 5), one face (attribute faces = 1)
//   /spherical/cube  geometry (18, 3, 3) with faces = 6 (n = 2): six grids of 3 x 3, mask (18, 3)
//   /batch/gim_4     data (2, 3, 4, 4), mask (2, 1, 4, 4), names "a", "b"
//   /batch/sphere_cube_1  data (1, 3, 12, 2), attribute domain = "cube": six grids of 2 x 2 in item "c"
//   /batch/gim_bad   count 5 for a stack of 2: not described
//   /relief/r        a group with a `distances` dataset: not described
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include "io/archive.h"
#include "io/hdf5.h"
#include "io/xdmf.h"

namespace {

using namespace gimforge;

std::vector<float> ramp(std::size_t n) {
  std::vector<float> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<float>(i);
  return v;
}

void image(h5::Group& g, const std::string& name, const h5::Dims& dims) {
  g.write_dataset(name, dims, ramp(h5::Dataset::product(dims)));
}

void mask(h5::Group& g, const std::string& name, const h5::Dims& dims) {
  g.write_dataset(name, dims, std::vector<std::uint8_t>(h5::Dataset::product(dims), 1));
}

/// The columns every batch output holds beside its stack (docs/archive.md, "Batch archives"): the sidecar
/// describes only outputs the readers accept.
void batch_columns(h5::Group& g, const std::vector<std::string>& names) {
  const auto n = static_cast<std::uint64_t>(names.size());
  g.write_strings("names", names);
  std::vector<std::int64_t> index(n);
  for (std::uint64_t k = 0; k < n; ++k) index[k] = static_cast<std::int64_t>(k);
  g.write_dataset("index", h5::Dims{n}, index);
  g.write_dataset("label_index", h5::Dims{n}, std::vector<std::int32_t>(n, -1));
  g.write_strings("label_names", std::vector<std::string>{});
  h5::Group failed = g.create_group("failed");
  failed.write_strings("names", std::vector<std::string>{});
  g.set_attribute("count", static_cast<std::int64_t>(n));
  g.set_attribute("failed_count", std::int64_t{0});
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: write_xdmf_sample OUT.h5\n");
    return 2;
  }
  try {
    const std::filesystem::path path = argv[1];
    {
      io::Archive archive = io::Archive::create(path, {});
      h5::Group gim = archive.root().create_group("gim/a");
      image(gim, "geometry", {5, 5, 3});
      image(gim, "colors", {5, 5, 3});
      h5::Group oct = archive.root().create_group("spherical/oct");
      image(oct, "geometry", {5, 5, 3});
      oct.open_dataset("geometry").set_attribute("faces", std::int64_t{1});
      mask(oct, "mask", {5, 5});
      h5::Group cube = archive.root().create_group("spherical/cube");
      image(cube, "geometry", {18, 3, 3});
      cube.open_dataset("geometry").set_attribute("faces", std::int64_t{6});
      mask(cube, "mask", {18, 3});
      h5::Group batch = archive.root().create_group("batch/gim_4");
      image(batch, "data", {2, 3, 4, 4});
      mask(batch, "mask", {2, 1, 4, 4});
      batch_columns(batch, {"a", "b"});
      h5::Group cubes = archive.root().create_group("batch/sphere_cube_1");
      image(cubes, "data", {1, 3, 12, 2});
      cubes.set_attribute("domain", "cube");
      batch_columns(cubes, {"c"});
      // Declaring more items than its stack holds: the readers refuse it, and the sidecar leaves it out (a
      // stack declaring 2^40 items made `ls --xdmf` grow without bound).
      h5::Group damaged = archive.root().create_group("batch/gim_bad");
      image(damaged, "data", {2, 3, 4, 4});
      batch_columns(damaged, {"a", "b"});
      damaged.set_attribute("count", std::int64_t{5});
      h5::Group relief = archive.root().create_group("relief/r");
      relief.write_dataset("distances", h5::Dims{1, 2, 2}, std::vector<std::uint16_t>(4, 0));
      archive.close();
    }
    std::printf("%s\n", io::write_xdmf_sidecar(path).c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "write_xdmf_sample: %s\n", e.what());
    return 1;
  }
}
