// End-to-end tests of names from outside (issue #15, finding 7), `gimforge ls` and the XDMF sidecar
// (finding 11), and the local frame seen by the user (finding 6): a georeferenced mesh converts as well as
// at the origin and reconstructs in its own coordinates.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "io/hdf5.h"
#include "io/mesh_io.h"
#include "kernels/core/mesh.h"
#include "tests/cli/run_process.h"

namespace {

namespace fs = std::filesystem;
using gimforge::test::ProcessResult;
using gimforge::test::run_gimforge;
using gimforge::test::TempDir;

const std::string kData = GIMFORGE_TEST_DATA_DIR;

/// No byte of `text` is a control character other than the newline.
bool only_printable_lines(const std::string& text) {
  return std::none_of(text.begin(), text.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return (u < 0x20 && c != '\n') || u == 0x7f;
  });
}

/// Writes tests/data/kitten.ply translated by `offset` as ASCII OBJ with full double precision.
void translated_copy(const std::string& out, const gimforge::Vec3& offset) {
  gimforge::TriMesh mesh = gimforge::io::read_mesh(kData + "/kitten.ply");
  for (gimforge::Vec3& p : mesh.positions) p += offset;
  mesh.normals.clear();
  gimforge::io::write_mesh(out, mesh);
}

TEST(CliNames, ControlCharactersInNamesNeverReachTheTerminal) {
  const TempDir dir;
  // A mesh whose file name carries a terminal escape and a newline that would forge a log line.
  const std::string evil = dir.file("k\x1b[2J\ngimforge: info: forged.obj");
  fs::copy_file(kData + "/tetra.obj", evil);
  const ProcessResult r = run_gimforge({"convert", evil, "--method", "relief", "--grid", "2", "--texture", "8",
                                        "--no-metric", "-o", dir.file("a.h5")});
  EXPECT_EQ(r.exit_code, 1) << "the default name (the file's stem) holds control characters";
  ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
  EXPECT_TRUE(only_printable_lines(r.err)) << r.err;
  EXPECT_NE(r.err.find("\\e[2J\\ngimforge"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir.file("a.h5")));

  // --name gives it a clean name: the conversion succeeds and every line printed is escaped.
  const ProcessResult ok = run_gimforge({"convert", evil, "--method", "relief", "--grid", "2", "--texture", "8",
                                         "--no-metric", "--name", "tetra", "-o", dir.file("a.h5")});
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_TRUE(only_printable_lines(ok.out)) << ok.out;
  EXPECT_TRUE(only_printable_lines(ok.err)) << ok.err;

  // The commands that read a mesh and print its name: info, validate, metrics.
  for (const std::vector<std::string>& args : {std::vector<std::string>{"info", evil},
                                               std::vector<std::string>{"validate", evil},
                                               std::vector<std::string>{"metrics", evil, evil, "-n", "1000"}}) {
    const ProcessResult p = run_gimforge(args);
    EXPECT_EQ(p.exit_code, 0) << args.front() << ": " << p.err;
    EXPECT_TRUE(only_printable_lines(p.out)) << args.front() << ": " << p.out;
    EXPECT_TRUE(only_printable_lines(p.err)) << args.front() << ": " << p.err;
  }
}

TEST(CliNames, PreviewAndLsRefuseOrEscapeHostileItemNames) {
  const TempDir dir;
  const std::string archive = dir.file("a.h5");
  ASSERT_EQ(run_gimforge({"-q", "convert", kData + "/tetra.obj", "--method", "relief", "--grid", "2", "--texture",
                          "8", "--no-metric", "-o", archive})
                .exit_code,
            0);
  {
    // Someone renames the item to a name with an escape sequence (HDF5 allows any byte but '/' and NUL).
    gimforge::h5::File f = gimforge::h5::File::open(archive, gimforge::h5::OpenMode::kReadWrite);
    gimforge::h5::Group relief = f.open_group("relief");
    relief.copy_to("tetra", relief, "x\x1b]0;owned\x07");
    f.close();
  }
  const ProcessResult ls = run_gimforge({"ls", archive});
  ASSERT_EQ(ls.exit_code, 0) << ls.err;
  EXPECT_TRUE(only_printable_lines(ls.out)) << ls.out;
  EXPECT_NE(ls.out.find("relief/x\\e]0;owned\\x07"), std::string::npos) << ls.out;
  EXPECT_NE(ls.out.find("relief/tetra"), std::string::npos) << ls.out;

  const ProcessResult p = run_gimforge({"preview", archive, "--name", "relief/x\x1b]0;owned\x07", "-o", dir.file("pics")});
  EXPECT_EQ(p.exit_code, 1);
  ASSERT_EQ(p.err_lines().size(), 1u) << p.err;
  EXPECT_TRUE(only_printable_lines(p.err)) << p.err;
  EXPECT_TRUE(!fs::exists(dir.file("pics")) || fs::is_empty(dir.file("pics")));
}

TEST(CliNames, PreviewShortensANameTooLongForItsPictureFiles) {
  // convert takes 255 bytes; preview's suffixes and its temporary names made such a name fail every picture.
  const TempDir dir;
  const std::string archive = dir.file("a.h5");
  const std::string name(250, 'b');
  ASSERT_EQ(run_gimforge({"-q", "convert", kData + "/fist.ply", "--size", "65", "--normal-size", "0", "--no-metric",
                          "--name", name, "-o", archive})
                .exit_code,
            0);
  const ProcessResult p = run_gimforge({"preview", archive, "-o", dir.file("pics")});
  ASSERT_EQ(p.exit_code, 0) << p.err;
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(dir.file("pics"))) files.push_back(entry.path().filename().string());
  ASSERT_EQ(files.size(), 1u);
  EXPECT_TRUE(files[0].starts_with(std::string(150, 'b'))) << files[0];
  EXPECT_TRUE(files[0].ends_with("_geometry.png")) << files[0];
  EXPECT_NE(files[0].find('~'), std::string::npos) << files[0];
  EXPECT_LT(files[0].size(), 255u);
}

TEST(CliNames, ConvertRefusesANameTheArchiveCannotHoldAsAUsageError) {
  // Once exit 1 with a line naming neither file nor option ("invalid geometry image name '..'").
  const TempDir dir;
  for (const std::string& name : {std::string(".."), std::string("a/b"), std::string(""), std::string(256, 'n')}) {
    const ProcessResult r = run_gimforge({"convert", kData + "/tetra.obj", "--method", "relief", "--grid", "1",
                                          "--no-metric", "--name", name, "-o", dir.file("a.h5")});
    EXPECT_EQ(r.exit_code, 2) << name;
    EXPECT_TRUE(r.err.starts_with("gimforge: error: --name: ")) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("a.h5")));
  }
}

TEST(CliNames, JobFilesRefuseTraversalAndControlCharacters) {
  const TempDir dir;
  fs::create_directories(dir.file("in"));
  fs::copy_file(kData + "/tetra.obj", dir.file("in/tetra.obj"));
  const auto job = [&](const std::string& text) {
    std::ofstream(dir.file("job.toml")) << text;
    return run_gimforge({"batch", "--job", dir.file("job.toml"), "-o", dir.file("b.h5")});
  };
  for (const std::string& bad :
       {std::string("[[collection]]\ninput = \"in\"\n[[output]]\nmethod = \"relief\"\nname = \"..\"\n"),
        std::string("[[collection]]\ninput = \"in\"\n[[output]]\nmethod = \"relief\"\nname = \"a\\u001b[2J\"\n"),
        std::string("[[collection]]\ninput = \"in\"\nlabel = \"x\\ny\"\n[[output]]\nmethod = \"relief\"\n")}) {
    const ProcessResult r = job(bad);
    EXPECT_EQ(r.exit_code, 1) << bad << r.err;
    ASSERT_EQ(r.err_lines().size(), 1u) << bad << r.err;
    EXPECT_TRUE(only_printable_lines(r.err)) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("b.h5")));
    EXPECT_FALSE(fs::exists(dir.file("b.h5.work"))) << "refused before any work";
  }
}

TEST(CliNames, GeoreferencedMeshConvertsAsAtTheOriginAndReconstructsInItsOwnCoordinates) {
  const TempDir dir;
  const gimforge::Vec3 utm(4.0e5, 5.0e6, 250.0);
  translated_copy(dir.file("here.obj"), gimforge::Vec3::Zero());
  translated_copy(dir.file("utm.obj"), utm);
  const auto psnr = [&](const std::string& mesh, const std::string& archive) {
    const ProcessResult r = run_gimforge({"-q", "convert", mesh, "--method", "gim", "--size", "65", "--normal-size",
                                          "0", "--metric-samples", "20000", "--json", "-o", archive, "--xdmf"});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return nlohmann::json::parse(r.out).at("psnr").get<double>();
  };
  const double at_origin = psnr(dir.file("here.obj"), dir.file("here.h5"));
  const double far = psnr(dir.file("utm.obj"), dir.file("utm.h5"));
  EXPECT_NEAR(far, at_origin, 0.1);
  EXPECT_TRUE(fs::exists(dir.file("utm.xmf"))) << "--xdmf writes the sidecar";
  // An archive named *.xmf keeps its name: its sidecar is *.xmf.xmf (it replaced the archive).
  fs::copy_file(dir.file("utm.h5"), dir.file("arc.xmf"));
  EXPECT_EQ(run_gimforge({"-q", "ls", dir.file("arc.xmf"), "--xdmf"}).exit_code, 0);
  EXPECT_TRUE(fs::exists(dir.file("arc.xmf.xmf")));
  EXPECT_EQ(run_gimforge({"-q", "ls", dir.file("arc.xmf")}).exit_code, 0) << "still an archive";
  // A directory where the sidecar goes is one error before anything is listed or converted.
  fs::create_directories(dir.file("side.xmf"));
  fs::copy_file(dir.file("utm.h5"), dir.file("side.h5"));
  const ProcessResult listed = run_gimforge({"ls", dir.file("side.h5"), "--xdmf"});
  EXPECT_EQ(listed.exit_code, 1);
  EXPECT_TRUE(listed.out.empty()) << listed.out;
  fs::create_directories(dir.file("new.xmf"));
  const ProcessResult converted = run_gimforge({"convert", dir.file("utm.obj"), "--size", "65", "--no-metric", "-o",
                                                dir.file("new.h5"), "--xdmf"});
  EXPECT_EQ(converted.exit_code, 1);
  EXPECT_NE(converted.err.find("new.xmf: is a directory"), std::string::npos) << converted.err;
  EXPECT_FALSE(fs::exists(dir.file("new.h5"))) << "refused before the conversion";

  ASSERT_EQ(run_gimforge({"-q", "reconstruct", dir.file("utm.h5"), "-o", dir.file("back.ply")}).exit_code, 0);
  ASSERT_EQ(run_gimforge({"-q", "reconstruct", dir.file("here.h5"), "-o", dir.file("back0.ply")}).exit_code, 0);
  const gimforge::TriMesh far_back = gimforge::io::read_mesh(dir.file("back.ply"));
  const gimforge::TriMesh near_back = gimforge::io::read_mesh(dir.file("back0.ply"));
  ASSERT_EQ(far_back.positions.size(), near_back.positions.size());
  double worst = 0;
  for (std::size_t i = 0; i < far_back.positions.size(); ++i)
    worst = std::max(worst, (far_back.positions[i] - utm - near_back.positions[i]).norm());
  // The same reconstruction, moved back to the input's coordinates (the diagonal is ~120: float32 images).
  EXPECT_LT(worst, 1e-4) << "reconstruct adds the frame origin back, in double";

  const ProcessResult ls = run_gimforge({"ls", dir.file("utm.h5"), "--json"});
  ASSERT_EQ(ls.exit_code, 0) << ls.err;
  const nlohmann::json j = nlohmann::json::parse(ls.out);
  ASSERT_EQ(j.at("items").size(), 1u);
  EXPECT_EQ(j["items"][0]["shape"], "65x65x3");
  EXPECT_NEAR(j["items"][0]["psnr"].get<double>(), far, 0.01);
  EXPECT_NE(j["items"][0]["command_line"].get<std::string>().find("convert"), std::string::npos);
}

}  // namespace

namespace {

// HDF5 1.10.8 itself crashes (SIGSEGV) on this archive, found by the relief-archive fuzzer
// (tests/fuzz/crashes/README.md). The reading commands run their work in a child process, so the user
// sees one error line and exit 1 (crash_guard.h). (Not under ASan: there the child's report is the output.)
TEST(CliCrashGuard, AnArchiveThatCrashesHdf5IsOneErrorLine) {
  const std::string crafted =
      std::string(GIMFORGE_TESTS_SOURCE_DIR) + "/fuzz/crashes/relief_archive/crash-f03b138131b64851a0769d17f61c319922fd5a56";
  ASSERT_TRUE(fs::exists(crafted));
  const TempDir dir;
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"reconstruct", crafted, "-o", dir.file("x.ply")},
        std::vector<std::string>{"preview", crafted, "-o", dir.file("pics")},
        std::vector<std::string>{"render", crafted, "-o", dir.file("x.png")}, std::vector<std::string>{"ls", crafted}}) {
    const ProcessResult r = run_gimforge(args, 60.0);
    EXPECT_EQ(r.exit_code, 1) << args[0] << ": " << r.err;
    ASSERT_EQ(r.err_lines().size(), 1u) << args[0] << ": " << r.err;
    EXPECT_EQ(r.err_lines()[0].rfind("gimforge: error: " + crafted, 0), 0u) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("x.ply")) || fs::exists(dir.file("x.png")));
  }
  // convert reads the archive it extends in a child first (probe_archive): refused before any work, and
  // the file is left as it was.
  fs::copy_file(crafted, dir.file("a.h5"));
  const auto before = fs::file_size(dir.file("a.h5"));
  const ProcessResult r = run_gimforge({"convert", kData + "/tetra.obj", "--method", "relief", "--grid", "2",
                                        "--texture", "8", "--no-metric", "-o", dir.file("a.h5")},
                                       60.0);
  EXPECT_EQ(r.exit_code, 1) << r.err;
  ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
  EXPECT_NE(r.err.find("crashed reading the archive"), std::string::npos) << r.err;
  EXPECT_EQ(fs::file_size(dir.file("a.h5")), before);
}

TEST(CliCrashGuard, AClosedPipeIsNotADamagedArchive) {
  // `gimforge ls A.h5 | head`: the listing's child died of SIGPIPE, and ls blamed the archive ("the HDF5
  // library crashed reading the archive (signal 13, PIPE)", exit 1). Now it ends as a closed pipe ends a
  // program, quietly (exit 141), and the same listing into a pipe that stays open is whole.
  const TempDir dir;
  const std::string archive = dir.file("a.h5");
  ASSERT_EQ(run_gimforge({"-q", "convert", kData + "/tetra.obj", "--method", "relief", "--grid", "1", "--texture", "8",
                          "--no-metric", "--name", "t", "-o", archive})
                .exit_code,
            0);
  {
    gimforge::h5::File f = gimforge::h5::File::open(archive, gimforge::h5::OpenMode::kReadWrite);
    gimforge::h5::Group relief = f.open_group("relief");
    for (int i = 0; i < 1500; ++i) relief.copy_to("t", relief, fmt::format("t{}", i));  // > 64 KiB of listing
  }
  const std::string ls = std::string(GIMFORGE_EXE) + " ls '" + archive + "'";
  const ProcessResult closed = gimforge::test::run_process(
      {"/bin/bash", "-c", ls + " | head -1 > /dev/null; echo \"ls exit ${PIPESTATUS[0]}\""}, 120.0);
  EXPECT_NE(closed.out.find("ls exit 141"), std::string::npos) << closed.out << closed.err;
  EXPECT_EQ(closed.err.find("crashed"), std::string::npos) << closed.err;
  const ProcessResult open = gimforge::test::run_process({"/bin/bash", "-c", ls + " | wc -l"}, 120.0);
  EXPECT_NE(open.out.find("1503"), std::string::npos) << open.out << open.err;  // 2 heading lines + 1501 items
}

// Every open finding of the archive fuzzers (tests/fuzz/crashes/: inputs on which HDF5 1.10.8 itself crashes,
// allocates without bound or loops) replayed through the product: `reconstruct` of each ends with exit 1 and
// one line naming the file, never a signal and never a hang — also where HDF5 corrupts the heap and glibc
// prints "malloc(): corrupted top size" before the abort (the parent drops that line: relay_stderr).
TEST(CliCrashGuard, EveryOpenFuzzFindingIsAnErrorNotASignal) {
  const fs::path crashes = fs::path(GIMFORGE_TESTS_SOURCE_DIR) / "fuzz/crashes";
  std::vector<std::string> inputs;
  for (const auto& target : fs::directory_iterator(crashes))
    if (target.is_directory())
      for (const auto& f : fs::directory_iterator(target.path())) inputs.push_back(f.path().string());
  std::sort(inputs.begin(), inputs.end());
  ASSERT_GE(inputs.size(), 30u);
  ASSERT_EQ(setenv("GIMFORGE_HDF5_CALL_SECONDS", "1", 1), 0);
  const TempDir dir;
  for (const std::string& input : inputs) {
    const ProcessResult r = run_gimforge({"reconstruct", input, "-o", dir.file("x.ply")}, 60.0);
    EXPECT_EQ(r.exit_code, 1) << input << ": " << r.err;
    ASSERT_EQ(r.err_lines().size(), 1u) << input << ": " << r.err;
    EXPECT_EQ(r.err_lines()[0].rfind("gimforge: error: " + input, 0), 0u) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("x.ply"))) << input;
  }
  unsetenv("GIMFORGE_HDF5_CALL_SECONDS");
}

// HDF5 1.10.8 loops forever on these archives (the fuzzers' timeout-* inputs, one per reader). In the
// guarded child every HDF5 metadata call is bounded (GIMFORGE_HDF5_CALL_SECONDS, 30 s by default, 1 here):
// each reading command ends with one error line and exit 1 instead of hanging. Without the bound every
// command below runs into the 60 s limit of run_gimforge.
TEST(CliCrashGuard, AnArchiveThatMakesHdf5LoopIsOneErrorLine) {
  const fs::path crashes = fs::path(GIMFORGE_TESTS_SOURCE_DIR) / "fuzz/crashes";
  std::vector<std::string> looping;
  for (const char* name : {"batch_archive/timeout-02fdadbff8fb1c53ea099cb6e7ad1a1226694fca",
                           "batch_shard/timeout-2ce20ee58256106f409ac40d1a6ff51a6f09270a",
                           "gim_archive/timeout-26ebf410cee30d988251f8cb2becc84c05415c76",
                           "relief_archive/timeout-523060c2e904fe0ca4d8a4d1e75813eb6d1c4f8e",
                           "sphere_archive/timeout-06ab9ecb6e95695abbe309c54c64d95c34034ed0"})
    looping.push_back((crashes / name).string());
  ASSERT_EQ(setenv("GIMFORGE_HDF5_CALL_SECONDS", "1", 1), 0);
  const TempDir dir;
  const auto expect_one_line = [](const ProcessResult& r, const std::string& what) {
    EXPECT_EQ(r.exit_code, 1) << what << ": " << r.err;
    ASSERT_EQ(r.err_lines().size(), 1u) << what << ": " << r.err;
    EXPECT_NE(r.err.find("did not return within 1 s reading the archive"), std::string::npos) << what << ": " << r.err;
  };
  for (const std::string& archive : looping) expect_one_line(run_gimforge({"ls", archive}, 60.0), "ls " + archive);
  const std::string& archive = looping.front();
  expect_one_line(run_gimforge({"reconstruct", archive, "-o", dir.file("x.ply")}, 60.0), "reconstruct");
  EXPECT_FALSE(fs::exists(dir.file("x.ply")));
  fs::copy_file(archive, dir.file("a.h5"));
  expect_one_line(run_gimforge({"convert", kData + "/tetra.obj", "--method", "relief", "--grid", "2", "--texture", "8",
                                "--no-metric", "-o", dir.file("a.h5")},
                               60.0),
                  "convert -o onto it");
  unsetenv("GIMFORGE_HDF5_CALL_SECONDS");
}

}  // namespace
