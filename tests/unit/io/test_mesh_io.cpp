// Tests of io/mesh_io.h: PLY/OBJ/OFF/STL readers (every encoding and scalar type, polygons, skipped
// elements and properties), the PLY writer (round trips), agreement between formats and real meshes. Bad
// input: test_mesh_io_bad_input.cpp.
#include "tests/unit/io/mesh_io_test_support.h"

namespace {

using namespace gimforge::test_io;  // NOLINT(google-build-using-namespace): the shared test vocabulary

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

TEST(ReadObj, ColoursOfZeroTo255AreScaled) {
  TempDir dir;  // no standard range: 0..1 as most tools write them, 0..255 when any component is above 1
  write_file(dir / "unit.obj", "v 0 0 0 0 0.5 1\nv 1 0 0 1 1 1\nv 0 1 0 0 0 0\nf 1 2 3\n");
  write_file(dir / "byte.obj", "v 0 0 0 0 128 255\nv 1 0 0 255 255 255\nv 0 1 0 0 0 1\nf 1 2 3\n");
  const TriMesh unit = read_mesh(dir / "unit.obj"), byte = read_mesh(dir / "byte.obj");
  ASSERT_TRUE(unit.has_colors() && byte.has_colors());
  EXPECT_EQ(unit.colors[0], Vec3f(0.0f, 0.5f, 1.0f));
  EXPECT_NEAR(byte.colors[0].y(), 128.0f / 255.0f, 1e-6f);
  EXPECT_EQ(byte.colors[0].z(), 1.0f);
  EXPECT_NEAR(byte.colors[2].z(), 1.0f / 255.0f, 1e-6f);
}

TEST(ReadObj, AByteOrderMarkFirstIsSkipped) {
  TempDir dir;  // as some Windows tools write it
  write_file(dir / "bom.obj", "\xEF\xBB\xBFv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const TriMesh m = read_mesh(dir / "bom.obj");
  EXPECT_EQ(m.num_vertices(), 3u);
  EXPECT_EQ(m.faces, (std::vector<Face>{{0, 1, 2}}));
}

TEST(ReadObj, ABackslashContinuesALine) {
  TempDir dir;  // the OBJ spec's continuation, also after a comment is cut off and over several lines
  write_file(dir / "cont.obj", "v 0 0 \\\n 0\nv 1 0 0\nv 1 1 0\nv 0 1 0 # last\nf 1 \\ # the quad\n2 \\\r\n3 4\n\\\n\n");
  const TriMesh m = read_mesh(dir / "cont.obj");
  EXPECT_EQ(m.num_vertices(), 4u);
  EXPECT_EQ(m.positions[0], Vec3(0, 0, 0));
  EXPECT_EQ(m.faces, (std::vector<Face>{{0, 1, 2}, {0, 2, 3}}));
  write_file(dir / "end.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 \\");
  expect_read_error(dir / "end.obj", {"continuation backslash"});
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

TEST(ReadStl, AsciiCoordinatesKeepTheirDecimalsAtGeoreferencedOffsets) {
  // An ASCII STL's numbers are read as doubles, as OBJ's and OFF's: at UTM offsets float32 rounded them to
  // 0.5 m, and two corners 0.2 m apart welded into one vertex (a degenerate face "repaired" away).
  TempDir dir;
  write_file(dir / "utm.stl",
             "solid utm\nfacet normal 0 0 1\nouter loop\nvertex 500001.373 4999998.456 110.0\n"
             "vertex 500001.573 4999998.456 110.0\nvertex 500001.373 4999999.123 110.0\nendloop\nendfacet\n"
             "facet normal 0 0 1\nouter loop\nvertex 500001.573 4999998.456 110.0\nvertex 500001.573 4999999.123 110.0\n"
             "vertex 500001.373 4999999.123 110.0\nendloop\nendfacet\nendsolid utm\n");
  const TriMesh m = read_mesh(dir / "utm.stl");
  ASSERT_EQ(m.positions.size(), 4u);
  EXPECT_EQ(m.faces, (std::vector<Face>{{0, 1, 2}, {1, 3, 2}}));
  EXPECT_EQ(m.positions[0], Vec3(500001.373, 4999998.456, 110.0));
  EXPECT_EQ(m.positions[3], Vec3(500001.573, 4999999.123, 110.0));
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


}  // namespace

TEST(Float32, ExactOnlyWhenEveryCoordinateIsAFloat) {
  // GCC 12 at -O2 vectorizes a loop that rounds doubles through float and stores them back as double without
  // the rounding (seen: x and y of every vertex kept their decimals): float32_exact compares per coordinate
  // with an early exit, which it does not vectorize. Every coordinate of every vertex is probed here.
  TriMesh m;
  for (int v = 0; v < 5; ++v) m.positions.emplace_back(412345.125 + v, 5312345.5, 120.5);
  m.faces = {{0, 1, 2}, {2, 3, 4}};
  EXPECT_TRUE(gimforge::io::float32_exact(m));
  for (std::size_t v = 0; v < m.positions.size(); ++v)
    for (int k = 0; k < 3; ++k) {
      TriMesh moved = m;
      moved.positions[v][k] += 0.001;
      EXPECT_FALSE(gimforge::io::float32_exact(moved)) << "vertex " << v << " axis " << k;
    }
  EXPECT_GT(gimforge::io::float32_relative_spacing(m), gimforge::io::kFloat32Tolerance);
}
