#pragma once
// A temporary folder every rank of the MPI tests sees (rank 0 makes it), for the files a test writes.
#include <stdlib.h>

#include <filesystem>
#include <string>

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

}  // namespace gimforge::test
