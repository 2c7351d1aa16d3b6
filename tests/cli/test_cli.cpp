// End-to-end tests of the gimforge executable: exit codes, --help/--version, JSON output of info and
// metrics on committed meshes and procedural ones written to a temporary directory.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>

#include <nlohmann/json.hpp>

#include "io/mesh_io.h"
#include "kernels/procedural.h"
#include "tests/cli/run_process.h"

namespace fs = std::filesystem;
using gimforge::test::run_gimforge;

namespace {

const std::string kData = GIMFORGE_TEST_DATA_DIR;

class TempDir {
 public:
  TempDir() {
    std::string pattern = (fs::temp_directory_path() / "gimforge-cli-XXXXXX").string();
    path_ = mkdtemp(pattern.data());
  }
  ~TempDir() { fs::remove_all(path_); }
  [[nodiscard]] std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

nlohmann::json run_json(const std::vector<std::string>& args) {
  const auto r = run_gimforge(args);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return nlohmann::json::parse(r.out);
}

}  // namespace

TEST(Cli, HelpAndVersion) {
  auto r = run_gimforge({"--help"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("metrics"), std::string::npos);
  EXPECT_NE(r.out.find("Exit codes"), std::string::npos);
  r = run_gimforge({"metrics", "--help"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("--samples"), std::string::npos);
  r = run_gimforge({"--version"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("gimforge "), std::string::npos);
}

TEST(Cli, UsageErrorsExitWithTwo) {
  EXPECT_EQ(run_gimforge({}).exit_code, 2);
  EXPECT_EQ(run_gimforge({"info"}).exit_code, 2);
  EXPECT_EQ(run_gimforge({"frobnicate"}).exit_code, 2);
  EXPECT_EQ(run_gimforge({"metrics", "a.ply", "b.ply", "--samples", "0"}).exit_code, 2);
  EXPECT_EQ(run_gimforge({"--log-level", "loud", "info", "x.ply"}).exit_code, 2);
}

TEST(Cli, InfoJsonClosedGenusZero) {
  const auto j = run_json({"info", kData + "/fist.ply", "--json"});
  for (const char* key : {"vertices", "faces", "components", "boundary_loops", "genus", "closed", "manifold",
                          "bbox_diagonal"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["vertices"], 1197);
  EXPECT_EQ(j["faces"], 2390);
  EXPECT_EQ(j["components"], 1);
  EXPECT_EQ(j["boundary_loops"], 0);
  EXPECT_EQ(j["genus"], nlohmann::json::array({0}));
  EXPECT_EQ(j["closed"], true);
  EXPECT_EQ(j["manifold"], true);
  EXPECT_EQ(j["euler_characteristic"], 2);
  EXPECT_GT(j["bbox_diagonal"].get<double>(), 0.0);
}

TEST(Cli, InfoJsonGenusOneAndDisk) {
  auto j = run_json({"info", kData + "/kitten.ply", "--json"});
  EXPECT_EQ(j["genus"], nlohmann::json::array({1}));
  EXPECT_EQ(j["closed"], true);
  j = run_json({"info", kData + "/cathead.ply", "--json"});
  EXPECT_EQ(j["boundary_loops"], 1);
  EXPECT_EQ(j["closed"], false);
  EXPECT_EQ(j["genus"], nlohmann::json::array({0}));
}

TEST(Cli, InfoTextMentionsGenus) {
  const auto r = run_gimforge({"info", kData + "/kitten.ply"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("genus            1"), std::string::npos) << r.out;
}

TEST(Cli, InfoRepairsWithWarning) {
  TempDir dir;
  gimforge::TriMesh m = gimforge::make_icosphere(1.0, 1);
  m.positions.push_back({5, 5, 5});
  m.faces.push_back(m.faces.front());
  gimforge::io::write_ply(dir.file("dup.ply"), m);
  const auto r = run_gimforge({"info", dir.file("dup.ply")});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("removed 1 duplicate face"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("removed 1 unreferenced vertex"), std::string::npos) << r.err;
}

TEST(Cli, MetricsJsonHasExactlyTheDocumentedKeys) {
  const auto j = run_json({"metrics", kData + "/fist.ply", kData + "/fist.ply", "--samples", "20000", "--json"});
  std::set<std::string> keys;
  for (auto it = j.begin(); it != j.end(); ++it) keys.insert(it.key());
  EXPECT_EQ(keys, (std::set<std::string>{"diag", "ab", "ba", "max", "rms", "psnr"}));
  for (const char* side : {"ab", "ba"}) {
    std::set<std::string> sub;
    for (auto it = j[side].begin(); it != j[side].end(); ++it) sub.insert(it.key());
    EXPECT_EQ(sub, (std::set<std::string>{"max", "mean", "rms"}));
  }
  // A mesh against itself: zero up to the rounding of the interpolated sample positions.
  const double diag = j["diag"].get<double>();
  EXPECT_LT(j["rms"].get<double>(), 1e-12 * diag);
  EXPECT_LT(j["max"].get<double>(), 1e-12 * diag);
  EXPECT_TRUE(j["psnr"].is_null() || j["psnr"].get<double>() > 240.0) << j.dump();
}

TEST(Cli, MetricsConcentricSpheres) {
  TempDir dir;
  gimforge::io::write_ply(dir.file("a.ply"), gimforge::make_icosphere(1.0, 5), {.double_precision = true});
  gimforge::io::write_ply(dir.file("b.ply"), gimforge::make_icosphere(1.01, 5), {.double_precision = true});
  const auto j = run_json({"metrics", dir.file("a.ply"), dir.file("b.ply"), "--samples", "50000", "--json"});
  const double rms = j["rms"].get<double>();
  EXPECT_NEAR(rms, 0.01, 0.0002);
  EXPECT_NEAR(j["psnr"].get<double>(), 20 * std::log10(j["diag"].get<double>() / rms), 1e-9);
  // Deterministic: the same command gives the same figures.
  const auto again = run_json({"metrics", dir.file("a.ply"), dir.file("b.ply"), "--samples", "50000", "--json"});
  EXPECT_EQ(again, j);
  // Text output.
  const auto r = run_gimforge({"metrics", dir.file("a.ply"), dir.file("b.ply"), "--samples", "1000"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("PSNR"), std::string::npos);
}

TEST(Cli, ValidateCleanAndMultiple) {
  auto r = run_gimforge({"validate", kData + "/fist.ply"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find(": ok"), std::string::npos);
  r = run_gimforge({"validate", kData + "/fist.ply", kData + "/does-not-exist.ply", kData + "/kitten.ply"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err_lines().size(), 1u) << r.err;
  EXPECT_NE(r.err.find("does-not-exist.ply"), std::string::npos);
  EXPECT_NE(r.out.find("kitten.ply: ok"), std::string::npos) << "the other files are still checked";
}

TEST(Cli, SharedMeshesIfPresent) {
  const std::string shared = GIMFORGE_SHARED_MESHES_DIR;
  if (!fs::exists(shared + "/bunny.ply")) GTEST_SKIP() << "../shared/data/meshes is absent: skipping shared-mesh checks";
  const auto j = run_json({"--quiet", "info", shared + "/bunny.ply", "--json"});
  EXPECT_EQ(j["vertices"], 35947);
  EXPECT_EQ(j["faces"], 69451);
  EXPECT_EQ(j["boundary_loops"], 5);
  EXPECT_EQ(j["genus"], nlohmann::json::array({0}));
  const auto t = run_json({"--quiet", "info", shared + "/teapot.ply", "--json"});
  EXPECT_EQ(t["components"], 4);
  EXPECT_EQ(t["manifold"], false);
  const auto e = run_json({"--quiet", "info", shared + "/eight.ply", "--json"});
  EXPECT_EQ(e["genus"], nlohmann::json::array({2}));
  const auto b = run_json({"--quiet", "info", shared + "/buddha.ply", "--json"});
  EXPECT_EQ(b["genus"], nlohmann::json::array({6}));
}

TEST(CliGim, ConvertReconstructPreview) {
  TempDir dir;
  const std::string archive = dir.file("out.h5");
  auto r = run_gimforge({"convert", kData + "/kitten.ply", "--method", "gim", "--size", "129", "--normal-size", "128",
                         "--metric-samples", "50000", "-o", archive, "--json"}, 300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["name"], "kitten");
  for (const auto& entry : fs::directory_iterator(fs::path(archive).parent_path()))
    EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos) << "left behind: " << entry.path();
  EXPECT_EQ(j["size"], 129);
  EXPECT_GT(j["psnr"].get<double>(), 60.0);
  EXPECT_GT(j["stretch_efficiency"].get<double>(), 0.2);
  // The same name twice is refused before any work.
  r = run_gimforge({"convert", kData + "/kitten.ply", "--size", "65", "-o", archive});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("already holds a geometry image 'kitten'"), std::string::npos) << r.err;
  // A second image in the same archive; then commands must be told which one.
  r = run_gimforge({"convert", kData + "/fist.ply", "--size", "65", "--metric-samples", "20000", "-o", archive});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_gimforge({"reconstruct", archive, "-o", dir.file("x.ply")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("choose one with --name"), std::string::npos) << r.err;
  // Every level of detail reconstructs closed, with the input's genus.
  for (const char* level : {"0", "1"}) {
    const std::string mesh = dir.file(std::string("kitten_") + level + ".ply");
    r = run_gimforge({"reconstruct", archive, "--name", "kitten", "--level", level, "-o", mesh});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto info = run_json({"info", mesh, "--json"});
    EXPECT_EQ(info["closed"], true) << "level " << level;
    EXPECT_EQ(info["manifold"], true) << "level " << level;
    EXPECT_EQ(info["genus"], nlohmann::json::array({1})) << "level " << level;
  }
  r = run_gimforge({"reconstruct", archive, "--name", "kitten", "--level", "2", "-o", dir.file("bad.ply")});
  EXPECT_EQ(r.exit_code, 1) << "below 65x65 the cut-nodes are off the grid";
  // Preview PNGs.
  r = run_gimforge({"preview", archive, "--name", "kitten", "-o", dir.file("png")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* png : {"png/kitten_geometry.png", "png/kitten_normals.png"}) {
    std::ifstream in(dir.file(png), std::ios::binary);
    char magic[8] = {};
    in.read(magic, 8);
    EXPECT_EQ(std::string(magic + 1, 3), "PNG") << png;
  }
}

TEST(CliGim, RefusesMeshesItCannotConvert) {
  TempDir dir;
  gimforge::io::write_ply(dir.file("two.ply"),
                          gimforge::concatenate(gimforge::make_icosphere(1.0, 1), gimforge::make_icosphere(0.5, 1)));
  auto r = run_gimforge({"convert", dir.file("two.ply"), "-o", dir.file("o.h5")});
  EXPECT_EQ(r.exit_code, 1);
  ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
  EXPECT_NE(r.err.find("2 connected components"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("multi-chart"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir.file("o.h5"))) << "no archive is left behind for a refused mesh";
  r = run_gimforge({"convert", kData + "/kitten.ply", "--size", "100", "-o", dir.file("o.h5")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("multiple of 64"), std::string::npos) << r.err;
  r = run_gimforge({"reconstruct", dir.file("missing.h5"), "-o", dir.file("m.ply")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("missing.h5"), std::string::npos) << r.err;
}
