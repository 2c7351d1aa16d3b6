// The local frame (docs/archive.md, "Local frame and origin"): every conversion runs on the mesh moved to
// the centre of its bounding box, so a mesh in georeferenced coordinates (10^5, 10^7 from the origin)
// converts exactly as it does at the origin; the origin is stored on the item, with its provenance.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "io/archive.h"
#include "io/relief_archive.h"
#include "jobs/load_mesh.h"
#include "jobs/pipeline.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "tests/unit/test_support.h"

namespace gimforge::jobs {
namespace {

/// The translations of the finding: none, 10^5 (relief classification changed already) and 10^7 (a GIM of
/// 24 dB instead of 68 dB), along all three axes as in UTM coordinates.
const std::array<double, 3> kOffsets{0.0, 1e5, 1e7};
Vec3 shift(double t) { return Vec3(t, 0.5 * t, 0.25 * t); }

/// A closed genus-0 surface without symmetries a kernel could tie on: a bent, squashed icosphere whose
/// coordinates are multiples of 2^-12, so that the translated copies hold exactly the same surface (every
/// coordinate plus 10^7 is a double) and the local frames agree bit for bit.
TriMesh blob() {
  TriMesh m = make_icosphere(1.0, 3);
  for (Vec3& p : m.positions) {
    const Vec3 q(1.3 * p.x(), p.y() + 0.2 * p.x() * p.x(), 0.8 * p.z() + 0.1);
    for (int k = 0; k < 3; ++k) p[k] = std::ldexp(std::round(std::ldexp(q[k], 12)), -12);
  }
  return m;
}

TriMesh translated(const TriMesh& mesh, const Vec3& by) {
  TriMesh m = mesh;
  translate(m, by);
  return m;
}

ConversionRequest request_for(Method method) {
  ConversionRequest r;
  r.method.method = method;
  r.method.size = 65;
  r.method.normal_size = 0;
  r.method.n = 16;
  r.method.grid = "8";
  r.method.texture = 16;
  r.fidelity.samples = 20'000;
  r.command_line = "test_local_frame";
  return r;
}

class LocalFrameTest : public test::ScratchDirTest {
 protected:
  /// The conversion of the blob translated by shift(t).
  Conversion convert(Method method, double t) const {
    return convert_mesh(device_, translated(blob(), shift(t)), request_for(method));
  }
  EmbreeDevice device_;
};

TEST(LocalFrame, OriginIsTheBoundingBoxCentreInDouble) {
  TriMesh m = translated(blob(), Vec3(4.1e5, 5.3e6, 120.0));
  const BoundingBox box = bounding_box(m);
  const Vec3 origin = local_frame_origin(m);
  EXPECT_EQ(origin, box.center());
  const TriMesh before = m;
  to_local_frame(m, origin);
  EXPECT_LT(bounding_box(m).center().norm(), 1e-12);
  to_input_frame(m, origin);
  for (std::size_t v = 0; v < m.num_vertices(); ++v) EXPECT_EQ(m.positions[v], before.positions[v]) << v;
  EXPECT_EQ(local_frame_origin(TriMesh{}), Vec3::Zero());
}

TEST_F(LocalFrameTest, GeometryImagesDoNotDependOnTheTranslation) {
  const Conversion base = convert(Method::Gim, 0.0);
  ASSERT_TRUE(base.fidelity);
  EXPECT_GT(base.fidelity->psnr, 40.0);
  for (const double t : kOffsets) {
    SCOPED_TRACE(t);
    const Conversion c = convert(Method::Gim, t);
    EXPECT_EQ(c.origin, base.origin + shift(t));
    EXPECT_NEAR(c.fidelity->psnr, base.fidelity->psnr, 0.1);
    // The same local surface: the same image, bit for bit.
    EXPECT_EQ(c.gim->image.positions, base.gim->image.positions);
  }
}

TEST_F(LocalFrameTest, SphericalImagesDoNotDependOnTheTranslation) {
  const Conversion base = convert(Method::Sphere, 0.0);
  ASSERT_TRUE(base.fidelity);
  EXPECT_GT(base.fidelity->psnr, 30.0);
  for (const double t : kOffsets) {
    SCOPED_TRACE(t);
    const Conversion c = convert(Method::Sphere, t);
    EXPECT_EQ(c.origin, base.origin + shift(t));
    EXPECT_NEAR(c.fidelity->psnr, base.fidelity->psnr, 0.1);
    EXPECT_EQ(c.sphere->image.positions, base.sphere->image.positions);
  }
}

TEST_F(LocalFrameTest, ReliefCellsDoNotDependOnTheTranslation) {
  const Conversion base = convert(Method::Relief, 0.0);
  const ReliefMap& b = base.relief.value();
  ASSERT_GT(b.cells.size(), 0u);
  ASSERT_LT(b.cells.size(), std::size_t{8 * 8 * 8});
  for (const double t : kOffsets) {
    SCOPED_TRACE(t);
    const Conversion c = convert(Method::Relief, t);
    const ReliefMap& m = c.relief.value();
    EXPECT_EQ(c.origin, base.origin + shift(t));
    EXPECT_EQ(m.origin, b.origin);  // the grid's corner, in the local frame
    EXPECT_EQ(m.cells.size(), b.cells.size());
    EXPECT_EQ(m.white_cells, b.white_cells);
    EXPECT_EQ(m.black_cells, b.black_cells);
    EXPECT_EQ(m.num_layers(), b.num_layers());
    // The same cells, classified alike, projecting the same distances.
    EXPECT_EQ(m.cells, b.cells);
    EXPECT_EQ(m.external_faces, b.external_faces);
    EXPECT_EQ(m.layer_face, b.layer_face);
    EXPECT_EQ(m.distances, b.distances);
    EXPECT_NEAR(c.fidelity->psnr, base.fidelity->psnr, 0.1);
  }
}

TEST_F(LocalFrameTest, ItemsRecordTheirOriginAndProvenance) {
  const Conversion gim = convert(Method::Gim, 1e7);
  const Conversion relief = convert(Method::Relief, 1e5);
  {
    io::Archive a = io::Archive::create(file("a.h5"), {.creator = "first", .parameters_json = "{}"});
    write_conversion(a, "blob", gim);
    write_conversion(a, "blob", relief);  // appended by another conversion
    a.close();
  }
  const io::Archive a = io::Archive::open(file("a.h5"));
  EXPECT_EQ(item_origin(a, Method::Gim, "blob"), gim.origin);
  EXPECT_EQ(item_origin(a, Method::Relief, "blob"), relief.origin);
  const h5::Group g = a.root().open_group("gim/blob");
  EXPECT_EQ(g.attribute<std::string>("command_line"), "test_local_frame");
  EXPECT_FALSE(g.attribute<std::string>("gimforge_version").empty());
  EXPECT_EQ(g.attribute<std::string>("created"), gim.created);
  EXPECT_EQ(nlohmann::json::parse(g.attribute<std::string>("creation_parameters")),
            creation_parameters(request_for(Method::Gim)));
  const h5::Group r = a.root().open_group("relief/blob");
  EXPECT_EQ(nlohmann::json::parse(r.attribute<std::string>("creation_parameters"))["method"], "relief");
  // The root describes the archive as a whole: first creation, last change, parameters true of every item.
  const io::ArchiveInfo info = a.info();
  EXPECT_EQ(info.creator, "first");
  EXPECT_EQ(info.creation_parameters, kConvertArchiveParameters);
  EXPECT_EQ(a.root().attribute<std::string>("modified"), relief.created);
  EXPECT_EQ(a.root().attribute<std::string>("modified_by"), "test_local_frame");
  // The record (read_record) holds numbers only: the origin is an array, not one of them.
  EXPECT_EQ(io::read_relief_map(a, "blob").origin, relief.relief->origin);
}

TEST_F(LocalFrameTest, ItemOriginIsZeroWhenAbsentAndRefusesAnythingButThreeFiniteNumbers) {
  {
    io::Archive a = io::Archive::create(file("o.h5"), {});
    h5::Group g = a.root().create_group("old");
    h5::Group bad = a.root().create_group("bad");
    const std::array<double, 2> two{1.0, 2.0};
    bad.set_attribute("frame_origin", std::span<const double>(two));
    h5::Group nan = a.root().create_group("nan");
    const std::array<double, 3> three{1.0, std::nan(""), 2.0};
    nan.set_attribute("frame_origin", std::span<const double>(three));
    h5::Group text = a.root().create_group("text");
    text.set_attribute("frame_origin", "0,0,0");
    h5::Group far = a.root().create_group("far");  // a float32 position added to it would vanish
    const std::array<double, 3> huge{1e300, 0.0, 0.0};
    far.set_attribute("frame_origin", std::span<const double>(huge));
    h5::Group utm = a.root().create_group("utm");
    const std::array<double, 3> east{612345.5, 4123456.25, 80.0};
    utm.set_attribute("frame_origin", std::span<const double>(east));
    a.close();
  }
  const io::Archive a = io::Archive::open(file("o.h5"));
  EXPECT_EQ(item_origin(a.root().open_group("old"), "o.h5:/old"), Vec3::Zero());
  EXPECT_EQ(item_origin(a.root().open_group("utm"), "o.h5:/utm"), Vec3(612345.5, 4123456.25, 80.0));
  for (const char* name : {"bad", "nan", "text", "far"}) {
    const std::string m = test::message_of<FormatError>([&] { (void)item_origin(a.root().open_group(name), name); });
    EXPECT_EQ(m, std::string(name) + ": attribute frame_origin is not 3 finite numbers within ±1e12");
  }
}

TEST_F(LocalFrameTest, AMeshBeyondTheFrameOriginsTheReadersTakeIsRefused) {
  // What gimforge writes it must read back (item_origin refuses origins beyond ±1e12).
  EXPECT_NE(test::message_of<InvalidInput>([&] { (void)convert(Method::Relief, 1e13); }).find("within ±1e12"),
            std::string::npos);
  EXPECT_NO_THROW((void)convert(Method::Relief, 1e11));
}

TEST_F(LocalFrameTest, BatchItemsCarryTheirOrigin) {
  const Conversion c = convert(Method::Gim, 1e5);
  EXPECT_EQ(c.numbers.at("frame_origin_x"), c.origin.x());  // the record: convert and batch alike
  const BatchItem item = batch_item(c);
  EXPECT_EQ(item.arrays.metrics.at("frame_origin_x"), c.origin.x());
  EXPECT_EQ(item.arrays.metrics.at("frame_origin_y"), c.origin.y());
  EXPECT_EQ(item.arrays.metrics.at("frame_origin_z"), c.origin.z());

  const Conversion r = convert(Method::Relief, 1e7);
  const BatchItem relief = batch_item(r);
  ASSERT_TRUE(relief.representation);
  {
    io::Archive a = io::Archive::create(file("b.h5"), {});
    h5::Group g = a.root().create_group("item");
    relief.representation(g);
    a.close();
  }
  const io::Archive a = io::Archive::open(file("b.h5"));
  EXPECT_EQ(item_origin(a.root().open_group("item"), "item"), r.origin);
}

TEST(Provenance, CommandLineIsQuotedAsAShellReadsIt) {
  const char* argv[] = {"gimforge", "convert", "my scan.ply", "--name", "it's", "-o", "out.h5"};
  set_command_line(7, argv);
  EXPECT_EQ(command_line(), R"(gimforge convert 'my scan.ply' --name 'it'\''s' -o out.h5)");
  set_command_line("gimforge batch --job j.toml");
  EXPECT_EQ(command_line(), "gimforge batch --job j.toml");
  ConversionRequest r;  // no command line of its own: the process's
  r.method.method = Method::Relief;
  r.method.grid = "4";
  r.method.texture = 8;
  r.fidelity.enabled = false;
  const EmbreeDevice device;
  EXPECT_EQ(convert_mesh(device, blob(), r).command_line, "gimforge batch --job j.toml");
  set_command_line("");
}

TEST(Provenance, FarMeshesAreWrittenInDouble) {
  EXPECT_FALSE(ply_options_for(blob()).double_precision);
  EXPECT_TRUE(ply_options_for(translated(blob(), shift(1e7))).double_precision);
  EXPECT_TRUE(ply_options_for(translated(blob(), shift(1e5))).double_precision);
}

}  // namespace
}  // namespace gimforge::jobs
