// Hostile archives (issue #15): archives come from other people, so every reader must refuse, with one
// clear error naming the file and the item, what would disclose other files (external raw storage,
// external and soft links, virtual datasets), what cannot be decoded (LZF and other unknown filters),
// integers that would crash or overflow arithmetic and allocations, and NaN / Inf / absurd values.
// Each test builds a valid archive with the writers, damages it with the HDF5 C API and calls the reader.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "io/batch_archive.h"
#include "io/batch_shard.h"
#include "io/gim_archive.h"
#include "io/hdf5_storage.h"
#include "io/relief_archive.h"
#include "io/sphere_archive.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/relief/relief_map.h"
#include "kernels/sphere/spherical_domain.h"
#include "tests/unit/test_support.h"

namespace fs = std::filesystem;
using namespace gimforge;
using gimforge::test::message_of;

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr const char* kSecret = "root:x:0:0:secret line of another file that must never reach an output\n";

/// Fails unless `msg` contains every part.
void expect_contains(const std::string& msg, std::initializer_list<std::string_view> parts) {
  for (const std::string_view part : parts)
    EXPECT_NE(msg.find(part), std::string::npos) << "message: " << msg << "\nmissing: " << part;
}

hid_t h5_type_of(const std::vector<float>&) { return H5T_NATIVE_FLOAT; }
hid_t h5_type_of(const std::vector<double>&) { return H5T_NATIVE_DOUBLE; }
hid_t h5_type_of(const std::vector<std::int32_t>&) { return H5T_NATIVE_INT32; }
hid_t h5_type_of(const std::vector<std::uint8_t>&) { return H5T_NATIVE_UINT8; }
hid_t h5_type_of(const std::vector<std::uint16_t>&) { return H5T_NATIVE_UINT16; }

/// Dataset `name` of `g`, deleted and created again with storage `dcpl` (H5P_DEFAULT: contiguous),
/// `dims` and `values` (not written when empty).
template <class T>
void recreate(hid_t g, const char* name, std::vector<hsize_t> dims, const std::vector<T>& values,
              hid_t dcpl = H5P_DEFAULT, hid_t file_type = -1) {
  if (H5Lexists(g, name, H5P_DEFAULT) > 0) {
    ASSERT_GE(H5Ldelete(g, name, H5P_DEFAULT), 0);
  }
  const hid_t space = H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
  const hid_t type = file_type >= 0 ? file_type : h5_type_of(values);
  const hid_t ds = H5Dcreate2(g, name, type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
  ASSERT_GE(ds, 0) << name;
  if (!values.empty()) {
    ASSERT_GE(H5Dwrite(ds, h5_type_of(values), H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
  }
  H5Dclose(ds);
  H5Sclose(space);
}

/// Replaces `name` by a dataset of `dims` float32 whose raw data lies in `raw` (external storage).
void make_external_storage(hid_t g, const char* name, std::vector<hsize_t> dims, const fs::path& raw) {
  std::ofstream(raw, std::ios::binary) << std::string(1 << 16, 'x').replace(0, std::string_view(kSecret).size(), kSecret);
  const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
  ASSERT_GE(H5Pset_external(dcpl, raw.c_str(), 0, H5F_UNLIMITED), 0);
  recreate(g, name, dims, std::vector<float>{}, dcpl, H5T_IEEE_F32LE);
  H5Pclose(dcpl);
}

/// Replaces `name` by a virtual dataset of `dims` float32 mapping the whole of `source`:/source.
void make_virtual(hid_t g, const char* name, std::vector<hsize_t> dims, const fs::path& source) {
  {
    const hid_t f = H5Fcreate(source.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    std::size_t n = 1;
    for (const hsize_t d : dims) n *= d;
    recreate(f, "source", dims, std::vector<float>(n, 1.0f));
    H5Fclose(f);
  }
  const hid_t space = H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
  const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
  ASSERT_GE(H5Pset_virtual(dcpl, space, source.c_str(), "/source", space), 0);
  recreate(g, name, dims, std::vector<float>{}, dcpl, H5T_IEEE_F32LE);
  H5Pclose(dcpl);
  H5Sclose(space);
}

/// Replaces `name` by a chunked copy of `values` whose pipeline holds filter `filter` (optional, so
/// HDF5 creates it even though no such filter is registered: what h5py's LZF leaves for other readers).
template <class T>
void make_filtered(hid_t g, const char* name, std::vector<hsize_t> dims, const std::vector<T>& values,
                   H5Z_filter_t filter = 32000) {
  const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
  ASSERT_GE(H5Pset_chunk(dcpl, static_cast<int>(dims.size()), dims.data()), 0);
  ASSERT_GE(H5Pset_filter(dcpl, filter, H5Z_FLAG_OPTIONAL, 0, nullptr), 0);
  recreate(g, name, dims, values, dcpl);
  H5Pclose(dcpl);
}

void make_soft(hid_t g, const char* name, const char* target) {
  if (H5Lexists(g, name, H5P_DEFAULT) > 0) {
    ASSERT_GE(H5Ldelete(g, name, H5P_DEFAULT), 0);
  }
  ASSERT_GE(H5Lcreate_soft(target, g, name, H5P_DEFAULT, H5P_DEFAULT), 0);
}

void make_external_link(hid_t g, const char* name, const fs::path& file, const char* object) {
  if (H5Lexists(g, name, H5P_DEFAULT) > 0) {
    ASSERT_GE(H5Ldelete(g, name, H5P_DEFAULT), 0);
  }
  ASSERT_GE(H5Lcreate_external(file.c_str(), object, g, name, H5P_DEFAULT, H5P_DEFAULT), 0);
}

/// Writes integer attribute `key` of object `path` of `f` with any HDF5 integer type (e.g. uint64).
void set_uint64_attribute(hid_t obj, const char* key, std::uint64_t value) {
  if (H5Aexists(obj, key) > 0) {
    ASSERT_GE(H5Adelete(obj, key), 0);
  }
  const hid_t space = H5Screate(H5S_SCALAR);
  const hid_t a = H5Acreate2(obj, key, H5T_STD_U64LE, space, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(H5Awrite(a, H5T_NATIVE_UINT64, &value), 0);
  H5Aclose(a);
  H5Sclose(space);
}

/// One archive per test: `build` writes it, `damage(group)` edits representation group `group_path`,
/// `read` reads it back; errors are gimforge::Error (FormatError mostly) with the file's path first.
class HostileArchiveTest : public gimforge::test::ScratchDirTest {
 protected:
  using Damage = std::function<void(h5::Group&)>;

  /// Builds the archive afresh, applies `damage` to `group_path` and returns the reader's error message.
  std::string error_after(const Damage& damage) {
    const fs::path path = file("a.h5");
    build(path);
    {
      h5::File f = h5::File::open(path, h5::OpenMode::kReadWrite);
      h5::Group g = f.open_group(group_path_);
      damage(g);
    }
    return message_of<Error>([&] { read(path); });
  }
  /// The error for `damage`, checked to start with the archive's path and to contain `parts`.
  void expect_refused(const Damage& damage, std::initializer_list<std::string_view> parts) {
    const std::string msg = error_after(damage);
    EXPECT_EQ(msg.rfind(file("a.h5").string(), 0), 0u) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    expect_contains(msg, parts);
  }

  virtual void build(const fs::path& path) = 0;
  virtual void read(const fs::path& path) = 0;
  std::string group_path_;
};

// ---- geometry images ----------------------------------------------------------------------------

/// A 9 × 9 geometry image with 2 units per side (paths +1 and −1 of 4 units), a 5 × 5 normal map and
/// colours.
class HostileGim : public HostileArchiveTest {
 protected:
  HostileGim() { group_path_ = "gim/g"; }
  void build(const fs::path& path) override {
    GeometryImage image;
    image.size = 9;
    for (std::size_t k = 0; k < 9 * 9 * 3; ++k) image.positions.push_back(static_cast<float>(k % 13) * 0.5f);
    image.normal_size = 5;
    image.normals.assign(5 * 5 * 3, 0.0f);
    for (std::size_t k = 2; k < image.normals.size(); k += 3) image.normals[k] = 1.0f;
    image.color_size = 9;
    image.colors.assign(9 * 9 * 3, 0.5f);
    image.sideband.units_per_side = 2;
    image.sideband.paths = {{1, 0, 4}, {-1, 4, 4}};
    io::Archive a = io::Archive::create(path, {});
    io::write_geometry_image(a, "g", image, {.source = "g.ply", .numbers = {{"psnr", 60.0}}});
    a.close();
  }
  void read(const fs::path& path) override { (void)io::read_geometry_image(io::Archive::open(path), "g"); }
  static std::vector<float> image_with(std::size_t count, float value) {
    std::vector<float> v(9 * 9 * 3, 0.25f);
    for (std::size_t k = 0; k < count; ++k) v[k] = value;
    return v;
  }
};

TEST_F(HostileGim, TheUndamagedArchiveReads) {
  build(file("a.h5"));
  const GeometryImage image = io::read_geometry_image(io::Archive::open(file("a.h5")), "g");
  EXPECT_EQ(image.size, 9u);
  EXPECT_EQ(image.sideband.units_per_side, 2u);
}

TEST_F(HostileGim, ExternalRawStorageIsRefusedAndNothingOfTheOtherFileIsRead) {
  const fs::path raw = file("passwd");
  expect_refused([&](h5::Group& g) { make_external_storage(g.id(), "geometry", {9, 9, 3}, raw); },
                 {"/gim/g/geometry", "external file", raw.string()});
  const std::string msg = error_after([&](h5::Group& g) { make_external_storage(g.id(), "geometry", {9, 9, 3}, raw); });
  EXPECT_EQ(msg.find("root:x"), std::string::npos) << msg;
}

TEST_F(HostileGim, ExternalAndSoftLinksAreNotFollowed) {
  const fs::path other = file("other.h5");
  build(other);
  expect_refused([&](h5::Group& g) { make_external_link(g.id(), "geometry", other, "/gim/g/geometry"); },
                 {"/gim/g/geometry", "is an external link", "other.h5", "follows only hard links"});
  expect_refused([&](h5::Group& g) { make_soft(g.id(), "geometry", "/gim/g/colors"); },
                 {"/gim/g/geometry is a soft link (to '/gim/g/colors')"});
  expect_refused([&](h5::Group& g) { make_soft(g.id(), "normals", "/gim/g/colors"); }, {"/gim/g/normals", "soft link"});
}

TEST_F(HostileGim, AGroupReachedThroughALinkIsRefused) {
  const fs::path other = file("other.h5");
  build(other);
  build(file("a.h5"));
  {
    h5::File f = h5::File::open(file("a.h5"), h5::OpenMode::kReadWrite);
    h5::Group gim = f.open_group("gim");
    make_external_link(gim.id(), "far", other, "/gim/g");
    make_soft(gim.id(), "near", "/gim/g");
  }
  const io::Archive a = io::Archive::open(file("a.h5"));
  expect_contains(message_of<FormatError>([&] { (void)io::read_geometry_image(a, "far"); }),
                  {"/gim/far is an external link", "follows only hard links"});
  expect_contains(message_of<FormatError>([&] { (void)io::read_geometry_image(a, "near"); }),
                  {"/gim/near is a soft link (to '/gim/g')"});
}

TEST_F(HostileGim, VirtualDatasetsAreRefused) {
  expect_refused([&](h5::Group& g) { make_virtual(g.id(), "geometry", {9, 9, 3}, file("source.h5")); },
                 {"/gim/g/geometry", "virtual dataset"});
}

TEST_F(HostileGim, UnknownFiltersAreNamedWithTheirCure) {
  expect_refused([](h5::Group& g) { make_filtered(g.id(), "geometry", {9, 9, 3}, image_with(0, 0.0f)); },
                 {"dataset /gim/g/geometry uses compression filter 32000 (lzf) which gimforge cannot read; rewrite it "
                  "with gzip or none"});
  expect_refused([](h5::Group& g) { make_filtered(g.id(), "geometry", {9, 9, 3}, image_with(0, 0.0f), 32015); },
                 {"filter 32015 (zstd)"});
  expect_refused([](h5::Group& g) { make_filtered(g.id(), "geometry", {9, 9, 3}, image_with(0, 0.0f), 31999); },
                 {"filter 31999 (unknown)"});
}

TEST_F(HostileGim, UnitsPerSideOutOfRangeIsAnErrorNotASignal) {
  for (const std::int64_t bad : {std::int64_t{0}, std::int64_t{-3}, std::int64_t{1} << 62, std::int64_t{1} << 21})
    expect_refused([&](h5::Group& g) { g.set_attribute("units_per_side", bad); },
                   {"/gim/g: attribute units_per_side = " + std::to_string(bad) + " is outside [1, 2^20]"});
  expect_refused([](h5::Group& g) { set_uint64_attribute(g.id(), "units_per_side", (std::uint64_t{1} << 63) + 5); },
                 {"attribute units_per_side = 9223372036854775813 is outside [1, 2^20]"});
  expect_refused([](h5::Group& g) { g.set_attribute("units_per_side", 3); },
                 {"n - 1 is not a multiple of units_per_side = 3"});
  expect_refused([](h5::Group& g) { g.set_attribute("units_per_side", "64"); }, {"units_per_side", "is a string"});
}

TEST_F(HostileGim, NonFiniteSamplesAreRefused) {
  expect_refused([](h5::Group& g) { recreate(g.id(), "geometry", {9, 9, 3}, image_with(243, kNaN)); },
                 {"sample 0 of dataset 'geometry' is nan"});
  expect_refused([](h5::Group& g) { recreate(g.id(), "geometry", {9, 9, 3}, image_with(243, kInf)); },
                 {"sample 0 of dataset 'geometry' is inf"});
  std::vector<float> half = image_with(0, 0.0f);
  for (std::size_t k = 120; k < half.size(); ++k) half[k] = kNaN;
  expect_refused([&](h5::Group& g) { recreate(g.id(), "geometry", {9, 9, 3}, half); },
                 {"sample 40 of dataset 'geometry' is nan"});
  std::vector<float> normals(75, 0.0f);
  normals[7] = -kInf;
  expect_refused([&](h5::Group& g) { recreate(g.id(), "normals", {5, 5, 3}, normals); },
                 {"sample 2 of dataset 'normals' is -inf"});
  expect_refused([](h5::Group& g) { recreate(g.id(), "colors", {9, 9, 3}, image_with(5, kNaN)); },
                 {"dataset 'colors' is nan"});
}

TEST_F(HostileGim, ANameLongerThanAFileNameStillReadsButIsNotWritten) {
  // An earlier gimforge wrote any length; only new names are held to 255 bytes (a file name: preview's).
  build(file("a.h5"));
  const std::string long_name(300, 'g');
  {
    const hid_t f = H5Fopen(file("a.h5").c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    ASSERT_GE(H5Lcreate_hard(f, "gim/g", f, ("gim/" + long_name).c_str(), H5P_DEFAULT, H5P_DEFAULT), 0);
    H5Fclose(f);
  }
  io::Archive a = io::Archive::open(file("a.h5"), h5::OpenMode::kReadWrite);
  EXPECT_EQ(io::read_geometry_image(a, long_name).size, 9u);
  const GeometryImage image = io::read_geometry_image(a, "g");
  EXPECT_NE(message_of<InvalidInput>([&] { io::write_geometry_image(a, long_name + "x", image, {}); })
                .find("is 301 bytes long"),
            std::string::npos);
}

TEST_F(HostileGim, AFloatImageWithQuantizationAttributesIsRefused) {
  // A 12-bit image rewritten as float32, its attributes kept: read as coordinates 0..4095, silently.
  expect_refused([](h5::Group& g) { g.open_dataset("geometry").set_attribute("bits", std::int64_t{12}); },
                 {"dataset 'geometry' is float32 but carries the quantization attribute 'bits'"});
}

TEST_F(HostileGim, WrongShapesTypesAndSizesAreRefused) {
  expect_refused([](h5::Group& g) { recreate(g.id(), "geometry", {9, 8, 3}, std::vector<float>(216, 0.0f)); },
                 {"dataset 'geometry' should have shape (n, n, 3)"});
  expect_refused([](h5::Group& g) { recreate(g.id(), "geometry", {9, 9, 3}, std::vector<double>(243, 0.0)); },
                 {"dataset 'geometry' is neither float32 nor quantized uint16"});
  // Quantized positions (compress --codec quant12/quant16) need their dequantization attributes.
  expect_refused([](h5::Group& g) { recreate(g.id(), "geometry", {9, 9, 3}, std::vector<std::uint16_t>(243, 7)); },
                 {"dataset 'geometry': quantized without 'scale' and 'offset'"});
  expect_refused([](h5::Group& g) { recreate(g.id(), "colors", {5, 5, 3}, std::vector<float>(75, 0.5f)); },
                 {"dataset 'colors' is 5x5, the geometry 9x9"});
  expect_refused([](h5::Group& g) { g.set_attribute("size", 17); }, {"attribute size = 17 disagrees"});
  expect_refused([](h5::Group& g) { g.set_attribute("normal_size", 512); }, {"attribute normal_size = 512 disagrees"});
  // Extents declared in the file cost nothing there: a huge image is refused before any allocation.
  expect_refused(
      [](h5::Group& g) {
        const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
        const std::vector<hsize_t> chunk{1, 1, 3};
        H5Pset_chunk(dcpl, 3, chunk.data());
        recreate(g.id(), "geometry", {1u << 20, 1u << 20, 3}, std::vector<float>{}, dcpl, H5T_IEEE_F32LE);
        H5Pclose(dcpl);
      },
      {"dataset 'geometry' has side 1048576, outside [2, 16385]"});
}

TEST_F(HostileGim, SidebandRowsOutOfRangeAreRefused) {
  const auto sideband = [](std::vector<std::int32_t> rows, std::vector<hsize_t> dims = {}) {
    if (dims.empty()) dims = {rows.size() / 3, 3};
    return [rows, dims](h5::Group& g) { recreate(g.id(), "sideband", dims, rows); };
  };
  constexpr std::int32_t kMin = std::numeric_limits<std::int32_t>::min();
  expect_refused(sideband({1, -1, 4, -1, 4, 4}), {"sideband row 0 (label 1, start_unit -1, units 4)"});
  expect_refused(sideband({1, 0, 0, -1, 4, 4}), {"sideband row 0", "units 0"});
  expect_refused(sideband({1, 0, 1000000000, -1, 4, 4}), {"units 1000000000"});
  expect_refused(sideband({kMin, 0, 4, -1, 4, 4}), {"label -2147483648"});
  expect_refused(sideband({1, 0, 4, 1, 4, 4}), {"label 1 has no unique mate"});
  expect_refused(sideband({1, 0, 3, -1, 3, 3}), {"paths cover 6 of 8 perimeter units"});
  expect_refused(sideband({1, 0, 4, -1, 5, 4}), {"path 1 does not start where path 0 ends"});
  expect_refused(sideband({1, 0, 4, -1, 4, 4, 0, 0}, {2, 4}), {"sideband is not a (q, 3) table"});
  expect_refused(sideband(std::vector<std::int32_t>(30, 0)), {"sideband has 10 paths, outside [1, 8]"});
  expect_refused([](h5::Group& g) { recreate(g.id(), "sideband", {2, 3}, std::vector<float>{1, 0, 4, -1, 4, 4}); },
                 {"sideband is not int32"});
}

// ---- spherical geometry images ------------------------------------------------------------------

/// An octahedral spherical image at n = 2 (5 × 5 samples on the unit sphere), with colours and its
/// parametrization.
class HostileSphere : public HostileArchiveTest {
 protected:
  HostileSphere() { group_path_ = "spherical/s"; }
  void build(const fs::path& path) override {
    SphericalImage image;
    image.domain = SphericalDomain::Octahedron;
    image.n = 2;
    const std::vector<Vec3> points = domain_positions(image.layout(), DomainEmbedding::Polyhedron);
    for (const Vec3& p : points) {
      image.mask.push_back(1);
      for (int c = 0; c < 3; ++c) {
        image.positions.push_back(static_cast<float>(p[c]));
        image.colors.push_back(0.5f);
      }
    }
    io::SphereParametrization param;
    param.input_vertices = 6;
    param.input_faces = 8;
    for (int v = 0; v < 6; ++v) param.sphere.push_back(Vec3::Unit(v % 3) * (v < 3 ? 1.0 : -1.0));
    io::Archive a = io::Archive::create(path, {});
    io::write_spherical_image(a, "s", image, param, {.source = "s.ply", .numbers = {}});
    a.close();
  }
  void read(const fs::path& path) override {
    const io::Archive a = io::Archive::open(path);
    (void)io::read_spherical_image(a, "s");
    (void)io::read_sphere_parametrization(a, "s");
  }
};

TEST_F(HostileSphere, TheUndamagedArchiveReads) {
  build(file("a.h5"));
  read(file("a.h5"));
}

TEST_F(HostileSphere, OtherFilesAreNeverReached) {
  const fs::path other = file("other.h5");
  build(other);
  expect_refused([&](h5::Group& g) { make_external_storage(g.id(), "geometry", {5, 5, 3}, file("raw")); },
                 {"/spherical/s/geometry", "external file"});
  expect_refused([&](h5::Group& g) { make_external_link(g.id(), "mask", other, "/spherical/s/mask"); },
                 {"/spherical/s/mask is an external link"});
  expect_refused([&](h5::Group& g) { make_soft(g.id(), "parametrization", "/spherical/s"); },
                 {"/spherical/s/parametrization is a soft link"});
  expect_refused([&](h5::Group& g) { make_virtual(g.id(), "colors", {5, 5, 3}, file("source.h5")); },
                 {"/spherical/s/colors", "virtual dataset"});
  expect_refused([](h5::Group& g) { make_filtered(g.id(), "mask", {5, 5}, std::vector<std::uint8_t>(25, 1)); },
                 {"dataset /spherical/s/mask uses compression filter 32000 (lzf)"});
}

TEST_F(HostileSphere, AbsurdNumbersAndNonFiniteValuesAreRefused) {
  expect_refused([](h5::Group& g) { g.set_attribute("n", std::int64_t{1} << 40); }, {"tessellation n = ", "out of range"});
  expect_refused([](h5::Group& g) { g.set_attribute("n", -1); }, {"tessellation n = -1 is out of range"});
  std::vector<float> colors(75, 0.5f);
  colors[4] = kNaN;
  expect_refused([&](h5::Group& g) { recreate(g.id(), "colors", {5, 5, 3}, colors); },
                 {"colour of defined sample 1 is not finite"});
  expect_refused([](h5::Group& g) { g.open_dataset("geometry").write(std::vector<float>(75, kInf)); },
                 {"defined sample 0 is not finite"});
  expect_refused([](h5::Group& g) { g.open_dataset("parametrization/sphere").set_attribute("input_faces", 0); },
                 {"attribute input_faces = 0 is outside [1, 2^32]"});
  expect_refused(
      [](h5::Group& g) { g.open_dataset("parametrization/sphere").set_attribute("input_faces", std::int64_t{1} << 62); },
      {"attribute input_faces = 4611686018427387904 is outside [1, 2^32]"});
}

// ---- relief maps --------------------------------------------------------------------------------

/// A relief map of a small torus (N = 2, 4 × 4 texels).
class HostileRelief : public HostileArchiveTest {
 protected:
  HostileRelief() { group_path_ = "relief/r"; }
  void build(const fs::path& path) override {
    static const ReliefMap map = [] {
      ReliefOptions o;
      o.grid = 2;
      o.texture = 4;
      return build_relief_map(make_torus(1.0, 0.35, 16, 8), o);
    }();
    io::Archive a = io::Archive::create(path, {});
    io::write_relief_map(a, "r", map, {.source = "r.ply", .numbers = {}});
    a.close();
  }
  void read(const fs::path& path) override { (void)io::read_relief_map(io::Archive::open(path), "r"); }
  static h5::Dims shape_of(h5::Group& g, const char* item) { return g.open_dataset(item).shape(); }
};

TEST_F(HostileRelief, TheUndamagedArchiveReads) {
  build(file("a.h5"));
  read(file("a.h5"));
}

TEST_F(HostileRelief, OtherFilesAreNeverReached) {
  const fs::path other = file("other.h5");
  build(other);
  expect_refused(
      [&](h5::Group& g) {
        const h5::Dims s = shape_of(g, "distances");
        const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
        H5Pset_external(dcpl, file("raw").c_str(), 0, H5F_UNLIMITED);
        std::ofstream(file("raw"), std::ios::binary) << std::string(1 << 16, 'x');
        recreate(g.id(), "distances", {s[0], s[1], s[2]}, std::vector<std::uint16_t>{}, dcpl, H5T_STD_U16LE);
        H5Pclose(dcpl);
      },
      {"/relief/r/distances", "external file"});
  expect_refused([&](h5::Group& g) { make_external_link(g.id(), "normals", other, "/relief/r/normals"); },
                 {"/relief/r/normals is an external link"});
  expect_refused([&](h5::Group& g) { make_soft(g.id(), "cells", "/relief/r/layer_cell"); },
                 {"/relief/r/cells is a soft link"});
  expect_refused(
      [&](h5::Group& g) {
        const h5::Dims s = shape_of(g, "distances");
        std::size_t n = s[0] * s[1] * s[2];
        make_filtered(g.id(), "distances", {s[0], s[1], s[2]}, std::vector<std::uint16_t>(n, 7));
      },
      {"dataset /relief/r/distances uses compression filter 32000 (lzf)"});
}

TEST_F(HostileRelief, AbsurdNumbersAreRefused) {
  expect_refused([](h5::Group& g) { g.set_attribute("cell_size", 1e308); }, {"leave the range of float32"});
  expect_refused([](h5::Group& g) { g.set_attribute("cell_size", 1e30); }, {"distances attribute scale", "disagrees"});
  expect_refused([](h5::Group& g) { g.open_dataset("distances").set_attribute("scale", 1e308); },
                 {"distances attribute scale = 1e+308 disagrees with cell_size"});
  expect_refused([](h5::Group& g) { g.set_attribute("origin", std::vector<double>{0.0, 1e300, 0.0}); },
                 {"leave the range of float32"});
  expect_refused([](h5::Group& g) { g.set_attribute("origin", std::vector<double>{0.0, std::nan(""), 0.0}); },
                 {"attribute origin is not 3 finite numbers"});
  expect_refused([](h5::Group& g) { g.set_attribute("n", 0); }, {"attribute n = 0 is out of range"});
  expect_refused([](h5::Group& g) { g.set_attribute("grey_cells", std::int64_t{1} << 62); }, {"grey_cells", "out of range"});
  expect_refused([](h5::Group& g) { g.set_attribute("texture", std::int64_t{1} << 40); }, {"texture", "out of range"});
}

// ---- batch shards and batch archives ------------------------------------------------------------

class HostileBatch : public gimforge::test::ScratchDirTest {
 protected:
  /// A 3 × 4 × 5 gim shard at shards/0.h5.
  fs::path shard() {
    const fs::path path = file("shards/0.h5");
    io::ItemArrays arrays{.channels = 3, .height = 4, .width = 5, .data = std::vector<float>(60, 0.5f), .mask = {},
                          .metrics = {{"psnr", 50.0}}, .sample_uv = {}};
    io::write_shard(path, {.output = "gim_5", .name = "item", .source = "item.ply", .label = "", .index = 0}, arrays);
    return path;
  }
  static void damage(const fs::path& path, const std::function<void(h5::File&)>& f) {
    h5::File file = h5::File::open(path, h5::OpenMode::kReadWrite);
    f(file);
  }
};

TEST_F(HostileBatch, DamagedShardsAreRefused) {
  const fs::path path = shard();
  EXPECT_NO_THROW((void)io::read_shard(path));
  damage(path, [](h5::File& f) {
    std::vector<float> data(60, 0.5f);
    data[17] = kNaN;
    recreate(f.id(), "data", {3, 4, 5}, data);
  });
  expect_contains(message_of<FormatError>([&] { (void)io::read_shard(path); }),
                  {path.string(), "dataset 'data' holds nan at channel 0, pixel (3, 2) of a defined sample"});
  damage(path, [&](h5::File& f) { make_external_storage(f.id(), "data", {3, 4, 5}, file("raw")); });
  expect_contains(message_of<FormatError>([&] { (void)io::read_shard(path); }), {path.string(), "external file"});
  damage(path, [](h5::File& f) { recreate(f.id(), "data", {3, 1u << 20, 5}, std::vector<float>{}, H5P_DEFAULT, H5T_IEEE_F32LE); });
  expect_contains(message_of<FormatError>([&] { (void)io::read_shard_info(path); }), {"extent 1048576 outside 1..65536"});
  damage(path, [&](h5::File& f) { make_soft(f.id(), "data", "/metrics"); });
  expect_contains(message_of<FormatError>([&] { (void)io::read_shard_info(path); }), {"/data is a soft link"});
}

TEST_F(HostileBatch, TheMergeCopiesNoLinkOrForeignDataset) {
  // A relief shard whose representation group hides a soft link and an external-storage dataset next to
  // what the reader checks: H5Ocopy would carry them into the consolidated archive.
  static const ReliefMap map = [] {
    ReliefOptions o;
    o.grid = 1;
    o.texture = 4;
    return build_relief_map(make_torus(1.0, 0.35, 12, 6), o);
  }();
  const io::ReliefRecord record{.source = "t.ply", .numbers = {}};
  const auto write = [&](const fs::path& path, const std::function<void(h5::Group&)>& extra) {
    io::write_shard(path, {.output = "relief_1_4", .name = "t", .source = "t.ply", .label = "", .index = 0}, {},
                    [&](h5::Group& g) {
                      io::write_relief_map(g, map, record);
                      extra(g);
                    });
  };
  const fs::path soft = file("soft.h5"), external = file("external.h5");
  write(soft, [](h5::Group& g) { make_soft(g.id(), "passwd", "/etc/passwd"); });
  write(external, [&](h5::Group& g) { make_external_storage(g.id(), "passwd", {16}, file("raw")); });
  for (const fs::path& s : {soft, external}) {
    const std::vector<io::MergeInput> inputs{{.output = "relief_1_4", .shards = {s}, .failed = {}, .attributes = {},
                                              .groups = true}};
    const std::string msg = message_of<Error>([&] { io::write_batch_archive(file("batch.h5"), {}, inputs); });
    expect_contains(msg, {"passwd"});
    EXPECT_FALSE(fs::exists(file("batch.h5"))) << msg;
  }
}

TEST_F(HostileBatch, BatchArchiveCountsAreRangeChecked) {
  const fs::path s = shard();
  const std::vector<io::MergeInput> inputs{{.output = "gim_5", .shards = {s}, .failed = {}, .attributes = {}, .groups = false}};
  io::write_batch_archive(file("batch.h5"), {}, inputs);
  EXPECT_EQ(io::read_batch_summary(file("batch.h5")).front().count, 1u);
  damage(file("batch.h5"), [](h5::File& f) { f.open_group("batch/gim_5").set_attribute("count", std::int64_t{1} << 62); });
  expect_contains(message_of<FormatError>([&] { (void)io::read_batch_summary(file("batch.h5")); }),
                  {"/batch/gim_5: attribute count = 4611686018427387904 is outside [0, 2^40]"});
  damage(file("batch.h5"), [](h5::File& f) {
    f.open_group("batch/gim_5").set_attribute("count", 1);
    make_soft(f.open_group("batch/gim_5").id(), "names", "/batch/gim_5/sources");
  });
  expect_contains(message_of<FormatError>([&] { (void)io::read_batch_summary(file("batch.h5")); }),
                  {"/batch/gim_5/names is a soft link"});
}

TEST_F(HostileBatch, LabelIndicesAndTheFailedCountAgreeWithTheirTables) {
  // Once read as given: ls printed "0 failed" beside failed_count = 2, and a label index past the names.
  const fs::path s = shard();
  const std::vector<io::MergeInput> inputs{{.output = "gim_5", .shards = {s}, .failed = {}, .attributes = {}, .groups = false}};
  io::write_batch_archive(file("batch.h5"), {}, inputs);
  damage(file("batch.h5"), [](h5::File& f) { f.open_group("batch/gim_5").set_attribute("failed_count", 2); });
  expect_contains(message_of<FormatError>([&] { (void)io::read_batch_summary(file("batch.h5")); }),
                  {"attribute failed_count = 2 disagrees with the 0 rows of 'failed/names'"});
  io::write_batch_archive(file("batch2.h5"), {}, inputs);
  damage(file("batch2.h5"), [](h5::File& f) {
    h5::Dataset labels = f.open_group("batch/gim_5").open_dataset("label_index");
    labels.write(std::vector<std::int32_t>{7});
  });
  expect_contains(message_of<FormatError>([&] { (void)io::read_batch_summary(file("batch2.h5")); }),
                  {"dataset 'label_index' holds 7, not -1 (no label) or an index of the 0 label names"});
}

// ---- the HDF5 layer itself ----------------------------------------------------------------------

class HostileHdf5 : public gimforge::test::ScratchDirTest {};

TEST_F(HostileHdf5, ReadsAreBoundedAndAttributesRangeChecked) {
  const fs::path path = file("huge.h5");
  {
    h5::File f = h5::File::create(path);
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    const std::vector<hsize_t> chunk{1, 1};
    H5Pset_chunk(dcpl, 2, chunk.data());
    recreate(f.id(), "huge", {std::uint64_t{1} << 31, std::uint64_t{1} << 31}, std::vector<float>{}, dcpl,
             H5T_IEEE_F32LE);
    H5Pclose(dcpl);
    f.set_attribute("k", 5);
  }
  const h5::File f = h5::File::open(path);
  expect_contains(message_of<FormatError>([&] { (void)f.open_dataset("huge").read<float>(); }),
                  {"dataset /huge", "more than gimforge reads at once (2^33 bytes)"});
  EXPECT_EQ(f.attribute_in_range("k", 1, 5), 5);
  expect_contains(message_of<FormatError>([&] { (void)f.attribute_in_range("k", 6, 1 << 20); }),
                  {path.string() + ":/: attribute k = 5 is outside [6, 2^20]"});
  expect_contains(message_of<FormatError>([&] { (void)f.finite_attribute_in_range("k", 0.0, 1.0); }), {"is an integer"});
}

// A declared extent costs a file nothing: unwritten chunks and unallocated contiguous data read as fill values.
TEST_F(HostileHdf5, DataTheFileDoesNotStoreIsRefusedBeforeItIsAllocated) {
  const fs::path path = file("unstored.h5");
  {
    h5::File f = h5::File::create(path);
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    const std::vector<hsize_t> chunk{4, 3};
    H5Pset_chunk(dcpl, 2, chunk.data());
    H5Pset_deflate(dcpl, 6);  // compressed chunks: stored bytes say nothing, the chunk count does
    recreate(f.id(), "stack", {std::uint64_t{1} << 24, 3}, std::vector<float>{}, dcpl, H5T_IEEE_F32LE);
    recreate(f.id(), "written", {8, 3}, std::vector<float>(24, 2.0f), dcpl, H5T_IEEE_F32LE);
    // Rows 0..3 of "stack" are written (its first chunk), the other 2^22 - 1 chunks are not.
    const hid_t ds = H5Dopen2(f.id(), "stack", H5P_DEFAULT);
    const std::vector<hsize_t> start{0, 0}, count{4, 3};
    const hid_t space = H5Dget_space(ds), mem = H5Screate_simple(2, count.data(), nullptr);
    H5Sselect_hyperslab(space, H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr);
    const std::vector<float> rows(12, 1.0f);
    EXPECT_GE(H5Dwrite(ds, H5T_NATIVE_FLOAT, mem, space, H5P_DEFAULT, rows.data()), 0);
    H5Sclose(mem), H5Sclose(space), H5Dclose(ds), H5Pclose(dcpl);
    recreate(f.id(), "contiguous", {1u << 20}, std::vector<double>{}, H5P_DEFAULT, H5T_IEEE_F64LE);
    const hid_t strings = H5Pcreate(H5P_DATASET_CREATE);
    const std::vector<hsize_t> one{64};
    H5Pset_chunk(strings, 1, one.data());
    const hid_t text = H5Tcopy(H5T_C_S1);
    H5Tset_size(text, H5T_VARIABLE);
    recreate(f.id(), "names", {1u << 20}, std::vector<float>{}, strings, text);
    H5Tclose(text), H5Pclose(strings);
    // An output whose item groups are left to their readers: one unstored dataset below "items".
    h5::Group out = f.create_group("out");
    out.create_group("items").create_group("0");
    recreate(out.id(), "items/0/geometry", {1u << 10}, std::vector<double>{}, H5P_DEFAULT, H5T_IEEE_F64LE);
    recreate(out.id(), "data", {4}, std::vector<double>{1, 2, 3, 4});
  }
  const h5::File f = h5::File::open(path);
  const h5::Dataset stack = f.open_dataset("stack");
  expect_contains(message_of<FormatError>([&] { (void)stack.read<float>(); }),
                  {path.string() + ": dataset /stack does not store its chunk at (4, 0) (it would read as fill values)"});
  EXPECT_EQ(stack.read_slab<float>({0, 0}, {4, 3}), std::vector<float>(12, 1.0f));  // the stored chunk
  EXPECT_EQ(stack.read_slab<float>({1, 1}, {2, 2}), std::vector<float>(4, 1.0f));
  expect_contains(message_of<FormatError>([&] { (void)stack.read_slab<float>({3, 0}, {2, 3}); }),
                  {"dataset /stack does not store its chunk at (4, 0) (it would read as fill values)"});
  expect_contains(message_of<FormatError>([&] { (void)stack.read_slab<float>({0, 0}, {1u << 15, 3}); }),
                  {"dataset /stack does not store its chunk at (4, 0)"});
  EXPECT_EQ(f.open_dataset("written").read<float>(), std::vector<float>(24, 2.0f));
  expect_contains(message_of<FormatError>([&] { (void)f.open_dataset("contiguous").read<double>(); }),
                  {"dataset /contiguous declares 1048576 values and stores none (they would read as fill values)"});
  expect_contains(message_of<FormatError>([&] { (void)f.open_dataset("names").read_strings(); }),
                  {"dataset /names does not store its chunk at (0)"});
  // Asked without reading (gimforge ls, XDMF sidecars): the whole dataset, or every dataset of a group.
  expect_contains(message_of<FormatError>([&] { h5::require_stored(stack); }),
                  {path.string() + ": dataset /stack does not store its chunk at (4, 0)"});
  EXPECT_NO_THROW(h5::require_stored(f.open_dataset("written")));
  expect_contains(message_of<FormatError>([&] { h5::require_stored(f.open_dataset("contiguous")); }),
                  {"dataset /contiguous declares 1048576 values and stores none"});
  expect_contains(message_of<FormatError>([&] { h5::require_stored(f.open_group("/")); }), {"dataset /contiguous"});
  expect_contains(message_of<FormatError>([&] { h5::require_stored(f.open_group("out")); }),
                  {"dataset /out/items/0/geometry declares 1024 values and stores none"});
  EXPECT_NO_THROW(h5::require_stored(f.open_group("out"), "items"));
}

}  // namespace
