// End-to-end tests of image conversions through a decimated proxy (--proxy-faces, jobs/proxy.h): the
// samples land on the full-resolution scan (the image is closer to it than the proxy is), every image
// method takes the option, batch job files take it, relief and bad values are refused; a closed wrap of
// the input (--wrap) lets gim and sphere take meshes of several pieces and holes.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "io/archive.h"
#include "io/batch_archive.h"
#include "io/hdf5.h"
#include "io/mesh_io.h"
#include "kernels/core/procedural.h"
#include "tests/cli/run_process.h"

using gimforge::test::run_gimforge;
using gimforge::test::TempDir;

namespace {

/// A displaced subdivided scan of `base` (synth subdivide): fine detail a coarse proxy cannot hold.
std::string make_scan(const TempDir& dir, const gimforge::TriMesh& base, const std::string& name, const char* segments) {
  const std::string base_path = dir.file(name + "_base.ply"), out = dir.file(name + ".ply");
  gimforge::io::write_ply(base_path, base);
  const auto r = run_gimforge({"synth", "subdivide", base_path, "--segments", segments, "--amplitude", "0.004",
                               "--wavelength", "0.05", "-o", out});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return out;
}

nlohmann::json convert(const std::string& mesh, const std::string& out, std::initializer_list<std::string> extra) {
  std::vector<std::string> args{"convert", mesh, "-o", out, "--metric-samples", "40000", "--json"};
  args.insert(args.end(), extra.begin(), extra.end());
  const auto r = run_gimforge(args, 300);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return r.exit_code == 0 ? nlohmann::json::parse(r.out) : nlohmann::json::object();
}

}  // namespace

TEST(CliProxy, GeometryImageOfAProxyCarriesTheScansDetail) {
  TempDir dir;
  const std::string scan = make_scan(dir, gimforge::make_torus(1.0, 0.4, 48, 24), "torus", "5");  // 57,600 faces
  const nlohmann::json j = convert(scan, dir.file("t.h5"), {"--method", "gim", "--size", "129", "--proxy-faces", "1500"});
  ASSERT_TRUE(j.contains("proxy_faces")) << j.dump();
  EXPECT_LE(j.at("proxy_faces").get<double>(), 1500.0);
  EXPECT_GT(j.at("proxy_faces").get<double>(), 1000.0);
  EXPECT_GT(j.at("transfer_along_normal").get<double>(), 0.9 * 129 * 129);
  // The image, resampled from the scan, is closer to it than the proxy it was parametrized on.
  EXPECT_GT(j.at("psnr").get<double>(), j.at("proxy_psnr").get<double>() + 3.0) << j.dump();
  // It reconstructs, closed (the torus is closed) and in the scan's place.
  const auto rec = run_gimforge({"reconstruct", dir.file("t.h5"), "-o", dir.file("t_rec.ply")});
  ASSERT_EQ(rec.exit_code, 0) << rec.err;
  const auto m = run_gimforge({"metrics", scan, dir.file("t_rec.ply"), "--samples", "40000", "--json"});
  ASSERT_EQ(m.exit_code, 0) << m.err;
  EXPECT_NEAR(nlohmann::json::parse(m.out).at("psnr").get<double>(), j.at("psnr").get<double>(), 1.0);
  // Without the proxy there is none (and auto leaves a 57,600-face input alone).
  for (const char* proxy : {"off", "auto"}) {
    const nlohmann::json whole = convert(scan, dir.file(std::string("w_") + proxy + ".h5"),
                                         {"--method", "gim", "--size", "65", "--proxy-faces", proxy});
    EXPECT_FALSE(whole.contains("proxy_faces")) << proxy;
  }
}

TEST(CliProxy, SphereAndMultiChartImagesTakeAProxyToo) {
  TempDir dir;
  const std::string scan = make_scan(dir, gimforge::make_icosphere(1.0, 3), "ball", "4");  // 20,480 faces
  const nlohmann::json s = convert(scan, dir.file("s.h5"), {"--method", "sphere", "--n", "32", "--proxy-faces", "1200"});
  ASSERT_TRUE(s.contains("proxy_faces")) << s.dump();
  EXPECT_GT(s.at("psnr").get<double>(), s.at("proxy_psnr").get<double>() + 3.0) << s.dump();
  const nlohmann::json m = convert(scan, dir.file("m.h5"),
                                   {"--method", "mcgim", "--samples", "16384", "--charts", "6", "--proxy-faces", "1200"});
  ASSERT_TRUE(m.contains("proxy_faces")) << m.dump();
  EXPECT_GT(m.at("psnr").get<double>(), m.at("proxy_psnr").get<double>() + 3.0) << m.dump();
  for (const char* archive : {"s.h5", "m.h5"})
    EXPECT_EQ(run_gimforge({"reconstruct", dir.file(archive), "-o", dir.file(std::string(archive) + ".ply")}).exit_code, 0);
}

TEST(CliProxy, BatchJobsTakeProxyFacesAndBadValuesAreRefused) {
  TempDir dir;
  const std::string scan = make_scan(dir, gimforge::make_torus(1.0, 0.4, 32, 16), "torus", "4");  // 16,384 faces
  std::filesystem::create_directories(dir.file("in"));
  std::filesystem::copy_file(scan, dir.file("in/torus.ply"));
  std::ofstream(dir.file("job.toml")) << "metric_samples = 20000\n[[collection]]\ninput = \"" << dir.file("in")
                                      << "\"\n[[output]]\nmethod = \"gim\"\nsize = 65\nproxy_faces = 1200\n";
  const auto b = run_gimforge({"batch", "--job", dir.file("job.toml"), "-o", dir.file("b.h5")}, 300);
  ASSERT_EQ(b.exit_code, 0) << b.err;
  const gimforge::io::Archive a = gimforge::io::Archive::open(dir.file("b.h5"));
  const auto summary = gimforge::io::read_batch_summary(dir.file("b.h5"));
  ASSERT_EQ(summary.size(), 1u);
  const auto metrics = a.root().open_group("batch/" + summary[0].output + "/metrics");
  const double faces = metrics.open_dataset("proxy_faces").read<double>().at(0);
  EXPECT_LE(faces, 1200.0);
  EXPECT_GT(faces, 800.0);
  EXPECT_GT(metrics.open_dataset("psnr").read<double>().at(0), metrics.open_dataset("proxy_psnr").read<double>().at(0));

  // Usage errors (exit 2), one line each.
  for (const auto& args : std::vector<std::vector<std::string>>{
           {"convert", scan, "--method", "relief", "--proxy-faces", "2000", "-o", dir.file("r.h5")},
           {"convert", scan, "--proxy-faces", "12", "-o", dir.file("x.h5")},
           {"convert", scan, "--proxy-faces", "many", "-o", dir.file("y.h5")},
           {"convert", scan, "--proxy-faces", "off", "--proxy-bricks", "4", "-o", dir.file("z.h5")}}) {
    const auto r = run_gimforge(args);
    EXPECT_EQ(r.exit_code, 2) << args[3] << ": " << r.err;
    EXPECT_NE(r.err.find("--proxy-faces"), std::string::npos) << r.err;
  }
  std::ofstream(dir.file("bad.toml")) << "[[collection]]\ninput = \"" << dir.file("in")
                                      << "\"\n[[output]]\nmethod = \"relief\"\nproxy_faces = 5000\n";
  const auto bad = run_gimforge({"batch", "--job", dir.file("bad.toml"), "-o", dir.file("bad.h5")});
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("proxy"), std::string::npos) << bad.err;
}

TEST(CliProxy, ALastCutPathPastThePerimeterEndConverts) {
  // This proxy's cut is laid out from a rotation that starts its last cut-path at the perimeter's end
  // (unit 256 of 256): the sideband refused it ("leaves the perimeter") until it stored positions mod 256.
  TempDir dir;
  const std::string base = std::string(GIMFORGE_TEST_DATA_DIR) + "/kitten.ply", scan = dir.file("k3.ply");
  ASSERT_EQ(run_gimforge({"synth", "subdivide", base, "--segments", "3", "-o", scan}).exit_code, 0);
  const nlohmann::json j = convert(scan, dir.file("k.h5"), {"--method", "gim", "--size", "65", "--proxy-faces", "1500"});
  EXPECT_GT(j.value("psnr", 0.0), 50.0) << j.dump();
  const auto rec = run_gimforge({"reconstruct", dir.file("k.h5"), "-o", dir.file("k.ply")});
  ASSERT_EQ(rec.exit_code, 0) << rec.err;
  const auto info = run_gimforge({"info", dir.file("k.ply"), "--json"});
  ASSERT_EQ(info.exit_code, 0) << info.err;
  const nlohmann::json t = nlohmann::json::parse(info.out);
  EXPECT_TRUE(t.at("closed").get<bool>()) << info.out;
}

TEST(CliProxy, ColoursComeFromTheFullSurface) {
  // The proxy has no colours; the image takes them from the input at the moved samples.
  TempDir dir;
  gimforge::TriMesh t = gimforge::make_torus(1.0, 0.4, 240, 120);  // 57,600 faces
  for (const gimforge::Vec3& p : t.positions)
    t.colors.emplace_back(static_cast<float>(0.5 + 0.3 * p.x()), static_cast<float>(0.5 + 0.3 * p.y()), 0.25f);
  const std::string mesh = dir.file("coloured.ply");
  gimforge::io::write_ply(mesh, t);
  const nlohmann::json j = convert(mesh, dir.file("c.h5"), {"--method", "gim", "--size", "65", "--proxy-faces", "1500"});
  ASSERT_TRUE(j.contains("proxy_faces")) << j.dump();
  const gimforge::io::Archive a = gimforge::io::Archive::open(dir.file("c.h5"));
  const auto group = a.root().open_group("gim/coloured");
  const std::vector<float> colours = group.open_dataset("colors").read<float>();
  const std::vector<float> geometry = group.open_dataset("geometry").read<float>();
  ASSERT_EQ(colours.size(), geometry.size());
  for (std::size_t i = 0; i < colours.size(); i += 3) {  // red follows x, green y (within the interpolation)
    EXPECT_NEAR(static_cast<double>(colours[i]), 0.5 + 0.3 * (static_cast<double>(geometry[i]) + j.at("frame_origin_x").get<double>()), 0.02) << i;
    EXPECT_NEAR(static_cast<double>(colours[i + 2]), 0.25, 0.003) << i;  // 8-bit in the PLY
  }
}

TEST(CliProxy, AWrapLetsSingleChartMethodsTakeMeshesOfPiecesAndHoles) {
  // A sphere with 732 one-face holes, and a small ball far from it: gim refuses it (two components), and
  // names --wrap; with --wrap the image is made from the closed wrap of the sphere, the ball is left out (a
  // warning says so) and the samples lie on the holed sphere.
  TempDir dir;
  gimforge::TriMesh holed = gimforge::make_icosphere(1.0, 4);
  std::vector<gimforge::Face> kept;
  for (std::size_t f = 0; f < holed.faces.size(); ++f)
    if (f % 7 != 3) kept.push_back(holed.faces[f]);
  holed.faces = kept;
  gimforge::TriMesh ball = gimforge::make_icosphere(0.25, 2);  // 8 voxels across at --wrap 64
  for (gimforge::Vec3& p : ball.positions) p += gimforge::Vec3(3.0, 0.0, 0.0);
  const std::string mesh = dir.file("pieces.ply");
  gimforge::io::write_ply(mesh, gimforge::concatenate(holed, ball));
  const auto refused = run_gimforge({"convert", mesh, "--method", "gim", "--size", "65", "-o", dir.file("r.h5")});
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.err.find("--wrap 512"), std::string::npos) << refused.err;

  for (const char* method : {"gim", "sphere"}) {
    const std::string out = dir.file(std::string(method) + ".h5");
    const auto r = run_gimforge({"convert", mesh, "--method", method, "--wrap", "64", "--metric-samples", "40000",
                                 "--json", "-o", out}, 300);
    ASSERT_EQ(r.exit_code, 0) << method << ": " << r.err;
    EXPECT_NE(r.err.find("left out"), std::string::npos) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j.at("wrap_resolution").get<double>(), 64.0);
    EXPECT_EQ(j.at("wrap_closing").get<double>(), 1.0);
    EXPECT_EQ(j.at("wrap_dropped_components").get<double>(), 1.0);
    EXPECT_GT(j.at("wrap_faces").get<double>(), 0.0);
    EXPECT_GT(j.at("proxy_faces").get<double>(), 0.0);
    // The fidelity counts the ball left out (6 % of the area, 2 units away): 22.8 dB. The samples were moved
    // onto the input: the image lies on the sphere (below).
    EXPECT_GT(j.at("psnr").get<double>(), 20.0) << j.dump();
    EXPECT_LT(j.at("psnr").get<double>(), 26.0) << j.dump();
    const auto rec = run_gimforge({"reconstruct", out, "-o", dir.file(std::string(method) + ".ply")});
    ASSERT_EQ(rec.exit_code, 0) << rec.err;
    const gimforge::TriMesh image = gimforge::io::read_mesh(dir.file(std::string(method) + ".ply"));
    double worst = 0.0;
    for (const gimforge::Vec3& p : image.positions) worst = std::max(worst, std::abs(p.norm() - 1.0));
    EXPECT_LT(worst, 0.01) << method;
    const auto info = run_gimforge({"info", dir.file(std::string(method) + ".ply"), "--json"});
    ASSERT_EQ(info.exit_code, 0) << info.err;
    EXPECT_TRUE(nlohmann::json::parse(info.out).at("closed").get<bool>()) << method << info.out;
  }
  // A batch output takes it too (named gim_65_wrap by default).
  std::filesystem::create_directories(dir.file("in"));
  std::filesystem::copy_file(mesh, dir.file("in/pieces.ply"));
  std::ofstream(dir.file("job.toml")) << "metric_samples = 20000\n[[collection]]\ninput = \"" << dir.file("in")
                                      << "\"\n[[output]]\nmethod = \"gim\"\nsize = 65\nwrap = 64\n";
  const auto b = run_gimforge({"batch", "--job", dir.file("job.toml"), "-o", dir.file("b.h5")}, 300);
  ASSERT_EQ(b.exit_code, 0) << b.err;
  const auto summary = gimforge::io::read_batch_summary(dir.file("b.h5"));
  ASSERT_EQ(summary.size(), 1u);
  EXPECT_EQ(summary[0].output, "gim_65_wrap");
  const gimforge::io::Archive a = gimforge::io::Archive::open(dir.file("b.h5"));
  EXPECT_EQ(a.root().open_group("batch/gim_65_wrap/metrics").open_dataset("wrap_resolution").read<double>().at(0), 64.0);
  // Usage errors (exit 2) naming --wrap.
  for (const auto& args : std::vector<std::vector<std::string>>{
           {"convert", mesh, "--method", "relief", "--wrap", "64", "-o", dir.file("x1.h5")},
           {"convert", mesh, "--wrap", "8", "-o", dir.file("x2.h5")},
           {"convert", mesh, "--wrap", "64:x", "-o", dir.file("x3.h5")},
           {"convert", mesh, "--wrap", "64:17", "-o", dir.file("x4.h5")},
           {"convert", mesh, "--wrap", "64", "--proxy-faces", "off", "-o", dir.file("x5.h5")}}) {
    const auto r = run_gimforge(args);
    EXPECT_EQ(r.exit_code, 2) << args[3] << " " << args[4] << ": " << r.err;
    EXPECT_NE(r.err.find("--wrap"), std::string::npos) << r.err;
  }
}
