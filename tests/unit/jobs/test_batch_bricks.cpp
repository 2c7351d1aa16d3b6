// A huge item of a batch as brick tasks (jobs/brick_tasks.h), in one process over the serial communicator:
// its image and statistics equal those of the same mesh converted whole; a stopped run keeps the plan and
// the pieces it journaled and a resume makes only the rest; a source rewritten since its plan is planned
// again; the plan's duplicate search keeps the first copy of a face, as the loader does.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "io/archive.h"
#include "io/input_file.h"
#include "io/journal.h"
#include "io/mesh_io.h"
#include "io/ply_ranges.h"
#include "jobs/batch_run.h"
#include "jobs/brick_tasks.h"
#include "jobs/load_mesh.h"
#include "jobs/pipeline.h"
#include "jobs/scan_bricks.h"
#include "kernels/core/procedural.h"
#include "mpi/comm.h"
#include "tests/unit/test_support.h"

namespace gimforge::jobs {
namespace {

namespace fs = std::filesystem;

/// A torus far from the origin (9,216 faces: small enough for the sanitizer build), with a ripple so that the
/// proxy must choose.
TriMesh scan(double ripple) {
  TriMesh t = make_torus(1.0, 0.4, 96, 48);
  for (Vec3& p : t.positions) p += Vec3(612345.0, 4123456.0, 80.0) + ripple * Vec3(std::sin(9 * p.x()), 0, 0);
  return t;
}

class BatchBricksTest : public test::ScratchDirTest {
 protected:
  void SetUp() override {
    ScratchDirTest::SetUp();
    fs::create_directories(dir_ / "in/a");
    fs::create_directories(dir_ / "in/b");
    // The same scan twice: a binary PLY (read in pieces: brick tasks) and an ASCII one (converted whole; the
    // shortest round-trip decimals give the same doubles).
    io::write_ply(dir_ / "in/a/scan.ply", scan(0.01), {.binary = true, .double_precision = true});
    io::write_ply(dir_ / "in/b/scan.ply", scan(0.01), {.binary = false, .double_precision = true});
  }

  [[nodiscard]] BatchOptions options(const std::string& archive) const {
    BatchOptions o;
    o.input = (dir_ / "in").string();
    o.output = file(archive).string();
    o.method.method = Method::Gim;
    o.method.size = 65;
    o.method.proxy_faces = "1000";
    o.method.proxy_bricks = 5;
    o.metric_samples = 5000;
    o.max_retries = 0;
    o.progress = false;
    return o;
  }

  /// The journal's brick records, as (output index, part).
  [[nodiscard]] std::vector<std::string> brick_records(const BatchOptions& o) const {
    std::vector<std::string> parts;
    for (const nlohmann::json& r : io::Journal::replay(o.output + ".work/journal.jsonl"))
      if (r.value("event", "") == "brick") parts.push_back(r.at("part").get<std::string>());
    return parts;
  }

  /// Stops once the journal holds `n` brick records.
  [[nodiscard]] std::function<bool()> stop_after_bricks(const BatchOptions& o, std::size_t n) const {
    return [this, o, n] {
      return fs::exists(o.output + ".work/journal.jsonl") && brick_records(o).size() >= n;
    };
  }

  /// Expects item 0 of the archive to hold the numbers `keys` that `convert` of `source` records (batch
  /// options: positions only, the batch's metric samples).
  static void expect_item_0_is_convert_of(const BatchOptions& o, const fs::path& source,
                                          std::initializer_list<const char*> keys) {
    ConversionRequest request;
    request.method = o.method;
    request.method.normal_size = 0;
    request.fidelity.samples = o.metric_samples;
    const EmbreeDevice device;
    const Conversion expected =
        convert_mesh(device, load_mesh(source.string(), load_policy(Method::Gim, false)).mesh, request);
    const io::Archive a = io::Archive::open(o.output);
    for (const char* key : keys)
      EXPECT_EQ(a.root().open_dataset(std::string("batch/gim_65/metrics/") + key).read<double>()[0],
                expected.numbers.at(key))
          << key;
  }

  /// Expects items 0 (bricks) and 1 (whole) of the archive to hold the same image and statistics.
  static void expect_items_equal(const BatchOptions& o) {
    const io::Archive a = io::Archive::open(o.output);
    const std::string g = "batch/" + o.method.default_output_name();
    const std::vector<float> data = a.root().open_dataset(g + "/data").read<float>();
    ASSERT_EQ(data.size(), 2u * 3 * 65 * 65);
    const std::size_t half = data.size() / 2;
    EXPECT_TRUE(std::equal(data.begin(), data.begin() + static_cast<std::ptrdiff_t>(half),
                           data.begin() + static_cast<std::ptrdiff_t>(half)))
        << "the item made by brick tasks differs from the one converted whole";
    for (const char* key : {"psnr", "proxy_psnr", "proxy_faces", "proxy_bricks", "hausdorff_max", "input_faces"}) {
      const std::vector<double> v = a.root().open_dataset(g + "/metrics/" + key).read<double>();
      ASSERT_EQ(v.size(), 2u) << key;
      EXPECT_EQ(v[0], v[1]) << key;
    }
    EXPECT_EQ(a.root().open_dataset(g + "/metrics/proxy_bricks").read<double>()[0], 5.0);
  }
};

// convert, relief and metrics by bricks under mpirun: ranks read the scan in pieces at different times, and some
// steps open it again by its path; a scan rewritten or replaced meanwhile gave a result of two files, exit 0.
TEST_F(BatchBricksTest, AScanChangedWhileItWasReadIsRefused) {
  const std::filesystem::path scan = dir_ / "scan.ply";
  std::ofstream(scan) << "ply\n";
  const std::string stamp = io::file_stamp(scan);
  EXPECT_NO_THROW(require_unchanged(mpi::Comm::serial(), scan, "scan.ply", stamp));
  std::filesystem::last_write_time(scan, std::filesystem::last_write_time(scan) + std::chrono::seconds(3));
  const std::string message =
      test::message_of<InvalidInput>([&] { require_unchanged(mpi::Comm::serial(), scan, "scan.ply", stamp); });
  EXPECT_NE(message.find("scan.ply: changed while it was read"), std::string::npos) << message;
  std::filesystem::remove(scan);
  EXPECT_THROW(require_unchanged(mpi::Comm::serial(), scan, "scan.ply", stamp), InvalidInput);
}

TEST_F(BatchBricksTest, BrickTasksGiveWhatAWholeConversionGives) {
  const BatchOptions o = options("b.h5");
  EXPECT_TRUE(converts_by_brick_tasks(dir_ / "in/a/scan.ply", o.method));
  EXPECT_FALSE(converts_by_brick_tasks(dir_ / "in/b/scan.ply", o.method));  // ASCII: not readable in pieces
  MethodOptions one_brick = o.method;
  one_brick.proxy_bricks = 1;
  EXPECT_FALSE(converts_by_brick_tasks(dir_ / "in/a/scan.ply", one_brick));
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::Done);
  expect_items_equal(o);
  EXPECT_FALSE(fs::exists(o.output + ".work"));
}

TEST_F(BatchBricksTest, AResumedRunKeepsThePlanAndPiecesItJournaled) {
  BatchOptions o = options("r.h5");
  // The plan and two pieces, then a stop.
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o, stop_after_bricks(o, 3)).status, BatchStatus::Stopped);
  const std::vector<std::string> first = brick_records(o);
  ASSERT_EQ(first.size(), 3u);
  EXPECT_EQ(first[0], "plan");
  EXPECT_TRUE(fs::exists(o.output + ".work/bricks/gim_65/0/plan.bin"));
  // A resumed run that stops after one more brick task: nothing journaled before is made again.
  o.resume = true;
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o, stop_after_bricks(o, 4)).status, BatchStatus::Stopped);
  const std::vector<std::string> second = brick_records(o);
  ASSERT_EQ(second.size(), 4u);
  EXPECT_EQ(std::set<std::string>(second.begin(), second.end()).size(), 4u) << "a part was made twice";
  // A damaged piece is made again, the rest kept.
  {
    std::ofstream damage(o.output + ".work/bricks/gim_65/0/" + second[1] + ".bin", std::ios::trunc);
    damage << "not a piece";
  }
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::Done);
  expect_items_equal(o);
}

TEST_F(BatchBricksTest, ASourceRewrittenSinceItsPlanIsPlannedAgain) {
  BatchOptions o = options("s.h5");
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o, stop_after_bricks(o, 3)).status, BatchStatus::Stopped);
  // The scan changes under its plan and two pieces (the job's identity names paths, not contents).
  const fs::path source = dir_ / "in/a/scan.ply";
  io::write_ply(source, scan(0.02), {.binary = true, .double_precision = true});
  EXPECT_NE(test::message_of<StaleBricks>([&] { (void)read_brick_plan(o.output + ".work/bricks/gim_65/0", source); })
                .find(kStaleBricks),
            std::string::npos);
  o.resume = true;
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::Done);
  // Item 0 is the new scan's conversion, as `convert` makes it.
  expect_item_0_is_convert_of(o, source, {"psnr", "proxy_psnr", "proxy_faces"});
}

// The scan rewritten in the middle of a run (after its plan and a piece): the next task finds the plan stale,
// the item is planned again at once without losing an attempt (--max-retries 0), and the archive holds the
// new scan's conversion.
TEST_F(BatchBricksTest, ASourceRewrittenDuringARunIsPlannedAgainAtOnce) {
  BatchOptions o = options("d.h5");
  const fs::path source = dir_ / "in/a/scan.ply";
  bool rewritten = false;
  const auto rewrite = [&] {
    if (!rewritten && fs::exists(o.output + ".work/journal.jsonl") && brick_records(o).size() >= 2) {
      io::write_ply(source, scan(0.02), {.binary = true, .double_precision = true});
      rewritten = true;
    }
    return false;
  };
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o, rewrite).status, BatchStatus::Done);
  EXPECT_TRUE(rewritten);
  expect_item_0_is_convert_of(o, source, {"psnr"});
}

// The work files are read as untrusted: a flipped byte, a directory or a link in their place is "plan again",
// never a crash, a huge allocation or a read elsewhere.
TEST_F(BatchBricksTest, DamagedOrForeignWorkFilesArePlannedAgain) {
  BatchOptions o = options("w.h5");
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o, stop_after_bricks(o, 3)).status, BatchStatus::Stopped);
  const fs::path dir = o.output + ".work/bricks/gim_65/0", source = dir_ / "in/a/scan.ply";
  const BrickPlanSummary plan = read_brick_plan(dir, source);
  {  // one byte of the plan flipped
    std::fstream f(dir / "plan.bin", std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(100);
    char c = 0;
    f.read(&c, 1);
    f.seekp(100);
    c = static_cast<char>(c ^ 1);
    f.write(&c, 1);
  }
  EXPECT_NE(test::message_of<StaleBricks>([&] { (void)read_brick_plan(dir, source); }).find("checksum"), std::string::npos);
  // A directory and a link where pieces should be.
  std::vector<std::size_t> made;
  for (std::size_t b = 0; b < plan.brick_faces.size(); ++b)
    if (fs::exists(dir / (std::to_string(b) + ".bin"))) made.push_back(b);
  ASSERT_EQ(made.size(), 2u);
  fs::remove(dir / (std::to_string(made[0]) + ".bin"));
  fs::create_directory(dir / (std::to_string(made[0]) + ".bin"));
  fs::remove(dir / (std::to_string(made[1]) + ".bin"));
  fs::create_symlink(source, dir / (std::to_string(made[1]) + ".bin"));
  EXPECT_THROW(check_brick_piece(dir, made[0], plan), StaleBricks);
  EXPECT_THROW(check_brick_piece(dir, made[1], plan), StaleBricks);
  fs::remove_all(dir / (std::to_string(made[0]) + ".bin"));
  o.resume = true;
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::Done);
  expect_items_equal(o);
}

// A link to a folder outside, standing for the item's brick folder, is removed (not followed): nothing
// outside is read, written or deleted; a folder standing for the plan goes too, without costing an attempt.
TEST_F(BatchBricksTest, LinksOutOfTheWorkDirectoryAreNeverFollowed) {
  BatchOptions o = options("l.h5");
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o, stop_after_bricks(o, 3)).status, BatchStatus::Stopped);
  const fs::path bricks = o.output + ".work/bricks/gim_65", outside = dir_ / "outside";
  fs::rename(bricks / "0", outside);
  { std::ofstream(outside / "precious.txt") << "keep me"; }
  fs::create_directory_symlink(outside, bricks / "0");
  std::set<fs::path> before;
  for (const auto& e : fs::directory_iterator(outside)) before.insert(e.path());
  o.resume = true;
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o, stop_after_bricks(o, 5)).status, BatchStatus::Stopped);
  std::set<fs::path> after;
  for (const auto& e : fs::directory_iterator(outside)) after.insert(e.path());
  EXPECT_EQ(after, before) << "a file outside the work directory was written or removed";
  EXPECT_FALSE(fs::is_symlink(bricks / "0"));
  // A folder where the new plan is.
  fs::remove(bricks / "0/plan.bin");
  fs::create_directory(bricks / "0/plan.bin");
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::Done);
  expect_items_equal(o);
  EXPECT_TRUE(fs::exists(outside / "precious.txt"));
}

TEST(BrickTasks, DuplicateFacesKeepTheFirstCopyInEveryPassCount) {
  const std::string path = (fs::path(::testing::TempDir()) / ("dup_" + std::to_string(::getpid()) + ".ply")).string();
  TriMesh t = make_torus(1.0, 0.4, 12, 8);  // 192 faces
  const std::size_t n = t.faces.size();
  t.faces.push_back({t.faces[5][1], t.faces[5][2], t.faces[5][0]});  // 192: a rotated copy of 5
  t.faces.push_back({t.faces[7][2], t.faces[7][1], t.faces[7][0]});  // 193: a flipped copy of 7
  t.faces.push_back(t.faces[5]);                                     // 194: another copy of 5
  t.faces.push_back({3, 3, 4});                                      // 195: degenerate, not counted
  t.faces.push_back({3, 3, 4});                                      // 196: its copy, not counted either
  io::write_ply(path, t, {.binary = true});
  const std::optional<io::PlyTriangleFile> file = io::PlyTriangleFile::open(path);
  ASSERT_TRUE(file.has_value());
  const std::vector<std::uint64_t> expected{n, n + 1, n + 2};
  for (const std::size_t per_pass : {std::size_t{1} << 20, std::size_t{50}, std::size_t{7}, std::size_t{1}})
    EXPECT_EQ(find_duplicate_faces(*file, per_pass), expected) << per_pass;
  fs::remove(path);
}

}  // namespace
}  // namespace gimforge::jobs
