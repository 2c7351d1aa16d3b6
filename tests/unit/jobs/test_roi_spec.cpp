// --roi (jobs/roi.h): every accepted form parsed and resolved against a loaded mesh, and every bad one
// refused with one line naming the cause.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>

#include <fmt/format.h>

#include "io/mesh_io.h"
#include "io/png_image.h"
#include "jobs/load_mesh.h"
#include "jobs/roi.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"

using namespace gimforge;
namespace fs = std::filesystem;

namespace {

class Scratch {
 public:
  Scratch() {
    std::string pattern = (fs::temp_directory_path() / "gimforge-test-roi-XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  Scratch(const Scratch&) = delete;
  Scratch& operator=(const Scratch&) = delete;
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  [[nodiscard]] fs::path operator/(const std::string& name) const { return path_ / name; }

 private:
  fs::path path_;
};

void write_text(const fs::path& path, const std::string& text) { std::ofstream(path) << text; }

jobs::MethodOptions with_roi(const std::string& roi) {
  jobs::MethodOptions m;
  m.sampling = "adaptive";
  m.roi = roi;
  return m;
}

/// The message of the InvalidInput / IoError `f` throws ("" when it throws none).
template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

/// A 4 × 4 grid (25 vertices), vertices 6 and 7 painted red, the others grey; with `unreferenced_first` the
/// file has an unreferenced vertex 0 before them (the loader's repair drops it and renumbers the others).
jobs::LoadedMesh grid_file(const Scratch& dir, bool unreferenced_first) {
  TriMesh m = make_grid(4, 4, 1.0);
  m.colors.assign(m.num_vertices(), Vec3f(0.5f, 0.5f, 0.5f));
  m.colors[6] = m.colors[7] = Vec3f(1.0f, 0.0f, 0.0f);
  if (unreferenced_first) {
    // Vertex 0 unreferenced: the loaded mesh renumbers every other vertex.
    m.positions.resize(m.positions.size() + 1);
    m.colors.resize(m.colors.size() + 1);
    std::copy_backward(m.positions.begin(), m.positions.end() - 1, m.positions.end());
    std::copy_backward(m.colors.begin(), m.colors.end() - 1, m.colors.end());
    m.positions[0] = Vec3(9, 9, 9);
    m.colors[0] = Vec3f(0.0f, 0.0f, 1.0f);
    for (Face& f : m.faces)
      for (auto& v : f) ++v;
  }
  const fs::path path = dir / (unreferenced_first ? "renumbered.ply" : "grid.ply");
  io::write_ply(path, m, {.binary = false, .double_precision = true, .comment = ""});
  return jobs::load_mesh(path, {.repair = true, .require_manifold = false, .require_oriented = false, .warn = false, .topology = true});
}

}  // namespace

TEST(RoiSpec, ParsesEveryForm) {
  EXPECT_EQ(jobs::parse_roi_spec("auto").kind, jobs::RoiSpec::Kind::Auto);
  EXPECT_DOUBLE_EQ(jobs::parse_roi_spec("auto").fraction, 0.1);
  EXPECT_DOUBLE_EQ(jobs::parse_roi_spec("auto:0.25").fraction, 0.25);
  const jobs::RoiSpec box = jobs::parse_roi_spec("box:-1,2.5,3e5,4,5,3.5e5");
  EXPECT_EQ(box.kind, jobs::RoiSpec::Kind::Box);
  EXPECT_EQ(box.lo, Vec3(-1, 2.5, 3e5));
  EXPECT_EQ(box.hi, Vec3(4, 5, 3.5e5));
  EXPECT_EQ(jobs::parse_roi_spec("vertices:sel.txt").file, "sel.txt");
  EXPECT_EQ(jobs::parse_roi_spec("mask:a:b.png").file, "a:b.png");  // only the first colon separates
  const jobs::RoiSpec color = jobs::parse_roi_spec("color:FF8000");
  EXPECT_EQ(color.kind, jobs::RoiSpec::Kind::Color);
  EXPECT_EQ(color.color, (std::array<int, 3>{255, 128, 0}));
  EXPECT_EQ(jobs::parse_roi_spec("color:#00ff00").color, (std::array<int, 3>{0, 255, 0}));
  const jobs::RoiSpec scalar = jobs::parse_roi_spec("scalar:quality>0.25");
  EXPECT_EQ(scalar.kind, jobs::RoiSpec::Kind::Scalar);
  EXPECT_EQ(scalar.property, "quality");
  EXPECT_DOUBLE_EQ(scalar.threshold, 0.25);
  EXPECT_DOUBLE_EQ(jobs::parse_roi_spec("scalar:confidence").threshold, 0.0);
}

TEST(RoiSpec, RefusesBadForms) {
  const std::vector<std::pair<std::string, std::string>> cases{
      {"", "expected auto"},
      {"roi", "expected auto"},
      {"auto:0", "fraction"},
      {"auto:1.5", "fraction"},
      {"auto:x", "fraction"},
      {"box:1,2,3", "6 numbers"},
      {"box:1,2,3,4,5,x", "'x' is not a finite number"},
      {"box:1,2,3,4,5,inf", "not a finite number"},
      {"box:4,5,6,1,2,3", "lowest"},
      {"vertices:", "expected auto"},
      {"color:red", "six hex digits"},
      {"color:12345", "six hex digits"},
      {"sphere:1", "unknown kind 'sphere'"},
      {"scalar:>1", "vertex property name"},
      {"scalar:q>x", "threshold after '>'"},
      {"scalar:q>nan", "threshold after '>'"},
  };
  for (const auto& [spec, cause] : cases) {
    const std::string message = error_of([&] { (void)jobs::parse_roi_spec(spec); });
    EXPECT_NE(message.find("--roi " + spec + ":"), std::string::npos) << message;
    EXPECT_NE(message.find(cause), std::string::npos) << spec << ": " << message;
    EXPECT_EQ(message.find('\n'), std::string::npos);
  }
  // MethodOptions::check refuses a bad form, a ROI without adaptive sampling and gains outside 1..64.
  EXPECT_NE(error_of([] { with_roi("box:1").check("convert"); }).find("6 numbers"), std::string::npos);
  jobs::MethodOptions uniform = with_roi("auto");
  uniform.sampling = "uniform";
  EXPECT_NE(error_of([&] { uniform.check("convert"); }).find("needs --sampling adaptive"), std::string::npos);
  jobs::MethodOptions gain = with_roi("auto");
  gain.roi_gain = 0.5;
  EXPECT_NE(error_of([&] { gain.check("convert"); }).find("--roi-gain"), std::string::npos);
  EXPECT_EQ(error_of([] { with_roi("auto:0.2").check("convert"); }), "");
}

TEST(RoiSpec, ResolvesVertexFormsOnTheLoadedMesh) {
  const Scratch dir;
  for (bool renumbered : {false, true}) {
    const jobs::LoadedMesh m = grid_file(dir, renumbered);
    ASSERT_EQ(m.mesh.num_vertices(), 25u);
    const std::size_t offset = renumbered ? 1 : 0;  // file vertex v + offset is loaded vertex v
    // vertices: file indices (the renumbered file's are one higher), with comments and commas.
    write_text(dir / "sel.txt", fmt::format("# chosen\n{}, {}\n{}  # last\n", 6 + offset, 7 + offset, 12 + offset));
    const RoiSource listed = jobs::resolve_roi(with_roi("vertices:" + (dir / "sel.txt").string()), m);
    ASSERT_EQ(listed.kind, RoiSource::Kind::Vertices);
    ASSERT_EQ(listed.vertices.size(), 25u);
    for (std::size_t v = 0; v < 25; ++v) EXPECT_EQ(listed.vertices[v], v == 6 || v == 7 || v == 12 ? 1 : 0) << v;
    // A UTF-8 byte-order mark before the first index (a Notepad file): its index was "not a vertex index".
    write_text(dir / "bom.txt", fmt::format("\xEF\xBB\xBF{}\n", 6 + offset));
    const RoiSource bom = jobs::resolve_roi(with_roi("vertices:" + (dir / "bom.txt").string()), m);
    for (std::size_t v = 0; v < 25; ++v) EXPECT_EQ(bom.vertices[v], v == 6 ? 1 : 0) << v;
    // color: the red vertices.
    const RoiSource red = jobs::resolve_roi(with_roi("color:ff0000"), m);
    for (std::size_t v = 0; v < 25; ++v) EXPECT_EQ(red.vertices[v], v == 6 || v == 7 ? 1 : 0) << v;
    // box: in the file's coordinates (the grid spans [0, 1]², z = 0; vertex v at (v % 5, v / 5) / 4).
    const RoiSource box = jobs::resolve_roi(with_roi("box:0.2,0.2,-1,0.3,0.55,1"), m);
    for (std::size_t v = 0; v < 25; ++v) EXPECT_EQ(box.vertices[v], v == 6 || v == 11 ? 1 : 0) << v;
  }
}

TEST(RoiSpec, ResolvesAPerVertexScalarOfThePly) {
  const Scratch dir;
  // A 2 × 1 strip of quads (6 vertices) with a quality per vertex, an unreferenced vertex first.
  write_text(dir / "q.ply", "ply\nformat ascii 1.0\nelement vertex 7\nproperty float x\nproperty float y\n"
                            "property float z\nproperty float quality\nelement face 4\n"
                            "property list uchar int vertex_indices\nend_header\n"
                            "9 9 9 5\n0 0 0 0\n1 0 0 0.9\n2 0 0 0.2\n0 1 0 0.7\n1 1 0 0\n2 1 0 -1\n"
                            "3 1 2 5\n3 1 5 4\n3 2 3 6\n3 2 6 5\n");
  const jobs::LoadedMesh m = jobs::load_mesh(dir / "q.ply", {.repair = true, .require_manifold = false, .require_oriented = false, .warn = false, .topology = true});
  ASSERT_EQ(m.mesh.num_vertices(), 6u);  // the unreferenced vertex is gone: the file's numbers are off by one
  const RoiSource roi = jobs::resolve_roi(with_roi("scalar:quality>0.5"), m);
  EXPECT_EQ(roi.vertices, (std::vector<std::uint8_t>{0, 1, 0, 1, 0, 0}));
  const RoiSource positive = jobs::resolve_roi(with_roi("scalar:quality"), m);
  EXPECT_EQ(positive.vertices, (std::vector<std::uint8_t>{0, 1, 1, 1, 0, 0}));
  const std::string missing = error_of([&] { (void)jobs::resolve_roi(with_roi("scalar:confidence"), m); });
  EXPECT_NE(missing.find("no scalar property 'confidence'"), std::string::npos) << missing;
  EXPECT_NE(missing.find("it has x, y, z, quality"), std::string::npos) << missing;
  EXPECT_NE(error_of([&] { (void)jobs::resolve_roi(with_roi("scalar:x"), m); }).find("other than positions"), std::string::npos);
  EXPECT_NE(error_of([&] { (void)jobs::resolve_roi(with_roi("scalar:quality>10"), m); }).find("selects no vertex"), std::string::npos);
  // Binary files too (the general reader: an extra property leaves the fast path).
  TriMesh grid = make_grid(2, 2, 1.0);
  io::write_ply(dir / "b.ply", grid);
  const jobs::LoadedMesh b = jobs::load_mesh(dir / "b.ply", {.repair = true, .require_manifold = false, .require_oriented = false, .warn = false, .topology = true});
  EXPECT_NE(error_of([&] { (void)jobs::resolve_roi(with_roi("scalar:quality"), b); }).find("(it has x, y, z)"), std::string::npos);
}

TEST(RoiSpec, ResolvesAutoAndMasks) {
  const Scratch dir;
  const jobs::LoadedMesh m = grid_file(dir, false);
  const RoiSource automatic = jobs::resolve_roi(with_roi("auto:0.3"), m);
  EXPECT_EQ(automatic.kind, RoiSource::Kind::Auto);
  EXPECT_DOUBLE_EQ(automatic.auto_fraction, 0.3);
  // A 3 × 2 RGB picture: white top left, grey (below half) and black elsewhere.
  std::vector<std::uint8_t> rgb(3 * 2 * 3, 0);
  for (int c = 0; c < 3; ++c) rgb[static_cast<std::size_t>(c)] = 255, rgb[static_cast<std::size_t>(3 + c)] = 100;
  io::write_png_rgb(dir / "mask.png", 3, 2, rgb);
  jobs::MethodOptions o = with_roi("mask:" + (dir / "mask.png").string());
  o.roi_gain = 3.0;
  const RoiSource mask = jobs::resolve_roi(o, m);
  EXPECT_EQ(mask.kind, RoiSource::Kind::Picture);
  EXPECT_EQ(mask.picture_width, 3u);
  EXPECT_EQ(mask.picture_height, 2u);
  EXPECT_EQ(mask.picture, (std::vector<std::uint8_t>{1, 0, 0, 0, 0, 0}));
  EXPECT_DOUBLE_EQ(mask.enhance.gain, 3.0);
  EXPECT_EQ(jobs::resolve_roi(jobs::MethodOptions{}, m).kind, RoiSource::Kind::None);
}

TEST(RoiSpec, BadFilesAndSelectionsGiveOneClearLine) {
  const Scratch dir;
  const jobs::LoadedMesh m = grid_file(dir, false);
  const auto message = [&](const std::string& roi) { return error_of([&] { (void)jobs::resolve_roi(with_roi(roi), m); }); };
  write_text(dir / "word.txt", "3 4\nfive\n");
  write_text(dir / "range.txt", "3 25\n");
  write_text(dir / "negative.txt", "-1\n");
  write_text(dir / "empty.txt", "# nothing\n");
  write_text(dir / "notpng.png", "not a picture");
  write_text(dir / "long.txt", "1 2\n" + std::string(1 << 20, '7') + "\n");  // one 1 MiB token
  std::vector<std::uint8_t> black(3 * 2 * 3, 0);
  io::write_png_rgb(dir / "black.png", 3, 2, black);
  const std::string d = (dir / "x").parent_path().string() + "/";
  const std::vector<std::pair<std::string, std::string>> cases{
      {"vertices:" + d + "word.txt", "word.txt:2: 'five' is not a vertex index"},
      {"vertices:" + d + "range.txt", "range.txt:1: vertex 25 is out of range (the mesh file has 25 vertices"},
      {"vertices:" + d + "negative.txt", "vertex -1 is out of range"},
      {"vertices:" + d + "empty.txt", "lists no vertex"},
      {"vertices:" + d + "long.txt", "long.txt:2: '7777777777"},
      {"vertices:" + d + "missing.txt", "missing.txt: no such file"},
      {"mask:" + d + "missing.png", "missing.png: no such file"},
      {"mask:" + d + "notpng.png", "notpng.png: not a readable PNG"},
      {"mask:" + d + "black.png", "no white pixel"},
      {"box:5,5,5,6,6,6", "selects no vertex"},
      {"color:00ff00", "selects no vertex"},
  };
  for (const auto& [roi, cause] : cases) {
    const std::string text = message(roi);
    EXPECT_NE(text.find(cause), std::string::npos) << roi << ": " << text;
    EXPECT_EQ(text.find('\n'), std::string::npos) << text;
  }
  // A mesh without colours.
  TriMesh plain = make_grid(2, 2, 1.0);
  io::write_ply(dir / "plain.ply", plain);
  const jobs::LoadedMesh p = jobs::load_mesh(dir / "plain.ply", {.repair = true, .require_manifold = false, .require_oriented = false, .warn = false, .topology = true});
  EXPECT_NE(error_of([&] { (void)jobs::resolve_roi(with_roi("color:ff0000"), p); }).find("no vertex colours"), std::string::npos);
}
