// End-to-end hostile archives (issue #15): `gimforge reconstruct`, `preview` and `render` on archives built
// to disclose other files (external raw storage, external and soft links, virtual datasets), to crash the
// readers (units_per_side = 0 divided by zero: SIGFPE, exit 136) or to produce NaN / Inf output. Each must
// exit 1 with exactly one stderr line "gimforge: error: ARCHIVE...: CAUSE", write no output file, and never
// echo the other file's bytes. (tests/unit/io/test_hostile_archives.cpp covers every case at the reader.)
#include <gtest/gtest.h>
#include <hdf5.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <limits>
#include <sstream>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "io/gim_archive.h"
#include "io/relief_archive.h"
#include "io/sphere_archive.h"
#include "kernels/core/procedural.h"
#include "kernels/relief/relief_map.h"
#include "kernels/sphere/spherical_domain.h"
#include "tests/cli/run_process.h"

namespace fs = std::filesystem;
using namespace gimforge;
using gimforge::test::run_gimforge;
using gimforge::test::TempDir;

namespace {

constexpr std::string_view kSecret = "root:x:0:0:a line of another file that must never reach an output";

/// A 9 × 9 geometry image "g" (2 units per side, one pair of mates) that reconstructs and previews.
void write_gim(const fs::path& path) {
  GeometryImage image;
  image.size = 9;
  for (std::uint32_t j = 0; j < 9; ++j)
    for (std::uint32_t i = 0; i < 9; ++i)
      image.positions.insert(image.positions.end(), {static_cast<float>(i), static_cast<float>(j), 0.0f});
  image.sideband.units_per_side = 2;
  image.sideband.paths = {{1, 0, 4}, {-1, 4, 4}};
  io::Archive a = io::Archive::create(path, {});
  io::write_geometry_image(a, "g", image, {.source = "g.ply", .numbers = {}});
  a.close();
}

/// An octahedral spherical image "s" at n = 2.
void write_sphere(const fs::path& path) {
  SphericalImage image;
  image.domain = SphericalDomain::Octahedron;
  image.n = 2;
  for (const Vec3& p : domain_positions(image.layout(), DomainEmbedding::Polyhedron)) {
    image.mask.push_back(1);
    for (int c = 0; c < 3; ++c) image.positions.push_back(static_cast<float>(p[c]));
  }
  io::SphereParametrization param;
  param.input_vertices = 6;
  param.input_faces = 8;
  for (int v = 0; v < 6; ++v) param.sphere.push_back(Vec3::Unit(v % 3) * (v < 3 ? 1.0 : -1.0));
  io::Archive a = io::Archive::create(path, {});
  io::write_spherical_image(a, "s", image, param, {.source = "s.ply", .numbers = {}});
  a.close();
}

/// A relief map "r" of a small torus (N = 2, 4 × 4 texels).
void write_relief(const fs::path& path) {
  ReliefOptions o;
  o.grid = 2;
  o.texture = 4;
  const ReliefMap map = build_relief_map(make_torus(1.0, 0.35, 16, 8), o);
  io::Archive a = io::Archive::create(path, {});
  io::write_relief_map(a, "r", map, {.source = "r.ply", .numbers = {}});
  a.close();
}

/// Opens `path` read-write and runs `f` on its object (group or dataset) `object`.
void damage(const fs::path& path, const char* object, const std::function<void(hid_t)>& f) {
  h5::File file = h5::File::open(path, h5::OpenMode::kReadWrite);
  const hid_t o = H5Oopen(file.id(), object, H5P_DEFAULT);
  ASSERT_GE(o, 0) << object;
  f(o);
  H5Oclose(o);
}

void unlink(hid_t g, const char* name) { ASSERT_GE(H5Ldelete(g, name, H5P_DEFAULT), 0); }

/// Replaces float32 dataset `name` of `dims` by one whose raw data is the file `raw` (which holds kSecret).
void external_storage(hid_t g, const char* name, std::vector<hsize_t> dims, const fs::path& raw) {
  std::string bytes(1 << 16, ' ');
  bytes.replace(0, kSecret.size(), kSecret);
  std::ofstream(raw, std::ios::binary) << bytes;
  unlink(g, name);
  const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
  ASSERT_GE(H5Pset_external(dcpl, raw.c_str(), 0, H5F_UNLIMITED), 0);
  const hid_t space = H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
  const hid_t ds = H5Dcreate2(g, name, H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
  ASSERT_GE(ds, 0);
  H5Dclose(ds);
  H5Sclose(space);
  H5Pclose(dcpl);
}

/// Writes float values over float32 dataset `name` (same shape).
void overwrite(hid_t g, const char* name, const std::vector<float>& values) {
  const hid_t ds = H5Dopen2(g, name, H5P_DEFAULT);
  ASSERT_GE(ds, 0);
  ASSERT_GE(H5Dwrite(ds, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
  H5Dclose(ds);
}

void int_attribute(hid_t obj, const char* key, std::int64_t value) {
  ASSERT_GE(H5Adelete(obj, key), 0);
  const hid_t space = H5Screate(H5S_SCALAR);
  const hid_t a = H5Acreate2(obj, key, H5T_STD_I64LE, space, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(H5Awrite(a, H5T_NATIVE_INT64, &value), 0);
  H5Aclose(a);
  H5Sclose(space);
}

void double_attribute(hid_t obj, const char* key, double value) {
  ASSERT_GE(H5Adelete(obj, key), 0);
  const hid_t space = H5Screate(H5S_SCALAR);
  const hid_t a = H5Acreate2(obj, key, H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(H5Awrite(a, H5T_NATIVE_DOUBLE, &value), 0);
  H5Aclose(a);
  H5Sclose(space);
}

class CliHostileArchive : public ::testing::Test {
 protected:
  /// Runs gimforge with `args`, expecting exit 1, one stderr line "gimforge: error: ARCHIVE..." holding
  /// every cause, no trace of kSecret anywhere, and no file at `output`.
  void expect_refused(const std::vector<std::string>& args, const fs::path& output,
                      std::initializer_list<std::string_view> causes) const {
    const auto r = run_gimforge(args, 60.0);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    const auto lines = r.err_lines();
    ASSERT_EQ(lines.size(), 1u) << r.err;
    EXPECT_EQ(lines[0].rfind("gimforge: error: " + archive_.string(), 0), 0u) << lines[0];
    for (const std::string_view cause : causes) EXPECT_NE(lines[0].find(cause), std::string::npos) << lines[0];
    EXPECT_EQ(r.out.find(kSecret.substr(0, 10)), std::string::npos) << r.out;
    EXPECT_EQ(r.err.find(kSecret.substr(0, 10)), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(output)) << output;
    if (fs::is_directory(output.parent_path())) {
      for (const auto& entry : fs::directory_iterator(output.parent_path())) {
        EXPECT_NE(entry.path().extension(), ".png") << entry.path();
      }
    }
  }
  [[nodiscard]] std::vector<std::string> reconstruct() const {
    return {"reconstruct", archive_.string(), "-o", ply_.string()};
  }
  [[nodiscard]] std::vector<std::string> preview() const {
    return {"preview", archive_.string(), "-o", previews_.string()};
  }

  TempDir dir_{"gimforge-hostile"};
  fs::path archive_ = dir_.file("hostile.h5");
  fs::path ply_ = dir_.file("out.ply");
  fs::path previews_ = dir_.file("previews");
};

TEST_F(CliHostileArchive, UndamagedArchivesReconstruct) {
  write_gim(archive_);
  const auto r = run_gimforge(reconstruct(), 60.0);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(ply_));
}

TEST_F(CliHostileArchive, ExternalRawStorageDisclosesNothing) {
  write_gim(archive_);
  const fs::path raw = dir_.file("passwd");
  damage(archive_, "gim/g", [&](hid_t g) { external_storage(g, "geometry", {9, 9, 3}, raw); });
  expect_refused(reconstruct(), ply_, {"/gim/g/geometry", "external file", raw.string()});
  expect_refused(preview(), previews_ / "g_geometry.png", {"/gim/g/geometry", "external file"});
}

TEST_F(CliHostileArchive, LinksToOtherFilesAndSoftLinksAreNotFollowed) {
  const fs::path other = dir_.file("other.h5");
  write_gim(other);
  write_gim(archive_);
  damage(archive_, "gim/g", [&](hid_t g) {
    unlink(g, "geometry");
    ASSERT_GE(H5Lcreate_external(other.c_str(), "/gim/g/geometry", g, "geometry", H5P_DEFAULT, H5P_DEFAULT), 0);
  });
  expect_refused(reconstruct(), ply_, {"/gim/g/geometry is an external link", "follows only hard links"});
  write_sphere(archive_);
  damage(archive_, "spherical/s", [&](hid_t g) {
    unlink(g, "mask");
    ASSERT_GE(H5Lcreate_soft("/spherical/s/geometry", g, "mask", H5P_DEFAULT, H5P_DEFAULT), 0);
  });
  expect_refused(reconstruct(), ply_, {"/spherical/s/mask is a soft link (to '/spherical/s/geometry')"});
}

TEST_F(CliHostileArchive, VirtualDatasetsAreRefused) {
  const fs::path source = dir_.file("source.h5");
  write_gim(source);
  write_gim(archive_);
  damage(archive_, "gim/g", [&](hid_t g) {
    unlink(g, "geometry");
    const std::vector<hsize_t> dims{9, 9, 3};
    const hid_t space = H5Screate_simple(3, dims.data(), nullptr);
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    ASSERT_GE(H5Pset_virtual(dcpl, space, source.c_str(), "/gim/g/geometry", space), 0);
    const hid_t ds = H5Dcreate2(g, "geometry", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    ASSERT_GE(ds, 0);
    H5Dclose(ds);
    H5Pclose(dcpl);
    H5Sclose(space);
  });
  expect_refused(reconstruct(), ply_, {"/gim/g/geometry", "virtual dataset"});
}

TEST_F(CliHostileArchive, UnitsPerSideZeroOrHugeIsAnErrorNotSigfpe) {
  for (const std::int64_t bad : {std::int64_t{0}, std::int64_t{1} << 62, std::int64_t{-64}}) {
    write_gim(archive_);
    damage(archive_, "gim/g", [&](hid_t g) { int_attribute(g, "units_per_side", bad); });
    expect_refused(reconstruct(), ply_,
                   {"/gim/g: attribute units_per_side = " + std::to_string(bad) + " is outside [1, 2^20]"});
    expect_refused(preview(), previews_ / "g_geometry.png", {"units_per_side"});
  }
}

TEST_F(CliHostileArchive, NonFiniteAndFarGeometryImagesAreRefused) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  std::vector<float> half(243, 1.0f);
  for (std::size_t k = 121; k < half.size(); ++k) half[k] = nan;
  // Finite, but where no input mesh lies: reconstruct once wrote a mesh that gimforge itself refuses to read.
  std::vector<float> far(243, 1.0f);
  far[122] = -3e38f;
  for (const auto& [values, cause] :
       {std::pair{std::vector<float>(243, nan), "sample 0 of dataset 'geometry' is nan"},
        std::pair{std::vector<float>(243, inf), "sample 0 of dataset 'geometry' is inf"},
        std::pair{half, "sample 40 of dataset 'geometry' is nan"},
        std::pair{far, "dataset 'geometry': sample 40 has a coordinate of magnitude 3e+38, beyond ±1e+18"}}) {
    write_gim(archive_);
    damage(archive_, "gim/g", [&](hid_t g) { overwrite(g, "geometry", values); });
    expect_refused(reconstruct(), ply_, {cause});
    expect_refused(preview(), previews_ / "g_geometry.png", {cause});
    EXPECT_FALSE(fs::exists(previews_)) << "the directory preview made for its pictures goes with the failure";
  }
}

TEST_F(CliHostileArchive, UnreadableFiltersAreNamed) {
  // What h5py writes with compression="lzf" (filter 32000, built into h5py only); without h5py, the same
  // filter id declared optional through the C API.
  write_gim(archive_);
  const std::string script = "import h5py, numpy\nf = h5py.File('" + archive_.string() +
                             "', 'r+')\ng = f['gim/g']\nd = g['geometry'][()]\ndel g['geometry']\n"
                             "g.create_dataset('geometry', data=d, compression='lzf')\nf.close()\n";
  const auto py = gimforge::test::run_process({GIMFORGE_PYTHON, "-c", script}, 60.0);
  if (py.exit_code != 0) {
    damage(archive_, "gim/g", [&](hid_t g) {
      unlink(g, "geometry");
      const std::vector<hsize_t> dims{9, 9, 3};
      const hid_t space = H5Screate_simple(3, dims.data(), nullptr);
      const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
      H5Pset_chunk(dcpl, 3, dims.data());
      ASSERT_GE(H5Pset_filter(dcpl, 32000, H5Z_FLAG_OPTIONAL, 0, nullptr), 0);
      const hid_t ds = H5Dcreate2(g, "geometry", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
      ASSERT_GE(ds, 0);
      H5Dclose(ds);
      H5Pclose(dcpl);
      H5Sclose(space);
    });
  }
  expect_refused(reconstruct(), ply_,
                 {"dataset /gim/g/geometry uses compression filter 32000 (lzf) which gimforge cannot read; rewrite it "
                  "with gzip or none"});
}

TEST_F(CliHostileArchive, MissingAndUnstoredImagesAreRefusedAndListedUnreadable) {
  const auto listed_unreadable = [&](std::string_view cause) {
    const auto ls = run_gimforge({"ls", archive_.string()}, 60.0);
    EXPECT_EQ(ls.exit_code, 1) << ls.err;  // ls once listed an image without data as a good one, exit 0
    EXPECT_NE(ls.out.find("gim/g"), std::string::npos) << ls.out;
    EXPECT_NE(ls.out.find("unreadable: "), std::string::npos) << ls.out;
    EXPECT_NE(ls.out.find(cause), std::string::npos) << ls.out;
    EXPECT_NE(ls.err.find("1 item is unreadable (listed above)"), std::string::npos) << ls.err;
  };
  write_gim(archive_);
  damage(archive_, "gim/g", [&](hid_t g) { unlink(g, "geometry"); });
  expect_refused(reconstruct(), ply_, {"no dataset 'geometry'"});
  listed_unreadable("/gim/g: no dataset 'geometry'");
  const auto xdmf = run_gimforge({"ls", archive_.string(), "--xdmf"}, 60.0);
  EXPECT_EQ(xdmf.exit_code, 1) << xdmf.err;  // the sidecar of the rest, and the listing's count of what is not
  EXPECT_NE(xdmf.err.find("1 item is unreadable (listed above)"), std::string::npos) << xdmf.err;
  // Declared, never written: it would read as fill values (zeros), a wrong surface.
  write_gim(archive_);
  damage(archive_, "gim/g", [&](hid_t g) {
    unlink(g, "geometry");
    const std::vector<hsize_t> dims{9, 9, 3};
    const hid_t space = H5Screate_simple(3, dims.data(), nullptr);
    const hid_t ds = H5Dcreate2(g, "geometry", H5T_IEEE_F32LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(ds, 0);
    H5Dclose(ds);
    H5Sclose(space);
  });
  expect_refused(reconstruct(), ply_, {"dataset /gim/g/geometry declares 243 values and stores none"});
  listed_unreadable("dataset /gim/g/geometry declares 243 values and stores none");
  expect_refused(preview(), previews_ / "g_geometry.png", {"stores none"});
  // Partly written: its first and last chunks are stored, the middle one is not. ls once read only the first and
  // last values and listed it readable, and the sidecar described it, though every reader refuses it.
  write_gim(archive_);
  damage(archive_, "gim/g", [&](hid_t g) {
    unlink(g, "geometry");
    const std::vector<hsize_t> dims{9, 9, 3}, chunk{3, 9, 3};
    const hid_t space = H5Screate_simple(3, dims.data(), nullptr);
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(dcpl, 3, chunk.data());
    const hid_t ds = H5Dcreate2(g, "geometry", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    ASSERT_GE(ds, 0);
    const std::vector<float> rows(81, 0.5f);
    for (const hsize_t row : {hsize_t{0}, hsize_t{6}}) {
      const std::vector<hsize_t> start{row, 0, 0};
      const hid_t file_space = H5Dget_space(ds), memory = H5Screate_simple(3, chunk.data(), nullptr);
      H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start.data(), nullptr, chunk.data(), nullptr);
      EXPECT_GE(H5Dwrite(ds, H5T_NATIVE_FLOAT, memory, file_space, H5P_DEFAULT, rows.data()), 0);
      H5Sclose(memory), H5Sclose(file_space);
    }
    H5Dclose(ds), H5Pclose(dcpl), H5Sclose(space);
  });
  expect_refused(reconstruct(), ply_, {"dataset /gim/g/geometry does not store its chunk at (3, 0, 0)"});
  listed_unreadable("dataset /gim/g/geometry does not store its chunk at (3, 0, 0)");
  const auto partial = run_gimforge({"ls", archive_.string(), "--xdmf"}, 60.0);
  EXPECT_EQ(partial.exit_code, 1) << partial.err;
  EXPECT_NE(partial.out.find("(it describes nothing"), std::string::npos) << partial.out;
  std::ifstream sidecar(dir_.file("hostile.xmf"));
  std::ostringstream text;
  text << sidecar.rdbuf();
  const std::string xml = text.str();
  EXPECT_NE(xml.find("<Domain>"), std::string::npos) << xml;
  EXPECT_EQ(xml.find("Grid"), std::string::npos) << xml;
  // Stored whole, but listed unreadable (its psnr is text): ls --xdmf once described it all the same.
  write_gim(archive_);
  damage(archive_, "gim/g", [&](hid_t g) {
    if (H5Aexists(g, "psnr") > 0) {
      ASSERT_GE(H5Adelete(g, "psnr"), 0);
    }
    const hid_t word = H5Tcopy(H5T_C_S1);
    H5Tset_size(word, 4);
    const hid_t scalar = H5Screate(H5S_SCALAR);
    const hid_t a = H5Acreate2(g, "psnr", word, scalar, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(H5Awrite(a, word, "high"), 0);
    H5Aclose(a), H5Sclose(scalar), H5Tclose(word);
  });
  const auto listed = run_gimforge({"ls", archive_.string(), "--xdmf"}, 60.0);
  EXPECT_EQ(listed.exit_code, 1) << listed.err;
  EXPECT_NE(listed.out.find("unreadable: "), std::string::npos) << listed.out;
  EXPECT_NE(listed.out.find("(it describes nothing"), std::string::npos) << listed.out;
  std::ifstream second(dir_.file("hostile.xmf"));
  std::ostringstream second_text;
  second_text << second.rdbuf();
  EXPECT_EQ(second_text.str().find("Grid"), std::string::npos) << second_text.str();
  const auto clean = run_gimforge({"ls", archive_.string(), "--xdmf", "--json"}, 60.0);
  EXPECT_EQ(clean.exit_code, 1) << clean.err;
}

TEST_F(CliHostileArchive, ADamagedFrameOriginIsRefusedByPreviewAsByReconstruct) {
  // preview does not draw the origin, and once drew such an image, exit 0, where reconstruct refused it.
  write_gim(archive_);
  damage(archive_, "gim/g", [&](hid_t g) {
    if (H5Aexists(g, "frame_origin") > 0) {
      ASSERT_GE(H5Adelete(g, "frame_origin"), 0);
    }
    const hsize_t four = 4;
    const std::vector<double> values{1.0, 2.0, 3.0, 4.0};
    const hid_t space = H5Screate_simple(1, &four, nullptr);
    const hid_t a = H5Acreate2(g, "frame_origin", H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(H5Awrite(a, H5T_NATIVE_DOUBLE, values.data()), 0);
    H5Aclose(a);
    H5Sclose(space);
  });
  expect_refused(reconstruct(), ply_, {"attribute frame_origin is not 3 finite numbers within ±1e12"});
  expect_refused(preview(), previews_ / "g_geometry.png", {"attribute frame_origin is not 3 finite numbers within ±1e12"});
  EXPECT_FALSE(fs::exists(previews_));
}

TEST_F(CliHostileArchive, AbsurdReliefNumbersAreRefusedByEveryCommand) {
  const fs::path png = dir_.file("render.png");
  write_relief(archive_);
  damage(archive_, "relief/r", [&](hid_t g) { double_attribute(g, "cell_size", 1e308); });
  expect_refused(reconstruct(), ply_, {"leave the range of float32"});
  expect_refused(preview(), previews_ / "r_distances.png", {"leave the range of float32"});
  expect_refused({"render", archive_.string(), "-o", png.string(), "--size", "16"}, png, {"leave the range of float32"});
  write_relief(archive_);
  damage(archive_, "relief/r/distances", [&](hid_t d) { double_attribute(d, "scale", 1e308); });
  expect_refused(reconstruct(), ply_, {"distances attribute scale = 1e+308 disagrees with cell_size"});
  expect_refused({"render", archive_.string(), "-o", png.string(), "--size", "16"}, png, {"disagrees"});
}

}  // namespace
