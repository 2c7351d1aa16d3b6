// End-to-end tests of the gimforge executable: exit codes, --help/--version, JSON output of info and
// metrics on committed meshes and procedural ones written to a temporary directory.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>

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
  // batch takes its meshes by option: a folder given as a word gets the hint; an unknown option stays CLI11's.
  const auto stray = run_gimforge({"batch", "models", "--size", "65", "-o", "never.h5"});
  EXPECT_EQ(stray.exit_code, 2);
  EXPECT_NE(stray.err.find("models: batch takes no positional argument: give the meshes with --input DIR"), std::string::npos)
      << stray.err;
  const auto unknown = run_gimforge({"batch", "--input", kData, "--bogus", "-o", "never.h5"});
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_NE(unknown.err.find("not expected: --bogus"), std::string::npos) << unknown.err;
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

TEST(Cli, MetricsTextCountsTheVerticesItAdded) {
  // --no-vertices left them out but the summary still said "plus vertices".
  const auto with = run_gimforge({"metrics", kData + "/fist.ply", kData + "/fist.ply", "--samples", "1000"});
  EXPECT_NE(with.out.find("1000 + 1000 area samples, plus 2394 vertices)"), std::string::npos) << with.out;
  const auto without =
      run_gimforge({"metrics", kData + "/fist.ply", kData + "/fist.ply", "--samples", "1000", "--no-vertices"});
  EXPECT_NE(without.out.find("1000 + 1000 area samples)"), std::string::npos) << without.out;
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
  // --json: a failed file is an object {"file", "error"} on stdout, alone as in a list (a single failed file
  // once printed nothing to parse).
  r = run_gimforge({"validate", kData + "/does-not-exist.ply", "--json"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err_lines().size(), 1u) << r.err;
  const auto alone = nlohmann::json::parse(r.out);
  EXPECT_EQ(alone["file"], kData + "/does-not-exist.ply");
  EXPECT_NE(alone["error"].get<std::string>().find("does not exist"), std::string::npos) << r.out;
  r = run_gimforge({"validate", kData + "/does-not-exist.ply", kData + "/fist.ply", "--json"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(nlohmann::json::parse(r.out).at(0), alone);
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
    EXPECT_FALSE(entry.path().filename().string().ends_with(".tmp")) << "left behind: " << entry.path();
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
  EXPECT_NE(r.err.find("--method relief"), std::string::npos) << "points to what converts it: " << r.err;
  EXPECT_NE(r.err.find("--method mcgim"), std::string::npos) << "points to what converts it: " << r.err;
  EXPECT_FALSE(fs::exists(dir.file("o.h5"))) << "no archive is left behind for a refused mesh";
  r = run_gimforge({"convert", kData + "/kitten.ply", "--size", "100", "-o", dir.file("o.h5")});
  EXPECT_EQ(r.exit_code, 2) << "a usage error";
  EXPECT_NE(r.err.find("multiple of 64"), std::string::npos) << r.err;
  r = run_gimforge({"reconstruct", dir.file("missing.h5"), "-o", dir.file("m.ply")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("missing.h5"), std::string::npos) << r.err;
}

namespace {

/// Reads the first bytes of a file and checks the PNG signature.
bool is_png(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[8] = {};
  in.read(magic, 8);
  return in.gcount() == 8 && std::string(magic + 1, 3) == "PNG";
}

/// Expected layout of a spherical image at tessellation n: faces, width, height, and the distinct domain
/// points (= vertices of the closed reconstruction), per docs/archive.md.
struct SphereLayout {
  int faces, width, height, points;
};
SphereLayout sphere_layout(const std::string& domain, int n) {
  if (domain == "tetra") return {1, 2 * n, n + 1, 2 * n * n + 2};
  if (domain == "cube") return {6, n + 1, n + 1, 6 * n * n + 2};
  return {1, 2 * n + 1, 2 * n + 1, 4 * n * n + 2};  // octa, flat-octa
}

/// Runs `info --json` on a reconstruction and checks it is one closed, manifold genus-0 surface with
/// `vertices` vertices.
void expect_closed_sphere(const std::string& mesh, int vertices, const std::string& what) {
  const auto info = run_json({"info", mesh, "--json"});
  EXPECT_EQ(info["closed"], true) << what;
  EXPECT_EQ(info["manifold"], true) << what;
  EXPECT_EQ(info["components"], 1) << what;
  EXPECT_EQ(info["genus"], nlohmann::json::array({0})) << what;
  EXPECT_EQ(info["vertices"], vertices) << what;
}

}  // namespace

TEST(CliSphere, ConvertReconstructPreviewEveryDomain) {
  TempDir dir;
  const std::string archive = dir.file("sphere.h5");
  for (const std::string domain : {"octa", "tetra", "cube", "flat-octa"}) {
    const std::string name = "fist_" + domain;
    auto r = run_gimforge({"convert", kData + "/fist.ply", "--method", "sphere", "--domain", domain, "--n", "16",
                           "--metric-samples", "20000", "-o", archive, "--name", name, "--json"}, 300);
    ASSERT_EQ(r.exit_code, 0) << domain << ": " << r.err;
    const auto j = nlohmann::json::parse(r.out);
    const SphereLayout layout = sphere_layout(domain, 16);
    EXPECT_EQ(j["name"], name);
    EXPECT_EQ(j["method"], "sphere");
    EXPECT_EQ(j["domain"], domain);
    EXPECT_EQ(j["n"], 16);
    EXPECT_EQ(j["faces"], layout.faces) << domain;
    EXPECT_EQ(j["width"], layout.width) << domain;
    EXPECT_EQ(j["height"], layout.height) << domain;
    EXPECT_EQ(j["flipped_triangles"], 0.0) << domain << ": the sphere map must be an embedding";
    EXPECT_EQ(j["holes_filled"], 0.0) << domain << ": fist.ply is closed";
    EXPECT_EQ(j["masked_samples"], 0.0) << domain;
    for (const char* key : {"map_efficiency", "domain_efficiency", "efficiency_domain_to_mesh"}) {
      EXPECT_GT(j[key].get<double>(), 0.5) << domain << " " << key;
      EXPECT_LE(j[key].get<double>(), 1.0) << domain << " " << key;
    }
    EXPECT_GT(j["psnr"].get<double>(), 40.0) << domain;
    for (const char* key :
         {"seconds_simplify", "seconds_optimize", "seconds_sample", "seconds_metric", "seconds_total"})
      EXPECT_GE(j[key].get<double>(), 0.0) << key;

    // Level 0 (n = 16) and the last level (n = 1) reconstruct closed, with one vertex per domain point.
    const std::string mesh0 = dir.file(name + "_0.ply");
    r = run_gimforge({"reconstruct", archive, "--name", name, "--level", "0", "-o", mesh0});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    expect_closed_sphere(mesh0, layout.points, domain + " level 0");
    const std::string mesh4 = dir.file(name + "_4.ply");
    r = run_gimforge({"reconstruct", archive, "--name", "spherical/" + name, "--level", "4", "-o", mesh4});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    expect_closed_sphere(mesh4, sphere_layout(domain, 1).points, domain + " level 4");
    r = run_gimforge({"reconstruct", archive, "--name", name, "--level", "5", "-o", dir.file("bad.ply")});
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.err.find("level 5 is out of range: n = 16 has levels 0..4"), std::string::npos) << r.err;

    r = run_gimforge({"preview", archive, "--name", name, "-o", dir.file("png")});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(is_png(dir.file("png/" + name + "_sphere_geometry.png"))) << domain;
    EXPECT_TRUE(is_png(dir.file("png/" + name + "_sphere_mask.png"))) << domain;
  }
  for (const auto& entry : fs::directory_iterator(fs::path(archive).parent_path()))
    EXPECT_FALSE(entry.path().filename().string().ends_with(".tmp")) << "left behind: " << entry.path();
}

TEST(CliSphere, StoredSphereMapIsResampledWithoutOptimizing) {
  TempDir dir;
  const std::string archive = dir.file("sphere.h5");
  const auto first = run_json({"convert", kData + "/cathead.ply", "--method", "sphere", "--n", "8",
                               "--metric-samples", "20000", "-o", archive, "--json"});
  EXPECT_GT(first["vertex_splits"].get<double>(), 0.0);
  // The same map into the cube: no optimization, same S->M efficiency, the hole still masked.
  const auto again = run_json({"convert", kData + "/cathead.ply", "--method", "sphere", "--domain", "cube", "--n", "8",
                               "--sphere-map", archive + ":cathead", "--name", "cube", "--metric-samples", "20000",
                               "-o", archive, "--json"});
  EXPECT_EQ(again["vertex_splits"].get<double>(), 0.0);
  EXPECT_DOUBLE_EQ(again["map_efficiency"].get<double>(), first["map_efficiency"].get<double>());
  EXPECT_EQ(again["holes_filled"].get<double>(), 1.0);
  EXPECT_GT(again["masked_samples"].get<double>(), 0.0);
  // Another mesh is refused, naming both.
  const auto r = run_gimforge({"convert", kData + "/fist.ply", "--method", "sphere", "--sphere-map",
                               archive + ":cathead", "-o", archive});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("fist.ply"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("131 vertices"), std::string::npos) << r.err;
  // --sphere-map belongs to --method sphere.
  EXPECT_EQ(run_gimforge({"convert", kData + "/fist.ply", "--sphere-map", archive, "-o", dir.file("g.h5")}).exit_code, 2);
  // The stored map converts as the run that stored it did, to the last bit: a map normalized once more on
  // reading measured the start grid of adaptive sampling differently in the last digits, and 12 rounds of moves
  // drifted 0.26 dB apart.
  const std::vector<std::string> adaptive{"convert", kData + "/fist.ply", "--method", "sphere", "--domain", "flat-octa",
                                          "--n", "16", "--sampling", "adaptive", "--adapt-rounds", "0", "--no-metric",
                                          "--json"};
  std::vector<std::string> direct = adaptive, stored = adaptive;
  direct.insert(direct.end(), {"-o", dir.file("direct.h5")});
  stored.insert(stored.end(), {"--sphere-map", dir.file("direct.h5"), "-o", dir.file("stored.h5")});
  const double start = run_json(direct)["adapt_rms_before"].get<double>();
  EXPECT_EQ(run_json(stored)["adapt_rms_before"].get<double>(), start);
  const auto geometry = [](const std::string& path) {
    return gimforge::io::Archive::open(path).root().open_dataset("spherical/fist/geometry").read<float>();
  };
  EXPECT_EQ(geometry(dir.file("direct.h5")), geometry(dir.file("stored.h5")));
}

TEST(CliSphere, HolesAreFilledMaskedAndLeftOpen) {
  TempDir dir;
  const std::string archive = dir.file("cat.h5");
  auto r = run_gimforge({"convert", kData + "/cathead.ply", "--method", "sphere", "--n", "16", "--metric-samples",
                         "20000", "-o", archive, "--json"}, 300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["domain"], "octa") << "the default domain";
  EXPECT_EQ(j["holes_filled"], 1.0) << "cathead.ply has one boundary loop";
  EXPECT_GT(j["hole_faces"].get<double>(), 0.0);
  EXPECT_GT(j["masked_samples"].get<double>(), 0.0) << "samples in the filled hole are undefined";
  EXPECT_LT(j["masked_samples"].get<double>(), 33.0 * 33.0 / 2);
  // The only image of the archive needs no --name; the hole stays open in the reconstruction.
  r = run_gimforge({"reconstruct", archive, "-o", dir.file("cat.ply")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto info = run_json({"info", dir.file("cat.ply"), "--json"});
  EXPECT_EQ(info["boundary_loops"], 1);
  EXPECT_EQ(info["closed"], false);
  EXPECT_EQ(info["genus"], nlohmann::json::array({0}));
  r = run_gimforge({"reconstruct", archive, "--no-fuse", "-o", dir.file("x.ply")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("--no-fuse applies to geometry images and multi-chart geometry images only"), std::string::npos) << r.err;
  r = run_gimforge({"preview", archive, "-o", dir.file("png")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(is_png(dir.file("png/cathead_sphere_geometry.png")));
  EXPECT_TRUE(is_png(dir.file("png/cathead_sphere_mask.png")));
}

TEST(CliSphere, GeometryAndSphericalImagesShareAnArchive) {
  TempDir dir;
  const std::string archive = dir.file("both.h5");
  auto r = run_gimforge({"convert", kData + "/fist.ply", "--method", "sphere", "--domain", "tetra", "--n", "8",
                         "--metric-samples", "20000", "-o", archive});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find(":/spherical/fist\n"), std::string::npos) << r.out;
  for (const char* line : {"spherical image  tetra, n = 8: 16x9 samples", "holes            none", "S->M", "D->S",
                           "D->M", "PSNR", "simplify", "optimize", "sample", "metric", "total"})
    EXPECT_NE(r.out.find(line), std::string::npos) << line << " in\n" << r.out;
  // The same spherical name twice is refused before any work; a geometry image may share it.
  r = run_gimforge({"convert", kData + "/fist.ply", "--method", "sphere", "--n", "4", "-o", archive});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("already holds a spherical geometry image 'fist'"), std::string::npos) << r.err;
  r = run_gimforge({"convert", kData + "/fist.ply", "--size", "65", "--normal-size", "64", "--metric-samples", "20000",
                    "-o", archive});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // Two images: commands must be told which; a plain name held by both kinds must be qualified.
  r = run_gimforge({"reconstruct", archive, "-o", dir.file("x.ply")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("holds 2 images (gim/fist, spherical/fist); choose one with --name"), std::string::npos)
      << r.err;
  r = run_gimforge({"preview", archive, "--name", "fist", "-o", dir.file("png")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("--name gim/fist or --name spherical/fist"), std::string::npos) << r.err;
  r = run_gimforge({"reconstruct", archive, "--name", "spherical/cat", "-o", dir.file("x.ply")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("no spherical geometry image 'cat'"), std::string::npos) << r.err;
  r = run_gimforge({"reconstruct", archive, "--name", "spherical/fist", "--level", "3", "-o", dir.file("s.ply")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_closed_sphere(dir.file("s.ply"), sphere_layout("tetra", 1).points, "tetra n = 1");
  r = run_gimforge({"reconstruct", archive, "--name", "gim/fist", "-o", dir.file("g.ply")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_gimforge({"preview", archive, "--name", "gim/fist", "-o", dir.file("png")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(is_png(dir.file("png/fist_geometry.png")));
}

TEST(CliSphere, ACollapsedMapIsAnErrorNotAnArchive) {
  // A closed cylinder 10^5 times longer than wide: its sphere map collapsed (S->M efficiency ~1e-8, all
  // samples at one end) and the archive held a 10 dB surface with exit 0.
  TempDir dir;
  gimforge::TriMesh m;
  constexpr std::uint32_t kAround = 8, kAlong = 40;
  for (std::uint32_t j = 0; j <= kAlong; ++j)
    for (std::uint32_t i = 0; i < kAround; ++i) {
      const double a = 2.0 * M_PI * i / kAround;
      m.positions.emplace_back(0.5 * std::cos(a), 0.5 * std::sin(a), 1e5 * j / kAlong);
    }
  const auto bottom = static_cast<std::uint32_t>(m.positions.size());
  m.positions.emplace_back(0.0, 0.0, 0.0);
  m.positions.emplace_back(0.0, 0.0, 1e5);
  for (std::uint32_t j = 0; j < kAlong; ++j)
    for (std::uint32_t i = 0; i < kAround; ++i) {
      const std::uint32_t p = j * kAround + i, q = j * kAround + (i + 1) % kAround;
      m.faces.push_back({p, q, q + kAround});
      m.faces.push_back({p, q + kAround, p + kAround});
    }
  for (std::uint32_t i = 0; i < kAround; ++i) {
    m.faces.push_back({bottom, (i + 1) % kAround, i});
    m.faces.push_back({bottom + 1, kAlong * kAround + i, kAlong * kAround + (i + 1) % kAround});
  }
  gimforge::io::write_ply(dir.file("needle.ply"), m);
  const auto r = run_gimforge({"convert", dir.file("needle.ply"), "--method", "sphere", "--n", "16", "--no-metric", "-o",
                               dir.file("n.h5")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
  EXPECT_NE(r.err.find("needle.ply: spherical parametrization: the map collapsed"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir.file("n.h5")));
}

TEST(CliSphere, APoorMapIsKeptWithAWarningThatNamesTheOtherMethods) {
  // A 1 x 1 x 1e-3 box: its map's efficiency is above the collapse refusal (1e-4) and below 0.02; a probe's
  // 1 x 1 x 1e-4 box (7e-4) gave 23 dB, gim 68, without a word.
  TempDir dir;
  gimforge::TriMesh box;
  for (int k = 0; k < 8; ++k) box.positions.emplace_back(k & 1, (k >> 1) & 1, (k >> 2 & 1) * 1e-3);
  box.faces = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
               {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  gimforge::io::write_ply(dir.file("box.ply"), box);
  const auto r = run_gimforge({"convert", dir.file("box.ply"), "--method", "sphere", "--n", "16", "--no-metric", "-o",
                               dir.file("b.h5")});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("box.ply: the sphere map's stretch efficiency is"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("suits --method gim, mcgim or relief better"), std::string::npos) << r.err;
}

TEST(CliSphere, RefusesOtherGenusAndMisplacedOptions) {
  TempDir dir;
  gimforge::io::write_ply(dir.file("torus.ply"), gimforge::make_torus(1.0, 0.35, 24, 12));
  auto r = run_gimforge({"convert", dir.file("torus.ply"), "--method", "sphere", "--n", "8", "-o", dir.file("t.h5")});
  EXPECT_NE(r.exit_code, 0);
  ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
  EXPECT_NE(r.err.find("torus.ply"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("genus 1"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("gim"), std::string::npos) << "the message points to the geometry-image method: " << r.err;
  EXPECT_FALSE(fs::exists(dir.file("t.h5"))) << "no archive is left behind for a refused mesh";

  const std::string fist = kData + "/fist.ply";
  const std::string out = dir.file("o.h5");
  r = run_gimforge({"convert", fist, "--method", "sphere", "--domain", "dodeca", "-o", out});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--domain: dodeca not in {octa,tetra,cube,flat-octa}"), std::string::npos) << r.err;
  r = run_gimforge({"convert", fist, "--domain", "cube", "-o", out});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--domain: applies to --method sphere only"), std::string::npos) << r.err;
  r = run_gimforge({"convert", fist, "--method", "gim", "--n", "16", "-o", out});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--n: applies to --method sphere only"), std::string::npos) << r.err;
  r = run_gimforge({"convert", fist, "--method", "sphere", "--size", "65", "-o", out});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--size: applies to --method gim only"), std::string::npos) << r.err;
  for (const char* n : {"0", "4097", "-3"}) {
    r = run_gimforge({"convert", fist, "--method", "sphere", "--n", n, "-o", out});
    EXPECT_EQ(r.exit_code, 2) << "--n " << n;
  }
  EXPECT_FALSE(fs::exists(out));
  r = run_gimforge({"convert", "--help"});
  EXPECT_EQ(r.exit_code, 0);
  for (const char* text : {"--method", "sphere", "--domain", "flat-octa", "--n", "Praun"})
    EXPECT_NE(r.out.find(text), std::string::npos) << text;
}

// Integer options are decimal: CLI11 alone read "0101" as octal 65 and "0x4" as 4.
TEST(Cli, IntegerOptionsAreDecimalOnly) {
  TempDir dir;
  for (const std::vector<std::string>& args : std::vector<std::vector<std::string>>{
           {"convert", kData + "/fist.ply", "--size", "0101", "-o", dir.file("a.h5")},
           {"convert", kData + "/fist.ply", "--proxy-bricks", "0x4", "-o", dir.file("b.h5")},
           {"-j", "01", "info", kData + "/fist.ply"}}) {
    const auto r = run_gimforge(args);
    EXPECT_EQ(r.exit_code, 2) << args[args.size() > 3 ? 3 : 1];
    EXPECT_NE(r.err.find("is not a decimal integer"), std::string::npos) << r.err;
  }
  EXPECT_EQ(run_gimforge({"-j", "1", "info", kData + "/fist.ply"}).exit_code, 0);
  // The global options after the command too (batch's help says "unless -j is given"; `batch -j 1` was refused).
  EXPECT_EQ(run_gimforge({"info", "-j", "1", "-q", kData + "/fist.ply"}).exit_code, 0);
  EXPECT_EQ(run_gimforge({"info", "-j", "07", kData + "/fist.ply"}).exit_code, 2);
  EXPECT_EQ(run_gimforge({"batch", "-j", "07", "--input", kData, "-o", dir.file("j.h5")}).exit_code, 2);
  // Counts given as text (auto or K) are decimal too; unsigned options refuse a sign instead of wrapping
  // (--bytes -5 was 2^64 - 5: no budget at all).
  for (const std::vector<std::string>& args : std::vector<std::vector<std::string>>{
           {"convert", kData + "/fist.ply", "--method", "mcgim", "--charts", "08", "-o", dir.file("c.h5")},
           {"convert", kData + "/fist.ply", "--method", "relief", "--grid", "010", "-o", dir.file("d.h5")},
           {"compress", dir.file("none.h5"), "--bytes", "-5", "-o", dir.file("e.h5")},
           {"batch", "--input", kData, "--codec", "j2k", "--rate", "-1", "-o", dir.file("f.h5")},
           {"convert", kData + "/fist.ply", "--metric-samples", "4294967296", "-o", dir.file("g.h5")},
           // Real numbers must be finite: CLI11's ranges let "nan" through (it then exited 1, or ran).
           {"batch", "--input", kData, "--item-timeout", "nan", "-o", dir.file("k.h5")},
           {"render", dir.file("none.h5"), "--fov", "nan", "-o", dir.file("l.png")},
           {"synth", "terrain", "--faces", "2000", "--offset", "1e400,0,0", "-o", dir.file("m.ply")},
           // A label that names, archives and logs cannot hold (it was exit 1 once the batch began).
           {"batch", "--input", kData, "--label", "a\nb", "-o", dir.file("n.h5")}}) {
    const auto r = run_gimforge(args);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_FALSE(fs::exists(args.back())) << args.back();
  }
  // Values beyond 64 bits were saturated (--rate 10^23 named an output gim_65_j2k18446744073709551615), and
  // an empty --name compressed every item.
  for (const std::vector<std::string>& args : std::vector<std::vector<std::string>>{
           {"batch", "--input", kData, "--codec", "j2k", "--rate", "99999999999999999999999", "-o", dir.file("h.h5")},
           {"compress", dir.file("none.h5"), "--bytes", "18446744073709551616", "-o", dir.file("i.h5")},
           {"compress", dir.file("none.h5"), "--name", "", "-o", dir.file("j.h5")}}) {
    const auto r = run_gimforge(args);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_TRUE(r.err.find("out of range") != std::string::npos || r.err.find("not in range") != std::string::npos ||
                r.err.find("empty name") != std::string::npos)
        << r.err;
    EXPECT_FALSE(fs::exists(args.back())) << args.back();
  }
}
