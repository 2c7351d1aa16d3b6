#pragma once
// A temporary folder every rank of the MPI tests sees (rank 0 makes it), for the files a test writes.
#include <stdlib.h>

#include <filesystem>
#include <functional>
#include <string>

#include <gtest/gtest.h>

#include "io/mesh_io.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "mpi/agree.h"
#include "mpi/comm.h"

namespace gimforge::test {

inline std::string shared_folder(const mpi::Comm& world, const std::string& prefix) {
  std::string dir;
  if (world.rank() == 0) {
    std::string pattern = (std::filesystem::temp_directory_path() / (prefix + "-XXXXXX")).string();
    dir = mkdtemp(pattern.data());
  }
  world.broadcast(dir, 0);
  return dir;
}

/// A binary PLY torus cut 100 bytes short, at DIR/cut.ply (rank 0 writes it; every rank gets the path).
inline std::string truncated_scan(const mpi::Comm& world, const std::string& dir) {
  const std::string scan = dir + "/cut.ply";
  if (world.rank() == 0) {
    io::write_ply(dir + "/whole.ply", make_torus(1.0, 0.4, 100, 50), {.binary = true});
    std::filesystem::copy_file(dir + "/whole.ply", scan);
    std::filesystem::resize_file(scan, std::filesystem::file_size(scan) - 100);
  }
  world.barrier();
  return scan;
}

/// `run` fails on this rank: the failing rank with an error naming the truncation, the others with PeerFailed.
inline void expect_fails_as_truncated(const mpi::Comm& world, const std::function<void()>& run) {
  bool failed = false;
  try {
    run();
  } catch (const mpi::PeerFailed&) {
    failed = true;
  } catch (const Error& e) {
    failed = true;
    EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(failed);
  world.barrier();
}

}  // namespace gimforge::test
