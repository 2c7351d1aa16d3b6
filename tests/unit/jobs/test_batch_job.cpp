// Batch job description: collection discovery, labels, job files (jobs/batch_job.h), and the header-only
// triangle estimates used to schedule the largest meshes first (io/mesh_header.h).
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>

#include "io/mesh_header.h"
#include "jobs/batch_job.h"
#include "kernels/core/errors.h"
#include "tests/unit/test_support.h"

namespace gimforge::jobs {
namespace {

namespace fs = std::filesystem;
using test::message_of;

const std::string kData = GIMFORGE_TEST_DATA_DIR;

class BatchJobTest : public test::ScratchDirTest {};

TEST_F(BatchJobTest, DiscoversMeshesRecursivelyWithFolderLabelsSortedByPath) {
  fs::create_directories(dir_ / "c/b");
  fs::copy_file(kData + "/fist.ply", dir_ / "c/b/fist.ply");
  fs::copy_file(kData + "/tetra.obj", dir_ / "c/tetra.obj");
  std::ofstream(dir_ / "c/readme.txt") << "not a mesh";
  const auto items = discover({{.input = dir_ / "c"}});
  ASSERT_EQ(items.size(), 2u);
  EXPECT_EQ(items[0].name, "b/fist");
  EXPECT_EQ(items[0].label, "b");
  EXPECT_EQ(items[1].name, "tetra");
  EXPECT_EQ(items[1].label, "");
  const auto fixed = discover({{.input = dir_ / "c", .label_rule = LabelRule::Fixed, .label = "shapes"}});
  EXPECT_EQ(fixed[1].label, "shapes");
  // batch --label reaches here without the job file's check: a tab or an ESC went into the archive.
  const std::string bad = message_of<InvalidInput>(
      [&] { (void)discover({{.input = dir_ / "c", .label_rule = LabelRule::Fixed, .label = "bad\x1b[31m"}}); });
  EXPECT_NE(bad.find("the label 'bad\\e[31m' contains a control character"), std::string::npos) << bad;
}

TEST_F(BatchJobTest, AFileWhosePathIsNotUtf8IsLeftOutNotFailingTheJob) {
  // Names and paths go into JSON and the archive's UTF-8 strings: such a file once failed the whole batch
  // with an internal JSON error.
  fs::create_directories(dir_ / "c");
  fs::copy_file(kData + "/fist.ply", dir_ / "c/fist.ply");
  fs::copy_file(kData + "/tetra.obj", dir_ / "c" / "bad\xff.obj");
  const auto items = discover({{.input = dir_ / "c"}});
  ASSERT_EQ(items.size(), 1u);
  EXPECT_EQ(items[0].name, "fist");
}

TEST_F(BatchJobTest, ListFilesAndDuplicateNames) {
  std::ofstream(dir_ / "list.txt") << "# meshes\n" << kData << "/fist.ply\n\n" << kData << "/kitten.ply\n";
  const auto items = discover({{.list = dir_ / "list.txt"}});
  ASSERT_EQ(items.size(), 2u);
  EXPECT_EQ(items[0].name, "fist");
  std::ofstream(dir_ / "dup.txt") << kData << "/fist.ply\n" << kData << "/../data/fist.ply\n";
  EXPECT_NE(message_of<InvalidInput>([&] { (void)discover({{.list = dir_ / "dup.txt"}}); }).find("'fist'"),
            std::string::npos);
  EXPECT_NE(message_of<IoError>([&] { (void)discover({{.input = dir_ / "missing"}}); }).find("missing"),
            std::string::npos);
  // A byte-order mark before the first line (it failed as "file does not exist"), a line holding a NUL (its
  // name, source and reason were stored cut at the NUL): the first read, the second skipped.
  std::ofstream(dir_ / "bom.txt", std::ios::binary) << "\xEF\xBB\xBF" << kData << "/fist.ply\n"
                                                    << kData << std::string("/kit\0ten.ply\n", 13) << kData << "/tetra.obj\n";
  const auto listed = discover({{.list = dir_ / "bom.txt"}});
  ASSERT_EQ(listed.size(), 2u);
  EXPECT_EQ(listed[0].source, kData + "/fist.ply");
  EXPECT_EQ(listed[1].name, "tetra");
}

// A list's label is the folder holding the file: "../a.ply" and "./a.ply" once gave the classes ".." and ".".
TEST_F(BatchJobTest, AListItemsLabelIsTheFolderThatHoldsItNotDotOrDotDot) {
  fs::create_directories(dir_ / "shapes/lists");
  fs::copy_file(kData + "/fist.ply", dir_ / "shapes/fist.ply");
  fs::copy_file(kData + "/tetra.obj", dir_ / "shapes/lists/tetra.obj");
  std::ofstream(dir_ / "shapes/lists/l.txt") << "../fist.ply\n./tetra.obj\n";
  const auto items = discover({{.list = dir_ / "shapes/lists/l.txt"}});
  ASSERT_EQ(items.size(), 2u);
  EXPECT_EQ(items[0].label, "shapes");
  EXPECT_EQ(items[1].label, "lists");
}

TEST_F(BatchJobTest, RelativeSourcesAreReadFromTheDirectoryTheJobStartedIn) {
  // A job started in dir_ with `--input c`, resumed from elsewhere with the folder's absolute path: the same
  // files (a probe's resume from another directory was refused as another job).
  fs::create_directories(dir_ / "c");
  fs::copy_file(kData + "/tetra.obj", dir_ / "c/tetra.obj");
  const nlohmann::json outputs = nlohmann::json::array();
  const nlohmann::json started = {{"items", {{"tetra", "c/tetra.obj", ""}}}, {"outputs", outputs},
                                  {"metric_samples", 1000}, {"directory", dir_.string()}};
  nlohmann::json resumed = started;
  resumed["items"][0][1] = (dir_ / "c/tetra.obj").string();
  resumed["directory"] = "/";
  EXPECT_EQ(job_difference(started, resumed), "");
  resumed["items"][0][1] = (dir_ / "c/other.obj").string();
  EXPECT_NE(job_difference(started, resumed).find("item 0 was 'c/tetra.obj'"), std::string::npos);
  // A journal of an earlier version records no directory: its sources are read from the current one.
  nlohmann::json earlier = started;
  earlier.erase("directory");
  resumed["items"][0][1] = (dir_ / "c/tetra.obj").string();
  EXPECT_NE(job_difference(earlier, resumed), "") << "c/tetra.obj is not there from " << fs::current_path();
  EXPECT_TRUE(job_json(BatchJob{}).contains("directory"));
}

TEST_F(BatchJobTest, JobFileErrorsNameFileAndLine) {
  std::ofstream(dir_ / "job.toml") << "[[collection]]\ninput = \"" << kData << "\"\n[[output]]\nmethod = \"gim\"\nsize = 100\n";
  const std::string msg = message_of<FormatError>([&] { (void)load_job_file(dir_ / "job.toml"); });
  EXPECT_NE(msg.find("job.toml:5"), std::string::npos) << "the line of 'size', not of [[output]]: " << msg;
  EXPECT_NE(msg.find("multiple of 64"), std::string::npos) << msg;
  std::ofstream(dir_ / "label.toml") << "[[collection]]\ninput = \"" << kData << "\"\nprefix = \"p\"\nlabel = \"a\tb\"\n"
                                      << "[[output]]\nmethod = \"gim\"\n";
  const std::string label = message_of<FormatError>([&] { (void)load_job_file(dir_ / "label.toml"); });
  EXPECT_NE(label.find("label.toml:4: label 'a\\tb' contains a control character"), std::string::npos) << label;
  std::ofstream(dir_ / "typo.toml") << "[[collection]]\ninput = \"x\"\nlabels = \"none\"\n";
  EXPECT_NE(message_of<FormatError>([&] { (void)load_job_file(dir_ / "typo.toml"); }).find("unknown key 'labels'"),
            std::string::npos);
  std::ofstream(dir_ / "ok.toml") << "[[collection]]\ninput = \"" << kData << "\"\nlabel = \"none\"\n"
                                   << "[[output]]\nmethod = \"sphere\"\nn = 16\n[[output]]\nmethod = \"gim\"\nsize = 129\n";
  const BatchJob job = load_job_file(dir_ / "ok.toml");
  ASSERT_EQ(job.outputs.size(), 2u);
  EXPECT_EQ(job.outputs[0].name, "sphere_octa_16");
  EXPECT_EQ(job.outputs[1].name, "gim_129");
  EXPECT_EQ(job.keys().size(), 2 * job.items.size());
  // The option checks shared with the command line speak of the job file's keys, not of its options.
  std::ofstream(dir_ / "gain.toml") << "[[collection]]\ninput = \"" << kData << "\"\n[[output]]\nmethod = \"gim\"\nsize = 65\n"
                                     << "sampling = \"adaptive\"\nroi = \"auto\"\nroi_gain = 100\n";
  const std::string gain = message_of<FormatError>([&] { (void)load_job_file(dir_ / "gain.toml"); });
  EXPECT_NE(gain.find("roi_gain 100 is outside 1..64"), std::string::npos) << gain;
  EXPECT_EQ(gain.find("--"), std::string::npos) << gain;
  std::ofstream(dir_ / "rate.toml") << "[[collection]]\ninput = \"" << kData << "\"\n[[output]]\nmethod = \"gim\"\nsize = 65\n"
                                     << "codec = \"j2k\"\nrate = 500\n";
  const std::string rate = message_of<FormatError>([&] { (void)load_job_file(dir_ / "rate.toml"); });
  EXPECT_NE(rate.find("rate 500 is below 1024 (the stored bytes per item, codec j2k)"), std::string::npos) << rate;
  // metric_samples = 0 was accepted, and every item then failed after its conversion.
  std::ofstream(dir_ / "ms.toml") << "metric_samples = 0\n[[collection]]\ninput = \"" << kData << "\"\n[[output]]\nmethod = \"gim\"\n";
  const std::string ms = message_of<FormatError>([&] { (void)load_job_file(dir_ / "ms.toml"); });
  EXPECT_NE(ms.find("ms.toml: metric_samples = 0 is outside 1.."), std::string::npos) << ms;
  // A prefix that leaves the item names' tree (--name batch/OUTPUT/../x could not read them back), and an
  // output name longer than a file name (every item converted, then every shard write failed).
  std::ofstream(dir_ / "up.toml") << "[[collection]]\ninput = \"" << kData << "\"\nprefix = \"../\"\n[[output]]\nmethod = \"gim\"\n";
  const std::string up = message_of<FormatError>([&] { (void)load_job_file(dir_ / "up.toml"); });
  EXPECT_NE(up.find("up.toml:3: prefix '../' must be names joined by '/' (as \"train/\"): its part '..' is '..'"),
            std::string::npos) << up;
  EXPECT_NE(message_of<InvalidInput>([&] { (void)discover({{.input = kData, .prefix = "/abs/"}}); })
                .find("the prefix '/abs/' must be names joined by '/'"),
            std::string::npos);
  EXPECT_FALSE(discover({{.input = kData, .prefix = "train/a/"}}).empty());
  std::ofstream(dir_ / "long.toml") << "[[collection]]\ninput = \"" << kData << "\"\n[[output]]\nmethod = \"gim\"\nname = \""
                                     << std::string(256, 'x') << "\"\n";
  const std::string long_name = message_of<FormatError>([&] { (void)load_job_file(dir_ / "long.toml"); });
  EXPECT_NE(long_name.find("is 256 bytes long (a file name holds at most 255)"), std::string::npos) << long_name;
}

TEST(MeshHeader, EstimatesTrianglesFromHeaders) {
  EXPECT_EQ(io::estimate_triangles(kData + "/fist.ply"), 2390u);
  EXPECT_EQ(io::estimate_triangles(kData + "/cube.off"), 6u);  // 6 quads: the header counts polygons
  EXPECT_GT(io::estimate_triangles(kData + "/tetra.obj"), 0u);
  EXPECT_EQ(io::estimate_triangles(kData + "/no-such-file.ply"), 0u);
}

TEST_F(BatchJobTest, ReliefOutputsAndTheirKeysAreChecked) {
  const std::string collection = "[[collection]]\ninput = \"" + kData + "\"\n[[output]]\n";
  std::ofstream(dir_ / "relief.toml") << "metric = false\n" << collection << "method = \"relief\"\ngrid = 4\ntexture = 16\n";
  const BatchJob job = load_job_file(dir_ / "relief.toml");
  ASSERT_EQ(job.outputs.size(), 1u);
  EXPECT_EQ(job.outputs[0].name, "relief_4_16");
  EXPECT_EQ(job.outputs[0].method.method, Method::Relief);
  EXPECT_FALSE(job.metric);
  const auto error = [&](const std::string& body) {
    std::ofstream(dir_ / "bad.toml") << collection << body;
    return message_of<FormatError>([&] { (void)load_job_file(dir_ / "bad.toml"); });
  };
  EXPECT_NE(error("method = \"relief\"\nsize = 65\n").find("'size' applies to method \"gim\" only"), std::string::npos);
  EXPECT_NE(error("method = \"relief\"\ngrid = 4294967300\n").find("'grid' must be an integer"), std::string::npos);
  EXPECT_NE(error("method = \"relief\"\ngrid = 4\nmax_grid = 8\n").find("grid \"auto\" only"), std::string::npos);
  EXPECT_NE(error("method = \"relief\"\ngrid = 4.5\n").find("'grid' must be"), std::string::npos);
  EXPECT_NE(error("method = \"relief\"\ntexture = 1\n").find("texture 1"), std::string::npos);
  // A geometry image too large to allocate is refused with the job, not after a conversion ran out of memory.
  EXPECT_NE(error("method = \"gim\"\nsize = 1048577\n").find("gim size 1048577 is too large (at most 8193)"),
            std::string::npos);
}

}  // namespace
}  // namespace gimforge::jobs
