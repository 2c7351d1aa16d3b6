// End-to-end tests of `gimforge convert-format`: OBJ, OFF and STL rewritten as the binary PLY of triangles the
// brick paths read in pieces, equal to what every command reads from the original (fan triangulation, STL
// welding, coordinates far from the origin kept exactly); colours kept or dropped; bad calls are one line.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <nlohmann/json.hpp>

#include "io/mesh_io.h"
#include "io/ply_ranges.h"
#include "kernels/core/procedural.h"
#include "tests/cli/run_process.h"

using gimforge::test::run_gimforge;
using gimforge::test::TempDir;

namespace {

void expect_same_mesh(const gimforge::TriMesh& a, const gimforge::TriMesh& b) {
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.faces, b.faces);
}

}  // namespace

TEST(CliConvertFormat, ObjFarFromTheOriginBecomesAPlyReadableInPieces) {
  TempDir dir;
  const std::string obj = dir.file("utm.obj"), ply = dir.file("utm.ply");
  {
    std::ofstream out(obj);
    out << "# a pyramid with a square base, at UTM coordinates\n"
        << "v 412345.123 5312345.456 120.5\nv 412346.123 5312345.456 120.5\nv 412346.123 5312346.456 120.5\n"
        << "v 412345.123 5312346.456 120.5\nv 412345.623 5312345.956 121.25\n"
        << "f 4 3 2 1\nf 1 2 5\nf 2 3 5\nf 3 4 5\nf 4 1 5\n";
  }
  const auto r = run_gimforge({"convert-format", obj, "--json", "-o", ply});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j.at("format"), "OBJ");
  EXPECT_EQ(j.at("faces").get<int>(), 6);
  EXPECT_EQ(j.at("triangulated").get<int>(), 1);
  EXPECT_EQ(j.at("precision"), "double");  // float would move these coordinates
  EXPECT_TRUE(j.at("readable_in_pieces").get<bool>());
  EXPECT_TRUE(j.at("relief_by_bricks").get<bool>());
  expect_same_mesh(gimforge::io::read_mesh(ply), gimforge::io::read_mesh(obj));
  const auto file = gimforge::io::PlyTriangleFile::open(ply);
  ASSERT_TRUE(file.has_value());
  EXPECT_EQ(file->faces(), 6u);
  EXPECT_TRUE(file->positions_only());
  // Float over these decimals would move them: refused when asked for, naming how far.
  const auto as_float = run_gimforge({"convert-format", obj, "--precision", "float", "-o", dir.file("f.ply")});
  EXPECT_EQ(as_float.exit_code, 1);
  EXPECT_NE(as_float.err.find("--precision float would move its vertices"), std::string::npos) << as_float.err;
  EXPECT_FALSE(std::filesystem::exists(dir.file("f.ply")));
  // A mesh whose coordinates are floats already (a float PLY at the same place) loses nothing as float: auto
  // and float keep it so, bit for bit (both were refused as "would move its vertices").
  // (Written through a float file: GCC 12 at -O2 drops a double → float → double round trip of a loop that
  // stores the result back as double.)
  const std::string float_ply = dir.file("utm_float.ply");
  gimforge::io::write_ply(float_ply, gimforge::io::read_mesh(obj), {.binary = true, .double_precision = false, .comment = ""});
  const gimforge::TriMesh rounded = gimforge::io::read_mesh(float_ply);
  ASSERT_NE(rounded.positions[0].x(), gimforge::io::read_mesh(obj).positions[0].x());
  // info --json says what its text warning says: the float file resolves 5·10^6 to 0.5 only; the OBJ keeps doubles.
  const auto info_float = run_gimforge({"info", float_ply, "--json"});
  ASSERT_EQ(info_float.exit_code, 0) << info_float.err;
  EXPECT_DOUBLE_EQ(nlohmann::json::parse(info_float.out).at("float32_resolution").get<double>(), 0.5);
  const auto info_obj = run_gimforge({"info", obj, "--json"});
  ASSERT_EQ(info_obj.exit_code, 0) << info_obj.err;
  EXPECT_TRUE(nlohmann::json::parse(info_obj.out).at("float32_resolution").is_null());
  // The same float32-exact values in a double PLY: the file keeps whatever it was given, no warning (it
  // was judged by the values alone, and a DEM of whole metres at UTM coordinates was told it lost detail).
  const std::string double_ply = dir.file("utm_double.ply");
  gimforge::io::write_ply(double_ply, rounded, {.binary = true, .double_precision = true, .comment = ""});
  const auto info_double = run_gimforge({"info", double_ply, "--json"});
  ASSERT_EQ(info_double.exit_code, 0) << info_double.err;
  EXPECT_TRUE(nlohmann::json::parse(info_double.out).at("float32_resolution").is_null()) << info_double.out;
  EXPECT_EQ(info_double.err.find("32-bit float"), std::string::npos) << info_double.err;
  for (const char* precision : {"auto", "float"}) {
    const std::string out = dir.file(std::string("again_") + precision + ".ply");
    const auto again = run_gimforge({"convert-format", float_ply, "--precision", precision, "--json", "-o", out});
    ASSERT_EQ(again.exit_code, 0) << again.err;
    EXPECT_EQ(nlohmann::json::parse(again.out).at("precision"), "float");
    expect_same_mesh(gimforge::io::read_mesh(out), rounded);
  }
}

TEST(CliConvertFormat, StlCornersAreWeldedAsEveryCommandReadsThem) {
  TempDir dir;
  const std::string stl = dir.file("torus.stl"), ply = dir.file("torus.ply");
  gimforge::io::write_mesh(stl, gimforge::make_torus(1.0, 0.4, 24, 12));
  const auto r = run_gimforge({"convert-format", stl, "--json", "-o", ply});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j.at("vertices").get<int>(), 24 * 12);  // welded: not three corners per face
  EXPECT_EQ(j.at("precision"), "float");            // STL stores floats
  expect_same_mesh(gimforge::io::read_mesh(ply), gimforge::io::read_mesh(stl));
}

TEST(CliConvertFormat, WeldJoinsATriangleSoupThatGeometryImagesThenConvert) {
  // A torus as a triangle soup (a PLY with three vertices per face): every face its own component, so the
  // geometry image refuses it, and the loader names the cure. --weld gives the torus back.
  TempDir dir;
  const gimforge::TriMesh torus = gimforge::make_torus(1.0, 0.4, 24, 12);
  gimforge::TriMesh soup;
  for (const gimforge::Face& f : torus.faces) {
    const auto base = static_cast<std::uint32_t>(soup.positions.size());
    for (const std::uint32_t v : f) soup.positions.push_back(torus.positions[v]);
    soup.faces.push_back({base, base + 1, base + 2});
  }
  const std::string in = dir.file("soup.ply"), out = dir.file("welded.ply");
  gimforge::io::write_mesh(in, soup);
  const auto refused = run_gimforge({"convert", in, "--size", "65", "--no-metric", "-o", dir.file("a.h5")});
  EXPECT_EQ(refused.exit_code, 1);
  EXPECT_NE(refused.err.find("convert-format --weld"), std::string::npos) << refused.err;
  const auto r = run_gimforge({"convert-format", in, "--weld", "--json", "-o", out});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j.at("welded").get<std::size_t>(), soup.positions.size() - torus.positions.size());
  EXPECT_EQ(j.at("removed_faces").get<int>(), 0);
  // The torus's vertices (numbered by first use) and its faces, in their order, at the file's positions.
  const gimforge::TriMesh welded = gimforge::io::read_mesh(out), stored = gimforge::io::read_mesh(in);
  EXPECT_EQ(welded.num_vertices(), torus.num_vertices());
  ASSERT_EQ(welded.num_faces(), stored.num_faces());
  for (std::size_t f = 0; f < stored.faces.size(); ++f)
    for (std::size_t k = 0; k < 3; ++k)
      ASSERT_EQ(welded.positions[welded.faces[f][k]], stored.positions[stored.faces[f][k]]) << "face " << f;
  const auto converted = run_gimforge({"convert", out, "--size", "65", "--no-metric", "-o", dir.file("b.h5")});
  EXPECT_EQ(converted.exit_code, 0) << converted.err;
  // Without --weld nothing is welded (the soup stays a soup).
  ASSERT_EQ(run_gimforge({"convert-format", in, "-o", dir.file("same.ply")}).exit_code, 0);
  EXPECT_EQ(gimforge::io::read_mesh(dir.file("same.ply")).num_vertices(), soup.num_vertices());
}

TEST(CliConvertFormat, WeldReadsABinaryStlWholeAndAutoKeepsWholeMetresDouble) {
  TempDir dir;
  // A binary STL was streamed past --weld: its degenerate and duplicate faces stayed.
  gimforge::TriMesh t;
  t.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  t.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}, {0, 1, 1}, {1, 2, 3}};
  const std::string stl = dir.file("t.stl");
  gimforge::io::write_mesh(stl, t);
  const auto welded = run_gimforge({"convert-format", stl, "--weld", "--json", "-o", dir.file("t.ply")});
  ASSERT_EQ(welded.exit_code, 0) << welded.err;
  const nlohmann::json j = nlohmann::json::parse(welded.out);
  EXPECT_EQ(j.at("faces").get<int>(), 4);
  EXPECT_EQ(j.at("removed_faces").get<int>(), 2);
  // Whole metres at UTM coordinates in a text file are float32 values, but a float PLY of them reads as one
  // that lost its decimals (info warns): auto writes double.
  gimforge::TriMesh dem = gimforge::make_grid(6, 6, 5.0);
  for (gimforge::Vec3& p : dem.positions) p = gimforge::Vec3(std::round(p.x()) + 400000.0, std::round(p.y()) + 5000000.0, 100.0);
  const std::string obj = dir.file("dem.obj"), ply = dir.file("dem.ply");
  gimforge::io::write_mesh(obj, dem);
  const auto r = run_gimforge({"convert-format", obj, "--json", "-o", ply});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out).at("precision"), "double");
  const auto info = run_gimforge({"info", ply, "--json"});
  EXPECT_TRUE(nlohmann::json::parse(info.out).at("float32_resolution").is_null()) << info.out;
}

TEST(CliConvertFormat, ColoursAreKeptUnlessPositionsOnly) {
  TempDir dir;
  const std::string off = dir.file("c.off"), with = dir.file("with.ply"), without = dir.file("without.ply");
  gimforge::TriMesh t = gimforge::make_torus(1.0, 0.4, 12, 6);
  t.colors.assign(t.positions.size(), gimforge::Vec3f(1.0f, 0.0f, 0.5f));
  gimforge::io::write_mesh(off, t);
  const auto r = run_gimforge({"convert-format", off, "--json", "-o", with});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j.at("readable_in_pieces").get<bool>());  // metrics and images by bricks read it
  EXPECT_FALSE(j.at("relief_by_bricks").get<bool>());   // relief by bricks would lose the colours
  ASSERT_EQ(run_gimforge({"convert-format", off, "--positions-only", "-o", without}).exit_code, 0);
  const gimforge::TriMesh a = gimforge::io::read_mesh(with), b = gimforge::io::read_mesh(without);
  EXPECT_EQ(a.colors.size(), a.positions.size());
  EXPECT_TRUE(b.colors.empty());
  expect_same_mesh(a, b);
  EXPECT_FALSE(gimforge::io::PlyTriangleFile::open(with)->positions_only());
  EXPECT_TRUE(gimforge::io::PlyTriangleFile::open(without)->positions_only());
}

TEST(CliConvertFormat, BadCallsAreOneErrorLine) {
  TempDir dir;
  const std::string obj = dir.file("m.obj");
  gimforge::io::write_mesh(obj, gimforge::make_torus(1.0, 0.4, 12, 6));
  {
    std::ofstream big(dir.file("big.obj"));
    big << "v 0 1e39 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n";  // beyond float: an error, not a written inf
  }
  for (const auto& args : std::vector<std::vector<std::string>>{
           {"convert-format", obj, "-o", obj},                          // over its input
           {"convert-format", dir.file("missing.obj"), "-o", dir.file("x.ply")},
           {"convert-format", obj, "-o", dir.file("no/such/dir/x.ply")},
           {"convert-format", obj, "-o", dir.file("x.obj")},                // PLY bytes under another name
           {"convert-format", dir.file("big.obj"), "--precision", "float", "-o", dir.file("x.ply")}}) {
    const auto r = run_gimforge(args);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_NE(r.err.find("gimforge: error:"), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("gimforge: error:"), r.err.rfind("gimforge: error:")) << r.err;
  }
  EXPECT_EQ(run_gimforge({"convert-format", obj, "--precision", "half", "-o", dir.file("x.ply")}).exit_code, 2);
  EXPECT_FALSE(std::filesystem::exists(dir.file("x.ply")));
  EXPECT_FALSE(std::filesystem::exists(dir.file("x.obj")));
}

namespace {

std::string bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string bytes(static_cast<std::size_t>(std::filesystem::file_size(path)), '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return bytes;
}

}  // namespace

// A binary STL is streamed (io/stl_stream.h) into the very bytes that reading it whole and writing it gives.
TEST(CliConvertFormat, BinaryStlIsStreamedIntoTheBytesOfReadingItWhole) {
  TempDir dir;
  const std::string stl = dir.file("utm.stl");
  gimforge::TriMesh t = gimforge::make_torus(1.0, 0.4, 40, 20);
  for (gimforge::Vec3& p : t.positions) {  // float coordinates, as a scan's STL has them (the writer keeps them)
    p += gimforge::Vec3(412345.0, 5312345.0, -0.0);
    for (int k = 0; k < 3; ++k) {
      const volatile float rounded = static_cast<float>(p[k]);  // volatile: GCC 12 -O2 dropped the rounding
      p[k] = static_cast<double>(rounded);
    }
  }
  gimforge::io::write_mesh(stl, t);
  const gimforge::TriMesh whole = gimforge::io::read_mesh(stl);
  for (const char* precision : {"auto", "double"}) {
    const std::string ply = dir.file(std::string("streamed_") + precision + ".ply");
    const std::string expected = dir.file(std::string("whole_") + precision + ".ply");
    const auto r = run_gimforge({"convert-format", stl, "--precision", precision, "--json", "-o", ply});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    EXPECT_TRUE(j.at("streamed").get<bool>());
    EXPECT_EQ(j.at("vertices").get<std::size_t>(), whole.num_vertices());
    gimforge::io::write_ply(expected, whole, {.binary = true, .double_precision = std::string(precision) == "double",
                                              .comment = "gimforge convert-format"});
    EXPECT_EQ(bytes_of(ply), bytes_of(expected)) << precision;
  }
  // Only the inputs and outputs are left: no side file.
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.file("")), std::filesystem::directory_iterator()), 5);
}

TEST(CliConvertFormat, AStreamedStlWithANanIsOneErrorLineAndNoFile) {
  TempDir dir;
  const std::string stl = dir.file("nan.stl");
  gimforge::io::write_mesh(stl, gimforge::make_torus(1.0, 0.4, 12, 6));
  {
    std::fstream f(stl, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(84 + 50 + 12 + 4);  // triangle 1, first corner, y
    const std::uint32_t nan = 0x7fc00000u;
    f.write(reinterpret_cast<const char*>(&nan), 4);
  }
  const auto r = run_gimforge({"convert-format", stl, "-o", dir.file("x.ply")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("triangle 1 has a non-finite coordinate"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("gimforge: error:"), r.err.rfind("gimforge: error:")) << r.err;
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.file("")), std::filesystem::directory_iterator()), 1);
}

// Formats read whole are refused, before any reading, when that would take more memory than there is.
TEST(CliConvertFormat, AHugeTextScanIsRefusedBeforeItIsRead) {
  TempDir dir;
  const std::string obj = dir.file("huge.obj");
  { std::ofstream(obj) << "v 0 0 0\n"; }
  std::filesystem::resize_file(obj, std::uintmax_t{1} << 40);  // 1 TB, sparse
  const auto r = run_gimforge({"convert-format", obj, "-o", dir.file("x.ply")}, 60);
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("reads this input whole"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir.file("x.ply")));
}
