// Tests of io/mesh_io.h on bad input: strict rejection with one-line messages that start with the path and
// the right exception type, every truncation and random corruption of valid files of every format.
#include "io/ply_ranges.h"
#include "tests/unit/io/mesh_io_test_support.h"

namespace {

using namespace gimforge::test_io;  // NOLINT(google-build-using-namespace): the shared test vocabulary

// ---------------------------------------------------------------------------------------------------
// Bad input: one-line messages starting with the path, the right exception type
// ---------------------------------------------------------------------------------------------------

const std::string kPlyHead =
    "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n";

std::string triangle_ply(float x0 = 0.0f, std::int32_t i2 = 2, std::uint8_t count = 3) {
  Bytes b;
  b.text(kPlyHead);
  b.put(x0).put(0.0f).put(0.0f).put(1.0f).put(0.0f).put(0.0f).put(0.0f).put(1.0f).put(0.0f);
  b.put(count).put(0).put(1).put(i2);
  return b.str();
}

const std::string kAsciiHead =
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n";

TEST(BadInput, FileSystemProblems) {
  TempDir dir;
  expect_read_error<gimforge::IoError>(dir / "missing.ply", {"does not exist"});
  fs::create_directory(dir / "d.ply");
  expect_read_error<gimforge::IoError>(dir / "d.ply", {"directory"});
  write_file(dir / "empty.ply", "");
  expect_read_error(dir / "empty.ply", {"empty"});
  write_file(dir / "m.xyz", "1 2 3\n");
  expect_read_error<gimforge::IoError>(dir / "m.xyz", {"unknown mesh file extension '.xyz'"});
  write_file(dir / "noext", "1 2 3\n");
  expect_read_error<gimforge::IoError>(dir / "noext", {"no file extension"});
  EXPECT_EQ(gimforge::io::format_from_extension("A.PlY"), MeshFormat::Ply);
  EXPECT_STREQ(gimforge::io::format_name(MeshFormat::Off), "OFF");
}

TEST(BadInput, UnreadableFile) {
  TempDir dir;
  write_file(dir / "locked.ply", triangle_ply());
  fs::permissions(dir / "locked.ply", fs::perms::none);
  // Root reads any file: act as user nobody for the read (the saved set-user-ID lets us return, also
  // when an assertion leaves the test early).
  struct EffectiveUser {
    uid_t saved = ::geteuid();
    explicit EffectiveUser(uid_t uid) {
      if (saved == 0 && ::seteuid(uid) != 0) throw std::runtime_error("cannot drop privileges");
    }
    ~EffectiveUser() {
      if (saved == 0) (void)!::seteuid(0);
    }
  } nobody(65534);
  expect_read_error<gimforge::IoError>(dir / "locked.ply", {"Permission denied"});
}

TEST(BadInput, WrongFormatBehindExtension) {
  TempDir dir;
  write_file(dir / "obj.ply", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  expect_read_error(dir / "obj.ply", {"not a PLY file", "OBJ"});
  write_file(dir / "ply.off", triangle_ply());
  expect_read_error(dir / "ply.off", {"not an OFF file", "PLY"});
  write_file(dir / "junk.obj", std::string("v 0 0 0\n\x01\x02\x00\xff", 12));
  expect_read_error(dir / "junk.obj", {"not an OBJ file", "binary data"});
  write_file(dir / "ply.obj", triangle_ply());
  expect_read_error(dir / "ply.obj", {"not an OBJ file"});
  write_file(dir / "off.stl", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  expect_read_error(dir / "off.stl", {"not an STL file", "OFF"});
  write_file(dir / "hello.obj", "hello world\n");
  expect_read_error(dir / "hello.obj", {"line 1", "unknown OBJ statement 'hello'"});
}

TEST(BadInput, PlyHeaderProblems) {
  TempDir dir;
  write_file(dir / "a.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n");
  expect_read_error(dir / "a.ply", {"missing end_header"});
  write_file(dir / "b.ply", kAsciiHead.substr(0, kAsciiHead.find("end_header")) + "0 0 0\n");
  expect_read_error(dir / "b.ply", {"missing end_header"});
  write_file(dir / "c.ply", "ply\nformat ascii 1.0\nelemnt vertex 3\nend_header\n");
  expect_read_error(dir / "c.ply", {"line 3", "bad PLY header", "'elemnt'"});
  write_file(dir / "d.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty flot x\nend_header\n");
  expect_read_error(dir / "d.ply", {"unknown property type 'flot'"});
  write_file(dir / "e.ply",
             "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n");
  expect_read_error(dir / "e.ply", {"no scalar 'z'"});
  write_file(dir / "f.ply",
             "ply\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n");
  expect_read_error(dir / "f.ply", {"no format line"});
  write_file(dir / "g.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n");
  expect_read_error(dir / "g.ply", {"unknown format"});
  write_file(dir / "h.ply", "ply\nformat ascii 1.0\nelement vertex -5\nend_header\n");
  expect_read_error(dir / "h.ply", {"element count"});
  write_file(dir / "i.ply",
             "ply\nformat ascii 1.0\nelement face 0\nproperty list float int vertex_indices\nend_header\n");
  expect_read_error(dir / "i.ply", {"not an integer type"});
  write_file(dir / "j.ply",
             "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n");
  expect_read_error(dir / "j.ply", {"no vertex element"});
  write_file(dir / "k.ply", "PLY\nformat ascii 1.0\n");
  expect_read_error(dir / "k.ply", {"not a PLY file"});
  write_file(dir / "l.ply",  // triangle strips only: it read as a mesh without faces
             "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
             "element tristrips 1\nproperty list int int vertex_indices\nend_header\n"
             "0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 2 3\n");
  expect_read_error(dir / "l.ply", {"triangle strips (element 'tristrips')", "'face' element"});
  write_file(dir / "m.ply",  // the same with an empty face element beside the strips
             "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
             "element face 0\nproperty list uchar int vertex_indices\n"
             "element tristrips 1\nproperty list int int vertex_indices\nend_header\n"
             "0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 2 3\n");
  expect_read_error(dir / "m.ply", {"triangle strips (element 'tristrips')"});
}

TEST(BadInput, PlyCountsLargerThanTheFile) {
  TempDir dir;
  std::string hostile = kPlyHead;
  hostile.replace(hostile.find("vertex 3"), 8, "vertex 4000000000");
  hostile.resize(200, '\0');
  write_file(dir / "hostile.ply", hostile);
  expect_read_error(dir / "hostile.ply",
                    {"truncated binary PLY", "of 4000000000 ends past the end of the file", "(file is 200 bytes)"});
  std::string faces = triangle_ply();
  faces.replace(faces.find("face 1"), 6, "face 4000000000");
  write_file(dir / "faces.ply", faces);
  // The bytes the vertices take come first: 3 float32 triples (a probe read "2390 face records of at least 1
  // bytes each, but only 29822 bytes follow" as a contradiction).
  expect_read_error(dir / "faces.ply", {"truncated binary PLY", "4000000000 face records",
                                        "after at least 36 bytes of the elements before them, but only 49 bytes follow"});
  std::string ascii = kAsciiHead + "0 0 0\n";
  ascii.replace(ascii.find("vertex 3"), 8, "vertex 4000000000");
  write_file(dir / "ascii.ply", ascii);
  expect_read_error(dir / "ascii.ply", {"truncated ASCII PLY", "vertex 1 of 4000000000"});
  std::string skipped = triangle_ply();
  skipped.replace(skipped.find("end_header"), 10, "element junk 3000000000\nproperty double d\nend_header");
  write_file(dir / "junk.ply", skipped);
  expect_read_error(dir / "junk.ply", {"truncated binary PLY", "3000000000 junk records"});
}

TEST(BadInput, TruncatedBinaryPly) {
  TempDir dir;
  const std::string full = triangle_ply();
  write_file(dir / "t.ply", full.substr(0, full.size() - 5));
  expect_read_error(dir / "t.ply", {"truncated binary PLY: face 0 of 1 ends past the end of the file (file is " +
                                    std::to_string(full.size() - 5) + " bytes)"});
  write_file(dir / "v.ply", full.substr(0, kPlyHead.size() + 20));
  expect_read_error(dir / "v.ply", {"truncated binary PLY: vertex 1 of 3"});
  write_file(dir / "list.ply", triangle_ply(0.0f, 2, 255));
  expect_read_error(dir / "list.ply", {"truncated binary PLY: face 0 of 1"});
}

TEST(BadInput, TruncatedAndMalformedAsciiPly) {
  TempDir dir;
  write_file(dir / "t.ply", kAsciiHead + "0 0 0\n1 0 0\n");
  expect_read_error(dir / "t.ply", {"truncated ASCII PLY", "vertex 2 of 3"});
  write_file(dir / "f.ply", kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n");
  expect_read_error(dir / "f.ply", {"truncated ASCII PLY", "face 0 of 1"});
  write_file(dir / "n.ply", kAsciiHead + "0 0 0\n1 abc 0\n0 1 0\n3 0 1 2\n");
  expect_read_error(dir / "n.ply", {"line 11", "vertex 1", "'abc' is not a number"});
  write_file(dir / "x.ply", kAsciiHead + "0 0 0 7\n1 0 0\n0 1 0\n3 0 1 2\n");
  expect_read_error(dir / "x.ply", {"line 10", "1 more values"});
  write_file(dir / "u.ply", kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n300 0 1 2\n");
  expect_read_error(dir / "u.ply", {"value 300 does not fit the PLY type uchar"});
  write_file(dir / "l.ply", kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n");
  expect_read_error(dir / "l.ply", {"a list of 4 values, but the line has only 3 more"});
  write_file(dir / "e.ply", kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n");
  expect_read_error(dir / "e.ply", {"line 14", "unexpected data after the last element"});
  write_file(dir / "i.ply", kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2.5\n");
  expect_read_error(dir / "i.ply", {"'2.5' is not an integer"});
}

TEST(BadInput, NonFiniteValues) {
  TempDir dir;
  write_file(dir / "nan.ply", triangle_ply(std::numeric_limits<float>::quiet_NaN()));
  expect_read_error(dir / "nan.ply", {"vertex 0 has a non-finite coordinate (nan)"});
  write_file(dir / "inf.ply", kAsciiHead + "0 0 0\n1 0 0\n0 Inf 0\n3 0 1 2\n");
  expect_read_error(dir / "inf.ply", {"line 12", "vertex 2 has a non-finite coordinate (inf)"});
  write_file(dir / "big.ply", kAsciiHead + "0 0 0\n1 0 0\n0 1e300 0\n3 0 1 2\n");  // overflows float
  expect_read_error(dir / "big.ply", {"vertex 2 has a non-finite coordinate (inf)"});
  write_file(dir / "nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n");
  expect_read_error(dir / "nan.obj", {"line 2", "vertex 1 has a non-finite coordinate (nan)"});
  write_file(dir / "inf.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 -inf 0\n3 0 1 2\n");
  expect_read_error(dir / "inf.off", {"vertex 2 has a non-finite coordinate (-inf)"});
  write_file(dir / "inf.stl",
             "solid s\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 1e999 0 0\nvertex 0 1 0\n"
             "endloop\nendfacet\nendsolid\n");
  expect_read_error(dir / "inf.stl", {"line 5", "facet 0 has a non-finite coordinate (inf)"});
  TriMesh m = cube();
  m.positions[2].y() = std::numeric_limits<double>::quiet_NaN();
  write_file(dir / "nan.stl", stl_binary(m));
  expect_read_error(dir / "nan.stl", {"triangle 0 has a non-finite coordinate (nan)"});
}

TEST(BadInput, ANonFiniteNormalDropsTheNormalsNotTheMesh) {
  // gimforge computes the normals it uses: a broken one in the file refused every command, convert-format
  // --positions-only included.
  TempDir dir;
  const std::string head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                           "property float nx\nproperty float ny\nproperty float nz\n"
                           "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  write_file(dir / "n.ply", head + "0 0 0 0 0 1\n1 0 0 0 nan 1\n0 1 0 0 0 1\n3 0 1 2\n");
  ReadInfo info;
  const TriMesh m = read_mesh(dir / "n.ply", &info);
  EXPECT_EQ(m.num_vertices(), 3u);
  EXPECT_FALSE(m.has_normals());
  EXPECT_EQ(info.dropped_normals, "vertex 1 has a non-finite normal (0, nan, 1)");
  write_file(dir / "n.off", "NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 inf 0 1\n3 0 1 2\n");
  EXPECT_FALSE(read_mesh(dir / "n.off", &info).has_normals());
  EXPECT_EQ(info.dropped_normals, "vertex 2 has a non-finite normal (inf, 0, 1)");
  write_file(dir / "ok.ply", head + "0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n");
  EXPECT_TRUE(read_mesh(dir / "ok.ply", &info).has_normals());
  EXPECT_EQ(info.dropped_normals, "");
}

TEST(BadInput, TheBrickReaderRefusesFarCoordinatesAsLoadingDoes) {
  // mpirun's brick paths read binary PLY in pieces (io/ply_ranges.h): a vertex at 1e300 was refused there
  // as "the surface has no area" or "non-manifold vertices" while one process said what it is.
  TempDir dir;
  TriMesh m = cube();
  m.positions[5].x() = 1e300;
  PlyWriteOptions doubles;
  doubles.double_precision = true;
  write_ply(dir / "far.ply", m, doubles);
  const std::optional<gimforge::io::PlyTriangleFile> file = gimforge::io::PlyTriangleFile::open(dir / "far.ply");
  ASSERT_TRUE(file.has_value());
  try {
    file->read_vertices(0, file->vertices(), [](std::uint64_t, std::span<const Vec3>) {});
    FAIL() << "a vertex at 1e300 read";
  } catch (const gimforge::FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("vertex 5 has a coordinate of magnitude 1e+300, beyond ±1e+18"), std::string::npos)
        << e.what();
  }
  m.positions[5].x() = 1e17;  // inside the bound: read
  write_ply(dir / "near.ply", m, doubles);
  std::size_t read = 0;
  gimforge::io::PlyTriangleFile::open(dir / "near.ply")->read_vertices(0, 8, [&](std::uint64_t, std::span<const Vec3> p) { read += p.size(); });
  EXPECT_EQ(read, 8u);
}

TEST(BadInput, IndicesOutOfRangeAndShortFaces) {
  TempDir dir;
  write_file(dir / "big.ply", triangle_ply(0.0f, 3));
  expect_read_error(dir / "big.ply", {"face 0: vertex index 3 is out of range (the file has 3 vertices)"});
  write_file(dir / "neg.ply", triangle_ply(0.0f, -1));
  expect_read_error(dir / "neg.ply", {"face 0: vertex index -1 is out of range (negative)"});
  write_file(dir / "two.ply", kAsciiHead + "0 0 0\n1 0 0\n0 1 0\n2 0 1\n");
  expect_read_error(dir / "two.ply", {"face 0 has 2 vertices; a face needs at least 3"});
  write_file(dir / "two_binary.ply", triangle_ply(0.0f, 2, 2));
  expect_read_error(dir / "two_binary.ply", {"face 0 has 2 vertices; a face needs at least 3"});
  write_file(dir / "zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
  expect_read_error(dir / "zero.obj", {"line 4", "vertex index 0 is out of range (OBJ indices start at 1)"});
  write_file(dir / "far.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
  expect_read_error(dir / "far.obj", {"line 4: face 0: vertex index 4 is out of range (the file has 3 vertices)"});
  write_file(dir / "back.obj", "v 0 0 0\nv 1 0 0\nf -1 -2 -3\n");
  expect_read_error(dir / "back.obj", {"vertex index -3 is out of range (only 2 vertices precede it)"});
  write_file(dir / "two.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2\n");
  expect_read_error(dir / "two.obj", {"line 5: face 0 has 2 vertices; a face needs at least 3"});
  write_file(dir / "ref.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/x 2 3\n");
  expect_read_error(dir / "ref.obj", {"malformed vertex reference '1/x'"});
  write_file(dir / "big.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n");
  expect_read_error(dir / "big.off", {"line 6: face 0: vertex index 9 is out of range"});
  write_file(dir / "two.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n");
  expect_read_error(dir / "two.off", {"face 0 has 2 vertices"});
  write_file(dir / "two.stl",
             "solid s\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\n"
             "endfacet\nendsolid\n");
  expect_read_error(dir / "two.stl", {"line 6: face 0 has 2 vertices"});
}

TEST(BadInput, OffProblems) {
  TempDir dir;
  write_file(dir / "a.off", "OFF\n3 1 0\n0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n");
  expect_read_error(dir / "a.off", {"line 4", "'zero' is not a number"});
  write_file(dir / "b.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n");
  expect_read_error(dir / "b.off", {"truncated OFF", "vertex 2 of 3"});
  write_file(dir / "c.off", "OFF\n300000000 1 0\n0 0 0\n");
  expect_read_error(dir / "c.off", {"truncated OFF", "vertex 1 of 300000000"});
  write_file(dir / "d.off", "OFF\n3 1 0\n0 0 0\n1 0 0 5\n0 1 0\n3 0 1 2\n");
  expect_read_error(dir / "d.off", {"vertex 1: expected 3 values, found 4"});
  write_file(dir / "e.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n5 0 1 2\n");
  expect_read_error(dir / "e.off", {"face 0 declares 5 vertices but lists only 3"});
  write_file(dir / "f.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n");
  expect_read_error(dir / "f.off", {"unexpected data after the last face"});
  write_file(dir / "g.off", "4OFF\n3 1 0\n");
  expect_read_error(dir / "g.off", {"unsupported OFF variant"});
  write_file(dir / "h.off", "OFF\n-3 1 0\n");
  expect_read_error(dir / "h.off", {"negative vertex count"});
  // Geomview's binary OFF: named as such, not "not an OFF file".
  write_file(dir / "i.off", std::string("OFF BINARY\n\0\0\0\x03\0\0\0\x01\0\0\0\0", 23));
  expect_read_error(dir / "i.off", {"binary OFF ('OFF BINARY') is not supported"});
  write_file(dir / "j.off", "OFF BINARY\n3 1 0\n");
  expect_read_error(dir / "j.off", {"binary OFF ('OFF BINARY') is not supported"});
}

TEST(BadInput, StlProblems) {
  TempDir dir;
  const std::string good = stl_binary(cube());
  write_file(dir / "short.stl", good.substr(0, good.size() - 7));
  expect_read_error(dir / "short.stl", {"binary STL size mismatch", "12 triangles", "(truncated)"});
  write_file(dir / "tiny.stl", std::string("\x01\x02\x03", 3));
  expect_read_error(dir / "tiny.stl", {"too short for a binary STL"});
  write_file(dir / "solidbin.stl", stl_binary(cube(), "solid x") + "junk");
  expect_read_error(dir / "solidbin.stl", {"binary STL size mismatch"});
  const std::string ascii = stl_ascii_text(cube());
  std::string bad = ascii;
  bad.replace(bad.find("endloop"), 7, "endlop");
  write_file(dir / "bad.stl", bad);
  expect_read_error(dir / "bad.stl", {"malformed ASCII STL", "expected 'vertex'", "'endlop'"});
  write_file(dir / "cut.stl", ascii.substr(0, ascii.size() / 2));
  expect_read_error(dir / "cut.stl", {"malformed ASCII STL", "missing 'endsolid'"});
  write_file(dir / "num.stl", "solid s\nfacet normal 0 0 0\nouter loop\nvertex 0 0 x\n");
  expect_read_error(dir / "num.stl", {"line 4", "'x' is not a number"});
}

/// Every prefix of a valid file either reads or throws FormatError: never crashes (the sanitizer build
/// checks for out-of-bounds reads) and never anything else.
TEST(BadInput, EveryTruncationOfValidFilesIsHandled) {
  TempDir dir;
  const TriMesh m = attributed_mesh();
  write_ply(dir / "b.ply", m);
  write_ply(dir / "a.ply", m, PlyWriteOptions{false, false, ""});
  write_file(dir / "c.obj", obj_text(m));
  write_file(dir / "c.off", off_text(m));
  write_file(dir / "a.stl", stl_ascii_text(m));
  write_file(dir / "b.stl", stl_binary(m));
  for (const std::string name : {"b.ply", "a.ply", "c.obj", "c.off", "a.stl", "b.stl"}) {
    const std::string full = read_file(dir / name);
    const fs::path cut = dir / ("cut_" + name);
    for (std::size_t n = 0; n < full.size(); ++n) {
      write_file(cut, full.substr(0, n));
      try {
        (void)read_mesh(cut);
      } catch (const gimforge::FormatError& e) {
        ASSERT_TRUE(std::string(e.what()).starts_with(cut.string() + ": ")) << e.what();
      }
    }
  }
}

/// Random byte corruption of files of every format and encoding (header and body) never crashes and
/// never throws anything but FormatError.
TEST(BadInput, RandomCorruptionIsHandled) {
  TempDir dir;
  std::mt19937 rng(7);
  const TriMesh m = attributed_mesh();
  write_ply(dir / "binary.ply", m);
  write_ply(dir / "ascii.ply", m, PlyWriteOptions{false, false, ""});
  const std::vector<std::pair<std::string, std::string>> bases{
      {"le.ply", pyramid_ply("binary_little_endian", "float", "uchar", "int")},
      {"be.ply", pyramid_ply("binary_big_endian", "double", "ushort", "uint16")},
      {"fast.ply", read_file(dir / "binary.ply")},
      {"attributes.ply", read_file(dir / "ascii.ply")},
      {"pyramid.ply", pyramid_ply("ascii", "float", "uchar", "int")},
      {"c.obj", obj_text(m)},
      {"c.off", off_text(m)},
      {"a.stl", stl_ascii_text(m)},
      {"b.stl", stl_binary(m)}};
  for (const auto& [name, base] : bases) {
    for (int trial = 0; trial < 600; ++trial) {
      std::string bytes = base;
      const int flips = 1 + trial % 4;
      for (int k = 0; k < flips; ++k) {
        const auto at = std::uniform_int_distribution<std::size_t>(0, bytes.size() - 1)(rng);
        const char replacement[] = {'\0', '\n', ' ', '-', '9', '/', 'e', '\xff'};
        bytes[at] = trial % 2 == 0 ? static_cast<char>(std::uniform_int_distribution<int>(0, 255)(rng))
                                   : replacement[std::uniform_int_distribution<std::size_t>(0, 7)(rng)];
      }
      write_file(dir / name, bytes);
      try {
        (void)read_mesh(dir / name);
      } catch (const gimforge::FormatError& e) {
        ASSERT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
      }
    }
  }
}


}  // namespace
