// End-to-end tests of relief maps in the gimforge executable: convert --method relief, reconstruct, preview,
// archives shared with other kinds, damaged archives and bad option values.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/archive.h"
#include "io/mesh_io.h"
#include "kernels/core/procedural.h"
#include "tests/cli/run_process.h"

namespace fs = std::filesystem;
using gimforge::test::run_gimforge;

namespace {

const std::string kData = GIMFORGE_TEST_DATA_DIR;

using gimforge::test::TempDir;

nlohmann::json run_json(const std::vector<std::string>& args) {
  const auto r = run_gimforge(args, 300);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return r.exit_code == 0 ? nlohmann::json::parse(r.out) : nlohmann::json::object();
}

bool is_png(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[8] = {};
  in.read(magic, 8);
  return in.gcount() == 8 && std::string(magic + 1, 3) == "PNG";
}

/// A coloured torus and a small sphere inside its hole: two components, genus 1, colours.
std::string write_torus_and_ball(const TempDir& dir) {
  gimforge::TriMesh torus = gimforge::make_torus(1.0, 0.35, 48, 24);
  for (const gimforge::Vec3& p : torus.positions)
    torus.colors.emplace_back(static_cast<float>(0.5 + 0.3 * p.x()), static_cast<float>(0.5 + 0.3 * p.y()), 0.2f);
  gimforge::TriMesh ball = gimforge::make_icosphere(0.3, 2);
  ball.colors.assign(ball.positions.size(), gimforge::Vec3f(0.9f, 0.1f, 0.1f));
  const std::string path = dir.file("torus_ball.ply");
  gimforge::TriMesh both = gimforge::concatenate(torus, ball);  // drops colours: set them again
  both.colors = torus.colors;
  both.colors.insert(both.colors.end(), ball.colors.begin(), ball.colors.end());
  gimforge::io::write_ply(path, both);
  return path;
}

}  // namespace

TEST(CliRelief, ConvertReconstructPreviewClosedMesh) {
  TempDir dir;
  const std::string archive = dir.file("relief.h5");
  const auto j = run_json({"convert", kData + "/fist.ply", "--method", "relief", "--grid", "4", "--texture", "16",
                           "--metric-samples", "20000", "-o", archive, "--json"});
  ASSERT_FALSE(j.empty());
  EXPECT_EQ(j["name"], "fist");
  EXPECT_EQ(j["method"], "relief");
  EXPECT_EQ(j["n"], 4);
  EXPECT_EQ(j["grid"], "given");
  EXPECT_EQ(j["texture"], 16);
  const auto grey = j["grey_cells"].get<std::size_t>();
  EXPECT_GT(grey, 0u);
  EXPECT_EQ(grey + j["white_cells"].get<std::size_t>() + j["black_cells"].get<std::size_t>(), 64u);
  EXPECT_EQ(j["border_cells"].get<std::size_t>() + j["interior_cells"].get<std::size_t>(), grey);
  EXPECT_EQ(j["watertight_inside_test"], true) << "fist.ply is closed";
  ASSERT_EQ(j["levels"].size(), 1u) << "a given grid is the only level";
  EXPECT_EQ(j["levels"][0]["n"], 4);
  EXPECT_EQ(j["levels"][0]["grey_cells"], grey);
  EXPECT_EQ(j["colors"], false);
  const auto layers = j["domain_faces"].get<double>();
  EXPECT_EQ(j["storage_bytes"].get<double>(), layers * 16 * 16 * 5 + static_cast<double>(grey) * 5);
  EXPECT_GT(j["psnr"].get<double>(), 30.0);
  for (const char* key : {"occlusion_ratio", "seconds_cells", "seconds_sampling", "seconds_metric", "seconds_total",
                          "hausdorff_rms", "reconstruction_faces"})
    EXPECT_GE(j[key].get<double>(), 0.0) << key;

  // The same name again is refused before any work.
  auto r = run_gimforge({"convert", kData + "/fist.ply", "--method", "relief", "--grid", "2", "-o", archive});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("already holds a relief map 'fist'"), std::string::npos) << r.err;

  // Reconstruction: the triangles counted by convert.
  const std::string mesh = dir.file("fist_relief.ply");
  r = run_gimforge({"reconstruct", archive, "-o", mesh});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("N = 4"), std::string::npos) << r.out;
  const auto info = run_json({"info", mesh, "--json"});
  EXPECT_EQ(info["faces"].get<double>(), j["reconstruction_faces"].get<double>());
  r = run_gimforge({"reconstruct", archive, "--level", "1", "-o", dir.file("x.ply")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("a relief map has level 0 only"), std::string::npos) << r.err;
  r = run_gimforge({"reconstruct", archive, "--no-fuse", "-o", dir.file("x.ply")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("--no-fuse applies to geometry images and multi-chart geometry images only"), std::string::npos) << r.err;

  // Preview: atlases of the maps and the cell slices; no colour atlas without colours.
  r = run_gimforge({"preview", archive, "-o", dir.file("png")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* png : {"fist_relief_distances.png", "fist_relief_normals.png", "fist_relief_cells.png"})
    EXPECT_TRUE(is_png(dir.file(std::string("png/") + png))) << png;
  EXPECT_FALSE(fs::exists(dir.file("png/fist_relief_colors.png")));
  EXPECT_EQ(r.out.find("note:"), std::string::npos) << "a watertight mesh's black cells are the enclosed ones: " << r.out;
  for (const auto& entry : fs::directory_iterator(fs::path(archive).parent_path()))
    EXPECT_FALSE(entry.path().filename().string().ends_with(".tmp")) << "left behind: " << entry.path();
}

TEST(CliRelief, AutomaticGridOnSeveralComponentsWithColours) {
  TempDir dir;
  const std::string mesh = write_torus_and_ball(dir);
  const std::string archive = dir.file("auto.h5");
  const auto j = run_json({"convert", mesh, "--method", "relief", "--max-grid", "8", "--occlusion-threshold", "0.02",
                           "--texture", "12", "--metric-samples", "20000", "-o", archive, "--json"});
  ASSERT_FALSE(j.empty());
  EXPECT_EQ(j["grid"], "auto");
  EXPECT_EQ(j["colors"], true);
  EXPECT_EQ(j["watertight_inside_test"], true) << "both components are closed";
  const auto& levels = j["levels"];
  ASSERT_GE(levels.size(), 2u) << "one cell cannot hold a torus around a ball without occlusion";
  for (std::size_t k = 0; k + 1 < levels.size(); ++k) {
    EXPECT_GT(levels[k]["occlusion_ratio"].get<double>(), 0.02) << "level " << k << " was doubled";
    EXPECT_EQ(levels[k + 1]["n"].get<int>(), 2 * levels[k]["n"].get<int>());
  }
  const auto& last = levels.back();
  EXPECT_EQ(last["n"], j["n"]);
  EXPECT_TRUE(last["occlusion_ratio"].get<double>() <= 0.02 || j["n"] == 8) << j.dump();
  EXPECT_EQ(j["occlusion_ratio"].get<double>(), last["occlusion_ratio"].get<double>());
  EXPECT_EQ(j["grid_levels_tried"].get<double>(), static_cast<double>(levels.size()));

  const auto r = run_gimforge({"preview", archive, "--name", "relief/torus_ball", "-o", dir.file("png")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(is_png(dir.file("png/torus_ball_relief_colors.png")));
  EXPECT_TRUE(is_png(dir.file("png/torus_ball_relief_cells.png")));
}

TEST(CliRelief, MeshWithHoleUsesTheReportedFallback) {
  TempDir dir;
  const std::string archive = dir.file("cat.h5");
  const auto r = run_gimforge({"convert", kData + "/cathead.ply", "--method", "relief", "--grid", "auto", "--max-grid",
                               "4", "--texture", "8", "--metric-samples", "20000", "-o", archive},
                              300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find(":/relief/cathead\n"), std::string::npos) << r.out;
  for (const char* line : {"grid             N = ", "cells            ", "domain faces     ", "levels tried     N = 1",
                           "inside test      FALLBACK (the mesh is not watertight)", "storage          ",
                           "reconstruction   ", "PSNR", "time             cells"})
    EXPECT_NE(r.out.find(line), std::string::npos) << line << " in\n" << r.out;
  const auto j = run_json({"convert", kData + "/cathead.ply", "--method", "relief", "--grid", "2", "--texture", "8",
                           "--metric-samples", "20000", "-o", archive, "--name", "cat2", "--json"});
  EXPECT_EQ(j["watertight_inside_test"], false);
  EXPECT_NE(j["inside_method"].get<std::string>().find("fallback"), std::string::npos) << j["inside_method"];
  // Two relief maps: commands must be told which.
  const auto rr = run_gimforge({"reconstruct", archive, "-o", dir.file("x.ply")});
  EXPECT_EQ(rr.exit_code, 1);
  EXPECT_NE(rr.err.find("holds 2 images (relief/cat2, relief/cathead); choose one with --name"), std::string::npos)
      << rr.err;
}

TEST(CliRelief, SharesAnArchiveWithASphericalImage) {
  TempDir dir;
  const std::string archive = dir.file("both.h5");
  auto r = run_gimforge({"convert", kData + "/fist.ply", "--method", "sphere", "--domain", "tetra", "--n", "4",
                         "--metric-samples", "20000", "-o", archive},
                        300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_gimforge({"convert", kData + "/fist.ply", "--method", "relief", "--grid", "2", "--texture", "8",
                    "--metric-samples", "20000", "-o", archive});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_gimforge({"reconstruct", archive, "--name", "fist", "-o", dir.file("x.ply")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("'fist' is both a spherical geometry image and a relief map; choose one with --name "
                       "spherical/fist or --name relief/fist"),
            std::string::npos)
      << r.err;
  r = run_gimforge({"reconstruct", archive, "--name", "relief/fist", "-o", dir.file("r.ply")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_gimforge({"reconstruct", archive, "--name", "relief/cat", "-o", dir.file("r.ply")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("no relief map 'cat'"), std::string::npos) << r.err;
  // preview draws every image without --name (their pictures are named apart), one with it.
  r = run_gimforge({"preview", archive, "-o", dir.file("all")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir.file("all/fist_sphere_geometry.png")));
  EXPECT_TRUE(fs::exists(dir.file("all/fist_relief_distances.png")));
  r = run_gimforge({"preview", archive, "--name", "relief/fist", "-o", dir.file("one")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_FALSE(fs::exists(dir.file("one/fist_sphere_geometry.png")));
  EXPECT_TRUE(fs::exists(dir.file("one/fist_relief_distances.png")));
}

TEST(CliRelief, DamagedArchiveIsOneClearError) {
  TempDir dir;
  const std::string archive = dir.file("d.h5");
  auto r = run_gimforge({"convert", kData + "/fist.ply", "--method", "relief", "--grid", "2", "--texture", "8",
                         "--metric-samples", "20000", "-o", archive});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  {
    gimforge::io::Archive a = gimforge::io::Archive::open(archive, gimforge::h5::OpenMode::kReadWrite);
    gimforge::h5::Dataset cases = a.root().open_dataset("relief/fist/case");
    std::vector<std::uint8_t> v = cases.read<std::uint8_t>();
    v[0] = static_cast<std::uint8_t>((v[0] + 1) % 10);
    cases.write(v);
    a.close();
  }
  for (const char* command : {"reconstruct", "preview"}) {
    r = run_gimforge({command, archive, "-o", dir.file(std::string(command) == "preview" ? "png" : "x.ply")});
    EXPECT_EQ(r.exit_code, 1) << command;
    ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
    EXPECT_NE(r.err.find(archive + ": relief map 'fist': grey cell 0 at ("), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("stored case"), std::string::npos) << r.err;
  }
}

TEST(CliRelief, BadOptionValuesAreUsageErrors) {
  TempDir dir;
  const std::string fist = kData + "/fist.ply";
  const std::string out = dir.file("o.h5");
  const struct {
    std::vector<std::string> args;
    const char* message;
  } cases[] = {
      {{"--grid", "0"}, "--grid: 0 is neither auto nor a number of cells per axis in [1, 1024]"},
      {{"--grid", "2000"}, "--grid: 2000 is neither auto"},
      {{"--grid", "many"}, "--grid: many is neither auto"},
      {{"--grid", "4x"}, "--grid: 4x is neither auto"},
      {{"--texture", "1"}, "--texture"},
      {{"--texture", "4096"}, "--texture"},
      {{"--max-grid", "0"}, "--max-grid"},
      {{"--occlusion-threshold", "-0.5"}, "--occlusion-threshold"},
      {{"--occlusion-threshold", "1.5"}, "--occlusion-threshold"},
      {{"--grid", "4", "--max-grid", "8"}, "--max-grid: applies to --grid auto only (this is --grid 4)"},
      {{"--grid", "4", "--occlusion-threshold", "0.1"}, "--occlusion-threshold: applies to --grid auto only"},
      {{"--size", "65"}, "--size: applies to --method gim only"},
  };
  for (const auto& c : cases) {
    std::vector<std::string> args{"convert", fist, "--method", "relief", "-o", out};
    args.insert(args.end(), c.args.begin(), c.args.end());
    const auto r = run_gimforge(args);
    EXPECT_EQ(r.exit_code, 2) << c.args.front() << " " << c.args.back();
    EXPECT_NE(r.err.find(c.message), std::string::npos) << c.message << " in\n" << r.err;
  }
  for (const auto& [option, value] : std::vector<std::pair<std::string, std::string>>{
           {"--grid", "4"}, {"--texture", "4"}, {"--max-grid", "4"}, {"--occlusion-threshold", "0.5"}}) {
    const auto r = run_gimforge({"convert", fist, option, value, "-o", out});
    EXPECT_EQ(r.exit_code, 2) << option;
    EXPECT_NE(r.err.find(option + ": applies to --method relief only"), std::string::npos) << r.err;
  }
  EXPECT_FALSE(fs::exists(out));
  const auto r = run_gimforge({"convert", "--help"});
  EXPECT_EQ(r.exit_code, 0);
  for (const char* text : {"relief", "--grid", "--texture", "--max-grid", "--occlusion-threshold", "Apaza"})
    EXPECT_NE(r.out.find(text), std::string::npos) << text;
}
