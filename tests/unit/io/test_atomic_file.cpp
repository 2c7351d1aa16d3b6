// io/atomic_file.h: the clean-up of stale temporaries (dead writers' leftovers removed, live writers' and
// other files kept) and the writers built on write_atomically (PLY, PNG) leaving no temporary file and
// the old file intact when a write or the commit fails.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "io/atomic_file.h"
#include "io/mesh_io.h"
#include "io/png_image.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"

namespace fs = std::filesystem;

namespace {

/// A fresh directory, removed with its contents on destruction.
class Dir {
 public:
  Dir() {
    std::string pattern = (fs::temp_directory_path() / "gimforge-atomic-XXXXXX").string();
    path_ = ::mkdtemp(pattern.data());
  }
  ~Dir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  Dir(const Dir&) = delete;
  Dir& operator=(const Dir&) = delete;
  [[nodiscard]] fs::path operator/(const std::string& name) const { return path_ / name; }
  [[nodiscard]] const fs::path& path() const { return path_; }
  /// The names in the directory, sorted.
  [[nodiscard]] std::set<std::string> names() const {
    std::set<std::string> out;
    for (const auto& e : fs::directory_iterator(path_)) out.insert(e.path().filename().string());
    return out;
  }

 private:
  fs::path path_;
};

void write_text(const fs::path& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

/// The host part of this process's temporary names ("<path>.<host>.<pid>.tmp").
std::string host_in_temporary_names() {
  const std::string name = gimforge::io::temporary_path("x").filename().string();
  const std::string tail = fmt::format(".{}.tmp", ::getpid());
  EXPECT_TRUE(name.starts_with("x.") && name.ends_with(tail)) << name;
  return name.substr(2, name.size() - 2 - tail.size());
}

/// The pid of a child that has exited and been reaped: a process that no longer exists.
pid_t dead_pid() {
  const pid_t pid = ::fork();
  if (pid == 0) ::_exit(0);
  int status = 0;
  ::waitpid(pid, &status, 0);
  EXPECT_NE(::kill(pid, 0), 0);
  return pid;
}

/// Lowers the file size limit of this process to `bytes` for its lifetime, so that writes beyond it fail
/// with EFBIG (SIGXFSZ ignored meanwhile).
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    ::getrlimit(RLIMIT_FSIZE, &saved_);
    old_handler_ = ::signal(SIGXFSZ, SIG_IGN);
    rlimit lowered = saved_;
    lowered.rlim_cur = bytes;
    ::setrlimit(RLIMIT_FSIZE, &lowered);
  }
  ~FileSizeLimit() {
    ::setrlimit(RLIMIT_FSIZE, &saved_);
    ::signal(SIGXFSZ, old_handler_);
  }
  FileSizeLimit(const FileSizeLimit&) = delete;
  FileSizeLimit& operator=(const FileSizeLimit&) = delete;

 private:
  rlimit saved_{};
  void (*old_handler_)(int){nullptr};
};

/// `f()`'s IoError message; a test failure when it throws nothing.
template <class F>
std::string io_error_of(F&& f) {
  try {
    f();
  } catch (const gimforge::IoError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no IoError";
  return {};
}

TEST(StaleTemporaries, RemovesDeadWritersOfThisHostOnlyAndNothingElse) {
  Dir dir;
  const std::string host = host_in_temporary_names();
  const auto tmp = [&](const std::string& file, const std::string& h, pid_t pid) {
    return fmt::format("{}.{}.{}.tmp", file, h, pid);
  };
  const pid_t dead = dead_pid();
  const pid_t live = ::getpid();
  const pid_t parent = ::getppid();  // alive, and (as root or not) another process than this one
  const std::string dead_tmp = tmp("out.h5", host, dead);
  const std::vector<std::string> kept = {
      "out.h5",                                   // the output itself
      tmp("out.h5", host, live),                  // this process is writing it
      tmp("out.h5", host, parent),                // another live process is writing it
      tmp("out.h5", "other-host", dead),          // cannot tell whether that writer lives
      tmp("other.h5", host, dead),                // a dead writer of another file
      tmp("out.h5x", host, dead),                 // ditto, a name that only starts like ours
      fmt::format("out.h5.{}.12ab.tmp", host),    // no pid
      fmt::format("out.h5.{}.0.tmp", host),       // no valid pid
      "out.h5.tmp",                               // no host and pid
      "out.h5.bak",                               // unrelated
  };
  write_text(dir / dead_tmp, "partial");
  for (const std::string& name : kept) write_text(dir / name, "keep");
  const std::string kept_dir = tmp("out.h5", host, dead_pid());  // a directory, not a leftover file
  fs::create_directory(dir / kept_dir);

  const auto removed = gimforge::io::remove_stale_temporaries(dir / "out.h5");
  ASSERT_EQ(removed.size(), 1u);
  EXPECT_EQ(removed.front(), dir / dead_tmp);
  EXPECT_FALSE(fs::exists(dir / dead_tmp));
  for (const std::string& name : kept) {
    EXPECT_TRUE(fs::exists(dir / name)) << name << " was removed";
    EXPECT_EQ(read_text(dir / name), "keep") << name;
  }
  EXPECT_TRUE(fs::is_directory(dir / kept_dir));
  // Nothing left to remove: a second call removes nothing.
  EXPECT_TRUE(gimforge::io::remove_stale_temporaries(dir / "out.h5").empty());

  // A caller that knows no writer runs elsewhere (a resumed batch) removes other hosts' leftovers too,
  // still never those of live processes here.
  const auto also = gimforge::io::remove_stale_temporaries(dir / "out.h5", /*other_hosts_are_dead=*/true);
  ASSERT_EQ(also.size(), 1u);
  EXPECT_EQ(also.front(), dir / tmp("out.h5", "other-host", dead));
  EXPECT_TRUE(fs::exists(dir / tmp("out.h5", host, live)));
  EXPECT_TRUE(fs::exists(dir / tmp("out.h5", host, parent)));
  EXPECT_TRUE(fs::exists(dir / tmp("other.h5", host, dead)));

  // A missing directory holds nothing to clean.
  EXPECT_TRUE(gimforge::io::remove_stale_temporaries(dir / "absent" / "out.h5").empty());
}

TEST(StaleTemporaries, RecognizesTheNamesWriteAtomicallyUses) {
  Dir dir;
  const fs::path out = dir / "a.h5";
  const pid_t child = ::fork();
  if (child == 0) {  // a writer that dies during its write, leaving its temporary file behind
    gimforge::io::write_atomically(out, [](const fs::path& tmp) {
      write_text(tmp, "half");
      ::_exit(0);
    });
    ::_exit(1);
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  ASSERT_EQ(dir.names().size(), 1u);
  const auto removed = gimforge::io::remove_stale_temporaries(out);
  ASSERT_EQ(removed.size(), 1u);
  EXPECT_TRUE(dir.names().empty());
}

TEST(DirectoryLock, ASecondHolderWaitsUntilTheFirstReleasesIt) {
  Dir dir;
  {
    const gimforge::io::DirectoryLock probe(dir.path());
    if (!probe.locked()) GTEST_SKIP() << dir.path() << ": the file system cannot lock directories";
  }
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  if (child == 0) {  // holds the lock for 0.3 s, then marks the release and exits (which releases it)
    const gimforge::io::DirectoryLock lock(dir.path());
    if (::write(ready[1], "x", 1) != 1) ::_exit(1);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    write_text(dir / "released", "");
    ::_exit(0);
  }
  char byte = 0;
  ASSERT_EQ(::read(ready[0], &byte, 1), 1);  // the child holds the lock now
  const auto t0 = std::chrono::steady_clock::now();
  {
    const gimforge::io::DirectoryLock lock(dir.path());
    EXPECT_TRUE(lock.locked());
    EXPECT_TRUE(fs::exists(dir / "released")) << "got the lock while the child held it";
    EXPECT_GE(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 0.2);
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  ::close(ready[0]);
  ::close(ready[1]);
  EXPECT_THROW(gimforge::io::DirectoryLock(dir / "absent"), gimforge::IoError);
}

TEST(WriterLock, ASecondWriterIsRefusedWithTheHoldersPidOrWaits) {
  Dir dir;
  const fs::path archive = dir / "out.h5";
  using gimforge::io::WriterLock;
  {
    const WriterLock held(archive, WriterLock::Wait::kNo);
    if (!held.locked()) GTEST_SKIP() << dir.path() << ": the file system cannot flock";
    EXPECT_TRUE(fs::exists(WriterLock::lock_path(archive)));
    try {  // another open file description: flock treats it as another writer, as it would another process
      const WriterLock second(archive, WriterLock::Wait::kNo);
      ADD_FAILURE() << "a second writer got the lock";
    } catch (const gimforge::io::ArchiveInUse& e) {
      EXPECT_EQ(std::string(e.what()), archive.string() + ": archive in use by pid " + std::to_string(::getpid()) +
                                           " (another gimforge is writing it); wait with --wait");
    }
  }
  EXPECT_FALSE(fs::exists(WriterLock::lock_path(archive))) << "removed on release";
  // A waiting writer gets it once the holder (a child process) is done, and only then.
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  if (child == 0) {
    const WriterLock lock(archive, WriterLock::Wait::kNo);
    if (::write(ready[1], "x", 1) != 1) ::_exit(1);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    write_text(dir / "released", "");
    ::_exit(0);
  }
  char byte = 0;
  ASSERT_EQ(::read(ready[0], &byte, 1), 1);
  {
    const WriterLock lock(archive, WriterLock::Wait::kYes);
    EXPECT_TRUE(lock.locked());
    EXPECT_TRUE(fs::exists(dir / "released")) << "got the lock while the child held it";
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  ::close(ready[0]);
  ::close(ready[1]);
  EXPECT_THROW(WriterLock(dir / "absent" / "x.h5", WriterLock::Wait::kNo), gimforge::IoError);
}

TEST(WriterLock, ALinkPlantedAsTheLockFileIsRefusedAndItsTargetKept) {
  Dir dir;
  write_text(dir / "victim.txt", "original");
  const fs::path archive = dir / "out.h5";
  using gimforge::io::WriterLock;
  fs::create_symlink(dir / "victim.txt", WriterLock::lock_path(archive));
  try {
    const WriterLock lock(archive, WriterLock::Wait::kNo);
    ADD_FAILURE() << "locked through a link";
  } catch (const gimforge::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("is a symbolic link"), std::string::npos) << e.what();
  }
  std::ifstream in(dir / "victim.txt");
  std::string text;
  std::getline(in, text);
  EXPECT_EQ(text, "original");
  EXPECT_TRUE(fs::is_symlink(WriterLock::lock_path(archive)));
}

TEST(OutputChecks, SameFileFollowsLinksAndCanCreateNamesTheDirectory) {
  Dir dir;
  write_text(dir / "a", "x");
  fs::create_hard_link(dir / "a", dir / "hard");
  fs::create_symlink("a", dir / "soft");
  write_text(dir / "b", "x");
  EXPECT_TRUE(gimforge::io::same_file(dir / "a", dir / "hard"));
  EXPECT_TRUE(gimforge::io::same_file(dir / "soft", dir / "a"));
  EXPECT_FALSE(gimforge::io::same_file(dir / "a", dir / "b"));
  EXPECT_FALSE(gimforge::io::same_file(dir / "a", dir / "absent"));
  EXPECT_NO_THROW(gimforge::io::check_can_create(dir / "new"));
  try {
    gimforge::io::check_can_create(dir / "absent" / "x.h5");
    ADD_FAILURE() << "no error";
  } catch (const gimforge::IoError& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "absent" / "x.h5").string() + ": cannot write here: directory '" +
                                         (dir / "absent").string() + "' does not exist");
  }
  EXPECT_THROW(gimforge::io::check_can_create(dir.path()), gimforge::IoError);
}

TEST(OutputChecks, DevicesAndPipesAreNeverReplaced) {
  // `-o /dev/null` used to rename the temporary file over the device node; a FIFO stands in for it here.
  Dir dir;
  const fs::path fifo = dir / "pipe.ply";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_THROW(gimforge::io::check_can_create(fifo), gimforge::IoError);
  bool wrote = false;
  try {
    gimforge::io::write_atomically(fifo, [&](const fs::path&) { wrote = true; });
    ADD_FAILURE() << "no error";
  } catch (const gimforge::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(wrote);
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_THROW(gimforge::io::check_can_create(""), gimforge::IoError);
}

TEST(WriteAtomically, CopiesKeepPermissionsAndErrorsNameTheOutput) {
  // convert -o EXISTING copies the archive and renames the copy over it: a private archive stays private.
  Dir dir;
  const fs::path archive = dir / "a.h5";
  std::ofstream(archive) << "archive bytes";
  ASSERT_EQ(::chmod(archive.c_str(), 0640), 0);
  gimforge::io::write_atomically(archive, [&](const fs::path& tmp) { gimforge::io::copy_contents(archive, tmp); });
  struct stat st {};
  ASSERT_EQ(::stat(archive.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 07777, 0640u);
  std::ifstream in(archive);
  std::string text;
  std::getline(in, text);
  EXPECT_EQ(text, "archive bytes");
  // An error about the temporary file names the output; an error of another type keeps its type.
  try {
    gimforge::io::write_atomically(archive, [&](const fs::path& tmp) { throw gimforge::IoError(tmp.string() + ": disk full"); });
    ADD_FAILURE() << "no error";
  } catch (const gimforge::IoError& e) {
    EXPECT_EQ(std::string(e.what()), archive.string() + ": disk full");
  }
  EXPECT_THROW(gimforge::io::write_atomically(archive, [&](const fs::path&) { throw gimforge::io::ArchiveInUse("held"); }),
               gimforge::io::ArchiveInUse);
  EXPECT_EQ(dir.names(), std::set<std::string>{"a.h5"});
}

TEST(WritePly, FailedWriteLeavesNoTemporaryAndTheOldFile) {
  Dir dir;
  const fs::path path = dir / "mesh.ply";
  write_text(path, "old contents");
  const gimforge::TriMesh mesh = gimforge::make_icosphere(1.0, 4);
  std::string message;
  {
    const FileSizeLimit limit(4096);  // the PLY is far larger: write() fails with EFBIG
    message = io_error_of([&] { gimforge::io::write_ply(path, mesh); });
  }
  EXPECT_TRUE(message.starts_with(path.string() + ": cannot write the temporary file")) << message;
  EXPECT_NE(message.find("File too large"), std::string::npos) << message;
  EXPECT_EQ(dir.names(), (std::set<std::string>{"mesh.ply"}));
  EXPECT_EQ(read_text(path), "old contents");
  // A missing directory is not created: the error names the file.
  message = io_error_of([&] { gimforge::io::write_ply(dir / "no" / "x.ply", mesh); });
  EXPECT_TRUE(message.starts_with((dir / "no" / "x.ply").string() + ": cannot create the temporary file"))
      << message;
  EXPECT_FALSE(fs::exists(dir / "no"));
}

/// Random bytes: an image that PNG cannot compress.
std::vector<std::uint8_t> noise(std::size_t n) {
  std::mt19937 rng(7);
  std::vector<std::uint8_t> out(n);
  for (auto& b : out) b = static_cast<std::uint8_t>(rng());
  return out;
}

TEST(WritePng, FailedWriteOrCommitLeavesNoTemporaryAndTheOldFile) {
  Dir dir;
  const fs::path path = dir / "image.png";
  const std::vector<std::uint8_t> rgb = noise(256 * 256 * 3);
  gimforge::io::write_png_rgb(path, 256, 256, rgb);
  const std::string good = read_text(path);
  EXPECT_EQ(good.substr(1, 3), "PNG");
  EXPECT_EQ(dir.names(), (std::set<std::string>{"image.png"}));
  std::string message;
  {
    const FileSizeLimit limit(4096);
    message = io_error_of([&] { gimforge::io::write_png_rgb(path, 256, 256, rgb); });
  }
  EXPECT_TRUE(message.starts_with(path.string() + ": cannot write PNG")) << message;
  EXPECT_EQ(dir.names(), (std::set<std::string>{"image.png"}));
  EXPECT_EQ(read_text(path), good);
  // A directory in the way: the rename fails and the temporary file is removed.
  fs::create_directories(dir / "taken.png" / "child");
  message = io_error_of([&] { gimforge::io::write_png_rgb(dir / "taken.png", 256, 256, rgb); });
  EXPECT_TRUE(message.starts_with((dir / "taken.png").string() + ": cannot commit")) << message;
  EXPECT_EQ(dir.names(), (std::set<std::string>{"image.png", "taken.png"}));
  // A missing directory is not created.
  message = io_error_of([&] { gimforge::io::write_png_rgb(dir / "no" / "x.png", 256, 256, rgb); });
  EXPECT_TRUE(message.starts_with((dir / "no" / "x.png").string() + ": cannot write PNG")) << message;
  EXPECT_FALSE(fs::exists(dir / "no"));
}

}  // namespace
