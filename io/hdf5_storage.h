#pragma once
/// \file hdf5_storage.h
/// Whether a file stores all of a dataset's data, asked without reading it (`gimforge ls`, XDMF sidecars).
/// Readers need not ask: every read checks the part it covers (hdf5.h, Dataset::read).
#include "io/hdf5.h"

namespace gimforge::h5 {

/// Throws FormatError naming the dataset when the file does not store all of its data: a chunk never
/// written, or contiguous data never allocated (both read as fill values). One chunk-index lookup per
/// chunk; nothing is read. Meant for files opened read-only: a writer's chunks may still be in HDF5's
/// chunk cache.
void require_stored(const Dataset& ds);
/// require_stored of every dataset below `group`, at any depth, each once however many links name it (and
/// FormatError for a link below it that is not a hard link, as Group::copy_to), except below its child
/// `skip` (a batch output's `items`: one group per item, which the readers check when they read one).
void require_stored(const Group& group, std::string_view skip = {});

}  // namespace gimforge::h5
