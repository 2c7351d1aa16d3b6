// Tests of parallel HDF5 through the h5 layer and mpi/hdf5_mpio.h: all ranks create one file with
// MPI-IO, write their own hyperslab collectively, and HDF5 must report that the I/O really was
// collective; the data and the collectively written attributes are then read back and checked.
// Files go to $GIMFORGE_TEST_TMPDIR (ctest sets it to the build directory), else /tmp.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "io/archive.h"
#include "io/hdf5.h"
#include "kernels/core/errors.h"
#include "mpi/comm.h"
#include "mpi/hdf5_mpio.h"
#include "mpi/mpi_comm.h"

namespace fs = std::filesystem;
using namespace gimforge;
using h5::Dims;
using mpi::Comm;

namespace {

constexpr std::uint64_t kRowsPerRank = 16;
constexpr std::uint64_t kCols = 8;

/// A path shared by all ranks (rank 0's pid and the rank count make it unique per run); removed by
/// rank 0 when the object dies, after all ranks are done with it.
class SharedFile {
 public:
  SharedFile(const Comm& comm, const std::string& stem) : comm_(comm) {
    const char* env = std::getenv("GIMFORGE_TEST_TMPDIR");
    std::string name = stem + "_" + std::to_string(getpid()) + "_np" + std::to_string(comm.size()) + ".h5";
    comm.broadcast(name, 0);
    path_ = fs::path(env != nullptr && *env != '\0' ? env : "/tmp") / name;
  }
  SharedFile(const SharedFile&) = delete;
  SharedFile& operator=(const SharedFile&) = delete;
  ~SharedFile() {
    comm_.barrier();
    if (comm_.rank() == 0) fs::remove(path_);
  }
  [[nodiscard]] const fs::path& path() const { return path_; }

 private:
  const Comm& comm_;
  fs::path path_;
};

float value_at(std::uint64_t row, std::uint64_t col) { return static_cast<float>(row * kCols + col) + 0.25f; }

/// The rows of rank `rank`, row-major.
std::vector<float> rows_of(int rank) {
  std::vector<float> rows;
  const auto first = static_cast<std::uint64_t>(rank) * kRowsPerRank;
  for (std::uint64_t r = first; r < first + kRowsPerRank; ++r)
    for (std::uint64_t c = 0; c < kCols; ++c) rows.push_back(value_at(r, c));
  return rows;
}

/// Number of entries of the whole (size * 16, 8) dataset that differ from value_at.
std::size_t mismatches(const std::vector<float>& all) {
  std::size_t bad = 0;
  for (std::size_t i = 0; i < all.size(); ++i) bad += all[i] != value_at(i / kCols, i % kCols);
  return bad;
}

/// Every rank writes its block of `name` collectively; returns the I/O mode HDF5 reports.
mpi::MpioIoMode write_own_rows(h5::Dataset& ds, const Comm& comm) {
  h5::DataTransfer xfer = mpi::collective_transfer();
  const auto first = static_cast<std::uint64_t>(comm.rank()) * kRowsPerRank;
  ds.write_slab(Dims{first, 0}, Dims{kRowsPerRank, kCols}, rows_of(comm.rank()), xfer);
  return mpi::actual_io_mode(xfer);
}

TEST(ParallelHdf5, EachRankWritesItsHyperslabCollectively) {
  const Comm comm = mpi::mpi_world();
  const SharedFile file(comm, "gimforge_parallel");
  const std::uint64_t rows = kRowsPerRank * static_cast<std::uint64_t>(comm.size());
  {
    h5::File f = h5::File::create(file.path(), h5::CreateMode::kTruncate, mpi::mpio_file_access(comm));
    f.set_attribute("ranks", comm.size());
    f.set_attribute("label", "written by all ranks");
    f.set_attribute("weights", std::vector<double>{0.5, 0.25});
    h5::Dataset ds = f.create_dataset("grid", h5::DataType::of<float>(), Dims{rows, kCols});
    ds.set_attribute("rows_per_rank", kRowsPerRank);
    EXPECT_EQ(write_own_rows(ds, comm), mpi::MpioIoMode::kContiguousCollective);
  }
  {  // all ranks read everything back, collectively
    h5::File f = h5::File::open(file.path(), h5::OpenMode::kReadOnly, mpi::mpio_file_access(comm));
    h5::DataTransfer xfer = mpi::collective_transfer();
    const h5::Dataset ds = f.open_dataset("grid");
    EXPECT_EQ(ds.shape(), (Dims{rows, kCols}));
    const std::vector<float> all = ds.read<float>(xfer);
    EXPECT_TRUE(mpi::is_collective(mpi::actual_io_mode(xfer)));
    EXPECT_EQ(all.size(), rows * kCols);
    EXPECT_EQ(mismatches(all), 0u);
    EXPECT_EQ(f.attribute<std::int64_t>("ranks"), comm.size());
    EXPECT_EQ(f.attribute<std::string>("label"), "written by all ranks");
    EXPECT_EQ(f.attribute<std::vector<double>>("weights"), (std::vector<double>{0.5, 0.25}));
    EXPECT_EQ(ds.attribute<std::int64_t>("rows_per_rank"), static_cast<std::int64_t>(kRowsPerRank));
  }
  comm.barrier();
  if (comm.rank() == 0) {  // and once more through the plain POSIX driver
    const h5::File f = h5::File::open(file.path());
    EXPECT_EQ(mismatches(f.open_dataset("grid").read<float>()), 0u);
  }
}

TEST(ParallelHdf5, CompressedChunksAreWrittenCollectively) {
  const Comm comm = mpi::mpi_world();
  const SharedFile file(comm, "gimforge_parallel_gzip");
  const std::uint64_t rows = kRowsPerRank * static_cast<std::uint64_t>(comm.size());
  {
    h5::File f = h5::File::create(file.path(), h5::CreateMode::kTruncate, mpi::mpio_file_access(comm));
    h5::Dataset ds = f.create_dataset("grid", h5::DataType::of<float>(), Dims{rows, kCols},
                                      {.chunk = {kRowsPerRank, kCols}, .deflate = 4, .shuffle = true});
    EXPECT_EQ(write_own_rows(ds, comm), mpi::MpioIoMode::kChunkCollective);
  }
  comm.barrier();
  if (comm.rank() == 0) {
    const h5::File f = h5::File::open(file.path());
    EXPECT_EQ(mismatches(f.open_dataset("grid").read<float>()), 0u);
  }
}

TEST(ParallelHdf5, RanksWithoutDataTakePartWithEmptyBlocks) {
  const Comm comm = mpi::mpi_world();
  const SharedFile file(comm, "gimforge_parallel_empty");
  {
    h5::File f = h5::File::create(file.path(), h5::CreateMode::kTruncate, mpi::mpio_file_access(comm));
    h5::Dataset ds = f.create_dataset("grid", h5::DataType::of<float>(), Dims{kRowsPerRank, kCols});
    h5::DataTransfer xfer = mpi::collective_transfer();
    const std::uint64_t mine = comm.rank() == 0 ? kRowsPerRank : 0;
    ds.write_slab(Dims{0, 0}, Dims{mine, kCols}, comm.rank() == 0 ? rows_of(0) : std::vector<float>{}, xfer);
    EXPECT_TRUE(mpi::is_collective(mpi::actual_io_mode(xfer)));
  }
  comm.barrier();
  if (comm.rank() == 0) {
    EXPECT_EQ(mismatches(h5::File::open(file.path()).open_dataset("grid").read<float>()), 0u);
  }
}

TEST(ParallelHdf5, ArchiveCreatedCollectivelyReadsBackSerially) {
  const Comm comm = mpi::mpi_world();
  const SharedFile file(comm, "gimforge_parallel_archive");
  std::string created = io::utc_timestamp();  // attribute values must agree on all ranks
  comm.broadcast(created, 0);
  const std::vector<float> image(4 * 3 * 3, 1.5f);
  {
    io::Archive a =
        io::Archive::create(file.path(), {.creator = "test_mpi", .parameters_json = "{}", .created = created},
                            h5::CreateMode::kTruncate, mpi::mpio_file_access(comm));
    h5::Group g = a.root().create_group("gim/sample");
    h5::DataTransfer xfer = mpi::collective_transfer();
    io::write_image(g, "geometry", Dims{4, 3, 3}, image, {}, xfer);
    EXPECT_TRUE(mpi::is_collective(mpi::actual_io_mode(xfer)));
    a.close();
  }
  comm.barrier();
  if (comm.rank() == 0) {
    const io::Archive a = io::Archive::open(file.path());
    EXPECT_EQ(a.info().created, created);
    EXPECT_EQ(a.root().open_dataset("gim/sample/geometry").read<float>(), image);
  }
}

TEST(ParallelHdf5, SerialCommGivesThePosixDriver) {
  EXPECT_EQ(mpi::mpio_file_access(Comm::serial()).id(), 0);
  EXPECT_THROW((void)mpi::actual_io_mode(h5::DataTransfer{}), InvalidInput);
}

}  // namespace
