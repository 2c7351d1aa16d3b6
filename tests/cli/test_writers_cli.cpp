// End-to-end tests of the command-line writers: writers of one archive take turns (ARCHIVE.lock, --wait),
// no output may replace an input, and mesh outputs are written in the format their extension names.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <future>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "io/archive.h"
#include "io/atomic_file.h"
#include "io/mesh_io.h"
#include "io/relief_archive.h"
#include "tests/cli/run_process.h"

namespace {

namespace fs = std::filesystem;
using gimforge::test::ProcessResult;
using gimforge::test::run_gimforge;
using gimforge::test::TempDir;

const std::string kData = GIMFORGE_TEST_DATA_DIR;

/// A quick relief conversion of a committed mesh into `archive` (a fraction of a second).
std::vector<std::string> quick_convert(const std::string& mesh, const std::string& archive,
                                       std::vector<std::string> extra = {}) {
  std::vector<std::string> args{"-q",      "convert",  kData + "/" + mesh, "--method", "relief", "--grid", "2",
                                "--texture", "8", "--no-metric", "-o", archive};
  args.insert(args.end(), extra.begin(), extra.end());
  return args;
}

std::vector<std::string> relief_names(const std::string& archive) {
  return gimforge::io::relief_map_names(gimforge::io::Archive::open(archive));
}

bool holds(const std::vector<std::string>& names, const std::string& name) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

/// Files of `dir` other than the ones named in `expected`.
std::vector<std::string> other_files(const fs::path& dir, const std::vector<std::string>& expected) {
  std::vector<std::string> out;
  for (const auto& entry : fs::directory_iterator(dir))
    if (!holds(expected, entry.path().filename().string())) out.push_back(entry.path().filename().string());
  return out;
}

/// Checks the one-line error of a refused writer.
void expect_in_use(const ProcessResult& r, const std::string& archive) {
  EXPECT_EQ(r.exit_code, 1) << r.err;
  const auto lines = r.err_lines();
  ASSERT_EQ(lines.size(), 1u) << r.err;
  EXPECT_TRUE(lines[0].starts_with("gimforge: error: " + archive + ": archive in use by ")) << lines[0];
  EXPECT_NE(lines[0].find("--wait"), std::string::npos) << lines[0];
}

}  // namespace

TEST(Writers, ASecondConvertIsRefusedBeforeAnyWorkWhileTheArchiveIsLocked) {
  const TempDir dir("gimforge-writers");
  const std::string archive = dir.file("out.h5");
  {
    const gimforge::io::WriterLock held(archive, gimforge::io::WriterLock::Wait::kNo);  // "another gimforge"
    ASSERT_TRUE(held.locked()) << "this file system cannot flock";
    const auto r = run_gimforge(quick_convert("kitten.ply", archive));
    expect_in_use(r, archive);
    EXPECT_NE(r.err.find("pid " + std::to_string(::getpid())), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(archive));
    EXPECT_EQ(other_files(dir.path(), {"out.h5.lock"}), std::vector<std::string>{});
  }
  EXPECT_FALSE(fs::exists(dir.file("out.h5.lock"))) << "the lock file is removed on release";
  // Free again: the same command succeeds and leaves only the archive.
  const auto r = run_gimforge(quick_convert("kitten.ply", archive));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(relief_names(archive), std::vector<std::string>{"kitten"});
  EXPECT_EQ(other_files(dir.path(), {"out.h5"}), std::vector<std::string>{});
}

TEST(Writers, WaitBlocksUntilTheOtherWriterIsDone) {
  const TempDir dir("gimforge-writers");
  const std::string archive = dir.file("out.h5");
  ASSERT_EQ(run_gimforge(quick_convert("tetra.obj", archive)).exit_code, 0);
  auto held = std::make_unique<gimforge::io::WriterLock>(archive, gimforge::io::WriterLock::Wait::kNo);
  auto waiting = std::async(std::launch::async, [&] { return run_gimforge(quick_convert("kitten.ply", archive, {"--wait"})); });
  EXPECT_EQ(waiting.wait_for(std::chrono::milliseconds(1500)), std::future_status::timeout)
      << "convert --wait did not wait for the lock: " << waiting.get().err;
  EXPECT_EQ(relief_names(archive), std::vector<std::string>{"tetra"});
  held.reset();
  const auto r = waiting.get();
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(relief_names(archive), (std::vector<std::string>{"kitten", "tetra"}));
}

TEST(Writers, ConcurrentConvertsNeverReportASuccessTheArchiveLacks) {
  const int trials = gimforge::test::trials(3, 10);
  for (int t = 0; t < trials; ++t) {
    const TempDir dir("gimforge-writers");
    const std::string archive = dir.file("out.h5");
    const bool existing = t % 2 == 1;
    if (existing) {
      ASSERT_EQ(run_gimforge(quick_convert("tetra.obj", archive)).exit_code, 0);
    }
    const std::vector<std::string> meshes{"kitten.ply", "cathead.ply", "fist.ply"};
    std::vector<std::future<ProcessResult>> runs;
    for (std::size_t i = 0; i < meshes.size(); ++i)
      runs.push_back(std::async(std::launch::async, [&, i] {
        // The last one waits its turn; the others may be refused.
        return run_gimforge(quick_convert(meshes[i], archive, i + 1 == meshes.size()
                                                                  ? std::vector<std::string>{"--wait"}
                                                                  : std::vector<std::string>{}));
      }));
    std::vector<std::string> succeeded;
    for (std::size_t i = 0; i < meshes.size(); ++i) {
      const ProcessResult r = runs[i].get();
      const std::string name = fs::path(meshes[i]).stem().string();
      if (r.exit_code == 0)
        succeeded.push_back(name);
      else
        expect_in_use(r, archive);
      if (i + 1 == meshes.size()) {
        EXPECT_EQ(r.exit_code, 0) << "--wait must not fail: " << r.err;
      }
    }
    const auto names = relief_names(archive);
    for (const std::string& name : succeeded) EXPECT_TRUE(holds(names, name)) << name << " reported success, trial " << t;
    EXPECT_EQ(names.size(), succeeded.size() + (existing ? 1u : 0u)) << "trial " << t;
    EXPECT_EQ(other_files(dir.path(), {"out.h5"}), std::vector<std::string>{}) << "trial " << t;
  }
}

TEST(Writers, BatchAndItsResumeAreRefusedUpFrontWhileTheArchiveIsLocked) {
  const TempDir dir("gimforge-writers");
  fs::create_directory(dir.path() / "in");
  fs::copy_file(kData + "/tetra.obj", dir.path() / "in" / "tetra.obj");
  const std::string archive = dir.file("b.h5");
  const std::vector<std::string> batch{"-q", "batch", "--input", dir.file("in"), "--method", "relief", "--grid", "2",
                                       "--texture", "8", "--no-metric", "-o", archive};
  {
    const gimforge::io::WriterLock held(archive, gimforge::io::WriterLock::Wait::kNo);
    expect_in_use(run_gimforge(batch), archive);
    auto resume = batch;
    resume.push_back("--resume");
    expect_in_use(run_gimforge(resume), archive);
    EXPECT_FALSE(fs::exists(archive + ".work")) << "a refused batch must not touch the job";
    EXPECT_FALSE(fs::exists(archive));
  }
  const auto r = run_gimforge(batch);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(other_files(dir.path(), {"in", "b.h5"}), std::vector<std::string>{});
}

// ---- no output may replace an input ----

namespace {

/// Checks the refusal of an output that is an input, and that the input is unchanged.
void expect_refused_over_input(const ProcessResult& r, const std::string& output, const std::string& input,
                               std::uintmax_t input_bytes) {
  EXPECT_EQ(r.exit_code, 1) << r.err;
  const auto lines = r.err_lines();
  ASSERT_EQ(lines.size(), 1u) << r.err;
  EXPECT_TRUE(lines[0].starts_with("gimforge: error: " + output + ": is the input ")) << lines[0];
  EXPECT_EQ(fs::file_size(input), input_bytes) << input << " was changed";
}

}  // namespace

TEST(Writers, NoCommandWritesOverItsInput) {
  const TempDir dir("gimforge-writers");
  const std::string archive = dir.file("a.h5");
  ASSERT_EQ(run_gimforge(quick_convert("kitten.ply", archive)).exit_code, 0);
  const auto bytes = fs::file_size(archive);
  // Through a hard link and a symbolic link, with extensions that the writers accept.
  fs::create_hard_link(archive, dir.file("hard.ply"));
  fs::create_symlink("a.h5", dir.file("soft.png"));
  expect_refused_over_input(run_gimforge({"reconstruct", archive, "-o", dir.file("hard.ply")}), dir.file("hard.ply"),
                            archive, bytes);
  expect_refused_over_input(run_gimforge({"render", archive, "--size", "16", "-o", dir.file("soft.png")}),
                            dir.file("soft.png"), archive, bytes);
  EXPECT_TRUE(fs::is_symlink(dir.file("soft.png")));
  // render's second picture (OUTPUT_reference.png) and the --reference mesh count as well.
  fs::create_hard_link(archive, dir.file("view_reference.png"));
  expect_refused_over_input(run_gimforge({"render", archive, "--size", "16", "-o", dir.file("view.png"), "--reference",
                                          kData + "/kitten.ply"}),
                            dir.file("view_reference.png"), archive, bytes);
  EXPECT_FALSE(fs::exists(dir.file("view.png"))) << "refused before any work";
  // preview's pictures in -o DIR.
  fs::create_directory(dir.path() / "pics");
  fs::create_hard_link(archive, dir.path() / "pics" / "kitten_relief_cells.png");
  expect_refused_over_input(run_gimforge({"preview", archive, "-o", dir.file("pics")}),
                            (dir.path() / "pics" / "kitten_relief_cells.png").string(), archive, bytes);
  EXPECT_FALSE(fs::exists(dir.path() / "pics" / "kitten_relief_distances.png")) << "refused before any picture";
  // convert MESH -o MESH (and through a link).
  fs::copy_file(kData + "/tetra.obj", dir.file("t.obj"));
  fs::create_symlink("t.obj", dir.file("t_link.h5"));
  const auto mesh_bytes = fs::file_size(dir.file("t.obj"));
  expect_refused_over_input(run_gimforge({"convert", dir.file("t.obj"), "--method", "relief", "-o", dir.file("t.obj")}),
                            dir.file("t.obj"), dir.file("t.obj"), mesh_bytes);
  expect_refused_over_input(run_gimforge({"convert", dir.file("t.obj"), "--method", "relief", "-o", dir.file("t_link.h5")}),
                            dir.file("t_link.h5"), dir.file("t.obj"), mesh_bytes);
  // batch -o naming one of its inputs (the list file).
  {
    std::ofstream(dir.file("list.txt")) << kData << "/tetra.obj\n";
  }
  const auto list_bytes = fs::file_size(dir.file("list.txt"));
  expect_refused_over_input(run_gimforge({"-q", "batch", "--list", dir.file("list.txt"), "--method", "relief", "--resume",
                                          "-o", dir.file("list.txt")}),
                            dir.file("list.txt"), dir.file("list.txt"), list_bytes);
}

TEST(Writers, AFullDiskIsOneErrorLineAndLeavesNoPartOfTheArchive) {
  // The file-size limit (ulimit -f, SIGXFSZ ignored) fails writes as a full disk does. HDF5 1.10.8 then
  // crashed at exit on the file whose close had failed (SIGSEGV after the error line); the error named the
  // temporary file.
  const TempDir dir("gimforge-writers");
  const std::string archive = dir.file("a.h5");
  ASSERT_EQ(run_gimforge(quick_convert("kitten.ply", archive)).exit_code, 0);
  const auto bytes = fs::file_size(archive);
  const auto limited = [](std::uintmax_t limit_bytes, const std::vector<std::string>& args) {
    return gimforge::test::run_gimforge_after("ulimit -f " + std::to_string(limit_bytes / 512) + "; trap '' XFSZ", args);
  };
  const auto expect_one_line = [](const ProcessResult& r, const std::string& path) {
    EXPECT_EQ(r.exit_code, 1) << r.err;
    const auto lines = r.err_lines();
    ASSERT_EQ(lines.size(), 1u) << r.err;
    EXPECT_TRUE(lines[0].starts_with("gimforge: error: " + path + ":")) << lines[0];
    EXPECT_NE(lines[0].find("File too large"), std::string::npos) << lines[0];
    EXPECT_EQ(lines[0].find(".tmp"), std::string::npos) << lines[0];
  };
  // Into the existing archive: the copy fits, the new item does not; the archive stays as it was.
  expect_one_line(limited(bytes + 1024, quick_convert("kitten.ply", archive, {"--name", "second"})), archive);
  EXPECT_EQ(fs::file_size(archive), bytes);
  EXPECT_EQ(relief_names(archive), std::vector<std::string>{"kitten"});
  // The copy itself does not fit.
  expect_one_line(limited(bytes / 2, quick_convert("kitten.ply", archive, {"--name", "second"})), archive);
  // A new archive.
  expect_one_line(limited(4096, quick_convert("kitten.ply", dir.file("new.h5"))), dir.file("new.h5"));
  EXPECT_EQ(other_files(dir.path(), {"a.h5"}), std::vector<std::string>{}) << "no temporary or partial file left";
}

// ---- mesh outputs are written in the format their extension names ----

TEST(Writers, ReconstructWritesTheFormatTheExtensionNames) {
  const TempDir dir("gimforge-writers");
  const std::string archive = dir.file("a.h5");
  ASSERT_EQ(run_gimforge(quick_convert("kitten.ply", archive)).exit_code, 0);
  ASSERT_EQ(run_gimforge({"reconstruct", archive, "-o", dir.file("r.ply")}).exit_code, 0);
  const gimforge::TriMesh ply = gimforge::io::read_mesh(dir.file("r.ply"));
  for (const std::string ext : {".obj", ".off", ".stl"}) {
    SCOPED_TRACE(ext);
    const std::string out = dir.file("r" + ext);
    const auto r = run_gimforge({"reconstruct", archive, "-o", out});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    gimforge::io::ReadInfo info;
    const gimforge::TriMesh back = gimforge::io::read_mesh(out, &info);  // refuses PLY bytes behind .obj
    EXPECT_EQ(info.format, gimforge::io::format_from_extension(out));
    EXPECT_EQ(back.num_faces(), ply.num_faces());
    if (ext != ".stl") {  // STL welds corners, so its vertex numbering may differ
      ASSERT_EQ(back.num_vertices(), ply.num_vertices());
      for (std::size_t i = 0; i < ply.num_vertices(); ++i)
        EXPECT_EQ(back.positions[i].cast<float>(), ply.positions[i].cast<float>()) << i;
    }
  }
  // An extension that names no mesh format: refused before any work, nothing written.
  const auto r = run_gimforge({"reconstruct", archive, "-o", dir.file("r.xyz")});
  EXPECT_EQ(r.exit_code, 1);
  ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
  EXPECT_NE(r.err.find(dir.file("r.xyz") + ": cannot write a mesh as '.xyz'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(".ply, .obj, .off, .stl"), std::string::npos) << r.err;
  EXPECT_EQ(r.out, "") << "the message must come before the reconstruction";
  EXPECT_FALSE(fs::exists(dir.file("r.xyz")));
}

TEST(Writers, AnArchiveNamedLikeAMeshIsRefusedBeforeAnyWork) {
  // batch -o COLLECTION/out.ply wrote an HDF5 file into its own collection, which the next batch over the
  // folder listed as a broken mesh.
  const TempDir dir("gimforge-writers");
  for (const std::vector<std::string>& args :
       {quick_convert("kitten.ply", dir.file("a.ply")),
        std::vector<std::string>{"batch", "--input", std::string(GIMFORGE_TEST_DATA_DIR), "-o", dir.file("b.OBJ")}}) {
    const auto r = run_gimforge(args);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_NE(r.err.find("an archive named like a mesh file"), std::string::npos) << r.err;
  }
  EXPECT_EQ(other_files(dir.path(), {}), std::vector<std::string>{});
}
