// Tests of relief maps in the archive (io/relief_archive.h): round trips of maps built from procedural
// meshes, the layout promised by docs/archive.md, and clear FormatErrors for damaged files.
#include <gtest/gtest.h>

#include "io/printable.h"
#include <hdf5.h>

#include <cmath>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "io/relief_archive.h"
#include "io/sphere_archive.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "kernels/relief/relief_map.h"
#include "tests/unit/test_support.h"

namespace fs = std::filesystem;
using namespace gimforge;
using gimforge::test::message_of;

namespace {

class ReliefArchiveTest : public gimforge::test::ScratchDirTest {};

/// A torus with a colour per vertex (so that the colour maps are written too).
TriMesh coloured_torus() {
  TriMesh m = make_torus(1.0, 0.35, 32, 16);
  for (const Vec3& p : m.positions)
    m.colors.push_back(Vec3f(static_cast<float>(0.5 + 0.4 * p.x()), static_cast<float>(0.5 + 0.4 * p.y()), 0.25f));
  return m;
}

/// A relief map of a small torus: the automatic grid choice (up to 4), 8 × 8 texels.
const ReliefMap& torus_map() {
  static const ReliefMap map = [] {
    ReliefOptions o;
    o.grid = 0;
    o.max_grid = 4;
    o.occlusion_threshold = 0.0;
    o.texture = 8;
    return build_relief_map(coloured_torus(), o);
  }();
  return map;
}

io::ReliefRecord sample_record() {
  return {.source = "meshes/torus.ply",
          .numbers = {{"psnr", 55.5}, {"occlusion_ratio", 0.01}, {"storage_bytes", 1234.0}, {"seconds_cells", 0.25},
                      {"seconds_sampling", 0.5}, {"seconds_total", 2.0}}};
}

void expect_same_map(const ReliefMap& got, const ReliefMap& want) {
  EXPECT_EQ(got.n, want.n);
  EXPECT_EQ(got.origin, want.origin);
  EXPECT_EQ(got.cell_size, want.cell_size);
  EXPECT_EQ(got.texture, want.texture);
  EXPECT_EQ(got.distance_scale, want.distance_scale);
  EXPECT_EQ(got.cells, want.cells);
  EXPECT_EQ(got.external_faces, want.external_faces);
  ASSERT_EQ(got.projections.size(), want.projections.size());
  for (std::size_t g = 0; g < got.projections.size(); ++g) {
    const CellProjection& a = got.projections[g];
    const CellProjection& b = want.projections[g];
    EXPECT_EQ(a.base_case, b.base_case) << "cell " << g;
    EXPECT_EQ(a.type, b.type) << "cell " << g;
    EXPECT_EQ(a.domain_faces, b.domain_faces) << "cell " << g;
    EXPECT_EQ(a.axis, b.axis) << "cell " << g;
    EXPECT_EQ(a.point, b.point) << "cell " << g;
    EXPECT_EQ(a.direction, b.direction) << "cell " << g;
  }
  EXPECT_EQ(got.first_layer, want.first_layer);
  EXPECT_EQ(got.layer_face, want.layer_face);
  EXPECT_EQ(got.layer_cell, want.layer_cell);
  EXPECT_EQ(got.distances, want.distances);
  EXPECT_EQ(got.normals, want.normals);
  EXPECT_EQ(got.colors, want.colors);
  ASSERT_EQ(got.levels.size(), want.levels.size());
  for (std::size_t k = 0; k < got.levels.size(); ++k) {
    EXPECT_EQ(got.levels[k].n, want.levels[k].n);
    EXPECT_EQ(got.levels[k].grey_cells, want.levels[k].grey_cells);
    EXPECT_EQ(got.levels[k].domain_faces, want.levels[k].domain_faces);
    EXPECT_EQ(got.levels[k].samples, want.levels[k].samples);
    EXPECT_EQ(got.levels[k].occluded, want.levels[k].occluded);
  }
  EXPECT_EQ(got.inside_method, want.inside_method);
  EXPECT_EQ(got.watertight_inside_test, want.watertight_inside_test);
  EXPECT_EQ(got.white_cells, want.white_cells);
  EXPECT_EQ(got.black_cells, want.black_cells);
}

/// Number of filters of a dataset's creation property list (0: stored without compression).
int filters(const h5::Dataset& ds) {
  const hid_t plist = H5Dget_create_plist(ds.id());
  const int n = H5Pget_nfilters(plist);
  H5Pclose(plist);
  return n;
}

TEST_F(ReliefArchiveTest, MapRoundTripsWithLayoutOfTheDocs) {
  const ReliefMap& want = torus_map();
  ASSERT_FALSE(want.colors.empty());
  ASSERT_GE(want.levels.size(), 2u) << "the torus needs more than one cell to avoid occlusion";
  const fs::path path = file("r.h5");
  {
    io::Archive a = io::Archive::create(path, {});
    io::write_relief_map(a, "torus", want, sample_record());
    a.close();
  }
  const io::Archive a = io::Archive::open(path);
  EXPECT_EQ(io::relief_map_names(a), std::vector<std::string>{"torus"});
  EXPECT_TRUE(io::spherical_image_names(a).empty());
  const ReliefMap got = io::read_relief_map(a, "torus");
  expect_same_map(got, want);
  EXPECT_EQ(got.seconds_cells, 0.25) << "timings come back from the record";
  EXPECT_EQ(got.seconds_sampling, 0.5);
  EXPECT_EQ(reconstruct_relief(got).positions, reconstruct_relief(want).positions);

  const io::ReliefRecord record = io::read_relief_record(a, "torus");
  EXPECT_EQ(record.source, "meshes/torus.ply");
  EXPECT_EQ(record.numbers, sample_record().numbers) << "cell_size and the integers are structural";

  // The layout promised by docs/archive.md.
  const std::uint64_t G = want.cells.size(), L = want.num_layers(), T = want.texture;
  const h5::Group g = a.root().open_group("relief/torus");
  EXPECT_EQ(g.attribute<std::string>("method"), "relief");
  EXPECT_EQ(g.attribute<std::int64_t>("n"), want.n);
  EXPECT_EQ(g.attribute<std::int64_t>("texture"), 8);
  EXPECT_EQ(g.attribute<std::int64_t>("grey_cells"), static_cast<std::int64_t>(G));
  EXPECT_EQ(g.attribute<std::int64_t>("layers"), static_cast<std::int64_t>(L));
  EXPECT_EQ(g.attribute<std::vector<double>>("origin"),
            (std::vector<double>{want.origin.x(), want.origin.y(), want.origin.z()}));
  EXPECT_EQ(g.attribute<double>("cell_size"), want.cell_size);
  const struct {
    const char* item;
    h5::Dims shape;
    h5::DType type;
  } items[] = {{"cells", {G, 3}, h5::DType::kUInt32},
               {"external_faces", {G}, h5::DType::kUInt8},
               {"case", {G}, h5::DType::kUInt8},
               {"projection", {G}, h5::DType::kUInt8},
               {"domain_faces", {G}, h5::DType::kUInt8},
               {"projection_params", {G, 6}, h5::DType::kFloat64},
               {"layer_cell", {L}, h5::DType::kUInt32},
               {"layer_face", {L}, h5::DType::kUInt8},
               {"distances", {L, T, T}, h5::DType::kUInt16},
               {"normals", {L, T, T, 3}, h5::DType::kInt8},
               {"colors", {L, T, T, 3}, h5::DType::kUInt8},
               {"grid_levels", {want.levels.size(), 5}, h5::DType::kInt64}};
  for (const auto& it : items) {
    const h5::Dataset ds = g.open_dataset(it.item);
    EXPECT_EQ(ds.shape(), it.shape) << it.item;
    EXPECT_EQ(ds.dtype(), it.type) << it.item;
  }
  EXPECT_EQ(filters(g.open_dataset("distances")), 2) << "shuffle + gzip like the image datasets";
  EXPECT_EQ(filters(g.open_dataset("normals")), 2);
  const h5::Dataset d = g.open_dataset("distances");
  EXPECT_EQ(d.attribute<double>("scale"), want.distance_scale);
  EXPECT_EQ(d.attribute<double>("offset"), 0.0);
  EXPECT_EQ(d.attribute<std::int64_t>("empty"), 65535);
  // The cell table as a reader without gimforge sees it: (i, j, k), case and projection codes.
  const auto ijk = g.open_dataset("cells").read<std::uint32_t>();
  const auto cases = g.open_dataset("case").read<std::uint8_t>();
  for (std::size_t c = 0; c < G; ++c) {
    EXPECT_EQ((ijk[3 * c + 2] * want.n + ijk[3 * c + 1]) * want.n + ijk[3 * c], want.cells[c]);
    EXPECT_EQ(cases[c], static_cast<std::uint8_t>(want.projections[c].base_case));
  }
  EXPECT_EQ(g.open_dataset("case").attribute<std::string>("names"), "0,1,2a,2b,3a,3b,4a,4b,5,6");
}

TEST_F(ReliefArchiveTest, MapWithoutColoursAndGivenGrid) {
  ReliefOptions o;
  o.grid = 2;
  o.texture = 5;
  const ReliefMap want = build_relief_map(make_icosphere(1.0, 2), o);
  ASSERT_TRUE(want.colors.empty());
  {
    io::Archive a = io::Archive::create(file("s.h5"), {});
    io::write_relief_map(a, "ball", want, sample_record());
    a.close();
  }
  const io::Archive a = io::Archive::open(file("s.h5"));
  expect_same_map(io::read_relief_map(a, "ball"), want);
  EXPECT_FALSE(a.root().exists("relief/ball/colors"));
}

TEST_F(ReliefArchiveTest, WritingRefusesBadNamesMapsAndRecords) {
  io::Archive a = io::Archive::create(file("w.h5"), {});
  const ReliefMap& good = torus_map();
  for (const std::string bad : {"", "a/b", ".."}) {
    const std::string msg = message_of<InvalidInput>([&] { io::write_relief_map(a, bad, good, sample_record()); });
    EXPECT_EQ(msg, "invalid relief map name '" + bad + "': it " + io::path_component_problem(bad) +
                       " (non-empty, not '.' or '..', no '/' or control characters, at most 255 bytes)");
  }
  ReliefMap short_distances = good;
  short_distances.distances.pop_back();
  std::string msg = message_of<InvalidInput>([&] { io::write_relief_map(a, "r", short_distances, sample_record()); });
  EXPECT_EQ(msg.rfind("relief map 'r': ", 0), 0u) << msg;
  EXPECT_NE(msg.find("distances"), std::string::npos) << msg;
  ReliefMap bad_projection = good;
  bad_projection.projections[0] = cell_projection(static_cast<std::uint8_t>(good.external_faces[0] ^ 1u));
  EXPECT_THROW(io::write_relief_map(a, "r", bad_projection, sample_record()), InvalidInput);
  ReliefMap bad_levels = good;
  bad_levels.levels.back().n *= 2;
  msg = message_of<InvalidInput>([&] { io::write_relief_map(a, "r", bad_levels, sample_record()); });
  EXPECT_EQ(msg.rfind("relief map 'r': the last grid level", 0), 0u) << msg;
  io::ReliefRecord clash = sample_record();
  clash.numbers["cell_size"] = 1.0;
  msg = message_of<InvalidInput>([&] { io::write_relief_map(a, "r", good, clash); });
  EXPECT_EQ(msg, "record number 'cell_size' would overwrite the attribute of that name");
  EXPECT_FALSE(a.root().exists("relief")) << "nothing is written for refused input";
  io::write_relief_map(a, "r", good, sample_record());
  EXPECT_THROW(io::write_relief_map(a, "r", good, sample_record()), LibraryError);
}

/// Writes the torus map as "t", lets `damage` change the group, and returns the FormatError of reading it.
class DamagedReliefTest : public ReliefArchiveTest {
 protected:
  template <class F>
  std::string read_error(F damage) {
    const fs::path path = file("d.h5");
    {
      io::Archive a = io::Archive::create(path, {});
      io::write_relief_map(a, "t", torus_map(), sample_record());
      h5::Group g = a.root().open_group("relief/t");
      damage(g);
      a.close();
    }
    const io::Archive a = io::Archive::open(path);
    return message_of<FormatError>([&] { (void)io::read_relief_map(a, "t"); });
  }
  [[nodiscard]] std::string prefix() const { return file("d.h5").string() + ": relief map 't': "; }
  static void remove(h5::Group& g, const char* item) { ASSERT_GE(H5Ldelete(g.id(), item, H5P_DEFAULT), 0); }
  /// A damage that changes dataset `item` in place through `edit` (same shape and type).
  template <class T, class E>
  static auto edit(const char* item, E e) {
    return [=](h5::Group& g) {
      h5::Dataset ds = g.open_dataset(item);
      std::vector<T> v = ds.read<T>();
      e(v);
      ds.write(v);
    };
  }
};

TEST_F(DamagedReliefTest, MissingOrMistypedDatasetsNameTheItem) {
  const ReliefMap& m = torus_map();
  const std::uint64_t L = m.num_layers();
  EXPECT_EQ(read_error([](h5::Group& g) { remove(g, "distances"); }), prefix() + "no dataset 'distances'");
  EXPECT_EQ(read_error([](h5::Group& g) { remove(g, "cells"); }), prefix() + "no dataset 'cells'");
  EXPECT_EQ(read_error([&](h5::Group& g) {
              remove(g, "normals");
              g.write_dataset("normals", {L, 8, 8, 3}, std::vector<std::uint8_t>(L * 64 * 3, 0));
            }),
            prefix() + "dataset 'normals' is uint8, expected int8");
  EXPECT_EQ(read_error([&](h5::Group& g) {
              remove(g, "distances");
              g.write_dataset("distances", {L, 8, 7}, std::vector<std::uint16_t>(L * 56, 0));
            }),
            prefix() + fmt::format("dataset 'distances' has shape ({}, 8, 7), expected ({}, 8, 8)", L, L));
  const std::string grey = read_error([&](h5::Group& g) { g.set_attribute("grey_cells", m.cells.size() - 1); });
  EXPECT_EQ(grey.rfind(prefix() + fmt::format("{} grey + {} white + {} black cells do not make the", m.cells.size() - 1,
                                              m.white_cells, m.black_cells),
                       0),
            0u)
      << grey;
  EXPECT_EQ(read_error([](h5::Group& g) { g.set_attribute("method", "sphere"); }),
            prefix() + "method is 'sphere', expected 'relief'");
  EXPECT_EQ(read_error([](h5::Group& g) { g.set_attribute("n", 0); }),
            prefix() + "attribute n = 0 is out of range [1, 1024]");
  EXPECT_EQ(read_error([](h5::Group& g) { g.set_attribute("cell_size", -1.0); }),
            prefix() + "attribute cell_size = -1 is not a positive number");
  const std::string missing = read_error([](h5::Group& g) { ASSERT_GE(H5Adelete(g.id(), "texture"), 0); });
  EXPECT_NE(missing.find("'texture'"), std::string::npos) << missing;
}

TEST_F(DamagedReliefTest, InconsistentCellTablesAreFormatErrors) {
  const ReliefMap& m = torus_map();
  // The stored case of a cell disagrees with its external faces.
  std::string msg = read_error(edit<std::uint8_t>("case", [](auto& v) { v[0] = static_cast<std::uint8_t>((v[0] + 1) % 10); }));
  EXPECT_EQ(msg.rfind(prefix() + "grey cell 0 at (", 0), 0u) << msg;
  EXPECT_NE(msg.find("stored case"), std::string::npos) << msg;
  msg = read_error(edit<std::uint8_t>("case", [](auto& v) { v[1] = 77; }));
  EXPECT_NE(msg.find("stored case #77 (not a case)"), std::string::npos) << msg;
  // Flipping an external face changes the case or the parameters: caught either way.
  msg = read_error(edit<std::uint8_t>("external_faces", [](auto& v) { v[2] ^= 0x01; }));
  EXPECT_NE(msg.find("grey cell 2 at"), std::string::npos) << msg;
  msg = read_error(edit<std::uint8_t>("external_faces", [](auto& v) { v[0] = 0xff; }));
  EXPECT_NE(msg.find("bits beyond the six faces"), std::string::npos) << msg;
  msg = read_error(edit<std::uint8_t>("projection", [](auto& v) { v[0] = static_cast<std::uint8_t>((v[0] + 1) % 4); }));
  EXPECT_NE(msg.find("stored projection type"), std::string::npos) << msg;
  msg = read_error(edit<std::uint8_t>("domain_faces", [](auto& v) { v[0] ^= 0x20; }));
  EXPECT_NE(msg.find("stored domain faces"), std::string::npos) << msg;
  msg = read_error(edit<double>("projection_params", [](auto& v) { v[0] += 0.125; }));
  EXPECT_NE(msg.find("stored projection parameters"), std::string::npos) << msg;
  msg = read_error(edit<std::uint32_t>("cells", [&](auto& v) { v[0] = m.n; }));
  EXPECT_NE(msg.find("lies outside the"), std::string::npos) << msg;
  msg = read_error(edit<std::uint32_t>("cells", [](auto& v) {
    for (int c = 0; c < 3; ++c) std::swap(v[static_cast<std::size_t>(c)], v[static_cast<std::size_t>(3 + c)]);
  }));
  EXPECT_NE(msg.find("grey cell 1 at"), std::string::npos) << msg;
  EXPECT_NE(msg.find("out of order"), std::string::npos) << msg;
  msg = read_error([](h5::Group& g) { g.set_attribute("white_cells", 0); });
  EXPECT_NE(msg.find("do not make the"), std::string::npos) << msg;
  msg = read_error(edit<std::uint8_t>("layer_face", [](auto& v) { v[0] = static_cast<std::uint8_t>((v[0] + 1) % 6); }));
  EXPECT_EQ(msg.rfind(prefix() + "grey cell 0: layers do not list its domain faces in order", 0), 0u) << msg;
}

TEST_F(DamagedReliefTest, InconsistentMapsAreFormatErrors) {
  const ReliefMap& m = torus_map();
  std::size_t empty = 0;
  while (empty < m.distances.size() && m.distances[empty] != kEmptyTexel) ++empty;
  ASSERT_LT(empty, m.distances.size()) << "the torus map should have empty texels";
  std::string msg = read_error(edit<std::int8_t>("normals", [&](auto& v) { v[3 * empty + 1] = 5; }));
  EXPECT_EQ(msg, prefix() + fmt::format("empty texel {} has a non-zero normal", empty));
  msg = read_error(edit<std::int8_t>("normals", [](auto& v) { v[0] = -128; }));
  EXPECT_EQ(msg, prefix() + "normal of texel 0 has a component -128 (snorm8 uses -127..127)");
  msg = read_error([](h5::Group& g) { g.open_dataset("distances").set_attribute("scale", 0.0); });
  EXPECT_EQ(msg, prefix() + "distances attribute scale = 0 is not a positive number");
  msg = read_error([](h5::Group& g) { g.open_dataset("distances").set_attribute("offset", 1.0); });
  EXPECT_NE(msg.find("offset = 1"), std::string::npos) << msg;
  msg = read_error(edit<std::int64_t>("grid_levels", [](auto& v) { v[v.size() - 5] += 1; }));
  EXPECT_NE(msg.find("dataset 'grid_levels': the last grid level (n = "), std::string::npos) << msg;
  msg = read_error(edit<std::int64_t>("grid_levels", [](auto& v) { v[4] = v[3] + 1; }));
  EXPECT_NE(msg.find("row 0 of 'grid_levels'"), std::string::npos) << msg;
}

}  // namespace
