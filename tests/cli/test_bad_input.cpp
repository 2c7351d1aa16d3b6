// End-to-end bad-input tests: each writes one broken mesh file into a temporary directory and runs
// `gimforge info FILE` (or `validate`), expecting exit code 1, exactly one non-empty stderr line
// "gimforge: error: ..." that names the file and the cause, and no hang.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "io/mesh_io.h"
#include "tests/cli/run_process.h"

namespace {

namespace fs = std::filesystem;
using gimforge::test::run_gimforge;

constexpr double kTimeoutSeconds = 60.0;

/// Little-endian bytes of a value (the tests' binary files are little-endian).
template <class T>
std::string le(T v) {
  auto b = std::bit_cast<std::array<char, sizeof(T)>>(v);
  if constexpr (std::endian::native == std::endian::big) std::reverse(b.begin(), b.end());
  return std::string(b.data(), b.size());
}

const std::string kBinaryHead =
    "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n";

const std::string kAsciiHead =
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n";

/// One binary triangle: vertex 0 has x = x0; the face has `count` as its list length and indices 0 1 i2.
std::string binary_triangle(float x0 = 0.0f, std::int32_t i2 = 2, std::uint8_t count = 3) {
  std::string s = kBinaryHead;
  for (const float v : {x0, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f}) s += le(v);
  return s + le(count) + le(std::int32_t{0}) + le(std::int32_t{1}) + le(i2);
}

class CliBadInput : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "gimforge-bad-input-XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
  }
  void TearDown() override {
    std::error_code ec;
    fs::permissions(dir_, fs::perms::owner_all, fs::perm_options::add, ec);
    fs::remove_all(dir_, ec);
  }

  /// Writes `bytes` to a file named `name` in the temporary directory and returns its path.
  std::string file(const std::string& name, std::string_view bytes) const {
    const fs::path p = dir_ / name;
    std::ofstream out(p, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return p.string();
  }
  [[nodiscard]] std::string path(const std::string& name) const { return (dir_ / name).string(); }

  /// Runs `gimforge <command> <file>` and checks the one-line error naming the file and every cause.
  static void expect_error(const std::string& file, std::initializer_list<std::string_view> causes,
                           const std::string& command = "info") {
    const auto start = std::chrono::steady_clock::now();
    const auto r = run_gimforge({command, file}, kTimeoutSeconds);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ASSERT_LT(seconds, kTimeoutSeconds) << "gimforge " << command << " " << file << " did not finish";
    ASSERT_NE(r.exit_code, 128 + SIGKILL) << "killed (timeout)";
    EXPECT_EQ(r.exit_code, 1) << "stderr: " << r.err;
    const auto lines = r.err_lines();
    ASSERT_EQ(lines.size(), 1u) << "stderr: " << r.err;
    const std::string& line = lines.front();
    EXPECT_TRUE(line.starts_with("gimforge: error: ")) << line;
    EXPECT_NE(line.find(file), std::string::npos) << "path missing: " << line;
    for (const std::string_view cause : causes) {
      EXPECT_NE(line.find(cause), std::string::npos) << "'" << cause << "' missing: " << line;
    }
  }

  fs::path dir_;
};

TEST_F(CliBadInput, EmptyFile) { expect_error(file("empty.ply", ""), {"empty"}); }

TEST_F(CliBadInput, TruncatedBinaryPly) {
  const std::string full = binary_triangle();
  expect_error(file("cut.ply", full.substr(0, full.size() - 6)), {"truncated binary PLY", "face 0 of 1"});
}

TEST_F(CliBadInput, HeaderCountsLargerThanFile) {
  std::string s = binary_triangle();
  s.replace(s.find("vertex 3"), 8, "vertex 1000");
  expect_error(file("counts.ply", s), {"truncated binary PLY", "of 1000 ends past the end of the file"});
}

TEST_F(CliBadInput, HostileHugeVertexCount) {
  std::string s = kBinaryHead;
  s.replace(s.find("vertex 3"), 8, "vertex 4000000000");
  s.resize(200, '\x01');
  expect_error(file("hostile.ply", s), {"truncated binary PLY", "of 4000000000", "(file is 200 bytes)"});
}

TEST_F(CliBadInput, NanCoordinateInBinaryPly) {
  expect_error(file("nan.ply", binary_triangle(std::numeric_limits<float>::quiet_NaN())),
               {"vertex 0 has a non-finite coordinate (nan)"});
}

TEST_F(CliBadInput, InfCoordinateInAsciiPly) {
  expect_error(file("inf.ply", kAsciiHead + "0 0 0\n1 0 inf\n0 1 0\n3 0 1 2\n"),
               {"line 11", "vertex 1 has a non-finite coordinate (inf)"});
}

TEST_F(CliBadInput, IndexOutOfRange) {
  expect_error(file("range.ply", binary_triangle(0.0f, 7)), {"face 0: vertex index 7 is out of range"});
}

TEST_F(CliBadInput, NegativeIndex) {
  expect_error(file("negative.ply", binary_triangle(0.0f, -2)), {"vertex index -2 is out of range (negative)"});
}

TEST_F(CliBadInput, Directory) {
  fs::create_directory(path("folder.ply"));
  expect_error(path("folder.ply"), {"is a directory"});
}

TEST_F(CliBadInput, MissingFile) { expect_error(path("nowhere.ply"), {"does not exist"}); }

TEST_F(CliBadInput, UnreadableFile) {
  const std::string p = file("locked.ply", binary_triangle());
  fs::permissions(p, fs::perms::none);
  if (::geteuid() != 0) {
    expect_error(p, {"Permission denied"});
    return;
  }
  // Root reads any file, so run gimforge as user nobody (setpriv from util-linux drops the privileges).
  if (!fs::exists("/usr/bin/setpriv")) GTEST_SKIP() << "running as root without /usr/bin/setpriv to drop privileges";
  const std::vector<std::string> as_nobody{"/usr/bin/setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"};
  std::vector<std::string> probe = as_nobody;
  probe.insert(probe.end(), {GIMFORGE_EXE, "--version"});
  if (gimforge::test::run_process(probe, kTimeoutSeconds).exit_code != 0)
    GTEST_SKIP() << "running as root, and user nobody cannot run " << GIMFORGE_EXE << " from here";
  fs::permissions(dir_, fs::perms::owner_all | fs::perms::others_exec | fs::perms::group_exec);
  std::vector<std::string> command = as_nobody;
  command.insert(command.end(), {GIMFORGE_EXE, "info", p});
  const auto r = gimforge::test::run_process(command, kTimeoutSeconds);
  EXPECT_EQ(r.exit_code, 1) << "stderr: " << r.err;
  const auto lines = r.err_lines();
  ASSERT_EQ(lines.size(), 1u) << "stderr: " << r.err;
  EXPECT_TRUE(lines.front().starts_with("gimforge: error: ")) << lines.front();
  EXPECT_NE(lines.front().find(p), std::string::npos) << lines.front();
  EXPECT_NE(lines.front().find("Permission denied"), std::string::npos) << lines.front();
}

TEST_F(CliBadInput, ObjTextInPlyFile) {
  expect_error(file("really_obj.ply", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"), {"not a PLY file", "OBJ"});
}

TEST_F(CliBadInput, PlyInOffFile) {
  expect_error(file("really_ply.off", binary_triangle()), {"not an OFF file", "PLY"});
}

TEST_F(CliBadInput, BinaryJunkInObjFile) {
  expect_error(file("junk.obj", std::string("\x7f"
                                            "ELF\x02\x01\x01\x00\x00\x00",
                                            10)),
               {"not an OBJ file", "binary data"});
}

TEST_F(CliBadInput, PolygonWithTwoVertices) {
  expect_error(file("two.ply", kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n2 0 1\n"),
               {"face 0 has 2 vertices; a face needs at least 3"});
}

TEST_F(CliBadInput, GarbledPlyHeader) {
  std::string s = binary_triangle();
  s.replace(s.find("property float y"), 16, "proprety float y");
  expect_error(file("garbled.ply", s), {"line 5", "bad PLY header", "'proprety'"});
}

TEST_F(CliBadInput, MissingEndHeader) {
  std::string s = kAsciiHead;
  s.replace(s.find("end_header\n"), 11, "");
  expect_error(file("noend.ply", s + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"), {"missing end_header"});
}

TEST_F(CliBadInput, NonNumericTokenInOff) {
  expect_error(file("word.off", "OFF\n3 1 0\n0 0 0\n1 0 zero\n0 1 0\n3 0 1 2\n"), {"line 4", "'zero' is not a number"});
}

TEST_F(CliBadInput, TruncatedAsciiPly) {
  expect_error(file("short.ply", kAsciiHead + "0 0 0\n1 0 0\n"), {"truncated ASCII PLY", "vertex 2 of 3"});
}

TEST_F(CliBadInput, BinaryStlSizeMismatch) {
  std::string s(80, ' ');
  s += le(std::uint32_t{10});
  s += std::string(50 * 9, '\0');
  expect_error(file("short.stl", s), {"binary STL size mismatch", "10 triangles"});
}

TEST_F(CliBadInput, MalformedAsciiStl) {
  expect_error(file("bad.stl",
                    "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
                    "endfacet\nendsolid x\n"),
               {"line 7", "malformed ASCII STL", "'endfacet'"});
}

TEST_F(CliBadInput, UnknownExtension) { expect_error(file("points.xyz", "0 0 0\n"), {"unknown mesh file extension"}); }

TEST_F(CliBadInput, ObjFaceReferencingVertexZero) {
  expect_error(file("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"),
               {"line 4", "vertex index 0 is out of range (OBJ indices start at 1)"});
}

TEST_F(CliBadInput, FaceListCount255WithTooFewBytes) {
  expect_error(file("list.ply", binary_triangle(0.0f, 2, 255)), {"truncated binary PLY", "face 0 of 1"});
}

TEST_F(CliBadInput, ZeroFaces) {
  expect_error(file("points.ply",
                    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n"),
               {"has no faces"});
}

TEST_F(CliBadInput, NonManifoldFanFailsValidate) {
  // Three triangles share the edge 0-1.
  expect_error(file("fan.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n"),
               {"non-manifold"}, "validate");
}

// A tetrahedron at 1e15 converts with no method (archives hold local frames within ±1e12): validate says so
// too. At 1e300 areas overflow: every command says so instead of "zero-area faces" or an internal
// function's "no area to sample".
TEST_F(CliBadInput, CoordinatesNoMethodTakesAreRefusedByValidateAndEveryReader) {
  const auto tetra = [&](const std::string& name, const std::string& at) {
    return file(name, "v " + at + " 0 0\nv " + at + " 1 0\nv " + at + " 0 1\nv " + at + " 1 1\nf 1 2 3\nf 1 3 4\n"
                      "f 1 4 2\nf 2 4 3\n");
  };
  expect_error(tetra("far.obj", "1e15"), {"lies 1e+15 from the origin", "±1e12"}, "validate");
  for (const std::string at : {"1e20", "1e80", "1e300"}) {  // areas overflow double from about 1e77
    const std::string huge = tetra("huge" + at + ".obj", at);
    const std::string magnitude = "magnitude " + std::string(at.substr(0, 2)) + "+" + std::string(at.substr(2));
    expect_error(huge, {magnitude, "overflow"}, "info");
    expect_error(huge, {magnitude, "overflow"}, "validate");
  }
}

// The mirror image: a mesh 1e-50 across stored an all-zero geometry image with exit 0, at 1e-20 its metric
// took minutes (squared distances underflow single precision), at 1e-150 every command said "no area".
TEST_F(CliBadInput, MeshesTooSmallToMeasureAreRefusedByEveryCommand) {
  const auto tetra = [&](const std::string& name, const std::string& unit) {
    return file(name, "v 0 0 0\nv 0 " + unit + " 0\nv 0 0 " + unit + "\nv " + unit + " " + unit + " " + unit +
                          "\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n");
  };
  for (const std::string unit : {"1e-14", "1e-50", "1e-160", "1e-170"}) {  // 1e-170: the squared diagonal underflows
    const std::string tiny = tetra("tiny" + unit + ".obj", unit);
    for (const std::string command : {"info", "validate"})
      expect_error(tiny, {"the mesh is only", "below 1e-12", "scale the mesh up"}, command);
    const auto r = run_gimforge({"convert", tiny, "--method", "gim", "--size", "65", "-o", path("t.h5")}, kTimeoutSeconds);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
    EXPECT_NE(r.err.find("the mesh is only"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(path("t.h5")));
  }
  const auto r = run_gimforge({"info", tetra("small.obj", "1e-11")}, kTimeoutSeconds);  // 1.7e-11 across: measured
  EXPECT_EQ(r.exit_code, 0) << r.err;
  // 0 across, every vertex at one point: validate passed it, sphere failed with "efficiency -nan", gim blamed its cut.
  const std::string point = tetra("point.obj", "0");
  for (const std::string command : {"info", "validate"})
    expect_error(point, {"the mesh is 0 across: all the vertices its faces use coincide"}, command);
  for (const std::string method : {"gim", "sphere"}) {
    const auto c = run_gimforge({"convert", point, "--method", method, "-o", path("p.h5")}, kTimeoutSeconds);
    EXPECT_EQ(c.exit_code, 1) << c.err;
    EXPECT_NE(c.err.find("point.obj: the mesh is 0 across"), std::string::npos) << c.err;
  }
}

// ---- messages and exit codes of the commands (issue #15, finding 9) ----

/// Two disjoint closed tetrahedra: two connected components.
constexpr std::string_view kTwoTetrahedra =
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 5 0 0\nv 6 0 0\nv 5 1 0\nv 5 0 1\n"
    "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\nf 5 7 6\nf 5 6 8\nf 5 8 7\nf 6 7 8\n";

/// A triangle whose three distinct vertices lie on a line: kept by the repairs, but of zero area.
const std::string kZeroArea = kAsciiHead + "0 0 0\n1 0 0\n2 0 0\n3 0 1 2\n";

TEST_F(CliBadInput, UsageErrorsExitWithTwoAndSayWhat) {
  const std::string mesh = file("t.obj", kTwoTetrahedra);
  const std::string out = path("out.h5");
  {
    const auto r = run_gimforge({"frobnicate", mesh}, kTimeoutSeconds);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
    EXPECT_NE(r.err.find("gimforge: error: unknown command 'frobnicate'"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("convert"), std::string::npos) << "lists the commands: " << r.err;
  }
  for (const std::vector<std::string>& args : std::vector<std::vector<std::string>>{
           {"convert", mesh, "--method", "gim", "--size", "100", "-o", out},
           {"convert", mesh, "--method", "gim", "--size", "1048577", "-o", out},
           {"batch", "-o", out},
           {"batch", "--method", "gim", "--size", "100", "--input", dir_.string(), "-o", out},
           {"-j", "100000", "info", mesh}}) {
    const auto r = run_gimforge(args, kTimeoutSeconds);
    std::string shown;
    for (const std::string& a : args) shown += a + " ";
    EXPECT_EQ(r.exit_code, 2) << shown << "\n" << r.err;
    EXPECT_EQ(r.err.find("out of memory"), std::string::npos) << shown << r.err;
    EXPECT_FALSE(fs::exists(out)) << shown;
  }
  // One line, as every error; the number checks come before the ranges, which called "abc" a value out of
  // range and printed double's range in 309 digits.
  for (const auto& [args, says] : std::vector<std::pair<std::vector<std::string>, std::string>>{
           {{"metrics", mesh, mesh, "--samples", "abc"}, "--samples: 'abc' is not a decimal integer"},
           {{"convert", mesh, "--size", "+129", "-o", out}, "--size: '+129' is not a decimal integer"},
           {{"synth", "terrain", "--grid", "4", "--seed", "-1", "-o", path("t.ply")}, "--seed: '-1' is negative"},
           {{"synth", "terrain", "--grid", "4", "--noise", "abc", "-o", path("t.ply")}, "--noise: 'abc' is not a number"},
           {{"batch", "--input", dir_.string(), "-o", out, "--item-timeout", "-1"}, "--item-timeout: Value -1 not in range"},
           // Beyond the option's type: CLI11's "Could not convert: --level = 4294967296".
           {{"reconstruct", out, "--level", "4294967296", "-o", path("r.ply")}, "--level: '4294967296' is out of range"},
           // An empty region was taken as none (--wrap '' was refused).
           {{"convert", mesh, "--sampling", "adaptive", "--roi", "", "-o", out}, "--roi: empty: it names no region"}}) {
    const auto r = run_gimforge(args, kTimeoutSeconds);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
    EXPECT_TRUE(r.err.starts_with("gimforge: error: " + says)) << r.err;
    EXPECT_LT(r.err.size(), 200u) << r.err;
  }
}

TEST_F(CliBadInput, ConversionErrorsNameTheFileAndWhatWorks) {
  // Several components: the message points to the methods that convert them by their options.
  {
    const std::string two = file("two.obj", kTwoTetrahedra);
    const auto r = run_gimforge({"convert", two, "--method", "gim", "-o", path("o.h5")}, kTimeoutSeconds);
    EXPECT_EQ(r.exit_code, 1);
    ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
    const std::string line = r.err_lines().front();
    EXPECT_TRUE(line.starts_with("gimforge: error: " + two + ": the mesh has 2 connected components")) << line;
    EXPECT_NE(line.find("--method relief"), std::string::npos) << line;
    EXPECT_NE(line.find("--method mcgim"), std::string::npos) << line;
  }
  // Every face degenerate: removed by the repairs, and the message says so.
  const std::string degenerate = kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n3 0 1 1\n";
  for (const char* method : {"gim", "sphere", "relief"}) {
    const auto r = run_gimforge({"convert", file("deg.ply", degenerate), "--method", method, "-o", path("o.h5")},
                                kTimeoutSeconds);
    EXPECT_EQ(r.exit_code, 1);
    ASSERT_FALSE(r.err_lines().empty());
    const std::string line = r.err_lines().back();
    EXPECT_TRUE(line.starts_with("gimforge: error: " + path("deg.ply") + ": no faces left after repair")) << line;
  }
  // Zero area: the kernel's words, with the file's name and without the kernel function's.
  for (const char* method : {"gim", "sphere"}) {
    const auto r = run_gimforge({"convert", file("flat.ply", kZeroArea), "--method", method, "-o", path("o.h5")},
                                kTimeoutSeconds);
    EXPECT_EQ(r.exit_code, 1);
    ASSERT_FALSE(r.err_lines().empty());
    const std::string line = r.err_lines().back();
    EXPECT_TRUE(line.starts_with("gimforge: error: " + path("flat.ply") + ": ")) << line;
    EXPECT_EQ(line.find("sample_surface"), std::string::npos) << line;
  }
}

TEST_F(CliBadInput, OutputPathsAreCheckedBeforeTheWork) {
  const std::string mesh = file("t.obj", kTwoTetrahedra);
  // A missing directory: named with the path given (not a temporary name), before the conversion.
  const std::string missing = path("nowhere/out.h5");
  for (const std::vector<std::string>& args : std::vector<std::vector<std::string>>{
           {"convert", mesh, "--method", "relief", "--grid", "2", "--texture", "8", "-o", missing},
           {"batch", "--input", dir_.string(), "--method", "relief", "-o", missing}}) {
    const auto r = run_gimforge(args, kTimeoutSeconds);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
    EXPECT_EQ(r.err_lines()[0], "gimforge: error: " + missing + ": cannot write here: directory '" +
                                    path("nowhere") + "' does not exist");
    EXPECT_EQ(r.out, "");
  }
  // -o DIR: one line.
  fs::create_directory(dir_ / "adir");
  const auto r = run_gimforge({"convert", mesh, "--method", "relief", "--grid", "2", "--texture", "8", "-o",
                               path("adir")}, kTimeoutSeconds);
  EXPECT_EQ(r.exit_code, 1);
  ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
  EXPECT_NE(r.err.find(path("adir") + ": is a directory"), std::string::npos) << r.err;
  // preview -o FILE and reconstruct -o DIR, on a real archive.
  const std::string archive = path("a.h5");
  ASSERT_EQ(run_gimforge({"-q", "convert", mesh, "--method", "relief", "--grid", "2", "--texture", "8", "--no-metric",
                          "-o", archive}, kTimeoutSeconds).exit_code, 0);
  const auto p = run_gimforge({"preview", archive, "-o", mesh}, kTimeoutSeconds);
  EXPECT_EQ(p.exit_code, 1);
  ASSERT_EQ(p.err_lines().size(), 1u) << p.err;
  EXPECT_EQ(p.err.find("internal error"), std::string::npos) << p.err;
  EXPECT_NE(p.err.find(mesh + ": is not a directory"), std::string::npos) << p.err;
  const auto q = run_gimforge({"reconstruct", archive, "-o", path("adir")}, kTimeoutSeconds);
  EXPECT_EQ(q.exit_code, 1);
  EXPECT_EQ(q.err_lines().size(), 1u) << q.err;
  EXPECT_EQ(q.out, "");
  // batch --log-dir where no folder can be made: the cause ("No such file or directory" of the log file once).
  const auto l = run_gimforge({"batch", "--input", dir_.string(), "--method", "relief", "--log-dir", mesh + "/logs",
                               "-o", path("b.h5")}, kTimeoutSeconds);
  EXPECT_EQ(l.exit_code, 1);
  ASSERT_EQ(l.err_lines().size(), 1u) << l.err;
  EXPECT_NE(l.err.find(mesh + "/logs: cannot create the --log-dir folder: Not a directory"), std::string::npos) << l.err;
}

TEST_F(CliBadInput, ReconstructListsTheValidLevels) {
  const std::string archive = path("g.h5");
  ASSERT_EQ(run_gimforge({"-q", "convert", GIMFORGE_TEST_DATA_DIR "/tetra.obj", "--method", "gim", "--size", "65",
                          "--no-metric", "-o", archive}, kTimeoutSeconds).exit_code, 0);
  const auto r = run_gimforge({"reconstruct", archive, "--level", "5", "-o", path("r.ply")}, kTimeoutSeconds);
  EXPECT_EQ(r.exit_code, 1);
  ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
  EXPECT_NE(r.err.find(archive + ":/gim/tetra: level 5 is out of range: a 65x65 geometry image has levels 0..0"),
            std::string::npos) << r.err;
}

// Named pipes where files are expected: every reader refuses them at once (an open() of a FIFO waits for a
// writer, and no signal handler can stop that wait). A batch converts the other items; a list that is a pipe
// nobody writes to reads as empty; an archive that is a pipe is refused.
TEST_F(CliBadInput, NamedPipesAreRefusedNotWaitedOn) {
  const std::string fifo_mesh = path("pipe.ply"), fifo_text = path("pipe.txt"), fifo_h5 = path("pipe.h5");
  for (const std::string& f : {fifo_mesh, fifo_text, fifo_h5}) ASSERT_EQ(::mkfifo(f.c_str(), 0600), 0) << f;
  expect_error(fifo_mesh, {"not a regular file"});
  expect_error(fifo_h5, {"not a regular file"}, "ls");
  expect_error(fifo_h5, {"not a regular file"}, "validate");
  const std::string list = file("list.txt", std::string(GIMFORGE_TEST_DATA_DIR "/tetra.obj\n") + fifo_mesh + "\n");
  const auto b = run_gimforge({"batch", "--list", list, "--size", "65", "--no-metric", "-o", path("b.h5")},
                              kTimeoutSeconds);
  EXPECT_EQ(b.exit_code, 3) << b.err;  // partial: the tetrahedron converted, the pipe failed
  EXPECT_NE(b.err.find(fifo_mesh + ": is not a regular file"), std::string::npos) << b.err;
  const auto l = run_gimforge({"batch", "--list", fifo_text, "--size", "65", "-o", path("l.h5")}, kTimeoutSeconds);
  EXPECT_EQ(l.exit_code, 1) << l.err;
  EXPECT_NE(l.err.find(fifo_text + ": the list names no mesh"), std::string::npos) << l.err;
  const auto j = run_gimforge({"batch", "--job", fifo_text, "-o", path("j.h5")}, kTimeoutSeconds);
  EXPECT_EQ(j.exit_code, 1) << j.err;
  EXPECT_EQ(j.err_lines().size(), 1u) << j.err;
}

}  // namespace

TEST(CliMemory, RequestsThatCannotFitAreRefusedBeforeAnyWork) {
  // They ran until the kernel asked for the memory (minutes), then ended with "out of memory", or were
  // killed without a word by the OOM killer. The address-space limit (ulimit -v) is one of the limits the
  // estimate is held against (jobs/memory_budget.h; another may be lower here); ASan's shadow memory does
  // not start under it.
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer does not start under ulimit -v";
#else
  const std::string kitten = std::string(GIMFORGE_TEST_DATA_DIR) + "/kitten.ply";
  const std::string out = (fs::temp_directory_path() / "gimforge-memory-never-written.h5").string();
  const auto limited = [](const std::vector<std::string>& args) {
    return gimforge::test::run_gimforge_after("ulimit -v 1500000", args, kTimeoutSeconds);
  };
  for (const auto& [args, advice] :
       {std::pair{std::vector<std::string>{"convert", kitten, "--method", "sphere", "--n", "4096", "-o", out}, "lower --n"},
        std::pair{std::vector<std::string>{"convert", kitten, "--method", "relief", "--grid", "1024", "--no-metric", "-o", out},
                  "lower --grid"},
        std::pair{std::vector<std::string>{"convert", kitten, "--size", "65", "--metric-samples", "134217728", "-o", out},
                  "--metric-samples"},
        // A relief map's texels: known once its cells are, refused before they are sampled.
        std::pair{std::vector<std::string>{"convert", kitten, "--method", "relief", "--grid", "32", "--texture", "256",
                                           "--no-metric", "-o", out},
                  "use a smaller grid or texture"},
        std::pair{std::vector<std::string>{"metrics", kitten, kitten, "--samples", "134217728"}, "lower --samples"}}) {
    SCOPED_TRACE(args[args.size() - 3]);
    const auto r = limited(args);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    const auto lines = r.err_lines();
    ASSERT_EQ(lines.size(), 1u) << r.err;
    EXPECT_NE(lines[0].find("GB of memory, more than the"), std::string::npos) << lines[0];
    EXPECT_NE(lines[0].find(advice), std::string::npos) << lines[0];
    EXPECT_FALSE(fs::exists(out));
  }
#endif
}
