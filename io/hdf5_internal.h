#pragma once
/// \file hdf5_internal.h
/// Private to the HDF5 layer (io/hdf5.cpp, io/hdf5_file.cpp, io/hdf5_guard.cpp): the checked-call and error helpers, and
/// what readers refuse (hdf5.h, Group). Includes <hdf5.h>; nothing outside io/hdf5*.cpp includes it.
#include <hdf5.h>

#include <cstdint>
#include <string>
#include <string_view>

#include "io/hdf5.h"

namespace gimforge::h5::detail {

/// Text of the innermost error on the default stack, "description (minor message)"; clears the stack.
std::string take_hdf5_error();
/// Calls an HDF5 name getter (H5Iget_name, H5Fget_name, H5Aget_name); "" on failure.
std::string read_name(ssize_t (*getter)(hid_t, char*, size_t), hid_t id);
/// "FILE:PATH[/CHILD]" naming `loc` (and optionally a child of it) in error messages.
std::string location(hid_t loc, std::string_view child = {});
/// Throws LibraryError "LOCATION: cannot OP: HDF5 ERROR". Reads the error stack before anything else.
[[noreturn]] void throw_library(std::string_view op, hid_t loc, std::string_view child = {});
/// Throws InvalidInput "LOCATION: cannot OP: WHY".
[[noreturn]] void throw_invalid(hid_t loc, std::string_view op, std::string_view why);
/// Throws FormatError "FILE: WHAT" (FILE: the file holding `loc`).
[[noreturn]] void throw_format(hid_t loc, std::string_view what);

/// Returns `status` or throws LibraryError when it is negative.
template <class T>
T check(T status, std::string_view op, hid_t loc, std::string_view child = {}) {
  if (status < 0) throw_library(op, loc, child);
  return status;
}

/// H5Dclose that remembers a failure in a file open for writing: a chunked dataset's last chunks reach the
/// file when it closes, so a full disk fails the close, not the write, and the close has no caller to tell.
/// File::flush and File::close of that file report it (io/hdf5_file.cpp).
int close_dataset(hid_t id);

/// The extents of dataspace `space` (errors name `loc`).
Dims space_dims(hid_t space, hid_t loc);

/// Wraps a freshly created identifier, or throws LibraryError when creation failed.
Handle make(hid_t id, Handle::CloseFn close, std::string_view op, hid_t loc, std::string_view child = {});

/// Keeps up to 1024 attributes in the header of the object that creation property list `ocpl` makes
/// (HDF5's default moves more than 8 into "dense" storage, a fractal heap whose blocks carry no checksum):
/// with the version-2 headers of the 1.10 format (io/hdf5_file.cpp) every attribute value is then under a
/// checksum. Throws LibraryError naming `op` at `loc`.
void keep_attributes_in_header(hid_t ocpl, hid_t loc, std::string_view op);

// ---- what readers refuse (io/hdf5_guard.cpp) -------------------------------------------------------

/// "2^20" for powers of two from 2^10 on, else the number: bounds read better that way in messages.
std::string bound_text(std::int64_t v);
/// Throws FormatError unless every existing component of the path `name` below `loc` is a hard link;
/// checked before anything traverses it (an external link would open another file). The walk ends at
/// a component that does not exist: the caller's open reports it as before.
void require_hard_links(hid_t loc, std::string_view name);
/// Throws FormatError when dataset `ds` keeps its raw data outside the file (external storage, virtual
/// dataset) or needs a filter this HDF5 cannot decode.
void check_dataset_storage(hid_t ds);
/// Throws FormatError when object `name` of `loc`, or anything below it, is reached through a link that
/// is not a hard link or is a dataset check_dataset_storage refuses (Group::copy_to).
void check_tree(hid_t loc, const std::string& name);
/// Switches off HDF5's loading of filter plugins once for the process (File::open).
void disable_plugins();

/// Arms alarm(2) for the duration of one metadata call when set_call_deadline set a bound (hdf5.h); the
/// outermost of nested scopes arms and disarms it.
class DeadlineScope {
 public:
  DeadlineScope() noexcept;
  ~DeadlineScope();
  DeadlineScope(const DeadlineScope&) = delete;
  DeadlineScope& operator=(const DeadlineScope&) = delete;
};

}  // namespace gimforge::h5::detail
