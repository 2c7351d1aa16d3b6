#pragma once
// What the mesh-format tests share (test_mesh_io.cpp, test_mesh_io_bad_input.cpp): a temporary directory,
// byte builders in either byte order, small meshes written in every format, and expectations on meshes
// and on the one-line errors of the readers.
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


namespace gimforge::test_io {

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

inline void write_file(const fs::path& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  ASSERT_TRUE(out.good()) << path;
}

inline std::string read_file(const fs::path& path) {
  std::string bytes(fs::file_size(path), '\0');
  std::ifstream in(path, std::ios::binary);
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return bytes;
}

/// Shortest text that reads back as the same double.
inline std::string num(double v) {
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
inline void expect_read_error(const fs::path& path, std::initializer_list<std::string_view> needles) {
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

inline void expect_same_mesh(const TriMesh& a, const TriMesh& b) {
  ASSERT_EQ(a.positions.size(), b.positions.size());
  for (std::size_t i = 0; i < a.positions.size(); ++i) ASSERT_EQ(a.positions[i], b.positions[i]) << "vertex " << i;
  ASSERT_EQ(a.faces, b.faces);
  ASSERT_EQ(a.colors.size(), b.colors.size());
  for (std::size_t i = 0; i < a.colors.size(); ++i) ASSERT_EQ(a.colors[i], b.colors[i]) << "colour " << i;
  ASSERT_EQ(a.normals.size(), b.normals.size());
  for (std::size_t i = 0; i < a.normals.size(); ++i) ASSERT_EQ(a.normals[i], b.normals[i]) << "normal " << i;
}

/// A unit cube with vertices numbered in order of first appearance in its faces (as STL welding numbers them).
inline TriMesh cube() {
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
inline TriMesh attributed_mesh() {
  TriMesh m = cube();
  for (std::size_t i = 0; i < m.positions.size(); ++i) {
    m.positions[i] = m.positions[i] * 1.5 - Vec3(0.25, 0.125, 0.0625);
    m.normals.push_back(Vec3f(0.0f, 0.6f, 0.8f) * (i % 2 == 0 ? 1.0f : -1.0f));
    m.colors.push_back(Vec3f(static_cast<float>(static_cast<double>(i * 30) / 255.0), static_cast<float>(255 / 255.0),
                             static_cast<float>(7 / 255.0)));
  }
  return m;
}

inline std::string obj_text(const TriMesh& m) {
  std::string s = "# cube\n";
  for (const Vec3& p : m.positions) s += "v " + num(p.x()) + " " + num(p.y()) + " " + num(p.z()) + "\n";
  for (const Face& f : m.faces)
    s += "f " + std::to_string(f[0] + 1) + " " + std::to_string(f[1] + 1) + " " + std::to_string(f[2] + 1) + "\n";
  return s;
}

inline std::string off_text(const TriMesh& m) {
  std::string s = "OFF\n" + std::to_string(m.positions.size()) + " " + std::to_string(m.faces.size()) + " 0\n";
  for (const Vec3& p : m.positions) s += num(p.x()) + " " + num(p.y()) + " " + num(p.z()) + "\n";
  for (const Face& f : m.faces)
    s += "3 " + std::to_string(f[0]) + " " + std::to_string(f[1]) + " " + std::to_string(f[2]) + "\n";
  return s;
}

inline std::string stl_ascii_text(const TriMesh& m) {
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

inline std::string stl_binary(const TriMesh& m, std::string_view header = "binary stl") {
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

inline void expect_pyramid(const TriMesh& m) {
  ASSERT_EQ(m.positions.size(), 5u);
  for (std::size_t i = 0; i < 5; ++i) {
    EXPECT_EQ(m.positions[i], Vec3(kPyramid[i][0], kPyramid[i][1], kPyramid[i][2])) << "vertex " << i;
  }
  EXPECT_EQ(m.faces, kPyramidTriangles);
}

/// A pyramid PLY with the given encoding and types, plus an unknown property in both elements and an
/// extra element (with a list) before and after.
inline std::string pyramid_ply(const std::string& format, const std::string& coord, const std::string& count,
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


}  // namespace gimforge::test_io
