/// \file hdf5_guard.cpp
/// What the HDF5 layer refuses to open (hdf5.h, Group; docs/archive.md "What readers refuse"): links that
/// are not hard links, datasets whose data lies outside the file, filters that cannot be decoded here; and
/// what it refuses to read: data a dataset declares but the file does not store (Dataset::readable_block,
/// require_stored).
/// Archives come from other people: none of this may make gimforge read another file or load code. Also
/// the bound on how long one metadata call may run (set_call_deadline), for HDF5's own endless loops.
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <climits>
#include <set>
#include <cstdint>
#include <string>
#include <vector>

#include "io/hdf5_internal.h"
#include "io/hdf5_storage.h"
#include "kernels/core/errors.h"

namespace gimforge::h5::detail {

/// "2^20" for powers of two from 2^10 on, else the number: bounds read better that way in messages.
std::string bound_text(std::int64_t v) {
  if (v >= 1024 && std::has_single_bit(static_cast<std::uint64_t>(v)))
    return fmt::format("2^{}", std::countr_zero(static_cast<std::uint64_t>(v)));
  if (v <= -1024 && v != INT64_MIN && std::has_single_bit(static_cast<std::uint64_t>(-v)))
    return fmt::format("-2^{}", std::countr_zero(static_cast<std::uint64_t>(-v)));
  if (v == INT64_MIN) return "-2^63";
  return std::to_string(v);
}

namespace {

/// Absolute path of `child` below `loc` ("/gim/bunny" + "geometry"), for messages.
std::string child_path(hid_t loc, std::string_view child) {
  if (child.starts_with('/')) return std::string(child);
  std::string path = read_name(H5Iget_name, loc);
  if (!path.ends_with('/')) path += '/';
  return path + std::string(child);
}


/// Throws FormatError "FILE: PATH is a soft link (to '/x'); gimforge follows only hard links" for link
/// `name` of `loc` of type `info`.
[[noreturn]] void throw_link(hid_t loc, const std::string& name, const H5L_info_t& info) {
  const std::string where = child_path(loc, name);
  std::string target;
  if ((info.type == H5L_TYPE_SOFT || info.type == H5L_TYPE_EXTERNAL) && info.u.val_size > 0 &&
      info.u.val_size < (1u << 16)) {
    std::vector<char> buf(info.u.val_size + 1, '\0');
    if (H5Lget_val(loc, name.c_str(), buf.data(), buf.size(), H5P_DEFAULT) >= 0) {
      if (info.type == H5L_TYPE_SOFT) {
        target = fmt::format(" (to '{}')", buf.data());
      } else {
        const char* file = nullptr;
        const char* object = nullptr;
        unsigned flags = 0;
        if (H5Lunpack_elink_val(buf.data(), info.u.val_size, &flags, &file, &object) >= 0 && file && object)
          target = fmt::format(" (to {}:{})", file, object);
      }
    }
  }
  H5Eclear2(H5E_DEFAULT);
  const std::string_view kind = info.type == H5L_TYPE_SOFT       ? "a soft link"
                                : info.type == H5L_TYPE_EXTERNAL ? "an external link"
                                                                 : "a user-defined link";
  throw_format(loc, fmt::format("{} is {}{}; gimforge follows only hard links", where, kind, target));
}

}  // namespace

/// Checks that every component of the path `name` below `loc` that exists is a hard link, before
/// anything traverses it (an external link would open another file). Components that do not exist end
/// the walk: the caller's open reports them as before.
void require_hard_links(hid_t loc, std::string_view name) {
  std::string prefix = name.starts_with('/') ? "/" : "";
  std::size_t pos = 0;
  while (pos < name.size()) {
    const std::size_t end = std::min(name.find('/', pos), name.size());
    const std::string_view part = name.substr(pos, end - pos);
    pos = end + 1;
    if (part.empty() || part == ".") continue;
    if (!prefix.empty() && !prefix.ends_with('/')) prefix += '/';
    prefix += part;
    H5L_info_t info{};
    if (H5Lexists(loc, prefix.c_str(), H5P_DEFAULT) <= 0 || H5Lget_info(loc, prefix.c_str(), &info, H5P_DEFAULT) < 0) {
      H5Eclear2(H5E_DEFAULT);
      return;
    }
    if (info.type != H5L_TYPE_HARD) throw_link(loc, prefix, info);
  }
}

namespace {

/// The name of filter `id`: what the file stores, else the name of a well-known registered filter.
std::string filter_name(H5Z_filter_t id, const char* stored) {
  if (stored != nullptr && stored[0] != '\0') return stored;
  switch (id) {
    case 32000: return "lzf";
    case 32001: return "blosc";
    case 32004: return "lz4";
    case 32008: return "bitshuffle";
    case 32013: return "zfp";
    case 32015: return "zstd";
    case 32017: return "sz";
    case 32026: return "blosc2";
    case 307: return "bzip2";
    case H5Z_FILTER_SZIP: return "szip";
    default: return "unknown";
  }
}

}  // namespace

/// Refuses dataset `ds` when its raw data lies outside the file (external storage, virtual dataset) or a
/// filter of its pipeline cannot be decoded here (hdf5.h, Group).
void check_dataset_storage(hid_t ds) {
  Handle dcpl = make(H5Dget_create_plist(ds), H5Pclose, "query dataset storage", ds);
  const std::string path = read_name(H5Iget_name, ds);
  const H5D_layout_t layout = H5Pget_layout(dcpl.id());
  if (layout == H5D_VIRTUAL)
    throw_format(ds, fmt::format("dataset {} is a virtual dataset (its data comes from other datasets or files); "
                                 "gimforge reads only data stored in the file itself",
                                 path));
  const int external = check(H5Pget_external_count(dcpl.id()), "query dataset storage", ds);
  if (external > 0) {
    char file[512] = {};
    off_t offset = 0;
    hsize_t size = 0;
    if (H5Pget_external(dcpl.id(), 0, sizeof file - 1, file, &offset, &size) < 0) H5Eclear2(H5E_DEFAULT);
    throw_format(ds, fmt::format("dataset {} stores its data in external file '{}'; gimforge reads only data "
                                 "stored in the file itself",
                                 path, file));
  }
  const int filters = check(H5Pget_nfilters(dcpl.id()), "query dataset filters", ds);
  for (int i = 0; i < filters; ++i) {
    unsigned flags = 0, config = 0;
    std::size_t nvalues = 0;
    char name[256] = {};
    const H5Z_filter_t id =
        H5Pget_filter2(dcpl.id(), static_cast<unsigned>(i), &flags, &nvalues, nullptr, sizeof name - 1, name, &config);
    if (id < 0) throw_library("query dataset filters", ds);
    const htri_t available = H5Zfilter_avail(id);
    unsigned info = 0;
    const bool decodes = available > 0 && H5Zget_filter_info(id, &info) >= 0 &&
                         (info & H5Z_FILTER_CONFIG_DECODE_ENABLED) != 0;
    H5Eclear2(H5E_DEFAULT);
    if (!decodes)
      throw_format(ds, fmt::format("dataset {} uses compression filter {} ({}) which gimforge cannot read; rewrite "
                                   "it with gzip or none",
                                   path, id, filter_name(id, name)));
  }
}

/// Switches off HDF5's loading of filter plugins (shared objects from HDF5_PLUGIN_PATH or the default
/// plugin directory) once for the process: a file must not make gimforge load and run code. Filters
/// built into the library (deflate, shuffle, fletcher32, scale-offset, n-bit) are unaffected.
void disable_plugins() {
  static const bool disabled = [] { return H5PLset_loading_state(0) >= 0; }();
  (void)disabled;
}

namespace {

/// What H5Lvisit found below a group: the first link that is not a hard link, and the datasets, each once
/// (a file may link one dataset under many names).
struct TreeScan {
  std::string soft;
  H5L_info_t soft_info{};
  std::vector<std::string> datasets;
  std::set<haddr_t> seen;
};


herr_t scan_link(hid_t group, const char* name, const H5L_info_t* info, void* data) noexcept {
  try {
    auto* scan = static_cast<TreeScan*>(data);
    if (info->type != H5L_TYPE_HARD) {
      scan->soft = name;
      scan->soft_info = *info;
      return 1;  // stop: reported by check_tree
    }
    H5O_info_t object{};
    if (H5Oget_info_by_name(group, name, &object, H5P_DEFAULT) < 0) return -1;
    if (object.type == H5O_TYPE_DATASET && scan->seen.insert(object.addr).second) scan->datasets.emplace_back(name);
    return 0;
  } catch (...) {
    return -1;
  }
}

}  // namespace

/// Refuses object `name` of `loc` (hdf5.h, Group::copy_to) when it or anything below it is a link other
/// than a hard link or a dataset check_dataset_storage refuses.
void check_tree(hid_t loc, const std::string& name) {
  require_hard_links(loc, name);
  Handle object = make(H5Oopen(loc, name.c_str(), H5P_DEFAULT), H5Oclose, "open object", loc, name);
  H5O_info_t info{};
  check(H5Oget_info(object.id(), &info), "query object", loc, name);
  std::vector<std::string> datasets;
  if (info.type == H5O_TYPE_GROUP) {
    TreeScan scan;
    check(H5Lvisit(object.id(), H5_INDEX_NAME, H5_ITER_INC, scan_link, &scan), "list group", loc, name);
    if (!scan.soft.empty()) throw_link(object.id(), scan.soft, scan.soft_info);
    for (const std::string& d : scan.datasets) {
      Handle ds = make(H5Dopen2(object.id(), d.c_str(), H5P_DEFAULT), H5Dclose, "open dataset", object.id(), d);
      check_dataset_storage(ds.id());
    }
  } else if (info.type == H5O_TYPE_DATASET) {
    check_dataset_storage(object.id());
  }
}

// ---- the bound on metadata calls ------------------------------------------------------------------

namespace {

unsigned g_call_deadline = 0;  ///< seconds, 0: none (set_call_deadline)
unsigned g_call_depth = 0;     ///< DeadlineScopes open

}  // namespace

DeadlineScope::DeadlineScope() noexcept {
  if (g_call_deadline > 0 && g_call_depth++ == 0) alarm(g_call_deadline);
}

DeadlineScope::~DeadlineScope() {
  if (g_call_deadline > 0 && g_call_depth > 0 && --g_call_depth == 0) alarm(0);
}

}  // namespace gimforge::h5::detail

namespace gimforge::h5 {

void set_call_deadline(unsigned seconds) {
  if (detail::g_call_depth > 0) alarm(0);
  detail::g_call_deadline = seconds;
  detail::g_call_depth = 0;
}

unsigned call_deadline() { return detail::g_call_deadline; }

// ---- data the file declares but does not store ----------------------------------------------------

namespace {

/// Throws FormatError when the file does not store the block of dataset `id` (at `path`) at `offset` with
/// extents `count` (inside the extents, non-empty): an unwritten chunk, or contiguous data never allocated.
void require_block_stored(hid_t id, const std::string& path, const Dims& offset, const Dims& count, const Dims& extents) {
  Handle dcpl = detail::make(H5Dget_create_plist(id), H5Pclose, "query dataset storage", id);
  const H5D_layout_t layout = H5Pget_layout(dcpl.id());
  if (layout < 0) detail::throw_library("query dataset storage", id);
  // Asked of contiguous data only: for chunked data HDF5 1.10 sums every chunk's size (the whole index per
  // read, quadratic over a stack read item by item); the chunks this read covers are looked up below instead.
  H5D_space_status_t allocated = H5D_SPACE_STATUS_ERROR;
  if (layout == H5D_CONTIGUOUS) detail::check(H5Dget_space_status(id, &allocated), "query dataset storage", id);
  if (layout == H5D_CONTIGUOUS && allocated == H5D_SPACE_STATUS_NOT_ALLOCATED)
    detail::throw_format(id, fmt::format("dataset {} declares {} values and stores none (they would read as fill "
                                         "values)",
                                         path, Dataset::product(extents)));
  if (layout != H5D_CHUNKED) return;  // compact data lives in the object header; virtual is refused at open
  std::vector<hsize_t> chunk(extents.size(), 0);
  if (H5Pget_chunk(dcpl.id(), static_cast<int>(chunk.size()), chunk.data()) != static_cast<int>(chunk.size()))
    detail::throw_library("query dataset chunks", id);
  // The chunks the block covers, each looked up in the chunk index: the read visits each of them anyway.
  Dims first(extents.size()), last(extents.size());
  for (std::size_t d = 0; d < extents.size(); ++d) {
    if (chunk[d] == 0) detail::throw_format(id, fmt::format("dataset {} has a chunk extent of 0", path));
    first[d] = offset[d] / chunk[d];
    last[d] = (offset[d] + count[d] - 1) / chunk[d];
  }
  Dims at = first;
  std::vector<hsize_t> coord(extents.size());
  for (;;) {
    for (std::size_t d = 0; d < at.size(); ++d) coord[d] = at[d] * chunk[d];
    // A lookup in the chunk index (H5Dget_chunk_info_by_coord walks all of it in HDF5 1.10), which fails
    // ("chunk storage is not allocated") for a chunk never written.
    hsize_t size = 0;
    if (H5Dget_chunk_storage_size(id, coord.data(), &size) < 0) {
      H5Eclear2(H5E_DEFAULT);
      size = 0;
    }
    if (size == 0)
      detail::throw_format(id, fmt::format("dataset {} does not store its chunk at ({}) (it would read as fill "
                                           "values)",
                                           path, fmt::join(coord, ", ")));
    std::size_t d = at.size();
    while (d > 0 && at[d - 1] == last[d - 1]) at[d - 1] = first[d - 1], --d;
    if (d == 0) return;
    ++at[d - 1];
  }
}

}  // namespace

std::size_t Dataset::readable_block(const Dims& offset, const Dims& count, std::size_t element_size) const {
  const std::size_t n = readable_count(count, element_size);
  const Dims extents = shape();
  if (n == 0 || offset.size() != extents.size() || count.size() != extents.size()) return n;
  for (std::size_t d = 0; d < extents.size(); ++d)
    if (offset[d] > extents[d] || count[d] > extents[d] - offset[d]) return n;  // the read refuses it
  // Only files opened for reading: a writer reading back what it wrote (still in HDF5's chunk cache, not
  // yet in the file) reads its own data.
  Handle file = detail::make(H5Iget_file_id(id()), H5Fclose, "query dataset storage", id());
  unsigned intent = 0;
  detail::check(H5Fget_intent(file.id(), &intent), "query dataset storage", id());
  if ((intent & H5F_ACC_RDWR) != 0) return n;
  require_block_stored(id(), path(), offset, count, extents);
  return n;
}

void require_stored(const Dataset& ds) {
  const Dims extents = ds.shape();
  if (Dataset::product(extents) == 0) return;
  require_block_stored(ds.id(), ds.path(), Dims(extents.size(), 0), extents, extents);
}

void require_stored(const Group& group, std::string_view skip) {
  if (!skip.empty()) {
    for (const std::string& child : group.children()) {
      if (child == skip) continue;
      H5O_info_t info{};
      detail::require_hard_links(group.id(), child);
      detail::check(H5Oget_info_by_name(group.id(), child.c_str(), &info, H5P_DEFAULT), "query object", group.id(), child);
      if (info.type == H5O_TYPE_GROUP) require_stored(group.open_group(child));
      if (info.type == H5O_TYPE_DATASET) require_stored(group.open_dataset(child));
    }
    return;
  }
  detail::TreeScan scan;
  detail::check(H5Lvisit(group.id(), H5_INDEX_NAME, H5_ITER_INC, detail::scan_link, &scan), "list group", group.id());
  if (!scan.soft.empty()) detail::throw_link(group.id(), scan.soft, scan.soft_info);
  // Opened by their paths below the group, which the visit found to be hard links only.
  for (const std::string& d : scan.datasets) {
    Handle ds = detail::make(H5Dopen2(group.id(), d.c_str(), H5P_DEFAULT), H5Dclose, "open dataset", group.id(), d);
    Handle space = detail::make(H5Dget_space(ds.id()), H5Sclose, "query dataset extents", ds.id());
    const Dims extents = detail::space_dims(space.id(), ds.id());
    if (Dataset::product(extents) > 0)
      require_block_stored(ds.id(), detail::read_name(H5Iget_name, ds.id()), Dims(extents.size(), 0), extents, extents);
  }
}

}  // namespace gimforge::h5
