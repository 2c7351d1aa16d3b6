// End-to-end tests of multi-chart geometry images in the gimforge executable: convert --method mcgim of a
// mesh of several components, reconstruct (watertight), preview, ls, --json, damaged archives and bad
// option values.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/archive.h"
#include "io/mesh_io.h"
#include "kernels/core/edge_topology.h"
#include "kernels/core/procedural.h"
#include "tests/cli/run_process.h"

namespace fs = std::filesystem;
using gimforge::test::run_gimforge;
using gimforge::test::TempDir;

namespace {

/// A torus and a ball beside it: two components, genus 1 and 0 — what gim and sphere refuse.
std::string write_torus_and_ball(const TempDir& dir) {
  gimforge::TriMesh ball = gimforge::make_icosphere(0.4, 3);
  for (gimforge::Vec3& p : ball.positions) p.x() += 2.0;
  const std::string path = dir.file("torus_ball.ply");
  gimforge::io::write_ply(path, gimforge::concatenate(gimforge::make_torus(1.0, 0.35, 48, 24), ball));
  return path;
}

/// Two unit cubes sharing the edge (1,1,0)-(1,1,1) (four faces on it), two faces of the first reversed: what
/// the loader calls non-manifold and inconsistently oriented.
std::string write_two_cubes_on_an_edge(const TempDir& dir) {
  const int f[12][3] = {{0, 1, 3}, {0, 3, 2}, {4, 6, 7}, {4, 7, 5}, {0, 4, 5}, {0, 5, 1},
                        {2, 3, 7}, {2, 7, 6}, {0, 2, 6}, {0, 6, 4}, {1, 5, 7}, {1, 7, 3}};
  std::vector<std::array<int, 3>> vertices;
  std::string faces;
  for (int c = 0; c < 2; ++c) {
    std::array<int, 8> index{};
    for (int k = 0; k < 8; ++k) {
      const std::array<int, 3> p{c + k / 4, c + (k / 2) % 2, k % 2};
      const auto it = std::find(vertices.begin(), vertices.end(), p);
      index[static_cast<std::size_t>(k)] = static_cast<int>(it - vertices.begin()) + 1;  // OBJ counts from 1
      if (it == vertices.end()) vertices.push_back(p);
    }
    for (int k = 0; k < 12; ++k) {
      const bool flip = c == 0 && (k == 2 || k == 7);
      const auto at = [&](int i) { return index[static_cast<std::size_t>(f[k][i])]; };
      faces += "f " + std::to_string(at(0)) + ' ' + std::to_string(at(flip ? 2 : 1)) + ' ' + std::to_string(at(flip ? 1 : 2)) + '\n';
    }
  }
  const std::string path = dir.file("two_cubes.obj");
  std::ofstream out(path);
  for (const auto& p : vertices) out << "v " << p[0] << ' ' << p[1] << ' ' << p[2] << '\n';
  out << faces;
  return path;
}

bool is_png(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[8] = {};
  in.read(magic, 8);
  return in.gcount() == 8 && std::string(magic + 1, 3) == "PNG";
}

}  // namespace

TEST(CliMcgim, ConvertsSeveralComponentsAndReconstructsWatertight) {
  TempDir dir;
  const std::string mesh = write_torus_and_ball(dir), archive = dir.file("m.h5");
  const auto r = run_gimforge({"convert", mesh, "--method", "mcgim", "--charts", "12", "--samples", "16384",
                               "--metric-samples", "20000", "--json", "-o", archive},
                              300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_LE(j.at("width").get<int>() * j.at("height").get<int>(), 16384);
  EXPECT_GT(j.at("psnr").get<double>(), 50.0);
  EXPECT_GE(j.at("charts").get<double>(), 12.0);
  EXPECT_GT(j.at("packing_efficiency").get<double>(), 0.4);
  EXPECT_GT(j.at("stretch_efficiency").get<double>(), 0.9);

  const std::string ply = dir.file("r.ply");
  const auto rec = run_gimforge({"reconstruct", archive, "-o", ply});
  ASSERT_EQ(rec.exit_code, 0) << rec.err;
  const gimforge::TriMesh t = gimforge::io::read_mesh(ply);
  const gimforge::EdgeTopology topo = gimforge::build_edge_topology(t);
  std::size_t boundary = 0, nonmanifold = 0;
  for (std::size_t e = 0; e < topo.num_edges(); ++e) {
    boundary += topo.valence(e) == 1 ? 1u : 0u;
    nonmanifold += topo.valence(e) > 2 ? 1u : 0u;
  }
  EXPECT_EQ(boundary, 0u);
  EXPECT_EQ(nonmanifold, 0u);
  // --no-fuse ignores the zipper: the charts come apart.
  const auto open = run_gimforge({"reconstruct", archive, "--no-fuse", "-o", dir.file("open.ply")});
  ASSERT_EQ(open.exit_code, 0) << open.err;
  const gimforge::TriMesh o = gimforge::io::read_mesh(dir.file("open.ply"));
  EXPECT_GT(o.num_vertices(), t.num_vertices());

  const auto pv = run_gimforge({"preview", archive, "-o", dir.file("pv")});
  ASSERT_EQ(pv.exit_code, 0) << pv.err;
  for (const char* name : {"torus_ball_mcgim_geometry.png", "torus_ball_mcgim_normals.png", "torus_ball_mcgim_charts.png"})
    EXPECT_TRUE(is_png(dir.file(std::string("pv/") + name))) << name;
  const auto ls = run_gimforge({"ls", archive});
  ASSERT_EQ(ls.exit_code, 0) << ls.err;
  EXPECT_NE(ls.out.find("mcgim"), std::string::npos) << ls.out;
}

TEST(CliMcgim, OtherImageMethodsNameMcgimForSeveralComponents) {
  TempDir dir;
  const std::string mesh = write_torus_and_ball(dir);
  for (const char* method : {"gim", "sphere"}) {
    const auto r = run_gimforge({"convert", mesh, "--method", method, "--no-metric", "-o", dir.file("x.h5")});
    EXPECT_EQ(r.exit_code, 1) << method;
    EXPECT_NE(r.err.find("--method mcgim"), std::string::npos) << method << ": " << r.err;
  }
}

TEST(CliMcgim, NonManifoldAndMisorientedInputIsCutThenConverted) {
  TempDir dir;
  const std::string mesh = write_two_cubes_on_an_edge(dir);
  // gim and sphere refuse it and name what takes it.
  for (const char* method : {"gim", "sphere"}) {
    const auto r = run_gimforge({"convert", mesh, "--method", method, "--no-metric", "-o", dir.file("x.h5")});
    EXPECT_EQ(r.exit_code, 1) << method;
    EXPECT_NE(r.err.find("non-manifold edge"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("--method mcgim cuts such a mesh"), std::string::npos) << method << ": " << r.err;
  }
  const std::string a = dir.file("m.h5");
  const auto c = run_gimforge({"convert", mesh, "--method", "mcgim", "--samples", "4096", "--json", "-o", a});
  ASSERT_EQ(c.exit_code, 0) << c.err;
  const nlohmann::json stats = nlohmann::json::parse(c.out);
  EXPECT_EQ(stats.at("cut_nonmanifold_edges"), 1.0) << stats.dump();
  EXPECT_EQ(stats.at("flipped_faces"), 2.0);
  EXPECT_EQ(stats.at("split_vertices"), 2.0);
  EXPECT_GT(stats.at("psnr").get<double>(), 100.0);  // flat faces: the image holds them exactly
  // Each cube gets its copy of the shared edge back: two closed, oriented 2-manifolds.
  const std::string ply = dir.file("m.ply");
  ASSERT_EQ(run_gimforge({"reconstruct", a, "-o", ply}).exit_code, 0);
  const auto info = run_gimforge({"info", ply, "--json"});
  const nlohmann::json t = nlohmann::json::parse(info.out);
  EXPECT_EQ(t.at("components"), 2);
  EXPECT_EQ(t.at("boundary_edges"), 0);
  EXPECT_EQ(t.at("nonmanifold_edges"), 0);
  EXPECT_EQ(t.at("inconsistent_edges"), 0);
}

TEST(CliMcgim, BadOptionsAreUsageErrors) {
  TempDir dir;
  const std::string mesh = std::string(GIMFORGE_TEST_DATA_DIR) + "/cube.off";
  const std::vector<std::vector<std::string>> bad{
      {"--method", "mcgim", "--charts", "0"},     {"--method", "mcgim", "--charts", "many"},
      {"--method", "mcgim", "--samples", "10"},   {"--method", "gim", "--charts", "8"},
      {"--method", "relief", "--optimize"},       {"--method", "mcgim", "--size", "257"}};
  for (const auto& extra : bad) {
    std::vector<std::string> args{"convert", mesh, "-o", dir.file("x.h5")};
    args.insert(args.end(), extra.begin(), extra.end());
    const auto r = run_gimforge(args);
    EXPECT_EQ(r.exit_code, 2) << extra.back() << ": " << r.err;
    // One line naming the option (CLI11 adds "Run with --help for more information.").
    ASSERT_FALSE(r.err_lines().empty());
    EXPECT_NE(r.err_lines().front().find(extra[2].starts_with("--") ? extra[2] : extra[0]), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("x.h5")));
  }
}

TEST(CliMcgim, DamagedArchivesAreOneErrorLine) {
  TempDir dir;
  const std::string archive = dir.file("m.h5");
  const std::string mesh = std::string(GIMFORGE_TEST_DATA_DIR) + "/cube.off";
  ASSERT_EQ(run_gimforge({"convert", mesh, "--method", "mcgim", "--charts", "6", "--samples", "4096", "--no-metric",
                          "-o", archive})
                .exit_code,
            0);
  struct Damage {
    const char* attribute;
    std::int64_t value;
  };
  // num_charts = 7 of 6: every chart id stays valid, only chart_stretch's shape disagrees (reconstruct, which
  // does not need the stretch, once wrote a mesh where preview refused).
  for (const Damage d : {Damage{"width", std::int64_t{1} << 40}, Damage{"height", 0}, Damage{"num_charts", -3},
                         Damage{"num_charts", 1}, Damage{"num_charts", 7}}) {
    const std::string copy = dir.file(std::string("bad_") + d.attribute + std::to_string(d.value) + ".h5");
    fs::copy_file(archive, copy);
    {
      gimforge::io::Archive a = gimforge::io::Archive::open(copy, gimforge::h5::OpenMode::kReadWrite);
      gimforge::h5::Group g = a.root().open_group("mcgim/cube");
      g.set_attribute(d.attribute, d.value);
    }
    for (const char* command : {"reconstruct", "preview"}) {
      const auto r = run_gimforge({command, copy, "-o", dir.file(std::string(command) == "reconstruct" ? "o.ply" : "pv")});
      EXPECT_EQ(r.exit_code, 1) << command << " " << d.attribute << "=" << d.value << ": " << r.err;
      EXPECT_EQ(r.err_lines().size(), 1u) << r.err;
      EXPECT_NE(r.err.find("mcgim/cube"), std::string::npos) << r.err;
      if (d.value == 7) {
        EXPECT_NE(r.err.find("dataset 'chart_stretch' does not have shape (7)"), std::string::npos) << r.err;
      }
    }
  }
  // A mask value of 2 is named as such, not as the zipper row that lists the sample.
  const std::string copy = dir.file("bad_mask.h5");
  fs::copy_file(archive, copy);
  {
    gimforge::io::Archive a = gimforge::io::Archive::open(copy, gimforge::h5::OpenMode::kReadWrite);
    gimforge::h5::Dataset mask = a.root().open_group("mcgim/cube").open_dataset("mask");
    std::vector<std::uint8_t> values = mask.read<std::uint8_t>();
    std::replace(values.begin(), values.end(), std::uint8_t{1}, std::uint8_t{2});
    mask.write(values);
  }
  const auto r = run_gimforge({"reconstruct", copy, "-o", dir.file("o.ply")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("is not 0 or 1"), std::string::npos) << r.err;
  // A defined sample where no mesh lies is refused as such; an undefined one for holding a position at all.
  for (const bool defined : {false, true}) {
    const std::string far = dir.file(defined ? "far_defined.h5" : "far_undefined.h5");
    fs::copy_file(archive, far);
    {
      gimforge::io::Archive a = gimforge::io::Archive::open(far, gimforge::h5::OpenMode::kReadWrite);
      gimforge::h5::Group g = a.root().open_group("mcgim/cube");
      const std::vector<std::uint8_t> mask = g.open_dataset("mask").read<std::uint8_t>();
      const auto at = static_cast<std::size_t>(std::find(mask.begin(), mask.end(), static_cast<std::uint8_t>(defined ? 1 : 0)) - mask.begin());
      ASSERT_LT(at, mask.size());
      gimforge::h5::Dataset geometry = g.open_dataset("geometry");
      std::vector<float> xyz = geometry.read<float>();
      xyz[3 * at] = 3e38f;
      geometry.write(xyz);
    }
    const auto f = run_gimforge({"reconstruct", far, "-o", dir.file("far.ply")});
    EXPECT_EQ(f.exit_code, 1) << f.err;
    EXPECT_NE(f.err.find(defined ? "has a coordinate of magnitude 3e+38, beyond ±1e+18" : "has a position"),
              std::string::npos)
        << f.err;
  }
}

// --optimize (§4.6) in every image method: the fit lowers its energy and a closed input stays closed.
TEST(CliMcgim, OptimizeFitsEveryImageMethodAndKeepsItClosed) {
  TempDir dir;
  gimforge::TriMesh blob = gimforge::make_icosphere(1.0, 3);
  for (gimforge::Vec3& p : blob.positions) p = gimforge::Vec3(1.6 * p.x(), p.y() + 0.3 * p.x() * p.x(), 0.7 * p.z());
  const std::string mesh = dir.file("blob.ply");
  gimforge::io::write_ply(mesh, blob);
  const std::vector<std::vector<std::string>> methods{{"--method", "gim", "--size", "65"},
                                                      {"--method", "sphere", "--n", "16"},
                                                      {"--method", "sphere", "--n", "12", "--domain", "cube"},
                                                      {"--method", "mcgim", "--charts", "6", "--samples", "4096"}};
  for (const auto& method : methods) {
    const std::string archive = dir.file(method[1] + method.back() + ".h5");
    std::vector<std::string> args{"convert", mesh, "--optimize", "--json", "--metric-samples", "20000", "-o", archive};
    args.insert(args.end(), method.begin(), method.end());
    const auto r = run_gimforge(args, 300);
    ASSERT_EQ(r.exit_code, 0) << method.back() << ": " << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    EXPECT_LT(j.at("fit_energy_after").get<double>(), j.at("fit_energy_before").get<double>()) << method.back();
    const std::string ply = dir.file(method[1] + method.back() + ".ply");
    ASSERT_EQ(run_gimforge({"reconstruct", archive, "-o", ply}).exit_code, 0);
    const gimforge::TriMesh t = gimforge::io::read_mesh(ply);
    const gimforge::EdgeTopology topo = gimforge::build_edge_topology(t);
    std::size_t open = 0;
    for (std::size_t e = 0; e < topo.num_edges(); ++e) open += topo.valence(e) != 2 ? 1u : 0u;
    EXPECT_EQ(open, 0u) << method.back() << ": boundary or non-manifold edges after the fit";
  }
}
