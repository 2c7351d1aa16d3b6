#pragma once
/// \file hdf5_mpio.h
/// MPI-IO for the HDF5 layer (io/hdf5.h): a FileAccess that opens files on all ranks of a communicator,
/// and DataTransfer properties for collective or independent dataset transfers, plus a query of what
/// HDF5 actually did (tests use it to assert that collective I/O really happened).
///
/// Usage (every line collective over `comm`):
///   h5::File f = h5::File::create(path, h5::CreateMode::kTruncate, mpi::mpio_file_access(comm));
///   h5::Dataset ds = f.create_dataset("x", h5::DataType::of<float>(), {n_total, 8});
///   h5::DataTransfer xfer = mpi::collective_transfer();
///   ds.write_slab({first_row, 0}, {my_rows, 8}, my_values, xfer);
///   assert(mpi::is_collective(mpi::actual_io_mode(xfer)));
#include "io/hdf5.h"
#include "mpi/comm.h"

namespace gimforge::mpi {

/// File access through HDF5's MPI-IO driver over `comm` (H5Pset_fapl_mpio; HDF5 keeps its own duplicate
/// of the communicator). With MPI-IO, file create/open/close and every metadata change (groups,
/// datasets, attributes, extents) are collective and must get identical arguments on all ranks.
/// The close degree is H5F_CLOSE_STRONG: closing the File (close() or its destructor) closes every
/// object still open in it, so the collective close happens at the same point on all ranks (the MPI-IO
/// default, SEMI, would fail on a rank still holding a Group). Objects outliving their File are then
/// invalid (their use throws LibraryError).
/// For a communicator that is not MPI-backed (the serial one) it returns the default (POSIX) access, so the same code
/// runs without MPI. Throws LibraryError when HDF5 refuses the setting.
[[nodiscard]] h5::FileAccess mpio_file_access(const Comm& comm);

/// A transfer property requesting collective MPI-IO (H5Pset_dxpl_mpio, H5FD_MPIO_COLLECTIVE): every rank
/// must take part in each read/write using it (possibly with an empty block). Use a fresh one per
/// transfer when querying actual_io_mode(). Throws LibraryError when HDF5 refuses the setting.
[[nodiscard]] h5::DataTransfer collective_transfer();

/// A transfer property requesting independent MPI-IO (H5FD_MPIO_INDEPENDENT, HDF5's default).
[[nodiscard]] h5::DataTransfer independent_transfer();

/// What HDF5 actually did in the last transfer made with a DataTransfer (H5D_mpio_actual_io_mode_t).
enum class MpioIoMode {
  kNoCollective,          ///< independent I/O only
  kChunkIndependent,      ///< chunked dataset, each chunk written independently
  kChunkCollective,       ///< chunked dataset, collective I/O
  kChunkMixed,            ///< chunked dataset, some chunks collective, some independent
  kContiguousCollective,  ///< contiguous dataset, collective I/O
};

/// The I/O mode HDF5 recorded in `xfer` during its last transfer (H5Pget_mpio_actual_io_mode).
/// Throws InvalidInput for a default DataTransfer (nothing recorded), LibraryError when HDF5 fails.
[[nodiscard]] MpioIoMode actual_io_mode(const h5::DataTransfer& xfer);

/// True for kChunkCollective and kContiguousCollective (all of the transfer was collective).
[[nodiscard]] constexpr bool is_collective(MpioIoMode mode) noexcept {
  return mode == MpioIoMode::kChunkCollective || mode == MpioIoMode::kContiguousCollective;
}

}  // namespace gimforge::mpi
