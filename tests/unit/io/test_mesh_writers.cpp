// Tests of io::write_mesh: every format the extension names (PLY, OBJ, OFF, STL) reads back to the same
// mesh, the bytes are the format's (never PLY under another name), unknown extensions are refused.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "io/mesh_io.h"
#include "kernels/core/errors.h"
#include "tests/unit/io/mesh_io_test_support.h"

namespace {

using gimforge::test_io::TempDir;
namespace fs = std::filesystem;
using gimforge::Face;
using gimforge::TriMesh;
using gimforge::Vec3;
using gimforge::Vec3f;
using gimforge::io::MeshFormat;

std::string head(const fs::path& path, std::size_t n) {
  std::string bytes(n, '\0');
  std::ifstream in(path, std::ios::binary);
  in.read(bytes.data(), static_cast<std::streamsize>(n));
  bytes.resize(static_cast<std::size_t>(in.gcount()));
  return bytes;
}

/// A closed octahedron-like mesh with awkward coordinates (0.1, 1e-7, -3.25e5 ...), every vertex used,
/// vertices numbered in the order the faces first use them (so STL's welding gives the same numbering).
TriMesh test_mesh(bool float_exact) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  TriMesh m;
  const std::array<Vec3, 6> base{Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1), Vec3(-1, 0, 0), Vec3(0, -1, 0),
                                 Vec3(0, 0, -1)};
  for (std::size_t i = 0; i < base.size(); ++i) {
    Vec3 p = base[i] * 3.25e5 + Vec3(0.1, 1e-7, u(rng));
    if (float_exact)
      for (int k = 0; k < 3; ++k) {
        const volatile float rounded = static_cast<float>(p[k]);
        p[k] = static_cast<double>(rounded);
      }
    m.positions.push_back(p);
  }
  m.faces = {Face{0, 1, 2}, Face{1, 3, 2}, Face{3, 4, 2}, Face{4, 0, 2},
             Face{1, 0, 5}, Face{3, 1, 5}, Face{4, 3, 5}, Face{0, 4, 5}};
  return m;
}

void expect_same(const TriMesh& a, const TriMesh& b) {
  ASSERT_EQ(a.num_vertices(), b.num_vertices());
  ASSERT_EQ(a.num_faces(), b.num_faces());
  for (std::size_t i = 0; i < a.num_vertices(); ++i)
    for (int k = 0; k < 3; ++k) EXPECT_EQ(a.positions[i][k], b.positions[i][k]) << "vertex " << i << " coordinate " << k;
  for (std::size_t f = 0; f < a.num_faces(); ++f) EXPECT_EQ(a.faces[f], b.faces[f]) << "face " << f;
  ASSERT_EQ(a.colors.size(), b.colors.size());
  for (std::size_t i = 0; i < a.colors.size(); ++i) EXPECT_EQ(a.colors[i], b.colors[i]) << "colour " << i;
  ASSERT_EQ(a.normals.size(), b.normals.size());
  for (std::size_t i = 0; i < a.normals.size(); ++i) EXPECT_EQ(a.normals[i], b.normals[i]) << "normal " << i;
}

}  // namespace

TEST(WriteMesh, EveryFormatReadsBackToTheSameMesh) {
  TempDir dir;
  for (const char* ext : {".ply", ".obj", ".off", ".stl", ".OBJ"}) {
    SCOPED_TRACE(ext);
    const bool stl = std::string(ext) == ".stl";
    const TriMesh m = test_mesh(/*float_exact=*/stl || std::string(ext) == ".ply");  // PLY and STL store float
    const fs::path path = dir / (std::string("rt") + ext);
    gimforge::io::write_mesh(path, m);
    gimforge::io::ReadInfo info;
    const TriMesh back = gimforge::io::read_mesh(path, &info);
    EXPECT_EQ(info.format, gimforge::io::format_from_extension(path));
    expect_same(m, back);
  }
  EXPECT_EQ(std::vector<fs::path>(fs::directory_iterator(dir.path()), fs::directory_iterator()).size(), 5u)
      << "no temporary file is left";
}

TEST(WriteMesh, ColoursAndNormalsSurviveObjAndOff) {
  TempDir dir;
  TriMesh m = test_mesh(false);
  for (std::size_t i = 0; i < m.num_vertices(); ++i) {
    // 1 and 0 are the colours an OFF reader would take for 0..255 integers if written without a point
    m.colors.emplace_back(i % 2 == 0 ? 1.0f : 0.0f, 0.25f, 1.0f / 3.0f);
    m.normals.emplace_back(Vec3f(0.6f, 0.0f, 0.8f));
  }
  {
    gimforge::io::write_mesh(dir / "c.off", m);
    expect_same(m, gimforge::io::read_mesh(dir / "c.off"));
  }
  {
    gimforge::io::write_mesh(dir / "c.obj", m);
    TriMesh expected = m;
    expected.normals.clear();  // the OBJ reader does not keep vn
    expect_same(expected, gimforge::io::read_mesh(dir / "c.obj"));
  }
}

TEST(WriteMesh, TheBytesAreTheFormatTheExtensionNames) {
  TempDir dir;
  const TriMesh m = test_mesh(true);
  gimforge::io::write_mesh(dir / "x.obj", m);
  gimforge::io::write_mesh(dir / "x.off", m);
  gimforge::io::write_mesh(dir / "x.stl", m);
  gimforge::io::write_mesh(dir / "x.ply", m);
  EXPECT_EQ(head(dir / "x.obj", 1), "#");
  EXPECT_NE(head(dir / "x.obj", 200).find("\nv "), std::string::npos);
  EXPECT_EQ(head(dir / "x.off", 4), "OFF\n");
  EXPECT_EQ(fs::file_size(dir / "x.stl"), 84u + 50u * m.num_faces());
  EXPECT_NE(head(dir / "x.stl", 5), "solid") << "a binary STL must not look like an ASCII one";
  EXPECT_EQ(head(dir / "x.ply", 4), "ply\n");
}

TEST(WriteMesh, UnknownExtensionsAreRefusedWithTheSupportedOnes) {
  TempDir dir;
  const TriMesh m = test_mesh(true);
  for (const char* name : {"x.xyz", "x", "x.h5"}) {
    SCOPED_TRACE(name);
    try {
      gimforge::io::write_mesh(dir / name, m);
      ADD_FAILURE() << "no error";
    } catch (const gimforge::InvalidInput& e) {
      const std::string what = e.what();
      EXPECT_TRUE(what.starts_with((dir / name).string() + ": cannot write a mesh as ")) << what;
      EXPECT_NE(what.find(".ply, .obj, .off, .stl"), std::string::npos) << what;
    }
    EXPECT_FALSE(fs::exists(dir / name));
  }
  EXPECT_EQ(gimforge::io::output_format("a/b.Stl"), MeshFormat::Stl);
  EXPECT_THROW((void)gimforge::io::output_format("a.ply.gz"), gimforge::InvalidInput);
}

TEST(WriteMesh, InconsistentMeshesAreRefusedBeforeWriting) {
  TempDir dir;
  TriMesh m = test_mesh(true);
  m.faces.push_back(Face{0, 1, 99});
  for (const char* name : {"bad.obj", "bad.off", "bad.stl"}) {
    EXPECT_THROW(gimforge::io::write_mesh(dir / name, m), gimforge::InvalidInput) << name;
    EXPECT_FALSE(fs::exists(dir / name)) << name;
  }
}

TEST(WriteMesh, Float32OutputOfAMeshFarFromTheOriginIsRefused) {
  // A 1 m mesh at UTM-like coordinates: float32 resolves 4·10^6 to 0.25, so an STL (or a float PLY) would
  // collapse it to a few points. The writers refuse, naming what keeps the coordinates; near the origin the
  // same mesh writes as before.
  TempDir dir;
  TriMesh far = test_mesh(false);
  for (Vec3& p : far.positions) p = p / 3.25e5 + Vec3(4.0e6, 5.0e5, 0.0);
  EXPECT_GT(gimforge::io::float32_relative_spacing(far), gimforge::io::kFloat32Tolerance);
  try {
    gimforge::io::write_mesh(dir / "far.stl", far);
    ADD_FAILURE() << "no exception";
  } catch (const gimforge::InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("far.stl: 32-bit float coordinates"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("write .ply, .obj or .off"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir / "far.stl"));
  gimforge::io::write_ply(dir / "far_double.ply", far, {.binary = true, .double_precision = true});
  gimforge::io::write_mesh(dir / "far.obj", far);
  TriMesh near = far;
  for (Vec3& p : near.positions) p -= Vec3(4.0e6, 5.0e5, 0.0);
  EXPECT_LT(gimforge::io::float32_relative_spacing(near), gimforge::io::kFloat32Tolerance);
  gimforge::io::write_mesh(dir / "near.stl", near);
  EXPECT_TRUE(fs::exists(dir / "near.stl"));
  // Coordinates that are floats already (read from an STL) lose nothing: written as they are.
  for (Vec3& p : far.positions)
    for (int k = 0; k < 3; ++k) {
      const volatile float rounded = static_cast<float>(p[k]);  // volatile: GCC 12 -O2 dropped the rounding
      p[k] = static_cast<double>(rounded);
    }
  gimforge::io::write_mesh(dir / "far_floats.stl", far);
  EXPECT_TRUE(fs::exists(dir / "far_floats.stl"));
}
