// End-to-end tests of `gimforge render`: ray casting a relief map into a PNG, the Embree reference beside
// it, the JSON report, and bad input.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/mesh_io.h"
#include "kernels/core/procedural.h"
#include "tests/cli/run_process.h"

namespace fs = std::filesystem;
using gimforge::test::run_gimforge;

namespace {

const std::string kData = GIMFORGE_TEST_DATA_DIR;

using gimforge::test::TempDir;

bool is_png(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[8] = {};
  in.read(magic, 8);
  return in.gcount() == 8 && std::string(magic + 1, 3) == "PNG";
}

/// A sphere mesh and its relief map (grid 4, 32² texels) in `dir`; returns {mesh, archive}.
std::pair<std::string, std::string> sphere_archive(const TempDir& dir) {
  const std::string mesh = dir.file("sphere.ply");
  gimforge::io::write_ply(mesh, gimforge::make_icosphere(1.0, 4));
  const std::string archive = dir.file("sphere.h5");
  const auto r = run_gimforge({"convert", mesh, "--method", "relief", "--grid", "4", "--texture", "32", "-o", archive,
                               "--metric-samples", "2000"},
                              300);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return {mesh, archive};
}

TEST(RenderCli, RaycastWithReferenceJson) {
  const TempDir dir;
  const auto [mesh, archive] = sphere_archive(dir);
  const std::string png = dir.file("view.png");
  const auto r = run_gimforge({"render", archive, "--view", "30,20", "--size", "96", "-o", png, "--reference", mesh,
                               "--json"},
                              300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(is_png(png));
  EXPECT_TRUE(is_png(dir.file("view_reference.png")));
  EXPECT_EQ(j["reference"]["output"], dir.file("view_reference.png"));
  EXPECT_EQ(j["name"], "sphere");
  EXPECT_EQ(j["size"], 96);
  EXPECT_EQ(j["raycast"]["rays"], 96 * 96);
  EXPECT_GT(j["raycast"]["rays_per_second"].get<double>(), 0.0);
  EXPECT_GT(j["raycast"]["hits"].get<int>(), 1000);
  EXPECT_GT(j["comparison"]["iou"].get<double>(), 0.98);
  EXPECT_GT(j["comparison"]["psnr"].get<double>(), 25.0);
  EXPECT_LT(j["comparison"]["depth_mean_abs"].get<double>(), 0.01);
  for (const char* key : {"mse", "depth_rms", "depth_p95", "normal_mean_deg", "hits_relief", "hits_reference"})
    EXPECT_TRUE(j["comparison"].contains(key)) << key;
}

TEST(RenderCli, TextReportAndOptions) {
  const TempDir dir;
  const auto [mesh, archive] = sphere_archive(dir);
  const std::string png = dir.file("top.png");
  const auto r = run_gimforge({"-j", "1", "render", archive, "--name", "relief/sphere", "--view=-45,90", "--up", "z",
                               "--size", "64", "--steps", "8", "--refine", "4", "--filter", "nearest", "-o", png,
                               "--reference", mesh});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(is_png(png));
  EXPECT_NE(r.out.find("Mrays/s on 1 thread"), std::string::npos) << r.out;  // -j 1 is what it ran on
  EXPECT_EQ(r.out.find("on 1 threads"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("silhouette IoU"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("PSNR"), std::string::npos) << r.out;
}

TEST(RenderCli, BadInput) {
  const TempDir dir;
  const auto [mesh, archive] = sphere_archive(dir);
  const std::string png = dir.file("x.png");
  auto r = run_gimforge({"render", archive, "--view", "30", "-o", png});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("AZIMUTH,ELEVATION"), std::string::npos) << r.err;
  r = run_gimforge({"render", archive, "--view", "30,100", "-o", png});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("elevation"), std::string::npos) << r.err;
  r = run_gimforge({"render", archive, "--name", "nothing", "-o", png});
  EXPECT_EQ(r.exit_code, 1);
  r = run_gimforge({"render", archive, "--size", "0", "-o", png});
  EXPECT_EQ(r.exit_code, 2);
  r = run_gimforge({"render", archive});  // no -o
  EXPECT_EQ(r.exit_code, 2);
  r = run_gimforge({"render", dir.file("missing.h5"), "-o", png});
  EXPECT_EQ(r.exit_code, 1);
  // The picture is PNG: another name is refused; a reference that cannot be read leaves no picture.
  r = run_gimforge({"render", archive, "-o", dir.file("x.jpg")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("name the output .png"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir.file("x.jpg")));
  r = run_gimforge({"render", archive, "--size", "16", "--reference", dir.file("missing.ply"), "-o", png});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_FALSE(fs::exists(png));
  // An archive without relief maps.
  const std::string gim = dir.file("gim.h5");
  r = run_gimforge({"convert", kData + "/fist.ply", "--method", "gim", "--size", "65", "--normal-size", "0",
                    "--metric-samples", "1000", "-o", gim},
                   300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_gimforge({"render", gim, "-o", png});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("no relief map"), std::string::npos) << r.err;
  r = run_gimforge({"render", gim, "--name", "fist", "-o", png});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("not a relief map"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(png));
}

}  // namespace
