// End-to-end test of `gimforge convert -o EXISTING.h5`: the archive is copied, the copy extended and
// renamed over the original, so a SIGKILL at any moment leaves either the old archive (byte for byte) or
// the complete new one, and the next convert removes the killed run's temporary file. A command ended by
// SIGINT, SIGTERM or SIGHUP removes its own temporary files, and its reading child (crash_guard.h) dies with it.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "io/archive.h"
#include "io/relief_archive.h"
#include "tests/cli/run_process.h"

namespace fs = std::filesystem;
using gimforge::test::run_gimforge;
using gimforge::test::run_process;
using gimforge::test::TempDir;
using Clock = std::chrono::steady_clock;

namespace {

const std::string kData = GIMFORGE_TEST_DATA_DIR;

std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

/// What can be seen of a directory from outside: each entry's name, size and modification time.
using DirState = std::set<std::tuple<std::string, std::uintmax_t, std::int64_t>>;
DirState state_of(const fs::path& dir) {
  DirState out;
  for (const auto& e : fs::directory_iterator(dir)) {
    struct stat st {};
    if (::stat(e.path().c_str(), &st) != 0) continue;  // removed meanwhile
    out.emplace(e.path().filename().string(), static_cast<std::uintmax_t>(st.st_size),
                static_cast<std::int64_t>(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec);
  }
  return out;
}

/// One run of `argv` that is killed with SIGKILL `delay` seconds after it starts writing into `dir`
/// (the first change of the directory or of a file in it), or runs to its end.
struct KillRun {
  bool killed{false};     ///< SIGKILL ended it
  int exit_code{-1};      ///< when it was not killed
  double write_start{-1}; ///< seconds from the start to its first write into `dir`; -1: none seen
  double total{0};        ///< seconds from the start to its end
};
/// Starts `argv` with stdout and stderr to /dev/null and SIGINT at its default action (a background
/// process of a shell without job control would ignore it); returns its pid.
pid_t spawn_quiet(const std::vector<std::string>& argv) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    const int devnull = ::open("/dev/null", O_WRONLY);
    ::dup2(devnull, 1);
    ::dup2(devnull, 2);
    ::signal(SIGINT, SIG_DFL);
    ::execv(args[0], args.data());
    ::_exit(127);
  }
  return pid;
}

KillRun run_and_kill_while_writing(const std::vector<std::string>& argv, const fs::path& dir, double delay) {
  const DirState before = state_of(dir);
  const auto t0 = Clock::now();
  const pid_t pid = spawn_quiet(argv);
  KillRun run;
  int status = 0;
  while (::waitpid(pid, &status, WNOHANG) == 0) {
    if (run.write_start < 0 && state_of(dir) != before) run.write_start = seconds_since(t0);
    if (run.write_start >= 0 && seconds_since(t0) >= run.write_start + delay) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      break;
    }
    if (seconds_since(t0) > 120) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      ADD_FAILURE() << "the run took over 120 s";
      break;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  run.total = seconds_since(t0);
  run.killed = WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
  if (WIFEXITED(status)) run.exit_code = WEXITSTATUS(status);
  return run;
}

/// Files in `dir` other than `expected`.
std::vector<std::string> unexpected_files(const fs::path& dir, const std::set<std::string>& expected) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(dir))
    if (!expected.contains(e.path().filename().string())) out.push_back(e.path().filename().string());
  return out;
}

TEST(CliConvertKill, KillsAtRandomMomentsLeaveTheOldOrTheCompleteNewArchive) {
  TempDir dir;
  TempDir refs;
  const fs::path work = dir.path();
  const std::string archive = dir.file("a.h5");
  const std::string mesh = kData + "/fist.ply";
  const std::vector<std::string> add_other = {"convert", mesh, "--method", "relief", "--grid", "4",
                                              "--texture", "16", "--metric-samples", "20000",
                                              "-o", archive, "--name", "other"};
  auto r = run_gimforge({"convert", mesh, "--method", "relief", "--grid", "4", "--texture", "16", "--metric-samples",
                         "20000", "-o", archive, "--name", "first"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string original = read_bytes(archive);
  fs::copy_file(archive, refs.file("original.h5"));
  const auto reconstruct = [&](const std::string& from, const std::string& name, const std::string& to) {
    const auto rec = run_gimforge({"reconstruct", from, "--name", name, "-o", to});
    EXPECT_EQ(rec.exit_code, 0) << from << " " << name << ": " << rec.err;
    return read_bytes(to);
  };
  const std::string first_mesh = reconstruct(archive, "first", refs.file("first.ply"));

  // The uninterrupted run: its reconstruction of "other", and when it writes.
  std::vector<std::string> argv = {GIMFORGE_EXE};
  argv.insert(argv.end(), add_other.begin(), add_other.end());
  const KillRun reference = run_and_kill_while_writing(argv, work, 1e9);
  ASSERT_FALSE(reference.killed);
  ASSERT_EQ(reference.exit_code, 0);
  ASSERT_GE(reference.write_start, 0.0) << "no write seen";
  const std::string other_mesh = reconstruct(archive, "other", refs.file("other.ply"));
  ASSERT_TRUE(reconstruct(archive, "first", refs.file("first2.ply")) == first_mesh);
  double writing = reference.total - reference.write_start;

  // Kill moments: every third trial anywhere in the run (mostly during the conversion, before anything
  // is written), the others at a random moment of the writing phase, which starts when the directory first
  // changes (a temporary file appears) and lasts about `writing` seconds (the copy of the archive, the new
  // datasets, close, fsync, rename); a run that finishes before its kill shortens `writing`.
  std::mt19937 rng(2024);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int killed_while_writing = 0;
  std::set<std::string> seen;  // "old" and "new": what the kills left
  for (int trial = 0; trial < 9; ++trial) {
    fs::copy_file(refs.file("original.h5"), archive, fs::copy_options::overwrite_existing);
    KillRun run;
    if (trial % 3 == 0) {
      const double when = unit(rng) * reference.total;
      const auto started = Clock::now();
      r = run_process(argv, when);
      run.killed = r.exit_code == 128 + SIGKILL;
      run.exit_code = r.exit_code;
      run.total = seconds_since(started);
    } else {
      run = run_and_kill_while_writing(argv, work, unit(rng) * 0.8 * writing);
      if (run.killed && run.write_start >= 0) ++killed_while_writing;
      if (!run.killed && run.write_start >= 0) writing = std::min(writing, 0.9 * (run.total - run.write_start));
    }
    const std::string what = "trial " + std::to_string(trial);
    if (!run.killed) {
      ASSERT_EQ(run.exit_code, 0) << what;
    }
    // The archive opens and still holds "first", bit-identical; "other" is there completely or not at
    // all, and when it is not, the file is the old one byte for byte.
    std::vector<std::string> names;
    {
      const auto a = gimforge::io::Archive::open(archive);
      names = gimforge::io::relief_map_names(a);
      for (const std::string& name : names) (void)gimforge::io::read_relief_map(a, name);
    }
    if (names == std::vector<std::string>{"first"}) {
      EXPECT_TRUE(run.killed) << what << ": a finished run added nothing";
      EXPECT_TRUE(read_bytes(archive) == original) << what << ": the old archive was modified";
      seen.insert("old");
    } else {
      ASSERT_EQ(names, (std::vector<std::string>{"first", "other"})) << what;
      EXPECT_TRUE(reconstruct(archive, "other", refs.file("check_other.ply")) == other_mesh) << what;
      seen.insert("new");
    }
    EXPECT_TRUE(reconstruct(archive, "first", refs.file("check_first.ply")) == first_mesh) << what;
    // At most the killed run's temporary file is left: one of each earlier killed run would be a leak. (Its
    // lock file a.h5.lock may stay too: the next writer locks and removes it.)
    const auto left = unexpected_files(work, {"a.h5", "a.h5.lock"});
    EXPECT_LE(left.size(), 1u) << what << ": " << ::testing::PrintToString(left);
    for (const std::string& name : left) EXPECT_TRUE(name.starts_with("a.h5.") && name.ends_with(".tmp")) << name;
  }
  std::printf("convert %.3f s, writing phase %.1f ms, %d kill(s) while writing, outcomes:%s%s\n", reference.total,
              1e3 * writing, killed_while_writing, seen.contains("old") ? " old" : "", seen.contains("new") ? " new" : "");
  EXPECT_GE(killed_while_writing, 3) << "too few kills landed while the archive was written";
  EXPECT_TRUE(seen.contains("old"));

  // The next successful convert removes the leftover and leaves nothing but the archive.
  fs::copy_file(refs.file("original.h5"), archive, fs::copy_options::overwrite_existing);
  r = run_gimforge(add_other);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(unexpected_files(work, {"a.h5"}), std::vector<std::string>{});
  EXPECT_TRUE(reconstruct(archive, "other", refs.file("other2.ply")) == other_mesh);
}

TEST(CliConvertKill, ConcurrentConvertsIntoOneArchiveKeepEveryImage) {
  TempDir dir;
  const std::string archive = dir.file("a.h5");
  const auto convert = [&](const std::string& name) {
    return run_gimforge({"convert", kData + "/fist.ply", "--method", "relief", "--grid", "4", "--texture", "16",
                         "--metric-samples", "20000", "-o", archive, "--name", name, "--wait"});
  };
  ASSERT_EQ(convert("first").exit_code, 0);
  // Identical work started at once: with --wait, the archive's lock (ARCHIVE.lock) makes the second wait for
  // the first's rename and add to its result (without --wait it would be refused: tests/cli/test_writers_cli.cpp).
  for (int round = 0; round < 3; ++round) {
    const std::string suffix = std::to_string(round);
    std::string b = "b", c = "c";
    b += suffix;
    c += suffix;
    gimforge::test::ProcessResult rb, rc;
    std::thread tb([&] { rb = convert(b); });
    std::thread tc([&] { rc = convert(c); });
    tb.join();
    tc.join();
    ASSERT_EQ(rb.exit_code, 0) << rb.err;
    ASSERT_EQ(rc.exit_code, 0) << rc.err;
    const auto a = gimforge::io::Archive::open(archive);
    const auto names = gimforge::io::relief_map_names(a);
    for (const std::string& name : {b, c})
      EXPECT_NE(std::find(names.begin(), names.end(), name), names.end())
          << "round " << round << ": " << name << " was lost; the archive holds " << ::testing::PrintToString(names);
  }
  EXPECT_EQ(unexpected_files(dir.path(), {"a.h5"}), std::vector<std::string>{});
}

/// Starts `argv` (stdout and stderr to /dev/null) and, once a temporary file ("*.tmp") appears in `dir`,
/// sends it `sig`; returns its wait status. Fails the test when no temporary file appears within 60 s.
int signal_while_writing(const std::vector<std::string>& argv, const fs::path& dir, int sig) {
  const pid_t pid = spawn_quiet(argv);
  const auto t0 = Clock::now();
  const auto writing = [&] {
    for (const auto& e : fs::directory_iterator(dir))
      if (e.path().extension() == ".tmp") return true;
    return false;
  };
  int status = 0;
  while (!writing()) {
    if (::waitpid(pid, &status, WNOHANG) != 0 || seconds_since(t0) > 60) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      ADD_FAILURE() << argv[1] << ": no temporary file seen";
      return status;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  ::kill(pid, sig);
  ::waitpid(pid, &status, 0);
  return status;
}

TEST(CliSignals, AnInterruptedCommandLeavesNoTemporaryFileAndNoChildThatGoesOnWriting) {
  TempDir dir;
  const fs::path work = dir.path();
  // A long write of the command's own process: synth's PLY, SIGTERM and SIGINT.
  for (const int sig : {SIGTERM, SIGINT}) {
    const int status = signal_while_writing(
        {GIMFORGE_EXE, "-q", "synth", "terrain", "--faces", "4000000", "-o", dir.file("t.ply")}, work, sig);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig) << status;
    EXPECT_EQ(unexpected_files(work, {}), std::vector<std::string>{}) << strsignal(sig);
  }
  // reconstruct writes in a child process (jobs/cli/crash_guard.h): SIGTERM, and SIGKILL, which the
  // child cannot hear of but through PR_SET_PDEATHSIG, ended the parent while the child wrote on and
  // committed the mesh seconds later.
  auto r = run_gimforge({"-q", "convert", kData + "/cathead.ply", "--method", "sphere", "--n", "512", "--no-metric",
                         "-o", dir.file("s.h5")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const int sig : {SIGTERM, SIGKILL}) {
    const int status =
        signal_while_writing({GIMFORGE_EXE, "-q", "reconstruct", dir.file("s.h5"), "-o", dir.file("r.obj")}, work, sig);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig) << status;
    std::this_thread::sleep_for(std::chrono::seconds(2));  // the old child took about a second more
    EXPECT_EQ(unexpected_files(work, {"s.h5"}), std::vector<std::string>{}) << strsignal(sig);
  }
}

}  // namespace
