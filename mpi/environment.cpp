/// \file environment.cpp
/// MpiEnvironment (see environment.h).
#include "mpi/environment.h"

#include <cstdlib>
#include <string_view>

#include <fmt/format.h>
#include <mpi.h>

#include "io/hdf5.h"
#include "kernels/core/errors.h"
#include "mpi/mpi_comm.h"

namespace gimforge::mpi {
namespace {

int to_mpi_level(ThreadLevel level) {
  switch (level) {
    case ThreadLevel::kSingle: return MPI_THREAD_SINGLE;
    case ThreadLevel::kFunneled: return MPI_THREAD_FUNNELED;
    case ThreadLevel::kSerialized: return MPI_THREAD_SERIALIZED;
    case ThreadLevel::kMultiple: return MPI_THREAD_MULTIPLE;
  }
  return MPI_THREAD_SINGLE;
}

ThreadLevel from_mpi_level(int level) {
  if (level >= MPI_THREAD_MULTIPLE) return ThreadLevel::kMultiple;
  if (level >= MPI_THREAD_SERIALIZED) return ThreadLevel::kSerialized;
  if (level >= MPI_THREAD_FUNNELED) return ThreadLevel::kFunneled;
  return ThreadLevel::kSingle;
}

std::string_view name(ThreadLevel level) {
  switch (level) {
    case ThreadLevel::kSingle: return "MPI_THREAD_SINGLE";
    case ThreadLevel::kFunneled: return "MPI_THREAD_FUNNELED";
    case ThreadLevel::kSerialized: return "MPI_THREAD_SERIALIZED";
    case ThreadLevel::kMultiple: return "MPI_THREAD_MULTIPLE";
  }
  return "?";
}

}  // namespace

MpiEnvironment::MpiEnvironment(int& argc, char**& argv, ThreadLevel required) { init(&argc, &argv, required); }

MpiEnvironment::MpiEnvironment(ThreadLevel required) { init(nullptr, nullptr, required); }

void MpiEnvironment::init(int* argc, char*** argv, ThreadLevel required) {
  int initialized = 0, finalized = 0, level = 0;
  check_mpi(MPI_Initialized(&initialized), "Initialized");
  check_mpi(MPI_Finalized(&finalized), "Finalized");
  if (finalized != 0) throw LibraryError("MpiEnvironment: MPI was already finalized and cannot be initialized again");
  if (initialized == 0) {
    check_mpi(MPI_Init_thread(argc, argv, to_mpi_level(required), &level), "Init_thread");
    owns_ = true;
  } else {
    check_mpi(MPI_Query_thread(&level), "Query_thread");
  }
  provided_ = from_mpi_level(level);
  if (provided_ < required) {
    if (owns_) MPI_Finalize();
    owns_ = false;
    throw LibraryError(fmt::format("MpiEnvironment: MPI provides {}, {} is required", name(provided_), name(required)));
  }
}

MpiEnvironment::~MpiEnvironment() {
  // HDF5's clean-up, which MPI_Finalize runs in the parallel build, crashes after a failed file close;
  // cli::main ends the process without it (h5::file_close_failed).
  if (h5::file_close_failed()) return;
  int finalized = 0;
  if (owns_ && MPI_Finalized(&finalized) == MPI_SUCCESS && finalized == 0) MPI_Finalize();
}

bool launched_by_mpi() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_SIZE", "PMI_RANK"})
    if (std::getenv(name) != nullptr) return true;
  return false;
}

bool may_be_rank_zero() {
  for (const char* name : {"OMPI_COMM_WORLD_RANK", "PMIX_RANK", "PMI_RANK", "SLURM_PROCID"})
    if (const char* v = std::getenv(name); v != nullptr && std::string_view(v) != "0") return false;
  return true;
}

}  // namespace gimforge::mpi
