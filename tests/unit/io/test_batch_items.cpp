// Tests of batch items read back as images (io/batch_items.h): the sideband a geometry-image item keeps
// through its shard and the merge, spherical items with their mask and layout, the frame origin, and the
// errors for names that are not there and for damaged stacks.
#include <gtest/gtest.h>
#include <hdf5.h>

#include "tests/unit/test_support.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "io/archive.h"
#include "io/batch_archive.h"
#include "io/batch_items.h"
#include "io/batch_shard.h"
#include "io/gim_archive.h"
#include "kernels/core/errors.h"

namespace fs = std::filesystem;
using namespace gimforge;
using gimforge::test::message_of;

namespace {

/// A sideband of one cut-path glued to itself around the square: +1 on the first half, -1 on the second.
const std::vector<std::int32_t> kFolded{1, 0, 128, -1, 128, 128};

io::ItemKey key(std::uint64_t index, const std::string& output) {
  return {.output = output, .name = "shapes/" + std::to_string(index), .source = std::to_string(index) + ".ply",
          .label = "shapes", .index = index};
}

/// A 65 x 65 geometry image item whose sample p, channel c holds index + p + c / 4, with `sideband`.
io::ItemArrays gim_item(std::uint64_t index, std::vector<std::int32_t> sideband) {
  io::ItemArrays a;
  a.channels = 3;
  a.height = a.width = 65;
  for (std::size_t c = 0; c < 3; ++c)
    for (std::size_t p = 0; p < 65 * 65; ++p) a.data.push_back(static_cast<float>(index) + static_cast<float>(p) + 0.25f * static_cast<float>(c));
  a.metrics = {{"psnr", 50.0}, {"frame_origin_x", 1e6}, {"frame_origin_y", 2e6}, {"frame_origin_z", -3.0}};
  a.units_per_side = sideband.empty() ? 0 : 64;
  a.sideband = std::move(sideband);
  return a;
}

class BatchItemsTest : public gimforge::test::ScratchDirTest {
 protected:
  fs::path merge(const std::vector<std::pair<io::ItemKey, io::ItemArrays>>& items,
                 std::map<std::string, std::string> attributes = {{"method", "gim"}, {"size", "65"}}) {
    io::MergeInput input{.output = items.front().first.output, .shards = {}, .failed = {},
                         .attributes = std::move(attributes), .groups = false};
    for (const auto& [k, a] : items) {
      const fs::path shard = file(k.output + "_" + std::to_string(k.index) + ".h5");
      io::write_shard(shard, k, a);
      input.shards.push_back(shard);
    }
    const fs::path archive = file("batch.h5");
    io::write_batch_archive(archive, {.creator = "test", .parameters_json = "{}"}, {&input, 1});
    return archive;
  }
};

TEST_F(BatchItemsTest, AGeometryImageItemKeepsItsSidebandThroughShardAndMerge) {
  // Item 1 has no sideband (a shard written before they were kept): its rows are empty, the others' intact.
  const fs::path path = merge({{key(0, "gim_65"), gim_item(0, kFolded)},
                               {key(1, "gim_65"), gim_item(1, {})},
                               {key(2, "gim_65"), gim_item(2, {0, 0, 256})}});
  const io::Archive archive = io::Archive::open(path);
  const io::BatchItem second = io::find_batch_item(archive, "gim_65/shapes/2");
  EXPECT_EQ(second.k, 2u);
  EXPECT_EQ(second.method, "gim");
  EXPECT_FALSE(second.group);
  EXPECT_EQ(second.path(), "batch/gim_65/shapes/2");
  const GeometryImage image = io::read_batch_geometry_image(archive, second);
  EXPECT_EQ(image.size, 65u);
  EXPECT_EQ(io::sideband_table(image.sideband), (std::vector<std::int32_t>{0, 0, 256}));
  EXPECT_EQ(image.positions[3 * 7 + 2], 2.0f + 7.0f + 0.5f);  // interleaved again: sample 7, channel z
  EXPECT_EQ(io::sideband_table(io::read_batch_geometry_image(archive, io::find_batch_item(archive, "gim_65/shapes/0")).sideband),
            kFolded);
  EXPECT_TRUE(io::read_batch_geometry_image(archive, io::find_batch_item(archive, "gim_65/shapes/1")).sideband.paths.empty());
  EXPECT_EQ(archive.root().open_dataset("batch/gim_65/sideband_offsets").read<std::int64_t>(),
            (std::vector<std::int64_t>{0, 2, 2, 3}));
  const Vec3 origin = io::read_batch_item_origin(archive, second, 1e12);
  EXPECT_EQ(origin, Vec3(1e6, 2e6, -3.0));
  EXPECT_EQ(io::batch_items(archive).size(), 3u);
}

TEST_F(BatchItemsTest, NamesThatAreNotThereAreRefusedSayingWhatIs) {
  const fs::path path = merge({{key(0, "gim_65"), gim_item(0, kFolded)}});
  const io::Archive archive = io::Archive::open(path);
  EXPECT_NE(message_of<InvalidInput>([&] { (void)io::find_batch_item(archive, "gim_129/shapes/0"); })
                .find("no batch output 'gim_129'"),
            std::string::npos);
  EXPECT_NE(message_of<InvalidInput>([&] { (void)io::find_batch_item(archive, "gim_65/shapes/9"); })
                .find("batch output 'gim_65' has no item 'shapes/9' (1 items: shapes/0)"),
            std::string::npos);
  EXPECT_NE(message_of<InvalidInput>([&] { (void)io::find_batch_item(archive, "gim_65"); }).find("names no item"),
            std::string::npos);
}

TEST_F(BatchItemsTest, TwoItemsOfOneNameAndAScalarMaskAreRefusedNotMisread) {
  const fs::path path = merge({{key(0, "gim_65"), gim_item(0, kFolded)}, {key(1, "gim_65"), gim_item(1, kFolded)}});
  {
    io::Archive rw = io::Archive::open(path, h5::OpenMode::kReadWrite);
    h5::Group g = rw.root().open_group("batch/gim_65");
    ASSERT_GE(H5Ldelete(g.id(), "names", H5P_DEFAULT), 0);
    g.write_strings("names", std::vector<std::string>{"shapes/1", "shapes/1"});
    g.set_attribute("method", std::string("sphere"));
    g.set_attribute("domain", std::string("octa"));
    g.set_attribute("n", std::string("32"));
    const hid_t scalar = H5Screate(H5S_SCALAR);  // a scalar where (N, 1, H, W) belongs
    const hid_t mask = H5Dcreate2(g.id(), "mask", H5T_NATIVE_UINT8, scalar, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(mask, 0);
    H5Dclose(mask);
    H5Sclose(scalar);
  }
  const io::Archive archive = io::Archive::open(path);
  EXPECT_NE(message_of<FormatError>([&] { (void)io::find_batch_item(archive, "gim_65/shapes/1"); })
                .find("the output names two items so"),
            std::string::npos);
  io::BatchItem first{"gim_65", "shapes/1", 0, "sphere", false, "0.ply"};
  EXPECT_NE(message_of<FormatError>([&] { (void)io::read_batch_spherical_image(archive, first); })
                .find("dataset 'mask' is not uint8 (N, 1, 65, 65)"),
            std::string::npos);
}

TEST_F(BatchItemsTest, SamplesWhereNoMeshLiesAreRefused) {
  // Finite, but beyond ±1e18 (io::kMaxCoordinate): the reconstruction would be a mesh gimforge refuses to read.
  io::ItemArrays far = gim_item(1, kFolded);
  far.data[65 * 65 + 7] = 3e38f;  // channel 1 of sample 7
  const fs::path path = merge({{key(0, "gim_65"), gim_item(0, kFolded)}, {key(1, "gim_65"), far}});
  const io::Archive archive = io::Archive::open(path);
  EXPECT_EQ(io::read_batch_geometry_image(archive, io::find_batch_item(archive, "gim_65/shapes/0")).size, 65u);
  const std::string message =
      message_of<FormatError>([&] { (void)io::read_batch_geometry_image(archive, io::find_batch_item(archive, "gim_65/shapes/1")); });
  EXPECT_NE(message.find("sample 7 has a coordinate of magnitude 3e+38, beyond ±1e+18"), std::string::npos) << message;
  EXPECT_NE(message.find("shapes/1"), std::string::npos) << message;
}

TEST_F(BatchItemsTest, AnInvalidSidebandIsRefusedWhenWrittenAndWhenRead) {
  // A path without its mate, and units that leave the perimeter: refused before a shard exists.
  EXPECT_THROW(io::check_item(key(0, "gim_65"), gim_item(0, {1, 0, 256})), InvalidInput);
  io::ItemArrays odd = gim_item(0, kFolded);
  odd.units_per_side = 48;  // 64 is no multiple of 48
  EXPECT_THROW(io::check_item(key(0, "gim_65"), odd), InvalidInput);
  // Offsets that point past the table, written into a merged archive: a FormatError naming the item.
  const fs::path path = merge({{key(0, "gim_65"), gim_item(0, kFolded)}});
  {
    io::Archive rw = io::Archive::open(path, h5::OpenMode::kReadWrite);
    h5::Dataset offsets = rw.root().open_dataset("batch/gim_65/sideband_offsets");
    offsets.write_slab({1}, {1}, std::vector<std::int64_t>{7});
  }
  const io::Archive archive = io::Archive::open(path);
  const std::string message = message_of<FormatError>(
      [&] { (void)io::read_batch_geometry_image(archive, io::find_batch_item(archive, "gim_65/shapes/0")); });
  EXPECT_NE(message.find("batch/gim_65/shapes/0: sideband_offsets (0 first, 0 and 7 for the item, 7 last) do not index "
                         "the 2 rows of 'sideband'"),
            std::string::npos)
      << message;
}

TEST_F(BatchItemsTest, AStackOfHugeImagesIsRefusedBeforeAnythingIsRead) {
  // A small file whose 'data' declares 20000 x 20000 images (chunks never written): refused from its shape,
  // without reading 4.8 GB of fill values.
  const fs::path path = merge({{key(0, "gim_65"), gim_item(0, kFolded)}});
  {
    io::Archive rw = io::Archive::open(path, h5::OpenMode::kReadWrite);
    h5::Group g = rw.root().open_group("batch/gim_65");
    ASSERT_GE(H5Ldelete(g.id(), "data", H5P_DEFAULT), 0);
    (void)g.create_dataset("data", h5::DataType::of<float>(), {1, 3, 20000, 20000}, {.chunk = h5::Dims{1, 1, 1000, 1000}});
  }
  const io::Archive archive = io::Archive::open(path);
  const std::string message = message_of<FormatError>(
      [&] { (void)io::read_batch_geometry_image(archive, io::find_batch_item(archive, "gim_65/shapes/0")); });
  EXPECT_NE(message.find("the stack holds 20000 x 20000 images; a geometry image is n x n, 2 <= n <= 16385"),
            std::string::npos)
      << message;
}

TEST_F(BatchItemsTest, ASphericalItemIsReadWithItsMaskAndLayout) {
  // Octahedron at n = 2: one 5 x 5 image. Samples 0 and 6 lie in a hole (mask 0, NaN).
  io::ItemArrays a;
  a.channels = 3;
  a.height = a.width = 5;
  a.data.assign(3 * 25, 0.5f);
  a.mask.assign(25, 1);
  for (const std::size_t p : {0u, 6u}) {
    a.mask[p] = 0;
    for (std::size_t c = 0; c < 3; ++c) a.data[c * 25 + p] = std::numeric_limits<float>::quiet_NaN();
  }
  const fs::path path = merge({{key(0, "sphere_octa_2"), a}}, {{"method", "sphere"}, {"domain", "octa"}, {"n", "2"}});
  io::BatchItem item;
  {
    const io::Archive archive = io::Archive::open(path);
    item = io::find_batch_item(archive, "sphere_octa_2/shapes/0");
    const SphericalImage image = io::read_batch_spherical_image(archive, item);
    EXPECT_EQ(image.domain, SphericalDomain::Octahedron);
    EXPECT_EQ(image.n, 2u);
    EXPECT_EQ(image.mask[6], 0);
    EXPECT_EQ(image.mask[7], 1);
    EXPECT_EQ(io::read_batch_item_origin(archive, item, 1e12), Vec3::Zero());  // no frame_origin metrics: zero
  }
  // Attributes that disagree with the stack's shape: n = 3 is a 7 x 7 image.
  {
    io::Archive rw = io::Archive::open(path, h5::OpenMode::kReadWrite);
    h5::Group g = rw.root().open_group("batch/sphere_octa_2");
    g.set_attribute("n", std::string("3"));
  }
  const io::Archive changed = io::Archive::open(path);
  const std::string message = message_of<FormatError>([&] { (void)io::read_batch_spherical_image(changed, item); });
  EXPECT_NE(message.find("the stack holds 5 x 5 images, domain octa at n = 3 is 7 x 7"), std::string::npos) << message;
}

}  // namespace
