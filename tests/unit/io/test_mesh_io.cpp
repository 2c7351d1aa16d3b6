// Tests of io/mesh_io.h: PLY/OBJ/OFF/STL readers (every encoding and scalar type, polygons, skipped
// elements and properties), the PLY writer (round trips), agreement between formats, real meshes, and
// strict rejection of bad input with one-line messages that start with the path.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "io/mesh_io.h"
#include "kernels/core/errors.h"

namespace {

namespace fs = std::filesystem;
using gimforge::Face;
using gimforge::TriMesh;
using gimforge::Vec3;
using gimforge::Vec3f;
using gimforge::io::MeshFormat;
using gimforge::io::PlyWriteOptions;
using gimforge::io::read_mesh;
using gimforge::io::ReadInfo;
using gimforge::io::write_ply;

// ---------------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------------

/// A fresh directory under the system temp dir, removed with its contents at the end of the test.
class TempDir {
 public:
  TempDir() {
    std::string pattern = (fs::temp_directory_path() / "gimforge-test-io-XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  [[nodiscard]] fs::path operator/(const std::string& name) const { return path_ / name; }
  [[nodiscard]] const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

void write_file(const fs::path& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  ASSERT_TRUE(out.good()) << path;
}

std::string read_file(const fs::path& path) {
  std::string bytes(fs::file_size(path), '\0');
  std::ifstream in(path, std::ios::binary);
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return bytes;
}

/// Shortest text that reads back as the same double.
std::string num(double v) {
  std::array<char, 64> buf{};
  const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return std::string(buf.data(), r.ptr);
}

/// Builds binary file contents in either byte order.
class Bytes {
 public:
  explicit Bytes(bool big_endian = false) : big_(big_endian) {}

  Bytes& text(std::string_view s) {
    s_ += s;
    return *this;
  }

  template <class T>
  Bytes& put(T v) {
    auto b = std::bit_cast<std::array<char, sizeof(T)>>(v);
    if (big_ != (std::endian::native == std::endian::big)) std::reverse(b.begin(), b.end());
    s_.append(b.data(), b.size());
    return *this;
  }

  /// Appends `v` as the PLY type `type` (char, uchar, ..., double, or the sized names).
  Bytes& value(std::string_view type, double v) {
    if (type == "char" || type == "int8") return put(static_cast<std::int8_t>(v));
    if (type == "uchar" || type == "uint8") return put(static_cast<std::uint8_t>(v));
    if (type == "short" || type == "int16") return put(static_cast<std::int16_t>(v));
    if (type == "ushort" || type == "uint16") return put(static_cast<std::uint16_t>(v));
    if (type == "int" || type == "int32") return put(static_cast<std::int32_t>(v));
    if (type == "uint" || type == "uint32") return put(static_cast<std::uint32_t>(v));
    if (type == "float" || type == "float32") return put(static_cast<float>(v));
    return put(v);
  }

  [[nodiscard]] const std::string& str() const { return s_; }

 private:
  bool big_;
  std::string s_;
};

/// Expects read_mesh(path) to throw E with a one-line message "<path>: ..." containing every needle.
template <class E = gimforge::FormatError>
void expect_read_error(const fs::path& path, std::initializer_list<std::string_view> needles) {
  try {
    (void)read_mesh(path);
    ADD_FAILURE() << "no exception reading " << path;
  } catch (const E& e) {
    const std::string msg = e.what();
    EXPECT_TRUE(msg.starts_with(path.string() + ": ")) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    for (const std::string_view n : needles)
      EXPECT_NE(msg.find(n), std::string::npos) << "'" << n << "' not in: " << msg;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type for " << path << ": " << e.what();
  }
}

void expect_same_mesh(const TriMesh& a, const TriMesh& b) {
  ASSERT_EQ(a.positions.size(), b.positions.size());
  for (std::size_t i = 0; i < a.positions.size(); ++i) ASSERT_EQ(a.positions[i], b.positions[i]) << "vertex " << i;
  ASSERT_EQ(a.faces, b.faces);
  ASSERT_EQ(a.colors.size(), b.colors.size());
  for (std::size_t i = 0; i < a.colors.size(); ++i) ASSERT_EQ(a.colors[i], b.colors[i]) << "colour " << i;
  ASSERT_EQ(a.normals.size(), b.normals.size());
  for (std::size_t i = 0; i < a.normals.size(); ++i) ASSERT_EQ(a.normals[i], b.normals[i]) << "normal " << i;
}

/// A unit cube with vertices numbered in order of first appearance in its faces (as STL welding numbers them).
TriMesh cube() {
  TriMesh m;
  const std::array<Vec3, 8> corners{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0),
                                    Vec3(0, 0, 1), Vec3(1, 0, 1), Vec3(1, 1, 1), Vec3(0, 1, 1)};
  const std::array<std::array<std::uint32_t, 4>, 6> quads{
      {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}}};
  std::array<int, 8> renumber{};
  renumber.fill(-1);
  const auto id = [&](std::uint32_t c) {
    if (renumber[c] < 0) {
      renumber[c] = static_cast<int>(m.positions.size());
      m.positions.push_back(corners[c]);
    }
    return static_cast<std::uint32_t>(renumber[c]);
  };
  for (const auto& q : quads) {
    m.faces.push_back(Face{id(q[0]), id(q[1]), id(q[2])});
    m.faces.push_back(Face{id(q[0]), id(q[2]), id(q[3])});
  }
  return m;
}

/// A small mesh with float-exact coordinates, normals and colours.
TriMesh attributed_mesh() {
  TriMesh m = cube();
  for (std::size_t i = 0; i < m.positions.size(); ++i) {
    m.positions[i] = m.positions[i] * 1.5 - Vec3(0.25, 0.125, 0.0625);
    m.normals.push_back(Vec3f(0.0f, 0.6f, 0.8f) * (i % 2 == 0 ? 1.0f : -1.0f));
    m.colors.push_back(Vec3f(static_cast<float>(static_cast<double>(i * 30) / 255.0), static_cast<float>(255 / 255.0),
                             static_cast<float>(7 / 255.0)));
  }
  return m;
}

std::string obj_text(const TriMesh& m) {
  std::string s = "# cube\n";
  for (const Vec3& p : m.positions) s += "v " + num(p.x()) + " " + num(p.y()) + " " + num(p.z()) + "\n";
  for (const Face& f : m.faces)
    s += "f " + std::to_string(f[0] + 1) + " " + std::to_string(f[1] + 1) + " " + std::to_string(f[2] + 1) + "\n";
  return s;
}

std::string off_text(const TriMesh& m) {
  std::string s = "OFF\n" + std::to_string(m.positions.size()) + " " + std::to_string(m.faces.size()) + " 0\n";
  for (const Vec3& p : m.positions) s += num(p.x()) + " " + num(p.y()) + " " + num(p.z()) + "\n";
  for (const Face& f : m.faces)
    s += "3 " + std::to_string(f[0]) + " " + std::to_string(f[1]) + " " + std::to_string(f[2]) + "\n";
  return s;
}

std::string stl_ascii_text(const TriMesh& m) {
  std::string s = "solid test\n";
  for (const Face& f : m.faces) {
    s += " facet normal 0 0 0\n  outer loop\n";
    for (const std::uint32_t v : f) {
      const Vec3& p = m.positions[v];
      s += "   vertex " + num(p.x()) + " " + num(p.y()) + " " + num(p.z()) + "\n";
    }
    s += "  endloop\n endfacet\n";
  }
  return s + "endsolid test\n";
}

std::string stl_binary(const TriMesh& m, std::string_view header = "binary stl") {
  Bytes b;
  std::string h(header);
  h.resize(80, ' ');
  b.text(h).put(static_cast<std::uint32_t>(m.faces.size()));
  for (const Face& f : m.faces) {
    b.put(0.0f).put(0.0f).put(0.0f);
    for (const std::uint32_t v : f) {
      for (const double x : m.positions[v]) b.put(static_cast<float>(x));
    }
    b.put(std::uint16_t{0});
  }
  return b.str();
}

/// Square pyramid: 5 vertices, a quad base and 4 triangles (6 triangles once fan-triangulated).
const std::array<std::array<double, 3>, 5> kPyramid{{{0, 0, 0}, {2, 0, 0}, {2, 2, 0}, {0, 2, 0}, {1, 1, 2}}};
const std::vector<std::vector<int>> kPyramidFaces{{0, 3, 2, 1}, {0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}};
const std::vector<Face> kPyramidTriangles{{0, 3, 2}, {0, 2, 1}, {0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}};

void expect_pyramid(const TriMesh& m) {
  ASSERT_EQ(m.positions.size(), 5u);
  for (std::size_t i = 0; i < 5; ++i) {
    EXPECT_EQ(m.positions[i], Vec3(kPyramid[i][0], kPyramid[i][1], kPyramid[i][2])) << "vertex " << i;
  }
  EXPECT_EQ(m.faces, kPyramidTriangles);
}

/// A pyramid PLY with the given encoding and types, plus an unknown property in both elements and an
/// extra element (with a list) before and after.
std::string pyramid_ply(const std::string& format, const std::string& coord, const std::string& count,
                        const std::string& index) {
  const bool ascii = format == "ascii";
  Bytes b(format == "binary_big_endian");
  b.text("ply\nformat " + format + " 1.0\ncomment pyramid\nobj_info test\n");
  b.text("element camera 1\nproperty float fov\nproperty list uchar float extra\n");
  b.text("element vertex 5\nproperty " + coord + " x\nproperty uchar flags\nproperty " + coord + " y\nproperty " +
         coord + " z\n");
  b.text("element face 5\nproperty list " + count + " " + index + " vertex_indices\nproperty short material\n");
  b.text("element edge 1\nproperty list uchar int pair\nend_header\n");
  if (ascii) {
    b.text("45.5 2 1 2\n");
    for (const auto& p : kPyramid) b.text(num(p[0]) + " 7 " + num(p[1]) + " " + num(p[2]) + "\n");
    for (const auto& f : kPyramidFaces) {
      std::string line = std::to_string(f.size());
      for (const int v : f) line.append(" ").append(std::to_string(v));
      b.text(line + " -3\n");
    }
    b.text("2 0 1\n");
    return b.str();
  }
  b.put(45.5f).put(std::uint8_t{2}).put(1.0f).put(2.0f);
  for (const auto& p : kPyramid) b.value(coord, p[0]).put(std::uint8_t{7}).value(coord, p[1]).value(coord, p[2]);
  for (const auto& f : kPyramidFaces) {
    b.value(count, static_cast<double>(f.size()));
    for (const int v : f) b.value(index, v);
    b.put(std::int16_t{-3});
  }
  b.put(std::uint8_t{2}).put(std::int32_t{0}).put(std::int32_t{1});
  return b.str();
}

// ---------------------------------------------------------------------------------------------------
// PLY: every encoding, every scalar type
// ---------------------------------------------------------------------------------------------------

TEST(ReadPly, EveryEncodingAndScalarTypeCombination) {
  TempDir dir;
  const std::vector<std::string> formats{"ascii", "binary_little_endian", "binary_big_endian"};
  const std::vector<std::string> all{"char", "uchar", "short", "ushort", "int",   "uint",   "float",   "double",
                                     "int8", "uint8", "int16", "uint16", "int32", "uint32", "float32", "float64"};
  const std::vector<std::string> integers{"char", "uchar", "int16", "ushort", "int", "uint32"};
  int files = 0;
  for (const auto& format : formats) {
    for (const auto& coord : all) {
      for (const auto& count : integers) {
        for (const auto& index : integers) {
          const fs::path path = dir / "p.ply";
          write_file(path, pyramid_ply(format, coord, count, index));
          ReadInfo info;
          const TriMesh m = read_mesh(path, &info);
          SCOPED_TRACE(format + " " + coord + " " + count + " " + index);
          expect_pyramid(m);
          EXPECT_EQ(info.encoding, format);
          EXPECT_EQ(info.polygons, 5u);
          EXPECT_EQ(info.triangulated, 1u);
          ++files;
        }
      }
    }
  }
  EXPECT_EQ(files, 3 * 16 * 6 * 6);
}

TEST(ReadPly, FastPathLayoutsMatchGeneralPath) {
  // Same content little-endian (fast path on x86) and big-endian (general path), with normals, colours,
  // an extra float property, int counts, polygons.
  TempDir dir;
  for (const std::string count : {"uchar", "int", "uint", "char"}) {
    for (const std::string index : {"int", "uint"}) {
      for (const std::string coord : {"float", "double"}) {
        TriMesh results[2];
        for (int big = 0; big < 2; ++big) {
          Bytes b(big == 1);
          b.text(std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") + " 1.0\n");
          b.text("element vertex 5\nproperty " + coord + " x\nproperty " + coord + " y\nproperty " + coord +
                 " z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty uchar red\nproperty uchar "
                 "green\nproperty uchar blue\nproperty float quality\n");
          b.text("element face 5\nproperty list " + count + " " + index + " vertex_indices\nend_header\n");
          for (std::size_t i = 0; i < 5; ++i) {
            const auto& p = kPyramid[i];
            b.value(coord, p[0]).value(coord, p[1]).value(coord, p[2]);
            b.put(0.0f).put(1.0f).put(-0.5f).put(static_cast<std::uint8_t>(i * 50)).put(std::uint8_t{255});
            b.put(std::uint8_t{0}).put(3.5f);
          }
          for (const auto& f : kPyramidFaces) {
            b.value(count, static_cast<double>(f.size()));
            for (const int v : f) b.value(index, v);
          }
          write_file(dir / "f.ply", b.str());
          results[big] = read_mesh(dir / "f.ply");
        }
        SCOPED_TRACE(count + " " + index + " " + coord);
        expect_pyramid(results[0]);
        expect_same_mesh(results[0], results[1]);
        ASSERT_EQ(results[0].colors.size(), 5u);
        EXPECT_EQ(results[0].colors[1], Vec3f(static_cast<float>(50 / 255.0), 1.0f, 0.0f));
        EXPECT_EQ(results[0].normals[4], Vec3f(0.0f, 1.0f, -0.5f));
      }
    }
  }
}

TEST(ReadPly, ColorsFromIntegerAndFloatTypesAndVertexIndexName) {
  TempDir dir;
  const std::string text =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "property float red\nproperty float green\nproperty float blue\nproperty float alpha\n"
      "element face 1\nproperty list uchar uint vertex_index\nend_header\n"
      "0 0 0 1.5 -0.25 0.5 1\n1 0 0 0 1 0.25 1\n0 1 0 1 1 1 1\n3 0 1 2\n";
  write_file(dir / "c.ply", text);
  const TriMesh m = read_mesh(dir / "c.ply");
  ASSERT_EQ(m.colors.size(), 3u);
  EXPECT_EQ(m.colors[0], Vec3f(1.0f, 0.0f, 0.5f));  // clamped into [0,1]
  EXPECT_EQ(m.colors[1], Vec3f(0.0f, 1.0f, 0.25f));
  EXPECT_EQ(m.faces, (std::vector<Face>{{0, 1, 2}}));

  const std::string ushort_colors =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "property ushort red\nproperty ushort green\nproperty ushort blue\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0 65535 0 0\n1 0 0 0 65535 0\n0 1 0 0 0 0\n3 0 1 2\n";
  write_file(dir / "u.ply", ushort_colors);
  const TriMesh u = read_mesh(dir / "u.ply");
  EXPECT_EQ(u.colors[0], Vec3f(1.0f, 0.0f, 0.0f));
  EXPECT_EQ(u.colors[1], Vec3f(0.0f, 1.0f, 0.0f));
}

TEST(ReadPly, PartialNormalsOrColoursAreIgnoredAndCrLfHeaderWorks) {
  TempDir dir;
  Bytes b;
  b.text(
      "ply\r\nformat binary_little_endian 1.0\r\nelement vertex 3\r\nproperty float x\r\nproperty float y\r\n"
      "property float z\r\nproperty float nx\r\nproperty uchar red\r\nelement face 1\r\n"
      "property list uchar int vertex_indices\r\nend_header\r\n");
  for (int i = 0; i < 3; ++i) b.put(static_cast<float>(i)).put(0.0f).put(0.0f).put(1.0f).put(std::uint8_t{9});
  b.put(std::uint8_t{3}).put(0).put(1).put(2);
  write_file(dir / "p.ply", b.str());
  const TriMesh m = read_mesh(dir / "p.ply");
  EXPECT_EQ(m.positions.size(), 3u);
  EXPECT_FALSE(m.has_normals());
  EXPECT_FALSE(m.has_colors());
  EXPECT_EQ(m.positions[2], Vec3(2, 0, 0));
}

TEST(ReadPly, VerticesWithoutFacesElement) {
  TempDir dir;
  write_file(dir / "pts.ply",
             "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\n"
             "end_header\n0.1 0.2 0.3\n\n4 5 6\n");
  const TriMesh m = read_mesh(dir / "pts.ply");
  EXPECT_EQ(m.positions.size(), 2u);
  EXPECT_EQ(m.positions[0], Vec3(0.1, 0.2, 0.3));
  EXPECT_TRUE(m.faces.empty());
}

// ---------------------------------------------------------------------------------------------------
// Writer round trips
// ---------------------------------------------------------------------------------------------------

TEST(WritePly, BinaryAndAsciiRoundTripsAreExact) {
  TempDir dir;
  const TriMesh m = attributed_mesh();
  for (const bool binary : {true, false}) {
    for (const bool dbl : {false, true}) {
      const fs::path path = dir / "rt.ply";
      write_ply(path, m, PlyWriteOptions{binary, dbl, "round trip"});
      ReadInfo info;
      const TriMesh back = read_mesh(path, &info);
      SCOPED_TRACE(std::string(binary ? "binary" : "ascii") + (dbl ? " double" : " float"));
      expect_same_mesh(m, back);
      EXPECT_EQ(info.encoding, binary ? "binary_little_endian" : "ascii");
      EXPECT_EQ(info.file_bytes, fs::file_size(path));
    }
  }
}

TEST(WritePly, DoublePrecisionKeepsEveryBit) {
  TempDir dir;
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> dist(-1e3, 1e3);
  TriMesh m;
  for (int i = 0; i < 300; ++i) m.positions.emplace_back(dist(rng), dist(rng), dist(rng));
  for (std::uint32_t i = 0; i + 2 < 300; ++i) m.faces.push_back(Face{i, i + 1, i + 2});
  for (const bool binary : {true, false}) {
    write_ply(dir / "d.ply", m, PlyWriteOptions{binary, true, ""});
    expect_same_mesh(m, read_mesh(dir / "d.ply"));
  }
  // Float precision: every coordinate comes back as the float nearest to it.
  write_ply(dir / "f.ply", m);
  const TriMesh f = read_mesh(dir / "f.ply");
  for (std::size_t i = 0; i < m.positions.size(); ++i) {
    EXPECT_EQ(f.positions[i], m.positions[i].cast<float>().cast<double>());
  }
}

TEST(WritePly, NoAttributesStayAbsentAndNoTemporaryFileRemains) {
  TempDir dir;
  const TriMesh m = cube();
  write_file(dir / "cube.ply", "old contents");
  write_ply(dir / "cube.ply", m);
  const TriMesh back = read_mesh(dir / "cube.ply");
  expect_same_mesh(m, back);
  EXPECT_FALSE(back.has_colors());
  EXPECT_FALSE(back.has_normals());
  int entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path())) ++entries;
  EXPECT_EQ(entries, 1);
}

TEST(WritePly, ErrorsNameThePath) {
  TempDir dir;
  const fs::path missing_dir = dir / "no/such/dir/x.ply";
  try {
    write_ply(missing_dir, cube());
    ADD_FAILURE() << "no exception";
  } catch (const gimforge::IoError& e) {
    EXPECT_TRUE(std::string(e.what()).starts_with(missing_dir.string() + ": ")) << e.what();
  }
  TriMesh bad = cube();
  bad.colors.resize(2);
  EXPECT_THROW(write_ply(dir / "bad.ply", bad), gimforge::InvalidInput);
  bad = cube();
  bad.faces.push_back(Face{0, 1, 99});
  EXPECT_THROW(write_ply(dir / "bad.ply", bad), gimforge::InvalidInput);
  EXPECT_THROW(write_ply(dir / "bad.ply", cube(), PlyWriteOptions{true, false, "two\nlines"}), gimforge::InvalidInput);
  EXPECT_FALSE(fs::exists(dir / "bad.ply"));
  // A directory in the way: the rename fails, and the temporary file is cleaned up.
  fs::create_directory(dir / "taken.ply");
  fs::create_directory(dir / "taken.ply" / "child");
  EXPECT_THROW(write_ply(dir / "taken.ply", cube()), gimforge::IoError);
  int entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path())) ++entries;
  EXPECT_EQ(entries, 1);
}

// ---------------------------------------------------------------------------------------------------
// OBJ, OFF, STL
// ---------------------------------------------------------------------------------------------------

TEST(ReadObj, FaceFormsNegativeIndicesPolygonsColoursAndIgnoredStatements) {
  TempDir dir;
  write_file(dir / "m.obj",
             "# comment\nmtllib m.mtl\no pyramid\ng base\n"
             "v 0 0 0 1 0 0\nv 2 0 0 0 1 0\nv 2 2 0 0 0 1\nv 0 2 0 0.5 0.5 0.5\nv 1 1 2 2 -1 0.25\n"
             "vt 0 0\nvt 1 0\nvn 0 0 1\nusemtl stone\ns 1\n"
             "f 1/1/1 4/2/1 3/1/1 2//1   # quad\n"
             "f 1//1 2//1 5//1\nf -4/1 -3/2 -1/1\nf 3 4 5\nf -2 1 -1\nl 1 2\np 3\n");
  ReadInfo info;
  const TriMesh m = read_mesh(dir / "m.obj", &info);
  expect_pyramid(m);
  ASSERT_EQ(m.colors.size(), 5u);
  EXPECT_EQ(m.colors[4], Vec3f(1.0f, 0.0f, 0.25f));
  EXPECT_EQ(info.format, MeshFormat::Obj);
  EXPECT_EQ(info.polygons, 5u);
  EXPECT_EQ(info.triangulated, 1u);
}

TEST(ReadObj, ColoursOnlyWhenEveryVertexHasThemAndWComponent) {
  TempDir dir;
  write_file(dir / "w.obj", "v 0 0 0 1\nv 1 0 0 0.5 0.5 0.5\nv 0 1 0\r\nf 1 2 3\r\n");
  const TriMesh m = read_mesh(dir / "w.obj");
  EXPECT_FALSE(m.has_colors());
  EXPECT_EQ(m.faces, (std::vector<Face>{{0, 1, 2}}));
}

TEST(ReadOff, VariantsHeaderlessAndColours) {
  TempDir dir;
  std::string off = "OFF\n# pyramid\n5 5 8\n";
  for (const auto& p : kPyramid) off += num(p[0]) + " " + num(p[1]) + " " + num(p[2]) + "\n";
  std::string faces;
  for (const auto& f : kPyramidFaces) {
    faces += std::to_string(f.size());
    for (const int v : f) faces.append(" ").append(std::to_string(v));
    faces += "\n";
  }
  write_file(dir / "a.off", off + faces);
  expect_pyramid(read_mesh(dir / "a.off"));
  // Headerless, counts on the keyword line, face colours.
  write_file(dir / "b.off", off.substr(4) + faces);
  expect_pyramid(read_mesh(dir / "b.off"));
  std::string same_line = "OFF 5 5 0\n" + off.substr(off.find("0 0 0")) + faces;
  same_line.replace(same_line.find("3 0 1 4\n"), 8, "3 0 1 4 255 0 0\n");
  write_file(dir / "c.off", same_line);
  expect_pyramid(read_mesh(dir / "c.off"));
  // COFF: integer colours are 0..255, real ones 0..1; NOFF normals; CNOFF both.
  write_file(dir / "d.off", "COFF\n3 1 0\n0 0 0 255 0 51 255\n1 0 0 0.5 1 0\n0 1 0 0 0 0 0\n3 0 1 2\n");
  const TriMesh d = read_mesh(dir / "d.off");
  ASSERT_EQ(d.colors.size(), 3u);
  EXPECT_EQ(d.colors[0], Vec3f(1.0f, 0.0f, static_cast<float>(51 / 255.0)));
  EXPECT_EQ(d.colors[1], Vec3f(0.5f, 1.0f, 0.0f));
  write_file(dir / "e.off", "NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n");
  const TriMesh e = read_mesh(dir / "e.off");
  ASSERT_EQ(e.normals.size(), 3u);
  EXPECT_EQ(e.normals[2], Vec3f(0, 0, 1));
  write_file(dir / "f.off", "CNOFF\n3 1 0\n0 0 0 0 0 1 1 1 1\n1 0 0 0 0 1 1 1 1\n0 1 0 0 0 1 1 1 1\n3 0 1 2\n");
  const TriMesh f = read_mesh(dir / "f.off");
  EXPECT_EQ(f.normals.size(), 3u);
  EXPECT_EQ(f.colors.size(), 3u);
}

TEST(ReadStl, AsciiAndBinaryWeldToTheSameIndexedMesh) {
  TempDir dir;
  const TriMesh m = cube();
  write_file(dir / "a.stl", stl_ascii_text(m));
  write_file(dir / "b.stl", stl_binary(m));
  write_file(dir / "c.STL", stl_binary(m, "solid but really binary"));
  ReadInfo ia;
  ReadInfo ib;
  ReadInfo ic;
  expect_same_mesh(m, read_mesh(dir / "a.stl", &ia));
  expect_same_mesh(m, read_mesh(dir / "b.stl", &ib));
  expect_same_mesh(m, read_mesh(dir / "c.STL", &ic));
  EXPECT_EQ(ia.encoding, "ascii");
  EXPECT_EQ(ib.encoding, "binary");
  EXPECT_EQ(ic.encoding, "binary");
  EXPECT_EQ(ib.polygons, 12u);
}

TEST(ReadStl, NegativeZeroWeldsWithZeroAndDegenerateFacetsAreKept) {
  TempDir dir;
  write_file(dir / "z.stl",
             "solid z\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n"
             "FACET NORMAL 0 0 1\nOUTER LOOP\nVERTEX -0 -0 0\nVERTEX 0 1 -0\nVERTEX 0 1 0\nENDLOOP\nENDFACET\n"
             "endsolid z\nsolid second\nendsolid\n");
  const TriMesh m = read_mesh(dir / "z.stl");
  EXPECT_EQ(m.positions.size(), 3u);
  EXPECT_EQ(m.faces, (std::vector<Face>{{0, 1, 2}, {0, 2, 2}}));
}

TEST(ReadAllFormats, SameMeshFromEveryFormat) {
  TempDir dir;
  const TriMesh m = cube();
  write_ply(dir / "c.ply", m);
  write_ply(dir / "ca.ply", m, PlyWriteOptions{false, false, ""});
  write_file(dir / "c.obj", obj_text(m));
  write_file(dir / "c.off", off_text(m));
  write_file(dir / "ca.stl", stl_ascii_text(m));
  write_file(dir / "cb.stl", stl_binary(m));
  const std::vector<std::pair<std::string, MeshFormat>> files{{"c.ply", MeshFormat::Ply},  {"ca.ply", MeshFormat::Ply},
                                                              {"c.obj", MeshFormat::Obj},  {"c.off", MeshFormat::Off},
                                                              {"ca.stl", MeshFormat::Stl}, {"cb.stl", MeshFormat::Stl}};
  for (const auto& [name, format] : files) {
    SCOPED_TRACE(name);
    ReadInfo info;
    expect_same_mesh(m, read_mesh(dir / name, &info));
    EXPECT_EQ(info.format, format);
  }
}

TEST(ReadAllFormats, CommittedTestData) {
  const fs::path data = GIMFORGE_TEST_DATA_DIR;
  struct Expect {
    const char* file;
    std::size_t v;
    std::size_t f;
  };
  for (const Expect& e :
       {Expect{"cathead.ply", 131, 248}, Expect{"fist.ply", 1197, 2390}, Expect{"kitten.ply", 1850, 3700},
        Expect{"tetra.obj", 4, 4}, Expect{"cube.off", 8, 12}, Expect{"cube_ascii.stl", 8, 12}}) {
    SCOPED_TRACE(e.file);
    const TriMesh m = read_mesh(data / e.file);
    EXPECT_EQ(m.num_vertices(), e.v);
    EXPECT_EQ(m.num_faces(), e.f);
  }
  // The OFF cube is stored as quads; the STL cube as triangles: same geometry, same triangle count.
  ReadInfo info;
  (void)read_mesh(data / "cube.off", &info);
  EXPECT_EQ(info.polygons, 6u);
  EXPECT_EQ(info.triangulated, 6u);
}

TEST(ReadAllFormats, SharedMeshes) {
  const fs::path dir = GIMFORGE_SHARED_MESHES_DIR;
  if (!fs::is_directory(dir)) GTEST_SKIP() << "shared mesh directory " << dir << " is absent";
  ReadInfo info;
  const TriMesh bunny = read_mesh(dir / "bunny.ply", &info);
  EXPECT_EQ(bunny.num_vertices(), 35947u);
  EXPECT_EQ(bunny.num_faces(), 69451u);
  EXPECT_EQ(info.encoding, "binary_little_endian");
  const TriMesh dragon = read_mesh(dir / "dragon.ply");
  EXPECT_EQ(dragon.num_vertices(), 437645u);
  EXPECT_EQ(dragon.num_faces(), 871414u);
  // The fast path and a re-encoded file (ascii, and binary written by us) agree.
  TempDir tmp;
  write_ply(tmp / "bunny_ascii.ply", bunny, PlyWriteOptions{false, false, ""});
  expect_same_mesh(bunny, read_mesh(tmp / "bunny_ascii.ply"));
}

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
  expect_read_error(dir / "faces.ply", {"truncated binary PLY", "4000000000 face records"});
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
             "solid s\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 1e39 0 0\nvertex 0 1 0\n"
             "endloop\nendfacet\nendsolid\n");
  expect_read_error(dir / "inf.stl", {"line 5", "facet 0 has a non-finite coordinate (inf)"});
  TriMesh m = cube();
  m.positions[2].y() = std::numeric_limits<double>::quiet_NaN();
  write_file(dir / "nan.stl", stl_binary(m));
  expect_read_error(dir / "nan.stl", {"triangle 0 has a non-finite coordinate (nan)"});
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
