/// \file hdf5_mpio.cpp
/// MPI-IO property helpers for the HDF5 layer (see hdf5_mpio.h).
#include "mpi/hdf5_mpio.h"

#include <hdf5.h>

#include "kernels/core/errors.h"
#include "mpi/mpi_comm.h"

namespace gimforge::mpi {
namespace {

h5::DataTransfer transfer(H5FD_mpio_xfer_t mode, std::string_view what) {
  h5::DataTransfer xfer;
  xfer.add(what, [mode](h5::Hid id) { return H5Pset_dxpl_mpio(id, mode); });
  return xfer;
}

}  // namespace

h5::FileAccess mpio_file_access(const Comm& comm) {
  h5::FileAccess access;
  if (!is_mpi(comm)) return access;
  const MPI_Comm native_comm = native(comm);
  access.add("H5Pset_fapl_mpio", [native_comm](h5::Hid id) { return H5Pset_fapl_mpio(id, native_comm, MPI_INFO_NULL); })
      .add("H5Pset_fclose_degree", [](h5::Hid id) { return H5Pset_fclose_degree(id, H5F_CLOSE_STRONG); });
  return access;
}

h5::DataTransfer collective_transfer() { return transfer(H5FD_MPIO_COLLECTIVE, "H5Pset_dxpl_mpio(collective)"); }

h5::DataTransfer independent_transfer() { return transfer(H5FD_MPIO_INDEPENDENT, "H5Pset_dxpl_mpio(independent)"); }

MpioIoMode actual_io_mode(const h5::DataTransfer& xfer) {
  if (xfer.id() <= 0) throw InvalidInput("mpi::actual_io_mode: a default DataTransfer records no MPI-IO mode");
  H5D_mpio_actual_io_mode_t mode = H5D_MPIO_NO_COLLECTIVE;
  h5::check_status(H5Pget_mpio_actual_io_mode(xfer.id(), &mode), "query H5Pget_mpio_actual_io_mode");
  switch (mode) {
    case H5D_MPIO_NO_COLLECTIVE: return MpioIoMode::kNoCollective;
    case H5D_MPIO_CHUNK_INDEPENDENT: return MpioIoMode::kChunkIndependent;
    case H5D_MPIO_CHUNK_COLLECTIVE: return MpioIoMode::kChunkCollective;
    case H5D_MPIO_CHUNK_MIXED: return MpioIoMode::kChunkMixed;
    case H5D_MPIO_CONTIGUOUS_COLLECTIVE: return MpioIoMode::kContiguousCollective;
  }
  return MpioIoMode::kNoCollective;
}

}  // namespace gimforge::mpi
