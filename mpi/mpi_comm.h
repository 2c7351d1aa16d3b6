#pragma once
/// \file mpi_comm.h
/// The MPI implementation of mpi::Comm. Each Comm duplicates the MPI communicator it is made from (so
/// its traffic never mixes with the caller's), switches the duplicate to MPI_ERRORS_RETURN, checks every
/// MPI call (failures become LibraryError with MPI_Error_string's text) and frees the duplicate when
/// destroyed (unless MPI is already finalized). MPI must be initialized (see environment.h).
#include <mpi.h>

#include <string_view>

#include "mpi/comm.h"

namespace gimforge::mpi {

/// A Comm over a duplicate of MPI_COMM_WORLD. Collective over MPI_COMM_WORLD.
/// Throws LibraryError when MPI is not initialized or the duplication fails.
[[nodiscard]] Comm mpi_world();

/// A Comm over a duplicate of `comm` (the caller keeps ownership of `comm`). Collective over `comm`.
/// Throws InvalidInput for MPI_COMM_NULL, LibraryError when MPI is not initialized or duplication fails.
[[nodiscard]] Comm from_mpi(MPI_Comm comm);

/// The MPI communicator behind an MPI Comm (owned by `comm`: valid while it lives), e.g. for HDF5's
/// MPI-IO driver. Throws InvalidInput for a Comm that is not MPI-backed (the serial one).
[[nodiscard]] MPI_Comm native(const Comm& comm);

/// True when `comm` is MPI-backed (made by mpi_world / from_mpi / split of those), false for the serial one.
[[nodiscard]] bool is_mpi(const Comm& comm) noexcept;

/// For code calling MPI directly on a communicator with MPI_ERRORS_RETURN: does nothing when `rc` is
/// MPI_SUCCESS, else throws LibraryError "MPI WHAT failed: MPI_Error_string text".
void check_mpi(int rc, std::string_view what);

}  // namespace gimforge::mpi
