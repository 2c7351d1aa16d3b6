/// \file hdf5_file.cpp
/// File of the checked HDF5 layer (hdf5.h): creating and opening files in the checksummed 1.10 format, and
/// where objects keep their attributes (docs/archive.md, "Integrity").
#include <fmt/format.h>
#include <hdf5.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>

#include "io/hdf5.h"
#include "io/hdf5_internal.h"
#include "kernels/core/errors.h"

namespace gimforge::h5 {

using namespace detail;

namespace detail {

void keep_attributes_in_header(hid_t ocpl, hid_t loc, std::string_view op) {
  if (H5Pset_attr_phase_change(ocpl, 1024, 1000) < 0) throw_library(op, loc, "");
}

}  // namespace detail

// ---- File --------------------------------------------------------------------------------------

namespace {

std::atomic<bool> close_failed{false};

/// H5Fclose, remembering a failure for file_close_failed(). A file open for writing is flushed first; when
/// that fails (a full disk) the write has failed, its file is a temporary that the writer removes
/// (io::write_atomically), and its blocks are released (truncated through the POSIX driver's descriptor) so
/// that the close itself can write what it must: a close that fails leaves HDF5 1.10.8 unable to shut down
/// (file_close_failed), under MPI in every rank's MPI_Finalize.
/// Returns a failure when the flush failed even if the close then succeeded: what was written is lost, and
/// File::close reports the flush's cause (`flush_error`: "file write failed: No space left on device"), not
/// what HDF5 says of a close after a failed flush ("slist already enabled?").
thread_local std::string flush_error;

/// Failed closes of written datasets (close_dataset), by file name: the first one's message.
std::mutex dataset_failures_mutex;
std::map<std::string, std::string> dataset_failures;

/// The entry of dataset_failures for file `name`, removed ("" when none). Never throws: closes run in
/// noexcept code.
std::string take_dataset_failure(const std::string& name) noexcept {
  try {
    const std::lock_guard<std::mutex> lock(dataset_failures_mutex);
    const auto it = dataset_failures.find(name);
    if (it == dataset_failures.end()) return {};
    std::string message = std::move(it->second);
    dataset_failures.erase(it);
    return message;
  } catch (...) {
    return {};
  }
}

/// Throws the first failed close of a written dataset of file `name`, if any.
void throw_dataset_failure(const std::string& name) {
  if (std::string message = take_dataset_failure(name); !message.empty()) throw IoError(message);
}

/// Whether file identifier `file` is open for writing.
bool open_for_writing(hid_t file) noexcept {
  unsigned intent = 0;
  return file >= 0 && H5Fget_intent(file, &intent) >= 0 && (intent & H5F_ACC_RDWR) != 0;
}

int close_file(Hid id) {
  flush_error.clear();
  const bool written = open_for_writing(id);
  // A written dataset whose close failed: what the file holds is not what was written.
  if (written) {
    try {
      flush_error = take_dataset_failure(read_name(H5Fget_name, id));
    } catch (...) {  // no memory for the name: the entry stays
    }
  }
  if (written && H5Fflush(id, H5F_SCOPE_LOCAL) < 0) {
    if (flush_error.empty()) {
      try {
        flush_error = take_hdf5_error();
      } catch (...) {
        flush_error = "cannot flush file";
      }
    }
    const hid_t fapl = H5Fget_access_plist(id);
    void* handle = nullptr;
    if (fapl >= 0 && H5Pget_driver(fapl) == H5FD_SEC2 && H5Fget_vfd_handle(id, fapl, &handle) >= 0 && handle != nullptr)
      (void)::ftruncate(*static_cast<int*>(handle), 0);
    if (fapl >= 0) H5Pclose(fapl);
    H5Eclear2(H5E_DEFAULT);
  }
  const herr_t status = H5Fclose(id);
  if (status < 0) close_failed.store(true);
  return flush_error.empty() ? status : -1;
}

/// Opens `path` as a file with flags, turning failure into IoError "PATH: cannot OP: ...".
Handle open_file(hid_t id, const std::filesystem::path& path, std::string_view op) {
  if (id < 0) throw IoError(fmt::format("{}: cannot {}: {}", path.string(), op, take_hdf5_error()));
  return Handle(id, close_file);
}

/// `access` with the 1.10 file format as both bounds: every object header (version 2) and every chunk index
/// (fixed and extensible arrays instead of version-1 B-trees) carries a checksum HDF5 verifies on read, so
/// a flipped bit in a quantized image's `scale` or in a chunk's address is an error, not a wrong surface.
/// Every reader since HDF5 1.10 (h5py included) opens the file.
Handle checksummed_metadata(const FileAccess& access) {
  Handle fapl = make(access.id() == H5P_DEFAULT ? H5Pcreate(H5P_FILE_ACCESS) : H5Pcopy(access.id()), H5Pclose,
                     "create property list", 0);
  check_status(H5Pset_libver_bounds(fapl.id(), H5F_LIBVER_V110, H5F_LIBVER_V110), "set property libver bounds");
  return fapl;
}

}  // namespace

File File::create(const std::filesystem::path& path, CreateMode mode, const FileAccess& access) {
  silence_errors();
  const unsigned flags = mode == CreateMode::kExclusive ? H5F_ACC_EXCL : H5F_ACC_TRUNC;
  const Handle fapl = checksummed_metadata(access);
  const Handle fcpl = make(H5Pcreate(H5P_FILE_CREATE), H5Pclose, "create property list", 0);
  keep_attributes_in_header(fcpl.id(), 0, "create HDF5 file");  // the root group's
  {  // a failure left by an earlier file of this name (a dataset closed after its file) is not this file's
    const std::lock_guard<std::mutex> lock(dataset_failures_mutex);
    dataset_failures.erase(path.string());
  }
  return File(open_file(H5Fcreate(path.c_str(), flags, fcpl.id(), fapl.id()), path, "create HDF5 file"));
}

File File::open(const std::filesystem::path& path, OpenMode mode, const FileAccess& access) {
  const DeadlineScope deadline;
  silence_errors();
  disable_plugins();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw IoError(fmt::format("{}: no such file", path.string()));
  // HDF5's open() of a named pipe would wait for a writer forever (io/input_file.h).
  if (!std::filesystem::is_regular_file(path, ec))
    throw IoError(fmt::format("{}: is not a regular file (a directory, pipe, device or socket), not an HDF5 archive",
                              path.string()));
  if (mode == OpenMode::kReadWrite) {
    // Objects added to an archive get checksummed headers too.
    const Handle fapl = checksummed_metadata(access);
    return File(open_file(H5Fopen(path.c_str(), H5F_ACC_RDWR, fapl.id()), path, "open HDF5 file"));
  }
  return File(open_file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, access.id()), path, "open HDF5 file"));
}

bool file_close_failed() noexcept { return close_failed.load(); }

int detail::close_dataset(hid_t id) {
  const hid_t file = H5Iget_file_id(id);
  const bool written = open_for_writing(file);
  std::string name, path;
  try {  // runs in noexcept code: without memory for the names the failure goes unnamed, never terminates
    if (written) name = read_name(H5Fget_name, file), path = read_name(H5Iget_name, id);
  } catch (...) {
  }
  if (file >= 0) H5Fclose(file);
  const herr_t status = H5Dclose(id);
  if (status < 0 && written && !name.empty()) {
    try {
      const std::lock_guard<std::mutex> lock(dataset_failures_mutex);
      dataset_failures.try_emplace(name, fmt::format("{}:{}: cannot write dataset: {}", name, path, take_hdf5_error()));
    } catch (...) {
    }
  }
  return status;
}

void Object::flush_file() const {
  const Handle file(H5Iget_file_id(id()), H5Fclose);
  if (!open_for_writing(file.id())) return;
  const std::string name = read_name(H5Fget_name, file.id());
  throw_dataset_failure(name);
  if (H5Fflush(file.id(), H5F_SCOPE_LOCAL) < 0)
    throw IoError(fmt::format("{}: cannot flush file: {}", name, take_hdf5_error()));
}

void File::flush() {
  throw_dataset_failure(file_name());
  check(H5Fflush(id(), H5F_SCOPE_GLOBAL), "flush file", id());
}

void File::close() {
  const std::string name = file_name();
  if (handle().reset()) return;
  if (flush_error.starts_with(name + ":")) throw IoError(std::exchange(flush_error, std::string()));
  if (!flush_error.empty())
    throw IoError(fmt::format("{}: cannot flush file: {}", name, std::exchange(flush_error, std::string())));
  throw IoError(fmt::format("{}: cannot close HDF5 file: {}", name, take_hdf5_error()));
}

}  // namespace gimforge::h5
