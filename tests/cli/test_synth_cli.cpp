// End-to-end tests of `gimforge synth`: a subdivided scan and a terrain written, read back and measured;
// the same seed gives the same bytes; bad options are usage errors; an unwritable output is one error line.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "io/mesh_io.h"
#include "kernels/core/procedural.h"
#include "kernels/core/topology.h"
#include "tests/cli/run_process.h"

namespace fs = std::filesystem;
using gimforge::test::run_gimforge;
using gimforge::test::TempDir;

namespace {

std::string bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream all;
  all << in.rdbuf();
  return all.str();
}

}  // namespace

TEST(CliSynth, SubdivideReachesTheFaceTargetAndStaysClosed) {
  TempDir dir;
  const std::string base = dir.file("torus.ply"), out = dir.file("s.ply");
  gimforge::io::write_ply(base, gimforge::make_torus(1.0, 0.35, 24, 12));  // 576 faces
  const auto r = run_gimforge({"synth", "subdivide", base, "--faces", "5000", "--json", "-o", out});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j.at("segments").get<int>(), 3);  // 576 · 3² = 5184 ≥ 5000 > 576 · 2²
  EXPECT_EQ(j.at("faces").get<std::uint64_t>(), 5184u);
  const gimforge::TriMesh m = gimforge::io::read_mesh(out);
  EXPECT_EQ(m.faces.size(), 5184u);
  const gimforge::TopologyReport t = gimforge::analyze_topology(m);
  EXPECT_TRUE(t.closed);
  EXPECT_TRUE(t.manifold);
  EXPECT_EQ(t.euler_characteristic, 0);
  // The displaced scan is close to, but not on, the base surface.
  const auto metrics = run_gimforge({"metrics", base, out, "--samples", "20000", "--json"});
  ASSERT_EQ(metrics.exit_code, 0) << metrics.err;
  const double psnr = nlohmann::json::parse(metrics.out).at("psnr").get<double>();
  EXPECT_GT(psnr, 40.0);
  EXPECT_LT(psnr, 80.0);
}

TEST(CliSynth, TerrainIsReproducibleAndGeoreferenced) {
  TempDir dir;
  const std::string a = dir.file("a.ply"), b = dir.file("b.ply"), c = dir.file("c.ply");
  for (const std::string& out : {a, b})
    ASSERT_EQ(run_gimforge({"synth", "terrain", "--grid", "60,40", "--offset", "500000,4100000,250", "-o", out}).exit_code, 0);
  EXPECT_EQ(bytes_of(a), bytes_of(b));
  ASSERT_EQ(run_gimforge({"synth", "terrain", "--grid", "60,40", "--seed", "7", "-o", c}).exit_code, 0);
  const gimforge::TriMesh m = gimforge::io::read_mesh(a);
  EXPECT_GE(m.positions.front().x(), 500000.0);
  EXPECT_GE(m.positions.front().y(), 4100000.0);
  const gimforge::TopologyReport t = gimforge::analyze_topology(m);
  EXPECT_FALSE(t.closed);
  EXPECT_TRUE(t.manifold);
  EXPECT_GT(t.boundary_loops, 1u);
  EXPECT_NE(gimforge::io::read_mesh(c).faces.size() + gimforge::io::read_mesh(c).positions.size(),
            m.faces.size() + m.positions.size());  // other holes
}

TEST(CliSynth, TerrainHolesNeverPinchAVertex) {
  // Holes that met, or cut single triangles, used to leave vertices where two fans of faces touch.
  TempDir dir;
  for (const auto& [grid, seed] : {std::pair{"10", "1"}, std::pair{"20", "5"}, std::pair{"200", "5"}, std::pair{"64", "9"}}) {
    const std::string out = dir.file(std::string("t") + grid + "_" + seed + ".ply");
    ASSERT_EQ(run_gimforge({"synth", "terrain", "--grid", grid, "--seed", seed, "--holes", "40", "--hole-radius", "0.06", "-o", out}).exit_code, 0);
    const gimforge::TopologyReport t = gimforge::analyze_topology(gimforge::io::read_mesh(out));
    EXPECT_TRUE(t.manifold) << grid << " " << seed << ": " << t.nonmanifold_vertices << " non-manifold vertices";
    EXPECT_EQ(t.referenced_vertices, t.vertices);
  }
}

TEST(CliSynth, BadOptionsAndOutputs) {
  TempDir dir;
  const std::string base = dir.file("ball.ply");
  gimforge::io::write_ply(base, gimforge::make_icosphere(1.0, 1));
  // Usage errors: exit 2.
  EXPECT_EQ(run_gimforge({"synth"}).exit_code, 2);
  EXPECT_EQ(run_gimforge({"synth", "subdivide", base, "--segments", "0", "-o", dir.file("x.ply")}).exit_code, 2);
  EXPECT_EQ(run_gimforge({"synth", "subdivide", base, "--segments", "2", "--faces", "100", "-o", dir.file("x.ply")}).exit_code, 2);
  EXPECT_EQ(run_gimforge({"synth", "terrain", "--grid", "10", "--offset", "1,2", "-o", dir.file("x.ply")}).exit_code, 2);
  EXPECT_EQ(run_gimforge({"synth", "terrain", "--grid", "10", "--spacing", "-1", "-o", dir.file("x.ply")}).exit_code, 2);
  // An offset no reader takes back (the file was written, then every command refused it).
  const auto far = run_gimforge({"synth", "terrain", "--grid", "10", "--offset", "1e300,0,0", "-o", dir.file("far.ply")});
  EXPECT_EQ(far.exit_code, 1);
  EXPECT_NE(far.err.find("--offset 1e+300 is beyond ±1e+18"), std::string::npos) << far.err;
  EXPECT_FALSE(fs::exists(dir.file("far.ply")));
  EXPECT_EQ(run_gimforge({"synth", "subdivide", base, "--amplitude", "1e300", "-o", dir.file("x.ply")}).exit_code, 2);
  EXPECT_EQ(run_gimforge({"synth", "terrain", "--grid", "10", "--seed", "-1", "-o", dir.file("x.ply")}).exit_code, 2);
  const auto none = run_gimforge({"synth", "terrain", "-o", dir.file("x.ply")});
  EXPECT_EQ(none.exit_code, 2);
  EXPECT_NE(none.err.find("--grid"), std::string::npos) << none.err;
  // Errors: exit 1, one line naming the cause, no file.
  const auto empty = run_gimforge({"synth", "terrain", "--grid", "1", "--holes", "1", "--hole-radius", "0.5", "-o", dir.file("x.ply")});
  EXPECT_EQ(empty.exit_code, 1);
  EXPECT_NE(empty.err.find("remove every face"), std::string::npos) << empty.err;
  const auto obj = run_gimforge({"synth", "terrain", "--grid", "5", "-o", dir.file("x.obj")});
  EXPECT_EQ(obj.exit_code, 1);
  EXPECT_NE(obj.err.find(".ply"), std::string::npos) << obj.err;
  // A pipe (or device) as the output would be replaced by the renamed file: refused, and left alone.
  const std::string fifo = dir.file("pipe.ply");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const auto special = run_gimforge({"synth", "terrain", "--grid", "5", "-o", fifo});
  EXPECT_EQ(special.exit_code, 1);
  EXPECT_NE(special.err.find("not a regular file"), std::string::npos) << special.err;
  EXPECT_TRUE(fs::is_fifo(fifo));
  // The base mesh as the output, by name or through a link, would be replaced: refused, and left alone.
  const std::string link = dir.file("link.ply");
  fs::create_symlink(base, link);
  for (const std::string& out : {base, link}) {
    const auto self = run_gimforge({"synth", "subdivide", base, "--segments", "2", "-o", out});
    EXPECT_EQ(self.exit_code, 1) << out;
    EXPECT_NE(self.err.find("is the input"), std::string::npos) << self.err;
  }
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_EQ(gimforge::io::read_mesh(base).faces.size(), gimforge::make_icosphere(1.0, 1).faces.size());
  const auto huge = run_gimforge({"synth", "subdivide", base, "--segments", "30000", "-o", dir.file("x.ply")});
  EXPECT_EQ(huge.exit_code, 1);
  EXPECT_NE(huge.err.find("32-bit"), std::string::npos) << huge.err;
  const auto missing = run_gimforge({"synth", "subdivide", dir.file("missing.ply"), "-o", dir.file("x.ply")});
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.err.find("missing.ply"), std::string::npos) << missing.err;
  const auto nowhere = run_gimforge({"synth", "terrain", "--grid", "8", "-o", dir.file("no/such/dir/x.ply")});
  EXPECT_EQ(nowhere.exit_code, 1);
  EXPECT_NE(nowhere.err.find("does not exist"), std::string::npos) << nowhere.err;
  EXPECT_FALSE(fs::exists(dir.file("x.ply")));
}
