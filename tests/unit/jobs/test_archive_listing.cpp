// `gimforge ls`: the listing names every representation and batch output with its method, size and PSNR,
// escapes hostile names, and lists an unreadable item with its reason instead of stopping.
#include "jobs/archive_listing.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "io/hdf5.h"
#include "jobs/batch_run.h"
#include "jobs/compress.h"
#include "jobs/pipeline.h"
#include "kernels/core/embree_device.h"
#include "mpi/comm.h"
#include "tests/unit/test_support.h"

namespace gimforge::jobs {
namespace {

namespace fs = std::filesystem;

const std::string kData = GIMFORGE_TEST_DATA_DIR;

class ArchiveListingTest : public test::ScratchDirTest {
 protected:
  /// Converts tests/data/MESH with `method` (small sizes) into `archive` as `name`.
  void convert_into(const fs::path& archive, const std::string& mesh, Method method, const std::string& name) {
    const LoadedMesh m = load_mesh(kData + "/" + mesh, load_policy(method, false));
    ConversionRequest request;
    request.method.method = method;
    request.method.size = 65;
    request.method.normal_size = 0;
    request.method.n = 8;
    request.method.grid = "2";
    request.method.texture = 8;
    request.fidelity.samples = 2000;
    request.source = mesh;
    const EmbreeDevice device;
    const Conversion c = convert_mesh(device, m.mesh, request);
    io::Archive a = fs::exists(archive) ? io::Archive::open(archive, h5::OpenMode::kReadWrite)
                                        : io::Archive::create(archive, {});
    write_conversion(a, name, c);
    a.close();
  }
};

TEST_F(ArchiveListingTest, ListsEveryRepresentationWithMethodSizeAndPsnr) {
  const fs::path path = file("a.h5");
  convert_into(path, "tetra.obj", Method::Gim, "tetra");
  convert_into(path, "cube.off", Method::Relief, "cube");
  const ArchiveListing listing = list_archive(io::Archive::open(path));
  ASSERT_EQ(listing.items.size(), 2u);
  const ListedItem& gim = listing.items[0];
  EXPECT_EQ(gim.group, "gim");
  EXPECT_EQ(gim.name, "tetra");
  EXPECT_EQ(gim.method, "gim");
  EXPECT_EQ(gim.shape, "65x65x3");
  ASSERT_TRUE(gim.psnr.has_value());
  EXPECT_GT(*gim.psnr, 30.0);
  EXPECT_EQ(gim.source, "tetra.obj");
  const ListedItem& relief = listing.items[1];
  EXPECT_EQ(relief.group, "relief");
  EXPECT_EQ(relief.method, "relief");
  EXPECT_NE(relief.shape.find("grid 2"), std::string::npos) << relief.shape;
  EXPECT_TRUE(relief.problem.empty()) << relief.problem;

  const std::string text = listing_text(listing);
  EXPECT_NE(text.find("gim/tetra"), std::string::npos) << text;
  EXPECT_NE(text.find("relief/cube"), std::string::npos) << text;
  const nlohmann::json j = listing_json(listing);
  ASSERT_EQ(j["items"].size(), 2u);
  EXPECT_EQ(j["items"][0]["shape"], "65x65x3");
  EXPECT_TRUE(j["items"][0]["psnr"].is_number());
}

// A quantized item keeps its conversion's PSNR, which is no longer its surface's: marked, with the legend.
TEST_F(ArchiveListingTest, ACodedItemsPsnrIsMarkedAsItsConversions) {
  convert_into(file("a.h5"), "tetra.obj", Method::Gim, "tetra");
  {
    const io::Archive in = io::Archive::open(file("a.h5"));
    io::Archive out = io::Archive::create(file("q.h5"), {});
    CompressOptions o;
    o.codec = CodecChoice::Quant12;
    o.measure = false;
    (void)compress_item(EmbreeDevice{}, in, ImageRef{Method::Gim, "tetra"}, out, o);
    out.close();
  }
  const ArchiveListing plain = list_archive(io::Archive::open(file("a.h5")));
  const ArchiveListing coded = list_archive(io::Archive::open(file("q.h5")));
  ASSERT_EQ(coded.items.size(), 1u);
  EXPECT_FALSE(plain.items[0].coded);
  EXPECT_TRUE(coded.items[0].coded);
  EXPECT_EQ(coded.items[0].psnr, plain.items[0].psnr);
  EXPECT_EQ(listing_text(plain).find('*'), std::string::npos);
  EXPECT_NE(listing_text(coded).find(fmt::format("{:.2f}*", *coded.items[0].psnr)), std::string::npos) << listing_text(coded);
  EXPECT_NE(listing_text(coded).find("before coding"), std::string::npos);
  EXPECT_EQ(listing_json(coded)["items"][0]["coded"], true);
}

TEST_F(ArchiveListingTest, EscapesHostileNamesAndReportsUnreadableItems) {
  const fs::path path = file("a.h5");
  convert_into(path, "tetra.obj", Method::Gim, "tetra");
  {
    // Someone else's archive: a name holding a terminal escape and a newline, and a group without its data.
    h5::File f = h5::File::open(path, h5::OpenMode::kReadWrite);
    h5::Group g = f.create_group("gim/evil\x1b[2J\ngimforge: info: forged");
    g.set_attribute("method", "gim");
    g.set_attribute("source", "x.ply");
    g.set_attribute("psnr", std::string_view("not a number"));
    f.close();
  }
  const ArchiveListing listing = list_archive(io::Archive::open(path));
  ASSERT_EQ(listing.items.size(), 2u);
  const std::string text = listing_text(listing);
  EXPECT_EQ(text.find('\x1b'), std::string::npos) << text;
  // Header + two items, one line each: the newline in the name did not forge a line.
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 4) << text;
  const auto evil = std::find_if(listing.items.begin(), listing.items.end(),
                                 [](const ListedItem& i) { return i.name != "tetra"; });
  ASSERT_NE(evil, listing.items.end());
  EXPECT_FALSE(evil->problem.empty()) << "a string psnr attribute is a damaged item";
}

TEST_F(ArchiveListingTest, ListsBatchOutputsWithCountsAndMeanPsnr) {
  fs::create_directories(dir_ / "in");
  fs::copy_file(kData + "/tetra.obj", dir_ / "in/tetra.obj");
  fs::copy_file(kData + "/cube.off", dir_ / "in/cube.off");
  BatchOptions o;
  o.input = (dir_ / "in").string();
  o.output = file("batch.h5").string();
  o.method.method = Method::Gim;
  o.method.size = 65;
  o.metric_samples = 2000;
  o.max_retries = 0;
  o.progress = false;
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::Done);
  const ArchiveListing listing = list_archive(io::Archive::open(o.output));
  ASSERT_EQ(listing.items.size(), 1u);
  const ListedItem& out = listing.items[0];
  EXPECT_EQ(out.group, "batch");
  EXPECT_EQ(out.name, "gim_65");
  EXPECT_EQ(out.count, 2);
  EXPECT_EQ(out.failed, 0);
  EXPECT_EQ(out.shape, "2x3x65x65");
  ASSERT_TRUE(out.psnr.has_value());
  EXPECT_GT(*out.psnr, 30.0);

  // A count the stack does not hold is a damaged output, as the readers say: never listed as converted.
  {
    io::Archive a = io::Archive::open(o.output, h5::OpenMode::kReadWrite);
    a.root().open_group("batch/gim_65").set_attribute("count", std::int64_t{3});
    a.close();
  }
  const ListedItem damaged = list_archive(io::Archive::open(o.output)).items.at(0);
  EXPECT_NE(damaged.problem.find("dataset 'data' has shape (2, 3, 65, 65), expected (3, C, H, W)"), std::string::npos)
      << damaged.problem;
  EXPECT_EQ(damaged.count, -1);
}

}  // namespace
}  // namespace gimforge::jobs
