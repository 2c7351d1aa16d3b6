// End-to-end tests of `gimforge batch` (issue #5): a collection with good and bad meshes, alone and under
// mpirun with 2 and 4 ranks (bit-identical data), kills at random moments followed by --resume, and
// SIGTERM (exit 4, resumable).
#include <gtest/gtest.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <hdf5.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "io/archive.h"
#include "io/batch_archive.h"
#include "io/hdf5.h"
#include "io/mesh_io.h"
#include "kernels/core/procedural.h"
#include "tests/cli/run_process.h"

namespace fs = std::filesystem;
using gimforge::test::run_gimforge;
using gimforge::test::run_process;

namespace {

const std::string kData = GIMFORGE_TEST_DATA_DIR;

class BatchTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "gimforge-batch-XXXXXX").string();
    root_ = mkdtemp(pattern.data());
    // Two classes of good meshes, and two bad ones.
    fs::create_directories(root_ / "meshes/round");
    fs::create_directories(root_ / "meshes/boxy");
    fs::create_directories(root_ / "meshes/bad");
    fs::copy_file(kData + "/fist.ply", root_ / "meshes/round/fist.ply");
    fs::copy_file(kData + "/kitten.ply", root_ / "meshes/round/kitten.ply");
    fs::copy_file(kData + "/cathead.ply", root_ / "meshes/boxy/cathead.ply");
    fs::copy_file(kData + "/cube.off", root_ / "meshes/boxy/cube.off");
    std::ofstream(root_ / "meshes/bad/corrupt.ply") << "ply\nformat binary_little_endian 1.0\nelement vertex 100\n";
    // Three triangles on one edge: not a 2-manifold.
    std::ofstream(root_ / "meshes/bad/fan.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\n"
                                                   "f 1 2 3\nf 2 1 4\nf 1 2 5\n";
  }
  void TearDown() override { fs::remove_all(root_); }

  [[nodiscard]] std::string path(const std::string& rel) const { return (root_ / rel).string(); }
  [[nodiscard]] std::vector<std::string> batch_args(const std::string& archive) const {
    return {"batch", "--input", path("meshes"), "--method", "gim", "--size", "65", "--metric-samples", "20000",
            "--max-retries", "0", "-o", archive};
  }

  fs::path root_;
};

/// Shell lines that stop (SIGSTOP) rank 2 of the mpirun job whose ranks carry the environment entry "$5" (a
/// tag of the test's own: other tests run batches beside it) and say "stopped" on stderr.
constexpr const char* kStopTaggedRank2 =
    "for d in /proc/[0-9]*; do\n"
    "  e=$(tr '\\0' '\\n' < $d/environ 2>/dev/null)\n"
    "  if echo \"$e\" | grep -qx \"$5\" && echo \"$e\" | grep -qx OMPI_COMM_WORLD_RANK=2; then\n"
    "    kill -STOP ${d#/proc/} && echo stopped >&2 && break; fi\n"
    "done\n";

/// Open MPI refuses to run as root unless told it may (CI containers run as root).
void allow_mpirun_as_root() {
  if (geteuid() != 0) return;
  setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
  setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
}

/// Runs Python `code` after `from load_archive import GimforgeDataset` (examples/), `path` as sys.argv[1].
auto run_loader(const std::string& code, const std::string& path) {
  return run_process({GIMFORGE_PYTHON, "-c",
                      "import sys; sys.path.insert(0, sys.argv[1]); from load_archive import GimforgeDataset; "
                      "sys.argv = sys.argv[1:]\n" + code,
                      std::string(GIMFORGE_TESTS_SOURCE_DIR) + "/../examples", path});
}

/// The stacked data of every output, as raw floats, for bit-identity checks.
std::vector<std::vector<float>> data_of(const std::string& archive) {
  std::vector<std::vector<float>> out;
  const gimforge::io::Archive a = gimforge::io::Archive::open(archive);
  for (const auto& s : gimforge::io::read_batch_summary(archive))
    out.push_back(a.root().open_group("batch/" + s.output).open_dataset("data").read<float>());
  return out;
}

TEST_F(BatchTest, SerialRunListsBadItemsAndStoresTheRest) {
  fs::create_symlink(path("nowhere.ply"), path("meshes/round/gone.ply"));  // dangling: said, then skipped
  const auto r = run_gimforge(batch_args(path("out.h5")), 300);
  EXPECT_EQ(r.exit_code, 3) << r.err;  // some items failed
  EXPECT_NE(r.err.find("gone.ply: skipped: not a regular file"), std::string::npos) << r.err;
  const auto summary = gimforge::io::read_batch_summary(path("out.h5"));
  ASSERT_EQ(summary.size(), 1u);
  const auto& s = summary.front();
  EXPECT_EQ(s.output, "gim_65");
  EXPECT_EQ(s.count, 4u);
  EXPECT_EQ(s.item_shape, (gimforge::h5::Dims{3, 65, 65}));
  EXPECT_EQ(s.names, (std::vector<std::string>{"boxy/cathead", "boxy/cube", "round/fist", "round/kitten"}));
  EXPECT_EQ(s.label_names, (std::vector<std::string>{"boxy", "round"}));
  EXPECT_EQ(s.failed_names, (std::vector<std::string>{"bad/corrupt", "bad/fan"}));
  // The reasons name the file and the cause.
  const gimforge::io::Archive a = gimforge::io::Archive::open(path("out.h5"));
  const auto reasons = a.root().open_group("batch/gim_65/failed").open_dataset("reasons").read_strings();
  ASSERT_EQ(reasons.size(), 2u);
  EXPECT_NE(reasons[0].find("corrupt.ply"), std::string::npos) << reasons[0];
  EXPECT_NE(reasons[1].find("fan.obj"), std::string::npos) << reasons[1];
  EXPECT_NE(reasons[1].find("manifold"), std::string::npos) << reasons[1];
  EXPECT_FALSE(fs::exists(path("out.h5.work")));  // the work directory is gone once the archive is complete
  // A second run refuses to overwrite the archive.
  EXPECT_EQ(run_gimforge(batch_args(path("out.h5"))).exit_code, 1);
  // --resume on a finished archive (e.g. a requeued job) does nothing, and exits as the run did: 3, since
  // items failed.
  auto resume = batch_args(path("out.h5"));
  resume.push_back("--resume");
  const auto again = run_gimforge(resume);
  EXPECT_EQ(again.exit_code, 3) << again.err;
  EXPECT_NE(again.out.find("already complete"), std::string::npos) << again.out;
  EXPECT_EQ(gimforge::io::read_batch_summary(path("out.h5")).front().count, 4u);
  // Killed after the archive was renamed into place but before the work directory was removed: --resume
  // finds this job's finished archive and removes what is left of the work directory.
  fs::create_directories(path("out.h5.work/shards/gim_65"));
  std::ofstream(path("out.h5.work/journal.jsonl")) << "{}\n";
  const auto leftover = run_gimforge(resume);
  EXPECT_EQ(leftover.exit_code, 3) << leftover.err;
  EXPECT_NE(leftover.out.find("already complete"), std::string::npos) << leftover.out;
  EXPECT_FALSE(fs::exists(path("out.h5.work")));
  // Another job's archive at the output is no finished run of this one: refused, and nothing removed.
  fs::create_directories(path("out.h5.work"));
  auto other = resume;
  other[std::size_t(std::find(other.begin(), other.end(), "65") - other.begin())] = "129";
  const auto refused = run_gimforge(other);
  EXPECT_EQ(refused.exit_code, 1) << refused.err;
  EXPECT_NE(refused.err.find("is not this job's archive"), std::string::npos) << refused.err;
  EXPECT_TRUE(fs::exists(path("out.h5.work")));
  // While a batch into the archive is interrupted (its journal in out.h5.work), convert does not write to
  // it: the batch's --resume would no longer recognise its archive and would strand every committed item.
  std::ofstream(path("out.h5.work/journal.jsonl")) << "{}\n";
  const std::vector<std::string> convert{"convert", path("meshes/round/fist.ply"), "--size", "65", "--no-metric",
                                         "--name", "extra", "-o", path("out.h5")};
  const auto blocked = run_gimforge(convert);
  EXPECT_EQ(blocked.exit_code, 1) << blocked.err;
  EXPECT_NE(blocked.err.find("a batch into this archive has not finished"), std::string::npos) << blocked.err;
  fs::remove_all(path("out.h5.work"));
  // A finished batch archive that convert extends stays this job's: --resume still finds it complete.
  ASSERT_EQ(run_gimforge(convert).exit_code, 0);
  const auto extended = run_gimforge(resume);
  EXPECT_EQ(extended.exit_code, 3) << extended.err;
  EXPECT_NE(extended.out.find("already complete"), std::string::npos) << extended.out;
}

TEST_F(BatchTest, ReliefAndSphereArchivesLoadWithTheExampleLoader) {
  const std::string loader = std::string(GIMFORGE_TESTS_SOURCE_DIR) + "/../examples/load_archive.py";
  // Relief maps take any mesh (the non-manifold fan too); only the corrupt file fails.
  auto r = run_gimforge({"batch", "--input", path("meshes"), "--method", "relief", "--grid", "4", "--texture", "8",
                         "--metric-samples", "5000", "--max-retries", "0", "-o", path("relief.h5")},
                        300);
  EXPECT_EQ(r.exit_code, 3) << r.err;
  auto summary = gimforge::io::read_batch_summary(path("relief.h5"));
  ASSERT_EQ(summary.size(), 1u);
  EXPECT_EQ(summary[0].output, "relief_4_8");
  EXPECT_TRUE(summary[0].groups);
  EXPECT_EQ(summary[0].count, 5u);
  auto py = run_process({GIMFORGE_PYTHON, loader, path("relief.h5")});
  ASSERT_EQ(py.exit_code, 0) << py.err;
  EXPECT_NE(py.out.find("items: 5  one group each (items/<k>"), std::string::npos) << py.out;
  EXPECT_NE(py.out.find("first item: bad/fan label 0 relief map N = 4"), std::string::npos) << py.out;
  // The Dataset class returns each item's maps.
  py = run_loader("ds = GimforgeDataset(sys.argv[1]); item = ds[4]; "
                  "assert item['name'] == 'round/kitten', item['name']; "
                  "d = item['relief']['distances']; assert d.dtype.name == 'uint16' and d.shape[1:] == (8, 8), d.shape; "
                  "assert item['attrs']['method'] == 'relief' and item['attrs']['psnr'] > 20",
                  path("relief.h5"));
  EXPECT_EQ(py.exit_code, 0) << py.err;

  r = run_gimforge({"batch", "--input", path("meshes"), "--method", "sphere", "--n", "8", "--metric-samples", "5000",
                    "--max-retries", "0", "-o", path("sphere.h5")},
                   300);
  EXPECT_EQ(r.exit_code, 3) << r.err;  // the corrupt file, the fan and the genus-1 kitten fail
  py = run_process({GIMFORGE_PYTHON, loader, path("sphere.h5")});
  ASSERT_EQ(py.exit_code, 0) << py.err;
  EXPECT_NE(py.out.find("items: 3  shape (C, H, W): 3x17x17"), std::string::npos) << py.out;
  EXPECT_NE(py.out.find("map_efficiency="), std::string::npos) << py.out;
}

TEST_F(BatchTest, ItemsReconstructAndPreviewAsConvertsImagesDo) {
  const auto run_ok = [](const std::vector<std::string>& args) {
    const auto r = run_gimforge(args, 300);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return r;
  };
  const auto bytes = [](const std::string& file) {
    std::ifstream in(file, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
  };
  // Each method's batch item reconstructs to the very mesh convert's image of the same mesh gives (the
  // geometry image glued by its sideband, the spherical image with its own connectivity, the relief map).
  const std::vector<std::vector<std::string>> methods{
      {"gim", "--size", "65"}, {"sphere", "--n", "8"}, {"relief", "--grid", "4", "--texture", "8"}};
  const std::vector<std::string> outputs{"gim_65", "sphere_octa_8", "relief_4_8"};
  for (std::size_t m = 0; m < methods.size(); ++m) {
    const std::string archive = path(methods[m][0] + ".h5"), single = path(methods[m][0] + "_convert.h5");
    std::vector<std::string> batch{"batch", "--input", path("meshes/round"), "--no-metric", "--max-retries", "0",
                                   "-o", archive, "--method"};
    batch.insert(batch.end(), methods[m].begin(), methods[m].end());
    (void)run_gimforge(batch, 300);  // the genus-1 kitten fails as a spherical image
    std::vector<std::string> convert{"convert", path("meshes/round/fist.ply"), "--no-metric", "-o", single, "--method"};
    convert.insert(convert.end(), methods[m].begin(), methods[m].end());
    run_ok(convert);
    const auto item = run_ok({"reconstruct", archive, "--name", "batch/" + outputs[m] + "/fist", "-o", path("item.ply")});
    EXPECT_NE(item.out.find("/batch/" + outputs[m] + "/fist level 0 -> "), std::string::npos) << item.out;
    run_ok({"reconstruct", single, "-o", path("single.ply")});
    EXPECT_EQ(bytes(path("item.ply")), bytes(path("single.ply"))) << methods[m][0];
  }
  const auto preview = run_ok({"preview", path("gim.h5"), "--name", "batch/gim_65/fist", "-o", path("pictures")});
  EXPECT_TRUE(fs::exists(path("pictures/gim_65/fist_geometry.png"))) << preview.out;
  // The item's folders are preview's own: a link in their place is refused, nothing is written where it points.
  fs::create_directories(path("linked"));
  fs::create_directories(path("elsewhere"));
  fs::create_directory_symlink(path("elsewhere"), path("linked/gim_65"));
  const auto linked = run_gimforge({"preview", path("gim.h5"), "--name", "batch/gim_65/fist", "-o", path("linked")});
  EXPECT_EQ(linked.exit_code, 1);
  EXPECT_NE(linked.err.find("is a symbolic link where preview writes the item's folder"), std::string::npos) << linked.err;
  EXPECT_TRUE(fs::is_empty(path("elsewhere")));
  // Without --name, an archive of several batch items says how to name one.
  const auto unnamed = run_gimforge({"reconstruct", path("gim.h5"), "-o", path("x.ply")});
  EXPECT_EQ(unnamed.exit_code, 1);
  EXPECT_NE(unnamed.err.find("holds no image but 2 batch items; choose one with --name batch/OUTPUT/ITEM, e.g. "
                             "--name batch/gim_65/fist"),
            std::string::npos)
      << unnamed.err;
  // The example loader gives an item's sideband rows too (what glues the image's cut).
  const auto py = run_loader("ds = GimforgeDataset(sys.argv[1]); rows, units = ds.sideband(0); "
                             "assert units == 64 and rows.ndim == 2 and rows.shape[1] == 3 and len(rows) >= 1, rows\n"
                             "try:\n    ds.sideband(-3)\nexcept IndexError:\n    pass\n"
                             "else:\n    raise SystemExit('sideband(-3) of 2 items gave no IndexError')",
                             path("gim.h5"));
  EXPECT_EQ(py.exit_code, 0) << py.err;
  // A batch archive written before items kept their sideband: the cut cannot be glued; --no-fuse gives the
  // open disk.
  {
    const gimforge::io::Archive a = gimforge::io::Archive::open(path("gim.h5"), gimforge::h5::OpenMode::kReadWrite);
    for (const char* name : {"sideband", "sideband_offsets"})
      ASSERT_GE(H5Ldelete(a.root().open_group("batch/gim_65").id(), name, H5P_DEFAULT), 0);
  }
  const auto unglued = run_gimforge({"reconstruct", path("gim.h5"), "--name", "batch/gim_65/fist", "-o", path("x.ply")});
  EXPECT_EQ(unglued.exit_code, 1);
  EXPECT_NE(unglued.err.find("keeps no sideband for this item"), std::string::npos) << unglued.err;
  run_ok({"reconstruct", path("gim.h5"), "--name", "batch/gim_65/fist", "--no-fuse", "-o", path("x.ply")});
  // render draws a batch's relief map too.
  const auto render = run_ok({"render", path("relief.h5"), "--name", "batch/relief_4_8/fist", "--size", "64", "-o",
                              path("fist.png")});
  EXPECT_NE(render.out.find("/batch/relief_4_8/fist view"), std::string::npos) << render.out;
  // An item name from the archive that would lead the pictures out of -o is refused, and nothing is left.
  {
    const gimforge::io::Archive a = gimforge::io::Archive::open(path("gim.h5"), gimforge::h5::OpenMode::kReadWrite);
    gimforge::h5::Group g = a.root().open_group("batch/gim_65");
    ASSERT_GE(H5Ldelete(g.id(), "names", H5P_DEFAULT), 0);
    (void)g.write_strings("names", std::vector<std::string>{"../../evil", "kitten"});
  }
  const auto evil = run_gimforge({"preview", path("gim.h5"), "--name", "batch/gim_65/../../evil", "-o", path("p2/x")});
  EXPECT_EQ(evil.exit_code, 1);
  EXPECT_NE(evil.err.find("it cannot name a picture file"), std::string::npos) << evil.err;
  EXPECT_FALSE(fs::exists(path("p2")));

  // An item that failed says why; relief groups swapped in the archive are refused, not read as each other.
  const auto failed = run_gimforge({"reconstruct", path("sphere.h5"), "--name", "batch/sphere_octa_8/kitten", "-o", path("x.ply")});
  EXPECT_EQ(failed.exit_code, 1);
  EXPECT_NE(failed.err.find("item 'kitten' of batch output 'sphere_octa_8' was not converted: "), std::string::npos)
      << failed.err;
  EXPECT_NE(failed.err.find("genus 1"), std::string::npos) << failed.err;
  {
    const gimforge::io::Archive a = gimforge::io::Archive::open(path("relief.h5"), gimforge::h5::OpenMode::kReadWrite);
    const gimforge::h5::Group group = a.root().open_group("batch/relief_4_8/items");
    const auto items = group.id();
    ASSERT_GE(H5Lmove(items, "0", items, "swap", H5P_DEFAULT, H5P_DEFAULT), 0);
    ASSERT_GE(H5Lmove(items, "1", items, "0", H5P_DEFAULT, H5P_DEFAULT), 0);
    ASSERT_GE(H5Lmove(items, "swap", items, "1", H5P_DEFAULT, H5P_DEFAULT), 0);
  }
  const auto swapped = run_gimforge({"reconstruct", path("relief.h5"), "--name", "batch/relief_4_8/fist", "-o", path("x.ply")});
  EXPECT_EQ(swapped.exit_code, 1);
  EXPECT_NE(swapped.err.find("holds the item converted from"), std::string::npos) << swapped.err;
}

TEST_F(BatchTest, AStoppedWorkerIsGivenUpOnAndTheBatchEndsResumably) {
  // mpirun with a master and two workers; worker rank 2 is stopped (SIGSTOP: hung, or its node gone) while
  // it holds items (24 items of ~0.3 s: it has work for seconds after the first result). Rank 0 gives up on
  // it after --worker-timeout, rank 1 converts the rest, and the job ends with exit 4 (the lost item has an
  // attempt left) instead of waiting for rank 2 forever. The job's ranks carry a tag of their own (other
  // tests run batches under mpirun beside this one); the stop waits for the first result, so rank 2 is past
  // the scheduler's start-up collectives.
  allow_mpirun_as_root();
  fs::create_directories(root_ / "many");
  for (int k = 0; k < 24; ++k) fs::copy_file(kData + "/kitten.ply", root_ / fmt::format("many/k{}.ply", k));
  const std::string tag = "GIMFORGE_TEST_TAG=" + root_.filename().string();
  const std::string script =
      "\"$0\" -n 3 --oversubscribe --bind-to none -x \"$5\" \"$1\" batch --input \"$2\" -o \"$3\" --method gim "
      "--size 65 --metric-samples 20000 --worker-timeout 8 2> \"$4\" & job=$!\n"
      "for i in $(seq 1200); do grep -q ' done, ' \"$4\" && break; sleep 0.05; done\n"
      + std::string(kStopTaggedRank2) +
      "wait $job; code=$?; cat \"$4\" >&2; exit $code\n";
  const auto t0 = std::chrono::steady_clock::now();
  const auto r = run_process({"/bin/sh", "-c", script, GIMFORGE_MPIEXEC, GIMFORGE_EXE, path("many"), path("out.h5"),
                              path("err.txt"), tag}, 240);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_NE(r.err.find("stopped"), std::string::npos) << "rank 2 was not found to stop\n" << r.err;
  EXPECT_EQ(r.exit_code, 4) << r.err;
  EXPECT_LT(seconds, 200.0);
  EXPECT_NE(r.err.find("rank 2 gave no answer for"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("run again with --resume"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("out.h5")));
  // Nothing was lost: the resumed job (every rank well) finishes every item.
  const auto again = run_process({GIMFORGE_MPIEXEC, "-n", "3", "--oversubscribe", "--bind-to", "none", GIMFORGE_EXE,
                                  "batch", "--input", path("many"), "-o", path("out.h5"), "--method", "gim", "--size",
                                  "65", "--metric-samples", "20000", "--worker-timeout", "8", "--resume"}, 240);
  EXPECT_EQ(again.exit_code, 0) << again.err;
  const auto summary = gimforge::io::read_batch_summary(path("out.h5"));
  ASSERT_EQ(summary.size(), 1u);
  EXPECT_EQ(summary.front().count, 24u);
  EXPECT_TRUE(summary.front().failed_names.empty());
}

TEST_F(BatchTest, AWorkerStoppedWhileIdleDoesNotHoldTheJobAtTheEnd) {
  // Rank 2 converts its one small item and is stopped while it has nothing to do; rank 1 still converts the
  // largest. No item is lost, but rank 2 never reaches the barriers between rounds: rank 0 waits there
  // --worker-timeout, merges the complete archive and ends the job (exit 0) instead of waiting forever.
  allow_mpirun_as_root();
  fs::create_directories(root_ / "three");
  fs::copy_file(kData + "/kitten.ply", root_ / "three/kitten.ply");
  fs::copy_file(kData + "/fist.ply", root_ / "three/fist.ply");
  fs::copy_file(kData + "/cathead.ply", root_ / "three/cathead.ply");
  const std::string tag = "GIMFORGE_TEST_TAG=" + root_.filename().string();
  const std::string script =
      "\"$0\" -n 3 --oversubscribe --bind-to none -x \"$5\" \"$1\" batch --input \"$2\" -o \"$3\" --method gim "
      "--size 257 --metric-samples 20000 --worker-timeout 6 --log-dir \"$4\" 2> \"$4.err\" & job=$!\n"
      "for i in $(seq 1200); do grep -q committed \"$4/rank-2.log\" 2>/dev/null && break; sleep 0.05; done\n"
      + std::string(kStopTaggedRank2) +
      "wait $job; code=$?; cat \"$4.err\" >&2; exit $code\n";
  const auto r = run_process({"/bin/sh", "-c", script, GIMFORGE_MPIEXEC, GIMFORGE_EXE, path("three"), path("out.h5"),
                              path("logs"), tag}, 240);
  ASSERT_NE(r.err.find("stopped"), std::string::npos) << "rank 2 was not found to stop\n" << r.err;
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("did not reach the barrier between rounds"), std::string::npos) << r.err;
  const auto summary = gimforge::io::read_batch_summary(path("out.h5"));
  ASSERT_EQ(summary.size(), 1u);
  EXPECT_EQ(summary.front().count, 3u);
  EXPECT_FALSE(fs::exists(path("out.h5.work")));
}

TEST_F(BatchTest, ResumeAfterKillsAtRandomMomentsGivesTheUninterruptedArchive) {
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_EQ(run_gimforge(batch_args(path("ref.h5")), 300).exit_code, 3);
  const double duration = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto reference = data_of(path("ref.h5"));
  std::mt19937 rng(12345);
  // Kill moments are drawn from [0, horizon): the reference run's duration at first, shortened to 90% of
  // any trial that finished before its kill (runs under mpirun with two workers, or on a machine whose
  // load dropped after the reference run, can be much faster), so that most kills land inside a run.
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  double horizon = duration;
  int killed = 0;
  allow_mpirun_as_root();
  // 4 trials (2 serial, 2 under mpirun) prove the property, each checking it completely; --full runs 10.
  const int count = gimforge::test::trials(4, 10);
  for (int trial = 0; trial < count; ++trial) {
    fs::remove_all(path("out.h5.work"));
    fs::remove(path("out.h5"));
    // Odd trials run under mpirun with a master and two workers; the kill takes mpirun and every rank.
    std::vector<std::string> args;
    if (trial % 2 == 1) args = {GIMFORGE_MPIEXEC, "-n", "3", "--oversubscribe", "--bind-to", "none"};
    args.push_back(GIMFORGE_EXE);
    for (const std::string& a : batch_args(path("out.h5"))) args.push_back(a);
    const double when = unit(rng) * horizon;
    const auto started = std::chrono::steady_clock::now();
    const auto first = run_process(args, when);  // SIGKILL to the whole job at a random moment of the run
    if (first.exit_code == 128 + SIGKILL) {
      ++killed;
    } else {
      const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
      horizon = std::min(horizon, 0.9 * took);
    }
    // Killed before the archive was renamed into place, or after it but before the work directory was
    // removed: resume.
    if (!fs::exists(path("out.h5")) || fs::exists(path("out.h5.work"))) {
      args.push_back("--resume");
      const auto resumed = run_process(args, 300);
      ASSERT_EQ(resumed.exit_code, 3) << "trial " << trial << " (killed at " << when << " s): " << resumed.err;
    }
    const auto summary = gimforge::io::read_batch_summary(path("out.h5"));
    ASSERT_EQ(summary.size(), 1u);
    EXPECT_EQ(summary.front().count, 4u) << "trial " << trial;  // every item exactly once
    EXPECT_EQ(summary.front().failed_names.size(), 2u) << "trial " << trial;
    EXPECT_EQ(data_of(path("out.h5")), reference) << "trial " << trial;
    EXPECT_FALSE(fs::exists(path("out.h5.work"))) << "trial " << trial;
    // h5py reads it: 4 items of (3, 65, 65), names in index order.
    const auto py = run_process({GIMFORGE_PYTHON, "-c",
                                 "import sys, h5py; g = h5py.File(sys.argv[1], 'r')['batch/gim_65']; "
                                 "assert g['data'].shape == (4, 3, 65, 65), g['data'].shape; "
                                 "assert [n.decode() for n in g['names'][...]] == "
                                 "['boxy/cathead', 'boxy/cube', 'round/fist', 'round/kitten']",
                                 path("out.h5")});
    EXPECT_EQ(py.exit_code, 0) << "trial " << trial << ": " << py.err;
  }
  EXPECT_GE(killed, count / 2);  // most kills land inside the run
}

/// `args` as one shell word list (single-quoted).
std::string shell_words(const std::vector<std::string>& args) {
  std::string out;
  for (const std::string& a : args) out += " '" + a + "'";
  return out;
}

TEST_F(BatchTest, SigtermStopsResumablyAndResumeFinishes) {
  std::vector<std::string> args = batch_args(path("out.h5"));
  args.insert(args.begin(), GIMFORGE_EXE);
  // SIGTERM 0.1 s after the journal appeared (the run takes seconds): exit 4, work kept for --resume.
  const std::string journal = path("out.h5.work/journal.jsonl");
  const std::string script = shell_words(args) + " & pid=$!; while [ ! -s '" + journal +
                             "' ]; do sleep 0.02; done; sleep 0.1; kill -TERM $pid; wait $pid; exit $?";
  const auto r = run_process({"/bin/sh", "-c", script}, 300);
  ASSERT_EQ(r.exit_code, 4) << r.err;
  EXPECT_NE(r.err.find("--resume"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::exists(path("out.h5.work/journal.jsonl")));
  EXPECT_FALSE(fs::exists(path("out.h5")));
  args.push_back("--resume");
  args.erase(args.begin());
  const auto resumed = run_gimforge(args, 300);
  EXPECT_EQ(resumed.exit_code, 3) << resumed.err;
  EXPECT_EQ(gimforge::io::read_batch_summary(path("out.h5")).front().count, 4u);
}

// Shards are files on disk: on --resume they are read in child processes before the run (probe_shards),
// and one that crashes HDF5 (SIGSEGV in 1.10.8's decoders) or makes it loop is redone instead of taking the
// batch down or hanging it. Without the probe the resume dies of SIGSEGV on the first one.
TEST_F(BatchTest, ResumeRedoesShardsThatCrashOrHangHdf5) {
  std::vector<std::string> args = batch_args(path("out.h5"));
  const auto clean = run_gimforge(batch_args(path("clean.h5")), 300);
  ASSERT_EQ(clean.exit_code, 3) << clean.err;
  args.insert(args.begin(), GIMFORGE_EXE);
  // SIGTERM once the journal records a committed item.
  const std::string journal = path("out.h5.work/journal.jsonl");
  const std::string script = shell_words(args) + " & pid=$!; while ! grep -q '\"done\"' '" + journal +
                             "' 2>/dev/null; do sleep 0.02; done; kill -TERM $pid; wait $pid; exit $?";
  const auto stopped = run_process({"/bin/sh", "-c", script}, 300);
  ASSERT_EQ(stopped.exit_code, 4) << stopped.err;
  std::vector<fs::path> shards;
  for (const auto& f : fs::recursive_directory_iterator(path("out.h5.work/shards")))
    if (f.path().extension() == ".h5") shards.push_back(f.path());
  ASSERT_FALSE(shards.empty());
  const fs::path crashes = fs::path(GIMFORGE_TESTS_SOURCE_DIR) / "fuzz/crashes/batch_shard";
  fs::copy_file(crashes / "crash-2ee0eedb009a4b0e241505fe85fa86b7874d6760", shards[0],
                fs::copy_options::overwrite_existing);
  if (shards.size() > 1)
    fs::copy_file(crashes / "timeout-2ce20ee58256106f409ac40d1a6ff51a6f09270a", shards[1],
                  fs::copy_options::overwrite_existing);
  args.erase(args.begin());
  args.push_back("--resume");
  ASSERT_EQ(setenv("GIMFORGE_HDF5_CALL_SECONDS", "1", 1), 0);
  const auto resumed = run_gimforge(args, 300);
  unsetenv("GIMFORGE_HDF5_CALL_SECONDS");
  EXPECT_EQ(resumed.exit_code, 3) << resumed.err;
  EXPECT_NE(resumed.err.find("redoing"), std::string::npos) << resumed.err;
  EXPECT_NE(resumed.err.find("the HDF5 library crashed reading the archive"), std::string::npos) << resumed.err;
  if (shards.size() > 1) {
    EXPECT_NE(resumed.err.find("did not return within 1 s"), std::string::npos) << resumed.err;
  }
  EXPECT_EQ(gimforge::io::read_batch_summary(path("out.h5")).front().count, 4u);
  EXPECT_EQ(data_of(path("out.h5")), data_of(path("clean.h5")));
}

TEST_F(BatchTest, DataAreBitIdenticalForOneTwoAndFourRanks) {
  allow_mpirun_as_root();
  ASSERT_EQ(run_gimforge(batch_args(path("one.h5")), 300).exit_code, 3);
  const auto reference = data_of(path("one.h5"));
  for (const char* ranks : {"2", "4"}) {
    const std::string archive = path(std::string("ranks") + ranks + ".h5");
    std::vector<std::string> args{GIMFORGE_MPIEXEC, "-n", ranks, "--oversubscribe", "--bind-to", "none", GIMFORGE_EXE};
    for (const std::string& a : batch_args(archive)) args.push_back(a);
    const auto r = run_process(args, 300);
    ASSERT_EQ(r.exit_code, 3) << ranks << " ranks: " << r.err;
    const auto summary = gimforge::io::read_batch_summary(archive);
    EXPECT_EQ(summary.front().count, 4u);
    EXPECT_EQ(summary.front().failed_names.size(), 2u);
    EXPECT_EQ(data_of(archive), reference) << ranks << " ranks";
  }
}

TEST_F(BatchTest, ItemTimeoutFailsTheItemWithItsReasonAndRetries) {
  const auto r = run_gimforge({"batch", "--input", path("meshes/round"), "--method", "gim", "--size", "65",
                               "--item-timeout", "0.000001", "--max-retries", "1", "-o", path("t.h5")}, 300);
  ASSERT_EQ(r.exit_code, 3) << r.err;
  const auto summary = gimforge::io::read_batch_summary(path("t.h5"));
  EXPECT_EQ(summary.front().count, 0u);
  ASSERT_EQ(summary.front().failed_names.size(), 2u);
  const gimforge::io::Archive a = gimforge::io::Archive::open(path("t.h5"));
  const auto failed = a.root().open_group("batch/gim_65/failed");
  for (const std::string& reason : failed.open_dataset("reasons").read_strings())
    EXPECT_NE(reason.find("timed out"), std::string::npos) << reason;
  for (const std::int32_t attempts : failed.open_dataset("attempts").read<std::int32_t>()) EXPECT_EQ(attempts, 2);
}

TEST_F(BatchTest, JobFileWithTwoOutputs) {
  std::ofstream(path("job.toml")) << "metric_samples = 10000\n"
                                     "[[collection]]\ninput = \"meshes/round\"\nlabel = \"round\"\n"
                                     "[[output]]\nmethod = \"gim\"\nsize = 65\n"
                                     "[[output]]\nmethod = \"sphere\"\ndomain = \"octa\"\nn = 8\n";
  const auto r = run_gimforge({"batch", "--job", path("job.toml"), "-o", path("job.h5")}, 300);
  ASSERT_EQ(r.exit_code, 3) << r.err;  // the kitten (genus 1) has no spherical image
  const auto summary = gimforge::io::read_batch_summary(path("job.h5"));
  ASSERT_EQ(summary.size(), 2u);
  EXPECT_EQ(summary[0].output, "gim_65");
  EXPECT_EQ(summary[0].count, 2u);
  EXPECT_EQ(summary[1].output, "sphere_octa_8");
  EXPECT_EQ(summary[1].count, 1u);
  EXPECT_EQ(summary[1].item_shape, (gimforge::h5::Dims{3, 17, 17}));
  EXPECT_EQ(summary[1].failed_names, (std::vector<std::string>{"kitten"}));
  EXPECT_EQ(summary[1].label_names, (std::vector<std::string>{"round"}));
  // A bad job file names the file and line.
  std::ofstream(path("bad.toml")) << "[[collection]]\ninput = 3\n";
  const auto bad = run_gimforge({"batch", "--job", path("bad.toml"), "-o", path("bad.h5")});
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("bad.toml:2"), std::string::npos) << bad.err;
}

}  // namespace

TEST_F(BatchTest, RetriesAreNoFailuresAndParseErrorsAreNotRetried) {
  // Relief maps take every mesh of the fixture but the corrupt file, which cannot parse: it fails once,
  // with --max-retries 2 left unused, and counts as one failure (not one per attempt).
  const std::vector<std::string> args{"batch", "--input", path("meshes"), "--method", "relief", "--grid", "2",
                                      "--texture", "8", "--no-metric", "--max-retries", "2", "-o", path("r.h5")};
  const auto r = run_gimforge(args, 300);
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("gimforge batch: 5/6 done, 1 failed"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("attempt 2 failed"), std::string::npos) << r.err;
  const auto summary = gimforge::io::read_batch_summary(path("r.h5"));
  ASSERT_EQ(summary.size(), 1u);
  EXPECT_EQ(summary.front().failed_names, std::vector<std::string>{"bad/corrupt"});
  const gimforge::io::Archive a = gimforge::io::Archive::open(path("r.h5"));
  const auto failed = a.root().open_group("batch/" + summary.front().output + "/failed");
  EXPECT_EQ(failed.open_dataset("attempts").read<std::int32_t>(), std::vector<std::int32_t>{1});
  const auto reasons = failed.open_dataset("reasons").read_strings();
  ASSERT_EQ(reasons.size(), 1u);
  EXPECT_NE(reasons[0].find("not retried"), std::string::npos) << reasons[0];
  // Its --resume exits 3 as well.
  auto resume = args;
  resume.push_back("--resume");
  EXPECT_EQ(run_gimforge(resume).exit_code, 3);
}

TEST_F(BatchTest, MetricsUnderMpirunPrintOnceTheSameResult) {
  // `mpirun -n N gimforge metrics A B --json`: one JSON document, the one a single process prints, and a
  // missing input is one error line and exit 1 on every rank count.
  allow_mpirun_as_root();
  const std::string a = path("ball.ply"), b = path("torus.ply");
  gimforge::io::write_ply(a, gimforge::make_icosphere(1.0, 4));
  gimforge::io::write_ply(b, gimforge::make_torus(1.0, 0.45, 48, 24));
  const auto one = run_gimforge({"metrics", a, b, "--samples", "30000", "--json"});
  ASSERT_EQ(one.exit_code, 0) << one.err;
  for (const char* ranks : {"2", "3"}) {
    const auto r = run_process({GIMFORGE_MPIEXEC, "-n", ranks, "--oversubscribe", "--bind-to", "none", GIMFORGE_EXE,
                                "metrics", a, b, "--samples", "30000", "--json"});
    ASSERT_EQ(r.exit_code, 0) << ranks << " ranks: " << r.err;
    EXPECT_EQ(r.out, one.out) << ranks << " ranks";
  }
  // Binary PLY pairs go by bricks (jobs/brick_metrics.h); an OBJ takes the whole-mesh path: the same JSON.
  const std::string obj = path("torus.obj");
  gimforge::io::write_mesh(obj, gimforge::make_torus(1.0, 0.45, 48, 24));
  const auto one_obj = run_gimforge({"metrics", a, obj, "--samples", "30000", "--json"});
  const auto two_obj = run_process({GIMFORGE_MPIEXEC, "-n", "2", "--oversubscribe", "--bind-to", "none",
                                    GIMFORGE_EXE, "metrics", a, obj, "--samples", "30000", "--json"});
  EXPECT_EQ(two_obj.exit_code, 0) << two_obj.err;
  EXPECT_EQ(two_obj.out, one_obj.out);
  // A degenerate face: dropped by both paths, and said once (by rank 0) as a whole load says it.
  gimforge::TriMesh with_degenerate = gimforge::make_icosphere(1.0, 4);
  with_degenerate.faces.push_back({3, 3, 4});
  const std::string dirty = path("dirty.ply");
  gimforge::io::write_ply(dirty, with_degenerate);
  const auto one_dirty = run_gimforge({"metrics", dirty, b, "--samples", "30000", "--json"});
  const auto two_dirty = run_process({GIMFORGE_MPIEXEC, "-n", "2", "--oversubscribe", "--bind-to", "none",
                                      GIMFORGE_EXE, "metrics", dirty, b, "--samples", "30000", "--json"});
  EXPECT_EQ(two_dirty.exit_code, 0) << two_dirty.err;
  EXPECT_EQ(two_dirty.out, one_dirty.out);
  for (const auto* r : {&one_dirty, &two_dirty}) {
    const std::string warning = "dirty.ply: repaired: removed 1 degenerate face(s)";
    const std::size_t at = r->err.find(warning);
    EXPECT_NE(at, std::string::npos) << r->err;
    EXPECT_EQ(r->err.find(warning, at + 1), std::string::npos) << r->err;
  }
  // A missing file, a truncated PLY, a usage error, samples beyond the memory: one error line, any rank count.
  fs::copy_file(b, path("cut.ply"));
  fs::resize_file(path("cut.ply"), fs::file_size(b) - 5);
  for (const std::string& wrong : {path("missing.ply"), path("cut.ply"), std::string("abc"), std::string("134217728")}) {
    const bool usage = wrong == "abc", samples = usage || wrong == "134217728";
    const auto bad = run_process({"/bin/sh", "-c", "ulimit -v 3000000; exec \"$@\"", "sh", GIMFORGE_MPIEXEC, "-n", "2",
                                  "--oversubscribe", "--bind-to", "none", GIMFORGE_EXE, "metrics", a, samples ? b : wrong,
                                  "--samples", samples ? wrong : "1000"});
    EXPECT_EQ(bad.exit_code, usage ? 2 : 1) << bad.err;
    const std::size_t first = bad.err.find("gimforge: error:");  // and no second
    EXPECT_TRUE(first != std::string::npos && bad.err.find("gimforge: error:", first + 1) == std::string::npos) << bad.err;
    EXPECT_NE(bad.err.find(wrong), std::string::npos) << bad.err;
  }
}

TEST_F(BatchTest, ConvertUnderMpirunWritesOneArchive) {
  // `mpirun -n 2 gimforge convert SCAN.ply` through a proxy goes by bricks (jobs/brick_convert.h): one
  // archive, one JSON document, the single process's figures; an OBJ is converted by rank 0 alone.
  allow_mpirun_as_root();
  const std::string scan = path("torus.ply"), obj = path("torus.obj");
  gimforge::io::write_ply(scan, gimforge::make_torus(1.0, 0.4, 120, 60));
  gimforge::io::write_mesh(obj, gimforge::make_torus(1.0, 0.4, 120, 60));
  const std::vector<std::string> args{"convert", scan, "--method", "gim", "--size", "65", "--proxy-faces", "1500",
                                      "--metric-samples", "20000", "--json", "-o"};
  auto with = [](std::vector<std::string> v, std::initializer_list<std::string> more) {
    v.insert(v.end(), more.begin(), more.end());
    return v;
  };
  const auto one = run_gimforge(with(args, {path("one.h5")}), 300);
  ASSERT_EQ(one.exit_code, 0) << one.err;
  std::vector<std::string> mpi{GIMFORGE_MPIEXEC, "-n", "2", "--oversubscribe", "--bind-to", "none", GIMFORGE_EXE};
  std::vector<std::string> bricks = mpi;
  bricks.insert(bricks.end(), args.begin(), args.end());
  bricks.push_back(path("two.h5"));
  const auto r = run_process(bricks, 300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json a = nlohmann::json::parse(one.out), b = nlohmann::json::parse(r.out);  // one document
  EXPECT_EQ(b.at("ranks").get<int>(), 2);
  EXPECT_EQ(a.at("proxy_psnr"), b.at("proxy_psnr"));
  EXPECT_NEAR(a.at("psnr").get<double>(), b.at("psnr").get<double>(), 1e-9 * a.at("psnr").get<double>());
  const auto listing = run_gimforge({"ls", path("two.h5")});
  EXPECT_NE(listing.out.find("gim/torus"), std::string::npos) << listing.out;
  std::vector<std::string> whole = mpi;
  for (const char* arg : {"convert", "--method", "gim", "--size", "65", "--metric-samples", "20000", "-o"}) whole.emplace_back(arg);
  whole.push_back(path("obj.h5"));
  whole.push_back(obj);
  const auto w = run_process(whole, 300);
  ASSERT_EQ(w.exit_code, 0) << w.err;
  EXPECT_NE(run_gimforge({"ls", path("obj.h5")}).out.find("gim/torus"), std::string::npos);
}

TEST_F(BatchTest, ConvertByBricksRefusesARegionOfInterestBeforeAnyWork) {
  // Bricks take no ROI: one error line from rank 0 before the scan is read, no archive (it used to come after
  // the decimation, then the ranks' abort).
  allow_mpirun_as_root();
  const std::string scan = path("torus.ply");
  gimforge::io::write_ply(scan, gimforge::make_torus(1.0, 0.4, 120, 60));
  const auto r = run_process({GIMFORGE_MPIEXEC, "-n", "2", "--oversubscribe", "--bind-to", "none", GIMFORGE_EXE, "convert",
                              scan, "--size", "65", "--proxy-faces", "1500", "--sampling", "adaptive", "--roi", "auto", "-o",
                              path("roi.h5")},
                             300);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("gimforge: error: --roi auto: a conversion split in bricks across ranks takes no region of interest"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.err.find("decimat"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("roi.h5")));
}

TEST_F(BatchTest, ReliefConvertUnderMpirunEqualsOneProcess) {
  // `mpirun -n 2 gimforge convert SCAN.ply --method relief` goes by bricks (jobs/brick_relief.h): one archive,
  // one JSON document, the single process's map and figures exactly; the summary says how many ranks.
  allow_mpirun_as_root();
  const std::string scan = path("torus.ply");
  gimforge::io::write_ply(scan, gimforge::make_torus(1.0, 0.4, 120, 60), {.binary = true});
  const std::vector<std::string> args{"convert", scan, "--method", "relief", "--texture", "16",
                                      "--metric-samples", "20000", "--json", "-o"};
  std::vector<std::string> single{args};
  single.push_back(path("one.h5"));
  const auto one = run_gimforge(single, 300);
  ASSERT_EQ(one.exit_code, 0) << one.err;
  std::vector<std::string> two{GIMFORGE_MPIEXEC, "-n", "2", "--oversubscribe", "--bind-to", "none", GIMFORGE_EXE};
  two.insert(two.end(), args.begin(), args.end());
  two.push_back(path("two.h5"));
  const auto r = run_process(two, 300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json a = nlohmann::json::parse(one.out), b = nlohmann::json::parse(r.out);  // one document
  EXPECT_EQ(b.at("ranks").get<int>(), 2);
  EXPECT_FALSE(a.contains("ranks"));
  for (const char* key : {"psnr", "hausdorff_rms", "hausdorff_max", "samples", "occluded_samples", "storage_bytes",
                          "reconstruction_faces", "grid_levels_tried", "input_faces", "input_vertices"})
    EXPECT_EQ(a.at(key), b.at(key)) << key;
  EXPECT_GT(b.at("rank_peak_rss_mb").get<double>(), 0.0);
  // The archives reconstruct to the same mesh.
  ASSERT_EQ(run_gimforge({"reconstruct", path("one.h5"), "-o", path("one.ply")}).exit_code, 0);
  ASSERT_EQ(run_gimforge({"reconstruct", path("two.h5"), "-o", path("two.ply")}).exit_code, 0);
  const gimforge::TriMesh m1 = gimforge::io::read_mesh(path("one.ply"));
  const gimforge::TriMesh m2 = gimforge::io::read_mesh(path("two.ply"));
  EXPECT_GT(m1.num_faces(), 1000u);
  EXPECT_EQ(m1.faces, m2.faces);
  EXPECT_EQ(m1.positions, m2.positions);
}

// A huge scan becomes brick tasks (jobs/brick_tasks.h): item a (binary PLY, read in pieces) goes by a plan,
// six pieces and a finish, item b (the same scan as ASCII PLY) whole; both give the same image, alone and
// under mpirun with two workers; a run killed after some pieces resumes from its brick journal.
TEST_F(BatchTest, AHugeScanGoesByBrickTasksAndResumesFromThemAfterAKill) {
  allow_mpirun_as_root();
  gimforge::TriMesh t = gimforge::make_torus(1.0, 0.4, 160, 80);  // 25,600 faces
  for (gimforge::Vec3& p : t.positions)
    p += gimforge::Vec3(612345.0, 4123456.0, 80.0) + 0.01 * gimforge::Vec3(std::sin(9 * p.x()), 0, 0);
  fs::create_directories(root_ / "scans/a");
  fs::create_directories(root_ / "scans/b");
  gimforge::io::write_ply(root_ / "scans/a/scan.ply", t, {.binary = true, .double_precision = true});
  gimforge::io::write_ply(root_ / "scans/b/scan.ply", t, {.binary = false, .double_precision = true});
  fs::copy_file(kData + "/cube.off", root_ / "scans/cube.off");
  const auto args = [&](const std::string& archive) {
    return std::vector<std::string>{"batch", "--input", path("scans"), "--method", "gim", "--size", "65",
                                    "--proxy-faces", "1500", "--proxy-bricks", "6", "--metric-samples", "5000",
                                    "--max-retries", "0", "-o", archive};
  };
  const auto r = run_gimforge(args(path("one.h5")), 300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("converted by brick tasks"), std::string::npos) << r.err;
  const std::vector<float> data = data_of(path("one.h5")).front();
  const std::size_t image = 3u * 65 * 65;  // items by path: a/scan, b/scan, cube
  ASSERT_EQ(data.size(), 3 * image);
  EXPECT_TRUE(std::equal(data.begin(), data.begin() + image, data.begin() + image));

  std::vector<std::string> mpi{GIMFORGE_MPIEXEC, "-n", "3", "--oversubscribe", "--bind-to", "none", GIMFORGE_EXE};
  for (const std::string& a : args(path("three.h5"))) mpi.push_back(a);
  const auto three = run_process(mpi, 300);
  ASSERT_EQ(three.exit_code, 0) << three.err;
  EXPECT_EQ(data_of(path("three.h5")).front(), data);

  // SIGKILL once the journal records the plan and at least two pieces.
  std::vector<std::string> killed = args(path("k.h5"));
  killed.insert(killed.begin(), GIMFORGE_EXE);
  const std::string journal = path("k.h5.work/journal.jsonl");
  const std::string script = shell_words(killed) + " & pid=$!; while kill -0 $pid 2>/dev/null; do c=$(grep -c " +
                             "'\"event\":\"brick\"' '" + journal +
                             "' 2>/dev/null); [ \"${c:-0}\" -ge 3 ] && break; sleep 0.01; done; kill -KILL $pid; "
                             "wait $pid; exit $?";
  const auto k = run_process({"/bin/sh", "-c", script}, 300);
  ASSERT_EQ(k.exit_code, 128 + SIGKILL) << "the run ended before the kill: " << k.err;
  std::vector<std::string> resume = args(path("k.h5"));
  resume.push_back("--resume");
  const auto resumed = run_gimforge(resume, 300);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  const auto kept = resumed.err.find("plan and ");
  ASSERT_NE(kept, std::string::npos) << resumed.err;
  EXPECT_GE(std::atoi(resumed.err.c_str() + kept + 9), 2) << resumed.err;  // "... and N of its pieces kept"
  EXPECT_EQ(data_of(path("k.h5")).front(), data);
}

TEST_F(BatchTest, AFullDiskStopsTheBatchResumablyInsteadOfFailingItems) {
  // Every item after the first that does not fit would fail the same way: the batch went on spending its
  // items' attempts ("cannot close HDF5 file: slist already enabled?"), and a resume after making room
  // found them failed for good. It now stops at the first, says why, and the resume finishes. The
  // file-size limit (ulimit -f) fails writes as a full disk does; PMIx keeps its data in memory
  // (PMIX_MCA_gds=hash), not in files the limit would refuse. A 65² shard is written when its dataset
  // closes, a 513² one (a chunk beyond HDF5's cache) in the write itself.
  for (const bool large : {false, true}) {
    SCOPED_TRACE(large);
    const std::string out = path(large ? "full513.h5" : "full65.h5");
    const std::vector<std::string> large_args{"batch", "--input", path("meshes/boxy"), "--method", "gim", "--size", "513",
                                              "--no-metric", "--max-retries", "0", "-o", out};
    std::vector<std::string> args = large ? large_args : batch_args(out);
    std::vector<std::string> quiet{"-q"};
    quiet.insert(quiet.end(), args.begin(), args.end());
    const auto full = gimforge::test::run_gimforge_after("ulimit -f 32; export PMIX_MCA_gds=hash", quiet, 300);
    EXPECT_EQ(full.exit_code, 1) << full.err;
    const auto lines = full.err_lines();
    ASSERT_EQ(lines.size(), 1u) << full.err;
    EXPECT_NE(lines[0].find(": File too large"), std::string::npos) << full.err;
    EXPECT_NE(lines[0].find("the batch stopped"), std::string::npos) << full.err;
    EXPECT_NE(lines[0].find("--resume"), std::string::npos) << full.err;
    args.push_back("--resume");
    const auto resumed = run_gimforge(args, 300);
    EXPECT_EQ(resumed.exit_code, large ? 0 : 3) << resumed.err;  // the two bad meshes
    EXPECT_EQ(gimforge::io::read_batch_summary(out).front().count, large ? 2u : 4u);
  }
  // Under mpirun the worker whose shard did not close ends without MPI_Finalize (HDF5 would crash in it) and the
  // launcher ends the job: rank 0 was killed before it said why. It says it first now.
  allow_mpirun_as_root();
  std::string line = "ulimit -f 32; export PMIX_MCA_gds=hash; exec " + std::string(GIMFORGE_MPIEXEC) +
                     " -n 2 --oversubscribe --bind-to none " + GIMFORGE_EXE + " -q";
  for (const std::string& a : batch_args(path("full_mpi.h5"))) line += " '" + a + "'";
  const auto full = run_process({"/bin/sh", "-c", line}, 300);
  const auto said = full.err.find("gimforge: error: ");
  ASSERT_TRUE(full.exit_code == 1 && said != std::string::npos) << full.err;
  const std::string cause = full.err.substr(said, full.err.find('\n', said) - said);
  EXPECT_TRUE(cause.find(": File too large") != std::string::npos && cause.find("batch stopped") != std::string::npos) << cause;
  std::vector<std::string> resume = batch_args(path("full_mpi.h5"));
  resume.push_back("--resume");
  EXPECT_EQ(run_gimforge(resume, 300).exit_code, 3);  // the two bad meshes
}
