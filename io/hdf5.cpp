/// \file hdf5.cpp
/// Implementation of the checked HDF5 layer (see hdf5.h). Every C call goes through check() or one of
/// the make_* helpers, which turn a negative status into an exception carrying the innermost HDF5 error.
#include "io/hdf5.h"

#include <fmt/format.h>
#include <hdf5.h>

#include <algorithm>
#include <climits>
#include <cmath>

#include "io/hdf5_internal.h"
#include "kernels/core/errors.h"

namespace gimforge::h5 {

static_assert(std::is_same_v<hid_t, Hid>, "hdf5.h hides hid_t as std::int64_t (HDF5 >= 1.10)");
static_assert(std::is_same_v<herr_t, int>, "Handle::CloseFn assumes herr_t is int");

using namespace detail;

namespace {

// ---- error reporting (declared in hdf5_internal.h) -----------------------------------------------

// ---- error reporting ---------------------------------------------------------------------------

/// The innermost entry of the default HDF5 error stack: its description and minor-class message.
struct InnermostError {
  std::string desc;
  hid_t minor = -1;
};

herr_t record_innermost(unsigned n, const H5E_error2_t* err, void* data) noexcept {
  if (n != 0 || err == nullptr) return 0;  // H5E_WALK_UPWARD visits the innermost error first
  auto* out = static_cast<InnermostError*>(data);
  try {
    out->desc = err->desc != nullptr ? err->desc : "";
  } catch (...) {  // out of memory while formatting an error: keep the message short
  }
  out->minor = err->min_num;
  return 0;
}

}  // namespace

namespace detail {

/// Text of the innermost error on the default stack, "description (minor message)"; clears the stack.
std::string take_hdf5_error() {
  InnermostError inner;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, record_innermost, &inner);
  std::string minor;
  if (inner.minor >= 0) {
    char buf[256] = {};
    if (H5Eget_msg(inner.minor, nullptr, buf, sizeof buf) > 0) minor = buf;
  }
  H5Eclear2(H5E_DEFAULT);
  // The POSIX driver's failures ("file write failed: time = ..., filename = ..., file descriptor = 5,
  // errno = 28, error message = 'No space left on device', buf = 0x..., ...", "unable to extend file
  // properly, errno = 27, error message = 'File too large'") become "file write failed: No space left on
  // device": the cause, without the driver's bookkeeping.
  if (const std::size_t at = inner.desc.find(", error message = '"); at != std::string::npos) {
    const std::size_t from = at + std::string_view(", error message = '").size();
    const std::size_t to = inner.desc.find('\'', from);
    const std::size_t head = std::min(inner.desc.find(": time = "), inner.desc.find(", errno = "));
    if (to != std::string::npos && head < at)
      inner.desc = inner.desc.substr(0, head) + ": " + inner.desc.substr(from, to - from);
  }
  if (inner.desc.empty() && minor.empty()) return "unknown HDF5 error";
  if (minor.empty() || inner.desc.empty()) return inner.desc + minor;
  return fmt::format("{} ({})", inner.desc, minor);
}

/// Calls an HDF5 name getter (H5Iget_name, H5Fget_name, H5Aget_name); "" on failure.
std::string read_name(ssize_t (*getter)(hid_t, char*, size_t), hid_t id) {
  const ssize_t len = getter(id, nullptr, 0);
  if (len <= 0) return {};
  std::string name(static_cast<std::size_t>(len) + 1, '\0');
  if (getter(id, name.data(), name.size()) < 0) return {};
  name.resize(static_cast<std::size_t>(len));
  return name;
}

/// "FILE:PATH[/CHILD]" naming `loc` (and optionally a child of it) in error messages.
std::string location(hid_t loc, std::string_view child) {
  if (loc <= 0) return "HDF5";
  std::string path = read_name(H5Iget_name, loc);
  if (!child.empty()) {
    if (!path.ends_with('/')) path += '/';
    path += child;
  }
  return fmt::format("{}:{}", read_name(H5Fget_name, loc), path);
}

/// Throws LibraryError "LOCATION: cannot OP: HDF5 ERROR". Reads the error stack before anything else.
[[noreturn]] void throw_library(std::string_view op, hid_t loc, std::string_view child) {
  std::string cause = take_hdf5_error();
  throw LibraryError(fmt::format("{}: cannot {}: {}", location(loc, child), op, cause));
}

/// Wraps a freshly created identifier, or throws LibraryError when creation failed.
Handle make(hid_t id, Handle::CloseFn close, std::string_view op, hid_t loc, std::string_view child) {
  check(id, op, loc, child);
  return Handle(id, close);
}

[[noreturn]] void throw_invalid(hid_t loc, std::string_view op, std::string_view why) {
  throw InvalidInput(fmt::format("{}: cannot {}: {}", location(loc), op, why));
}

[[noreturn]] void throw_format(hid_t loc, std::string_view what) {
  throw FormatError(fmt::format("{}: {}", read_name(H5Fget_name, loc), what));
}

Dims space_dims(hid_t space, hid_t loc) {
  const int rank = check(H5Sget_simple_extent_ndims(space), "query dataspace", loc);
  std::vector<hsize_t> dims(static_cast<std::size_t>(rank));
  check(H5Sget_simple_extent_dims(space, dims.data(), nullptr), "query dataspace", loc);
  return Dims(dims.begin(), dims.end());
}

}  // namespace detail

namespace {

// ---- types -------------------------------------------------------------------------------------

/// In-memory HDF5 type of a numeric DType (predefined: never closed).
hid_t native_type(DType type) {
  switch (type) {
    case DType::kUInt8: return H5T_NATIVE_UINT8;
    case DType::kUInt16: return H5T_NATIVE_UINT16;
    case DType::kInt32: return H5T_NATIVE_INT32;
    case DType::kInt64: return H5T_NATIVE_INT64;
    case DType::kFloat32: return H5T_NATIVE_FLOAT;
    case DType::kFloat64: return H5T_NATIVE_DOUBLE;
    case DType::kInt8: return H5T_NATIVE_INT8;
    case DType::kUInt32: return H5T_NATIVE_UINT32;
    case DType::kString: break;
  }
  throw InvalidInput("HDF5: strings have no numeric memory type");
}

/// On-disk HDF5 type of a numeric DType: little-endian, fixed width (predefined: never closed).
hid_t file_type(DType type) {
  switch (type) {
    case DType::kUInt8: return H5T_STD_U8LE;
    case DType::kUInt16: return H5T_STD_U16LE;
    case DType::kInt32: return H5T_STD_I32LE;
    case DType::kInt64: return H5T_STD_I64LE;
    case DType::kFloat32: return H5T_IEEE_F32LE;
    case DType::kFloat64: return H5T_IEEE_F64LE;
    case DType::kInt8: return H5T_STD_I8LE;
    case DType::kUInt32: return H5T_STD_U32LE;
    case DType::kString: break;
  }
  throw InvalidInput("HDF5: strings have no numeric file type");
}

std::size_t element_size(DataType type) {
  switch (type.kind) {
    case DType::kUInt8:
    case DType::kInt8: return 1;
    case DType::kUInt16: return 2;
    case DType::kInt32:
    case DType::kUInt32:
    case DType::kFloat32: return 4;
    case DType::kInt64:
    case DType::kFloat64: return 8;
    case DType::kString: return type.string_length == 0 ? sizeof(hvl_t) : type.string_length;
  }
  return 1;
}

/// A UTF-8 string type: variable-length when `length` is 0, else fixed `length` bytes, null-padded.
Handle make_string_type(std::size_t length) {
  Handle type = make(H5Tcopy(H5T_C_S1), H5Tclose, "copy string type", 0);
  check(H5Tset_size(type.id(), length == 0 ? H5T_VARIABLE : length), "set string size", 0);
  check(H5Tset_cset(type.id(), H5T_CSET_UTF8), "set string character set", 0);
  if (length != 0) check(H5Tset_strpad(type.id(), H5T_STR_NULLPAD), "set string padding", 0);
  return type;
}

/// "a string", "an integer", ... for attribute type messages.
std::string_view class_name(H5T_class_t cls) {
  switch (cls) {
    case H5T_STRING: return "a string";
    case H5T_INTEGER: return "an integer";
    case H5T_FLOAT: return "a floating-point number";
    default: return "a value of an unsupported type";
  }
}

/// Strings stored fixed-length: cut at the first NUL, drop space padding.
std::string unpad(const char* data, std::size_t size, H5T_str_t pad) {
  std::string s(data, std::find(data, data + size, '\0'));
  if (pad == H5T_STR_SPACEPAD) s.erase(s.find_last_not_of(' ') + 1);
  return s;
}

std::vector<hsize_t> to_hsize(const Dims& dims) { return std::vector<hsize_t>(dims.begin(), dims.end()); }

/// A link creation property list that creates missing intermediate groups.
Handle intermediate_lcpl() {
  Handle lcpl = make(H5Pcreate(H5P_LINK_CREATE), H5Pclose, "create link property list", 0);
  check(H5Pset_create_intermediate_group(lcpl.id(), 1), "set intermediate group creation", 0);
  return lcpl;
}

// ---- attributes --------------------------------------------------------------------------------

/// Creates (replacing an existing one) attribute `name` on `obj` and writes `buf` into it.
void write_attribute(hid_t obj, const std::string& name, hid_t mem_type, hid_t file_type_id, hid_t space,
                     const void* buf) {
  const std::string op = fmt::format("write attribute '{}'", name);
  if (check(H5Aexists(obj, name.c_str()), op, obj) > 0) check(H5Adelete(obj, name.c_str()), op, obj);
  Handle attr = make(H5Acreate2(obj, name.c_str(), file_type_id, space, H5P_DEFAULT, H5P_DEFAULT), H5Aclose, op, obj);
  check(H5Awrite(attr.id(), mem_type, buf), op, obj);
}

/// An open attribute whose stored class was checked against the expected one.
struct CheckedAttribute {
  Handle attr;
  Handle type;
  std::size_t count = 0;  ///< number of stored values (0 for an empty array)
};

/// Opens attribute `name` of `obj` and checks it holds `expected` values; with `scalar`, exactly one.
CheckedAttribute open_attribute(hid_t obj, std::string_view name, H5T_class_t expected, bool scalar) {
  const std::string key(name);
  const std::string op = fmt::format("read attribute '{}'", name);
  const std::string path = read_name(H5Iget_name, obj);
  if (check(H5Aexists(obj, key.c_str()), op, obj) == 0)
    throw_format(obj, fmt::format("{} has no attribute '{}'", path, name));
  CheckedAttribute a;
  a.attr = make(H5Aopen(obj, key.c_str(), H5P_DEFAULT), H5Aclose, op, obj);
  a.type = make(H5Aget_type(a.attr.id()), H5Tclose, op, obj);
  const H5T_class_t cls = H5Tget_class(a.type.id());
  if (cls != expected)
    throw_format(
        obj, fmt::format("attribute '{}' of {} is {}, expected {}", name, path, class_name(cls), class_name(expected)));
  Handle space = make(H5Aget_space(a.attr.id()), H5Sclose, op, obj);
  a.count = static_cast<std::size_t>(check(H5Sget_simple_extent_npoints(space.id()), op, obj));
  if (scalar && a.count != 1)
    throw_format(obj, fmt::format("attribute '{}' of {} holds {} values, expected one", name, path, a.count));
  return a;
}

template <class T>
std::vector<T> read_numeric_attribute(hid_t obj, std::string_view name, H5T_class_t cls, hid_t mem_type) {
  const DeadlineScope deadline;
  CheckedAttribute a = open_attribute(obj, name, cls, false);
  constexpr std::size_t kMaxAttributeValues = std::size_t{1} << 20;  // attributes hold small metadata only
  if (a.count > kMaxAttributeValues)
    throw_format(obj, fmt::format("attribute '{}' of {} holds {} values, more than an attribute may ({})", name,
                                  read_name(H5Iget_name, obj), a.count, kMaxAttributeValues));
  std::vector<T> values(a.count);
  if (a.count > 0) check(H5Aread(a.attr.id(), mem_type, values.data()), "read attribute", obj, name);
  return values;
}

/// A dataspace for `n` values: null (no elements) when n is 0, else 1-D.
Handle vector_space(std::size_t n, hid_t loc) {
  if (n == 0) return make(H5Screate(H5S_NULL), H5Sclose, "create dataspace", loc);
  const hsize_t dims[1] = {n};
  return make(H5Screate_simple(1, dims, nullptr), H5Sclose, "create dataspace", loc);
}

// ---- dataset helpers ---------------------------------------------------------------------------

/// Throws FormatError unless dataset `ds` stores strings (`strings`) or numbers (!`strings`).
void require_class(hid_t ds, bool strings) {
  Handle type = make(H5Dget_type(ds), H5Tclose, "query dataset type", ds);
  const bool is_string = H5Tget_class(type.id()) == H5T_STRING;
  if (is_string != strings)
    throw_format(ds, fmt::format("dataset {} holds {}, expected {}", read_name(H5Iget_name, ds),
                                 is_string ? "strings" : "numbers", strings ? "strings" : "numbers"));
}

/// File and memory dataspaces selecting block (`offset`, `count`) of `ds` and `n` contiguous values.
struct Selection {
  Handle file;
  Handle memory;
};

Selection select_block(hid_t ds, const Dims& offset, const Dims& count, std::size_t n, std::string_view op) {
  Selection sel;
  sel.file = make(H5Dget_space(ds), H5Sclose, op, ds);
  const Dims shape = space_dims(sel.file.id(), ds);
  if (offset.size() != shape.size() || count.size() != shape.size())
    throw_invalid(ds, op, fmt::format("offset and count need rank {}", shape.size()));
  for (std::size_t d = 0; d < shape.size(); ++d)
    if (offset[d] > shape[d] || count[d] > shape[d] - offset[d])
      throw_invalid(ds, op,
                    fmt::format("block [{}, +{}) leaves dimension {} of extent {}", offset[d], count[d], d, shape[d]));
  if (n != Dataset::product(count))
    throw_invalid(ds, op, fmt::format("got {} values for a block of {}", n, Dataset::product(count)));
  const hsize_t mem_dims[1] = {std::max<hsize_t>(n, 1)};
  sel.memory = make(H5Screate_simple(1, mem_dims, nullptr), H5Sclose, op, ds);
  if (n == 0) {  // an empty block still takes part in collective transfers
    check(H5Sselect_none(sel.file.id()), op, ds);
    check(H5Sselect_none(sel.memory.id()), op, ds);
  } else {
    const std::vector<hsize_t> start = to_hsize(offset), extent = to_hsize(count);
    check(H5Sselect_hyperslab(sel.file.id(), H5S_SELECT_SET, start.data(), nullptr, extent.data(), nullptr), op, ds);
  }
  return sel;
}

/// A buffer HDF5 accepts for an empty selection or array (it rejects null buffers); never accessed.
std::byte g_empty_buffer[8];
const void* nonnull(const void* data) { return data != nullptr ? data : g_empty_buffer; }
void* nonnull(void* data) { return data != nullptr ? data : g_empty_buffer; }

/// The size of HDF5 type `type` in bytes; throws LibraryError when HDF5 cannot tell.
std::size_t type_size(hid_t type, std::string_view op, hid_t loc) {
  const std::size_t size = H5Tget_size(type);
  if (size == 0) throw_library(op, loc);
  return size;
}

/// Chunk shape chosen when compression or resizing needs one: extents (the first one at least 1024 when
/// resizable) halved, largest first, until a chunk holds at most 1 MiB.
Dims default_chunk(const Dims& shape, std::size_t elem_size, bool resizable) {
  constexpr std::uint64_t kTargetBytes = 1u << 20;
  Dims chunk = shape;
  if (resizable) chunk[0] = std::max<std::uint64_t>(chunk[0], 1024);
  for (auto& c : chunk) c = std::max<std::uint64_t>(c, 1);
  while (Dataset::product(chunk) * elem_size > kTargetBytes) {
    auto largest = std::max_element(chunk.begin(), chunk.end());
    if (*largest == 1) break;
    *largest = (*largest + 1) / 2;
  }
  return chunk;
}

/// The dataset creation property list for `options` (validated against `shape`).
Handle make_dcpl(hid_t loc, std::string_view name, const Dims& shape, DataType type, const DatasetOptions& options) {
  const std::string op = fmt::format("create dataset '{}'", name);
  if (options.deflate < 0 || options.deflate > 9)
    throw_invalid(loc, op, fmt::format("deflate level {} is outside 0..9", options.deflate));
  if (!options.chunk.empty() && options.chunk.size() != shape.size())
    throw_invalid(loc, op,
                  fmt::format("chunk rank {} differs from dataset rank {}", options.chunk.size(), shape.size()));
  const bool empty = std::find(shape.begin() + (options.resizable ? 1 : 0), shape.end(), 0u) != shape.end();
  if (empty && options.resizable)
    throw_invalid(loc, op, "a resizable dataset needs non-zero extents beyond the first dimension");
  Handle dcpl = make(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, op, loc);
  keep_attributes_in_header(dcpl.id(), loc, op);
  const bool wants_chunks = !options.chunk.empty() || options.deflate > 0 || options.shuffle || options.resizable;
  if (!wants_chunks || empty) return dcpl;  // contiguous (a fixed zero extent cannot be chunked)
  const Dims chunk =
      options.chunk.empty() ? default_chunk(shape, element_size(type), options.resizable) : options.chunk;
  for (std::size_t d = 0; d < chunk.size(); ++d)
    if (chunk[d] == 0 || (chunk[d] > shape[d] && !(options.resizable && d == 0)))
      throw_invalid(loc, op, fmt::format("chunk extent {} in dimension {} is not in 1..{}", chunk[d], d, shape[d]));
  const std::vector<hsize_t> dims = to_hsize(chunk);
  check(H5Pset_chunk(dcpl.id(), static_cast<int>(dims.size()), dims.data()), op, loc);
  if (options.shuffle) check(H5Pset_shuffle(dcpl.id()), op, loc);
  if (options.deflate > 0) check(H5Pset_deflate(dcpl.id(), static_cast<unsigned>(options.deflate)), op, loc);
  return dcpl;
}

/// Iteration callback (H5Literate, H5Aiterate2) appending each name to a std::vector<std::string>.
template <class Info>
herr_t collect_name(hid_t, const char* name, const Info*, void* data) noexcept {
  try {
    static_cast<std::vector<std::string>*>(data)->emplace_back(name);
    return 0;
  } catch (...) {
    return -1;  // stops the iteration; the caller reports it
  }
}

}  // namespace

// ---- free functions, handles, property lists -----------------------------------------------------

void silence_errors() {
  static const bool silenced = [] { return H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr) >= 0; }();
  (void)silenced;
}

int check_status(int status, std::string_view what) {
  if (status < 0) throw LibraryError(fmt::format("HDF5: cannot {}: {}", what, take_hdf5_error()));
  return status;
}

bool Handle::reset() noexcept {
  bool ok = true;
  if (id_ > 0 && close_ != nullptr) ok = close_(id_) >= 0;
  id_ = 0;
  close_ = nullptr;
  return ok;
}

void PropertyList::apply(std::string_view what, const PropertySetter& setter) {
  silence_errors();
  if (!handle_.valid()) {
    const hid_t cls = kind_ == Kind::kFileAccess ? H5P_FILE_ACCESS : H5P_DATASET_XFER;
    handle_ = make(H5Pcreate(cls), H5Pclose, "create property list", 0);
  }
  check_status(setter(handle_.id()), fmt::format("set property {}", what));
}

// ---- Object ------------------------------------------------------------------------------------

std::string Object::path() const { return read_name(H5Iget_name, id()); }

std::string Object::file_name() const { return read_name(H5Fget_name, id()); }

bool Object::has_attribute(std::string_view name) const {
  const DeadlineScope deadline;
  const std::string key(name);
  return check(H5Aexists(id(), key.c_str()), "query attribute", id(), key) > 0;
}

std::vector<std::string> Object::attribute_names() const {
  const DeadlineScope deadline;
  std::vector<std::string> names;
  check(H5Aiterate2(id(), H5_INDEX_NAME, H5_ITER_INC, nullptr, collect_name<H5A_info_t>, &names), "list attributes",
        id());
  return names;
}

void Object::set_attribute(std::string_view name, std::string_view value) {
  Handle type = make_string_type(0);
  Handle space = make(H5Screate(H5S_SCALAR), H5Sclose, "create dataspace", id());
  const std::string text(value);
  const char* ptr = text.c_str();
  write_attribute(id(), std::string(name), type.id(), type.id(), space.id(), &ptr);
}

void Object::set_int64_attribute(std::string_view name, std::int64_t value) {
  Handle space = make(H5Screate(H5S_SCALAR), H5Sclose, "create dataspace", id());
  write_attribute(id(), std::string(name), H5T_NATIVE_INT64, H5T_STD_I64LE, space.id(), &value);
}

void Object::set_double_attribute(std::string_view name, double value) {
  Handle space = make(H5Screate(H5S_SCALAR), H5Sclose, "create dataspace", id());
  write_attribute(id(), std::string(name), H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, space.id(), &value);
}

void Object::set_attribute(std::string_view name, std::span<const double> values) {
  Handle space = vector_space(values.size(), id());
  write_attribute(id(), std::string(name), H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, space.id(), nonnull(values.data()));
}

void Object::set_attribute(std::string_view name, std::span<const std::int64_t> values) {
  Handle space = vector_space(values.size(), id());
  write_attribute(id(), std::string(name), H5T_NATIVE_INT64, H5T_STD_I64LE, space.id(), nonnull(values.data()));
}

void Object::throw_out_of_int64_range(std::string_view name) const {
  throw_invalid(id(), fmt::format("write attribute '{}'", name), "value does not fit in int64");
}

template <>
std::string Object::attribute<std::string>(std::string_view name) const {
  const DeadlineScope deadline;
  CheckedAttribute a = open_attribute(id(), name, H5T_STRING, true);
  const htri_t variable = check(H5Tis_variable_str(a.type.id()), "read attribute", id(), name);
  if (variable > 0) {
    Handle mem = make_string_type(0);
    char* ptr = nullptr;
    check(H5Aread(a.attr.id(), mem.id(), &ptr), "read attribute", id(), name);
    std::string value = ptr != nullptr ? ptr : "";
    H5free_memory(ptr);
    return value;
  }
  std::string buf(type_size(a.type.id(), "read attribute", id()), '\0');
  check(H5Aread(a.attr.id(), a.type.id(), buf.data()), "read attribute", id(), name);
  return unpad(buf.data(), buf.size(), H5Tget_strpad(a.type.id()));
}

template <>
std::int64_t Object::attribute<std::int64_t>(std::string_view name) const {
  const DeadlineScope deadline;
  CheckedAttribute a = open_attribute(id(), name, H5T_INTEGER, true);
  std::int64_t value = 0;
  check(H5Aread(a.attr.id(), H5T_NATIVE_INT64, &value), "read attribute", id(), name);
  return value;
}

template <>
double Object::attribute<double>(std::string_view name) const {
  const DeadlineScope deadline;
  CheckedAttribute a = open_attribute(id(), name, H5T_FLOAT, true);
  double value = 0;
  check(H5Aread(a.attr.id(), H5T_NATIVE_DOUBLE, &value), "read attribute", id(), name);
  return value;
}

template <>
std::vector<double> Object::attribute<std::vector<double>>(std::string_view name) const {
  return read_numeric_attribute<double>(id(), name, H5T_FLOAT, H5T_NATIVE_DOUBLE);
}

template <>
std::vector<std::int64_t> Object::attribute<std::vector<std::int64_t>>(std::string_view name) const {
  return read_numeric_attribute<std::int64_t>(id(), name, H5T_INTEGER, H5T_NATIVE_INT64);
}

std::int64_t Object::attribute_in_range(std::string_view name, std::int64_t lo, std::int64_t hi) const {
  const DeadlineScope deadline;
  // An unsigned attribute above INT64_MAX must not wrap into range: read its sign and size first.
  CheckedAttribute a = open_attribute(id(), name, H5T_INTEGER, true);
  std::int64_t value = 0;
  if (H5Tget_sign(a.type.id()) == H5T_SGN_NONE && H5Tget_size(a.type.id()) >= sizeof(std::uint64_t)) {
    std::uint64_t u = 0;
    check(H5Aread(a.attr.id(), H5T_NATIVE_UINT64, &u), "read attribute", id(), name);
    if (u > static_cast<std::uint64_t>(INT64_MAX))
      throw FormatError(fmt::format("{}:{}: attribute {} = {} is outside [{}, {}]", file_name(), path(), name, u,
                                    bound_text(lo), bound_text(hi)));
    value = static_cast<std::int64_t>(u);
  } else {
    check(H5Aread(a.attr.id(), H5T_NATIVE_INT64, &value), "read attribute", id(), name);
  }
  if (value < lo || value > hi)
    throw FormatError(fmt::format("{}:{}: attribute {} = {} is outside [{}, {}]", file_name(), path(), name, value,
                                  bound_text(lo), bound_text(hi)));
  return value;
}

double Object::finite_attribute_in_range(std::string_view name, double lo, double hi) const {
  const DeadlineScope deadline;
  const double value = attribute<double>(name);
  if (!std::isfinite(value) || value < lo || value > hi)
    throw FormatError(fmt::format("{}:{}: attribute {} = {} is outside [{}, {}]", file_name(), path(), name, value, lo, hi));
  return value;
}

// ---- Dataset -----------------------------------------------------------------------------------

std::uint64_t Dataset::product(const Dims& dims) noexcept {
  std::uint64_t n = 1;
  for (const auto d : dims) n *= d;
  return n;
}

std::size_t Dataset::readable_count(const Dims& extents, std::size_t element_size) const {
  std::uint64_t n = 1;
  bool overflow = false;
  for (const auto d : extents) {
    if (d != 0 && n > UINT64_MAX / d) overflow = true;
    n = overflow ? n : n * d;
  }
  if (overflow || (element_size > 0 && n > kMaxReadBytes / element_size))
    throw_format(id(), fmt::format("dataset {} has extents ({}): {} values, more than gimforge reads at once ({} "
                                   "bytes)",
                                   path(), fmt::join(extents, ", "), overflow ? std::string("too many")
                                                                              : std::to_string(n),
                                   bound_text(static_cast<std::int64_t>(kMaxReadBytes))));
  return static_cast<std::size_t>(n);
}

Dims Dataset::shape() const {
  Handle space = make(H5Dget_space(id()), H5Sclose, "query dataset shape", id());
  return space_dims(space.id(), id());
}

std::uint64_t Dataset::element_count() const { return product(shape()); }

DType Dataset::dtype() const {
  Handle type = make(H5Dget_type(id()), H5Tclose, "query dataset type", id());
  const std::size_t size = H5Tget_size(type.id());
  switch (H5Tget_class(type.id())) {
    case H5T_STRING: return DType::kString;
    case H5T_FLOAT:
      if (size == 4) return DType::kFloat32;
      if (size == 8) return DType::kFloat64;
      break;
    case H5T_INTEGER: {
      const bool is_signed = H5Tget_sign(type.id()) == H5T_SGN_2;
      if (size == 1 && !is_signed) return DType::kUInt8;
      if (size == 1 && is_signed) return DType::kInt8;
      if (size == 2 && !is_signed) return DType::kUInt16;
      if (size == 4 && is_signed) return DType::kInt32;
      if (size == 4 && !is_signed) return DType::kUInt32;
      if (size == 8 && is_signed) return DType::kInt64;
      break;
    }
    default: break;
  }
  throw_format(id(), fmt::format("dataset {} has an element type outside gimforge's set", path()));
}

void Dataset::write_numeric(const void* data, std::size_t n, DType type, const DataTransfer& xfer) {
  require_class(id(), false);
  const std::uint64_t expected = element_count();
  if (n != expected)
    throw_invalid(id(), "write dataset", fmt::format("got {} values, the dataset holds {}", n, expected));
  if (n == 0) return;
  check(H5Dwrite(id(), native_type(type), H5S_ALL, H5S_ALL, xfer.id(), data), "write dataset", id());
}

void Dataset::read_numeric(void* data, std::size_t n, DType type, const DataTransfer& xfer) const {
  require_class(id(), false);
  if (n == 0) return;
  check(H5Dread(id(), native_type(type), H5S_ALL, H5S_ALL, xfer.id(), data), "read dataset", id());
}

void Dataset::write_slab_numeric(const Dims& offset, const Dims& count, const void* data, std::size_t n, DType type,
                                 const DataTransfer& xfer) {
  require_class(id(), false);
  const Selection sel = select_block(id(), offset, count, n, "write dataset block");
  check(H5Dwrite(id(), native_type(type), sel.memory.id(), sel.file.id(), xfer.id(), nonnull(data)),
        "write dataset block", id());
}

void Dataset::read_slab_numeric(const Dims& offset, const Dims& count, void* data, std::size_t n, DType type,
                                const DataTransfer& xfer) const {
  require_class(id(), false);
  const Selection sel = select_block(id(), offset, count, n, "read dataset block");
  check(H5Dread(id(), native_type(type), sel.memory.id(), sel.file.id(), xfer.id(), nonnull(data)),
        "read dataset block", id());
}

void Dataset::extend(std::uint64_t first_extent) {
  Dims dims = shape();
  if (dims.empty()) throw_invalid(id(), "extend dataset", "a scalar dataset has no dimension to extend");
  dims[0] = first_extent;
  const std::vector<hsize_t> extent = to_hsize(dims);
  check(H5Dset_extent(id(), extent.data()), "extend dataset", id());
}

void Dataset::append_numeric(const void* data, std::size_t n, DType type) {
  const Dims dims = shape();
  if (dims.empty()) throw_invalid(id(), "append to dataset", "a scalar dataset has no rows");
  const std::uint64_t rows = dims.front();
  const std::uint64_t row = product(Dims(dims.begin() + 1, dims.end()));
  if (row == 0 ? n != 0 : n % row != 0)
    throw_invalid(id(), "append to dataset", fmt::format("{} values are not whole rows of {}", n, row));
  if (n == 0) return;
  Dims offset(dims.size(), 0), count = dims;
  offset.at(0) = rows;
  count.at(0) = n / row;
  extend(rows + n / row);
  write_slab_numeric(offset, count, data, n, type, DataTransfer{});
}

void Dataset::write_strings(std::span<const std::string> data) {
  require_class(id(), true);
  const std::uint64_t expected = element_count();
  if (data.size() != expected)
    throw_invalid(id(), "write dataset", fmt::format("got {} strings, the dataset holds {}", data.size(), expected));
  if (data.empty()) return;
  Handle type = make(H5Dget_type(id()), H5Tclose, "write dataset", id());
  if (check(H5Tis_variable_str(type.id()), "write dataset", id()) > 0) {
    std::vector<const char*> ptrs;
    for (const auto& s : data) ptrs.push_back(s.c_str());
    check(H5Dwrite(id(), type.id(), H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data()), "write dataset", id());
    return;
  }
  const std::size_t length = type_size(type.id(), "write dataset", id());
  std::vector<char> buf(length * data.size(), '\0');
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (data[i].size() > length)
      throw_invalid(id(), "write dataset",
                    fmt::format("string {} has {} bytes, the dataset stores {}", i, data[i].size(), length));
    std::copy(data[i].begin(), data[i].end(), buf.begin() + static_cast<std::ptrdiff_t>(i * length));
  }
  check(H5Dwrite(id(), type.id(), H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data()), "write dataset", id());
}

std::vector<std::string> Dataset::read_strings() const {
  const DeadlineScope deadline;
  require_class(id(), true);
  Handle type = make(H5Dget_type(id()), H5Tclose, "read dataset", id());
  const bool variable_length = check(H5Tis_variable_str(type.id()), "read dataset", id()) > 0;
  // Each element costs its bytes in the file's type and a std::string here: both count against the limit.
  const Dims extents = shape();
  const auto n = readable_block(Dims(extents.size(), 0), extents,
                                (variable_length ? sizeof(char*) : type_size(type.id(), "read dataset", id())) +
                                    sizeof(std::string));
  std::vector<std::string> out;
  out.reserve(n);
  if (n == 0) return out;
  if (variable_length) {
    Handle mem = make_string_type(0);
    Handle space = make(H5Dget_space(id()), H5Sclose, "read dataset", id());
    std::vector<char*> ptrs(n, nullptr);
    check(H5Dread(id(), mem.id(), H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data()), "read dataset", id());
    for (const char* p : ptrs) out.emplace_back(p != nullptr ? p : "");
    H5Dvlen_reclaim(mem.id(), space.id(), H5P_DEFAULT, ptrs.data());
    return out;
  }
  const std::size_t length = type_size(type.id(), "read dataset", id());
  std::vector<char> buf(length * n);
  check(H5Dread(id(), type.id(), H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data()), "read dataset", id());
  const H5T_str_t pad = H5Tget_strpad(type.id());
  for (std::size_t i = 0; i < n; ++i) out.push_back(unpad(buf.data() + i * length, length, pad));
  return out;
}

// ---- Group -------------------------------------------------------------------------------------

Group Group::create_group(std::string_view name) {
  const std::string key(name);
  Handle lcpl = intermediate_lcpl();
  Handle gcpl = make(H5Pcreate(H5P_GROUP_CREATE), H5Pclose, "create group", id(), key);
  keep_attributes_in_header(gcpl.id(), id(), "create group");
  return Group(
      make(H5Gcreate2(id(), key.c_str(), lcpl.id(), gcpl.id(), H5P_DEFAULT), H5Gclose, "create group", id(), key));
}

Group Group::open_group(std::string_view name) const {
  const DeadlineScope deadline;
  const std::string key(name);
  require_hard_links(id(), key);
  return Group(make(H5Gopen2(id(), key.c_str(), H5P_DEFAULT), H5Gclose, "open group", id(), key));
}

Group Group::require_group(std::string_view name) { return exists(name) ? open_group(name) : create_group(name); }

void Group::copy_to(std::string_view name, Group& destination, std::string_view new_name) const {
  const std::string from(name), to(new_name);
  check_tree(id(), from);
  Handle lcpl = intermediate_lcpl();
  check(H5Ocopy(id(), from.c_str(), destination.id(), to.c_str(), H5P_DEFAULT, lcpl.id()), "copy object", id(), from);
}

bool Group::exists(std::string_view name) const {
  const DeadlineScope deadline;
  std::string prefix = name.starts_with('/') ? "/" : "";
  std::size_t pos = 0;
  while (pos < name.size()) {
    const std::size_t end = std::min(name.find('/', pos), name.size());
    if (end > pos) {
      if (!prefix.empty() && !prefix.ends_with('/')) prefix += '/';
      prefix += name.substr(pos, end - pos);
      if (check(H5Lexists(id(), prefix.c_str(), H5P_DEFAULT), "query link", id(), prefix) == 0) return false;
      require_hard_links(id(), prefix);  // before anything traverses it
    }
    pos = end + 1;
  }
  return true;
}

std::vector<std::string> Group::children() const {
  const DeadlineScope deadline;
  std::vector<std::string> names;
  check(H5Literate(id(), H5_INDEX_NAME, H5_ITER_INC, nullptr, collect_name<H5L_info_t>, &names), "list group", id());
  return names;
}

Dataset Group::create_dataset(std::string_view name, DataType type, const Dims& shape, const DatasetOptions& options) {
  const std::string key(name);
  const std::string op = fmt::format("create dataset '{}'", key);
  if (shape.empty()) throw_invalid(id(), op, "a dataset needs rank >= 1");
  Handle dcpl = make_dcpl(id(), key, shape, type, options);
  Dims max_dims = shape;
  if (options.resizable) max_dims[0] = H5S_UNLIMITED;
  const std::vector<hsize_t> dims = to_hsize(shape), max = to_hsize(max_dims);
  Handle space = make(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), max.data()), H5Sclose, op, id());
  Handle string_type;
  if (type.kind == DType::kString) string_type = make_string_type(type.string_length);
  const hid_t stored = type.kind == DType::kString ? string_type.id() : file_type(type.kind);
  Handle lcpl = intermediate_lcpl();
  return Dataset(make(H5Dcreate2(id(), key.c_str(), stored, space.id(), lcpl.id(), dcpl.id(), H5P_DEFAULT), close_dataset,
                      "create dataset", id(), key));
}

Dataset Group::open_dataset(std::string_view name) const {
  const DeadlineScope deadline;
  const std::string key(name);
  require_hard_links(id(), key);
  Dataset ds(make(H5Dopen2(id(), key.c_str(), H5P_DEFAULT), close_dataset, "open dataset", id(), key));
  check_dataset_storage(ds.id());
  return ds;
}

Dataset Group::write_strings(std::string_view name, std::span<const std::string> data, DataType type,
                             const DatasetOptions& options) {
  if (type.kind != DType::kString) throw_invalid(id(), "write strings", "the dataset type must be a string type");
  Dataset ds = create_dataset(name, type, {data.size()}, options);
  ds.write_strings(data);
  return ds;
}

}  // namespace gimforge::h5
