#pragma once
/// \file hdf5.h
/// A thin, checked RAII layer over the HDF5 C API (in the spirit of HighFive's bits/h5*_wrapper.hpp).
///
/// - Every HDF5 call is checked. A failure becomes a typed exception with a one-line message
///   `FILE:PATH: cannot OPERATION: INNERMOST HDF5 ERROR (MINOR CLASS)`:
///   gimforge::IoError when a file cannot be created or opened (the message starts with the file path),
///   gimforge::FormatError when an object holds another kind of value than requested (wrong attribute type),
///   gimforge::LibraryError for any other HDF5 failure, gimforge::InvalidInput for bad arguments.
/// - HDF5's automatic error printing is switched off once for the process (see silence_errors()), so
///   neither normal nor failing runs print `HDF5-DIAG` noise; the error text travels in the exception.
/// - Handles are move-only and closed by their destructor.
/// - This header does not include <hdf5.h>: identifiers are carried as `Hid` (HDF5 1.10's `hid_t` is
///   int64_t; hdf5.cpp checks this at compile time). `id()` accessors expose the raw identifier as an
///   escape hatch for the MPI-IO helpers (mpi/hdf5_mpio.h) and for tests.
///
/// Thread safety: the Debian HDF5 build is not thread-safe; use this layer from one thread at a time.
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <ranges>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

namespace gimforge::h5 {

/// An HDF5 identifier (`hid_t` in the C API).
using Hid = std::int64_t;
/// Dataset and dataspace extents, slowest-varying dimension first (row-major, like numpy/h5py).
using Dims = std::vector<std::uint64_t>;

/// Turns HDF5's automatic error printing off for the default error stack. Idempotent and thread-safe (a
/// function-local static). File::create / File::open and property lists call it, and every other object
/// comes from a File, so callers never need to.
void silence_errors();

/// True once an HDF5 file of this process failed to close (H5Fclose: a full disk, an I/O error while it
/// flushed). HDF5 1.10.8 then leaves the half-destroyed file in its identifier table, and its own clean-up
/// (at exit, and at MPI_Finalize in the parallel build) crashes on it (HDFGroup/hdf5#2257, fixed in later
/// releases). cli::main ends such a process with std::_Exit after its error line, and MpiEnvironment
/// leaves MPI_Finalize out, so that a full disk is exit 1 and one line, not a SIGSEGV.
[[nodiscard]] bool file_close_failed() noexcept;

/// Bounds how long one HDF5 metadata call of this process may run: opening a file, a group or a dataset,
/// testing and listing links, reading attributes and string datasets (raw numeric reads are not bounded:
/// they can legitimately take long). 0, the default, means no bound. HDF5 1.10.8 loops forever inside its
/// metadata decoders on some crafted files (tests/fuzz/crashes/, timeout-*); the processes that read other
/// people's archives (jobs/cli/crash_guard.h) set a bound, and a call still running when it passes ends the
/// process with SIGALRM (alarm(2); the default action), which their parent reports as one error line. For a
/// process that does not use SIGALRM otherwise; single-threaded, like the rest of this layer.
void set_call_deadline(unsigned seconds);
/// The bound set_call_deadline set (0: none).
[[nodiscard]] unsigned call_deadline();

/// For code calling the HDF5 C API directly (e.g. mpi/hdf5_mpio.cpp): returns `status` when it is
/// non-negative, else throws LibraryError "HDF5: cannot WHAT: INNERMOST HDF5 ERROR".
int check_status(int status, std::string_view what);

/// The most bytes one read (Dataset::read, read_slab, read_strings) allocates: 8 GiB. A dataset's extents
/// are declared in the file and cost nothing there (a chunked dataset without chunks reads as fill values),
/// so a hostile file could otherwise ask for any allocation; readers check shapes against their own limits
/// first, this bound catches what they do not.
inline constexpr std::uint64_t kMaxReadBytes = std::uint64_t{1} << 33;

// ---------------------------------------------------------------------------------------------------
// Handles and property lists
// ---------------------------------------------------------------------------------------------------

/// Move-only owner of one HDF5 identifier and the function that closes it (H5Fclose, H5Dclose, ...).
/// An empty handle holds id 0 and closes nothing.
class Handle {
 public:
  /// The HDF5 close function of the identifier's kind (returns a negative value on failure).
  using CloseFn = int (*)(Hid);

  Handle() noexcept = default;
  /// Takes ownership of `id` (must be valid, i.e. > 0); `close` releases it.
  Handle(Hid id, CloseFn close) noexcept : id_(id), close_(close) {}
  Handle(Handle&& other) noexcept { swap(other); }
  Handle& operator=(Handle&& other) noexcept {
    Handle tmp(std::move(other));
    swap(tmp);
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  /// Closes the identifier; a failure is ignored (destructors must not throw).
  ~Handle() { reset(); }

  /// The raw identifier (0 when empty).
  [[nodiscard]] Hid id() const noexcept { return id_; }
  /// True when the handle owns an identifier.
  [[nodiscard]] bool valid() const noexcept { return id_ > 0; }
  /// Closes the identifier now; returns false when HDF5 reported a failure. The handle is empty afterwards.
  bool reset() noexcept;
  /// Exchanges the owned identifiers.
  void swap(Handle& other) noexcept {
    std::swap(id_, other.id_);
    std::swap(close_, other.close_);
  }

 private:
  Hid id_ = 0;
  CloseFn close_ = nullptr;
};

/// Sets one property on a raw HDF5 property list; returns the HDF5 status (negative on failure).
using PropertySetter = std::function<int(Hid plist)>;

/// A property list that is created lazily: until a property is added, id() is H5P_DEFAULT (0), so a
/// default-constructed list costs nothing. Properties compose (as in HighFive): each add() applies one
/// more setter to the same list.
class PropertyList {
 public:
  /// The raw identifier, or H5P_DEFAULT (0) when no property was added.
  [[nodiscard]] Hid id() const noexcept { return handle_.id(); }

 protected:
  /// Which HDF5 property list class to create.
  enum class Kind { kFileAccess, kDataTransfer };
  explicit PropertyList(Kind kind) noexcept : kind_(kind) {}
  /// Creates the list if needed and applies `setter`. Throws LibraryError naming `what` on failure.
  void apply(std::string_view what, const PropertySetter& setter);

 private:
  Kind kind_;
  Handle handle_;
};

/// File access properties (H5P_FILE_ACCESS): the file driver and its settings. mpi/hdf5_mpio.h builds
/// one for MPI-IO; a default-constructed one means the POSIX (sec2) driver.
class FileAccess : public PropertyList {
 public:
  FileAccess() noexcept : PropertyList(Kind::kFileAccess) {}
  /// Applies one more property (e.g. `H5Pset_fapl_mpio`); `what` names it in error messages.
  /// Throws LibraryError when the setter fails. Returns *this so calls chain.
  FileAccess& add(std::string_view what, const PropertySetter& setter) {
    apply(what, setter);
    return *this;
  }
};

/// Data transfer properties (H5P_DATASET_XFER) for dataset reads and writes: e.g. collective MPI-IO
/// (mpi/hdf5_mpio.h). After a transfer HDF5 records in it what actually happened.
class DataTransfer : public PropertyList {
 public:
  DataTransfer() noexcept : PropertyList(Kind::kDataTransfer) {}
  /// Applies one more property (e.g. `H5Pset_dxpl_mpio`); `what` names it in error messages.
  /// Throws LibraryError when the setter fails. Returns *this so calls chain.
  DataTransfer& add(std::string_view what, const PropertySetter& setter) {
    apply(what, setter);
    return *this;
  }
};

// ---------------------------------------------------------------------------------------------------
// Element types
// ---------------------------------------------------------------------------------------------------

/// Element types a dataset can hold. Numbers are stored little-endian; strings as UTF-8.
enum class DType { kUInt8, kUInt16, kInt32, kInt64, kFloat32, kFloat64, kString, kInt8, kUInt32 };

/// The C++ element types readable and writable as numbers.
template <class T>
concept Numeric = std::same_as<T, std::uint8_t> || std::same_as<T, std::uint16_t> || std::same_as<T, std::int32_t> ||
    std::same_as<T, std::int64_t> || std::same_as<T, float> || std::same_as<T, double> ||
    std::same_as<T, std::int8_t> || std::same_as<T, std::uint32_t>;

/// A contiguous, sized range of Numeric elements (std::vector<float>, std::span<const std::uint16_t>, ...).
template <class R>
concept NumericRange = std::ranges::contiguous_range<R> && std::ranges::sized_range<R> &&
    Numeric<std::remove_cv_t<std::ranges::range_value_t<R>>>;

/// The DType of a Numeric C++ type.
template <Numeric T>
inline constexpr DType kDTypeOf = std::same_as<T, std::uint8_t>    ? DType::kUInt8
                                  : std::same_as<T, std::uint16_t> ? DType::kUInt16
                                  : std::same_as<T, std::int32_t>  ? DType::kInt32
                                  : std::same_as<T, std::int64_t>  ? DType::kInt64
                                  : std::same_as<T, std::int8_t>   ? DType::kInt8
                                  : std::same_as<T, std::uint32_t> ? DType::kUInt32
                                  : std::same_as<T, float>         ? DType::kFloat32
                                                                   : DType::kFloat64;

/// The stored type of a new dataset: a DType plus, for strings, the fixed length in bytes
/// (0 = variable-length UTF-8, the default for name tables and attributes).
struct DataType {
  DType kind = DType::kFloat32;
  std::size_t string_length = 0;

  /// The type storing C++ type T.
  template <Numeric T>
  [[nodiscard]] static constexpr DataType of() {
    return {kDTypeOf<T>, 0};
  }
  /// Variable-length UTF-8 strings.
  [[nodiscard]] static constexpr DataType var_string() { return {DType::kString, 0}; }
  /// Fixed-length UTF-8 strings of `length` bytes, null-padded (length >= 1).
  [[nodiscard]] static constexpr DataType fixed_string(std::size_t length) { return {DType::kString, length}; }
};

// ---------------------------------------------------------------------------------------------------
// Objects and attributes
// ---------------------------------------------------------------------------------------------------

/// The C++ types an attribute can be read as: variable- or fixed-length strings, a 64-bit integer, a
/// double, or 1-D arrays of integers or doubles.
template <class T>
concept AttributeValue = std::same_as<T, std::string> || std::same_as<T, std::int64_t> || std::same_as<T, double> ||
    std::same_as<T, std::vector<double>> || std::same_as<T, std::vector<std::int64_t>>;

/// Base of File, Group and Dataset: an open HDF5 object that can carry attributes.
/// Attribute writes replace an existing attribute of the same name. Strings are stored as scalar
/// variable-length UTF-8, integers as int64, floating-point numbers as float64, vectors as 1-D arrays.
class Object {
 public:
  /// The raw identifier (escape hatch for the C API; stays owned by this object).
  [[nodiscard]] Hid id() const noexcept { return handle_.id(); }
  /// Absolute path of the object inside its file ("/" for the root group).
  [[nodiscard]] std::string path() const;
  /// Name of the file holding the object, as given when it was opened.
  [[nodiscard]] std::string file_name() const;
  /// Writes what HDF5 caches of the object's file to disk when the file is open for writing (nothing for
  /// a file open for reading). Throws IoError naming the file and the cause (a full disk, a dataset whose
  /// last chunks could not be written).
  void flush_file() const;

  /// True when the object has an attribute called `name`.
  [[nodiscard]] bool has_attribute(std::string_view name) const;
  /// Names of all attributes, in name order.
  [[nodiscard]] std::vector<std::string> attribute_names() const;

  /// Writes a string attribute (variable-length UTF-8).
  void set_attribute(std::string_view name, std::string_view value);
  /// Writes a string attribute (variable-length UTF-8); keeps string literals away from the bool overload.
  void set_attribute(std::string_view name, const char* value) { set_attribute(name, std::string_view(value)); }
  /// Writes an integer attribute as int64. Throws InvalidInput for an unsigned value above INT64_MAX.
  template <std::integral T>
  requires(!std::same_as<T, bool>) void set_attribute(std::string_view name, T value) {
    if (!std::in_range<std::int64_t>(value)) throw_out_of_int64_range(name);
    set_int64_attribute(name, static_cast<std::int64_t>(value));
  }
  /// Writes a floating-point attribute as float64.
  template <std::floating_point T>
  void set_attribute(std::string_view name, T value) {
    set_double_attribute(name, static_cast<double>(value));
  }
  /// Writes a 1-D float64 array attribute.
  void set_attribute(std::string_view name, std::span<const double> values);
  /// Writes a 1-D int64 array attribute.
  void set_attribute(std::string_view name, std::span<const std::int64_t> values);

  /// Reads attribute `name` as T (see AttributeValue). Throws FormatError when it is missing, holds
  /// another kind of value ("FILE: attribute 'format_version' of / is a string, expected an integer"), or,
  /// for a scalar T, holds more than one value. Integers stored with any width/sign are accepted as int64.
  template <AttributeValue T>
  [[nodiscard]] T attribute(std::string_view name) const;
  /// Reads integer attribute `name` and checks it lies in [lo, hi] before anyone computes with it: throws
  /// FormatError "FILE:PATH: attribute units_per_side = 0 is outside [1, 2^20]" otherwise (and what
  /// attribute<std::int64_t> throws). Every integer a reader takes from a file goes through this (or an
  /// equivalent check): archives come from other people.
  [[nodiscard]] std::int64_t attribute_in_range(std::string_view name, std::int64_t lo, std::int64_t hi) const;
  /// Reads float attribute `name` and checks it is finite and in [lo, hi]: throws FormatError
  /// "FILE:PATH: attribute cell_size = inf is outside [1e-300, 1e+300]" otherwise.
  [[nodiscard]] double finite_attribute_in_range(std::string_view name, double lo, double hi) const;

 protected:
  explicit Object(Handle handle) noexcept : handle_(std::move(handle)) {}
  /// The owned handle (File::close resets it).
  Handle& handle() noexcept { return handle_; }

 private:
  void set_int64_attribute(std::string_view name, std::int64_t value);
  void set_double_attribute(std::string_view name, double value);
  [[noreturn]] void throw_out_of_int64_range(std::string_view name) const;

  Handle handle_;
};

template <>
std::string Object::attribute<std::string>(std::string_view name) const;
template <>
std::int64_t Object::attribute<std::int64_t>(std::string_view name) const;
template <>
double Object::attribute<double>(std::string_view name) const;
template <>
std::vector<double> Object::attribute<std::vector<double>>(std::string_view name) const;
template <>
std::vector<std::int64_t> Object::attribute<std::vector<std::int64_t>>(std::string_view name) const;

// ---------------------------------------------------------------------------------------------------
// Datasets
// ---------------------------------------------------------------------------------------------------

/// Storage options of a new dataset.
/// - `chunk`: chunk shape, same rank as the dataset, every entry >= 1 (and <= the extent for fixed
///   dimensions). Empty = contiguous, unless compression, shuffle or `resizable` ask for chunks, in which
///   case a default is chosen (extents halved, largest first, until a chunk holds <= 1 MiB).
/// - `deflate`: gzip level 0..9 (0 = no compression).
/// - `shuffle`: byte-shuffle filter before deflate (helps float and uint16 data compress).
/// - `resizable`: the first dimension is unlimited and can grow with Dataset::extend/append.
/// A fixed-size dataset with a zero extent cannot be chunked: it is stored contiguous and unfiltered.
struct DatasetOptions {
  Dims chunk{};
  int deflate = 0;
  bool shuffle = false;
  bool resizable = false;
};

/// An open dataset. Reads and writes convert between the requested C++ type and the stored type as HDF5
/// does (e.g. float <-> double); numbers and strings do not mix (FormatError).
class Dataset : public Object {
 public:
  /// Current extents.
  [[nodiscard]] Dims shape() const;
  /// Product of the extents.
  [[nodiscard]] std::uint64_t element_count() const;
  /// The stored element type. Throws FormatError for a type outside DType (e.g. compound).
  [[nodiscard]] DType dtype() const;

  /// Writes the whole dataset from `data` (row-major, element_count() values, else InvalidInput).
  template <NumericRange R>
  void write(const R& data, const DataTransfer& xfer = {}) {
    write_numeric(std::ranges::data(data), std::ranges::size(data), kDTypeOf<Value<R>>, xfer);
  }
  /// Reads the whole dataset, row-major. Throws FormatError when it holds more than kMaxReadBytes, or when the
  /// file does not store all of it (an unwritten chunk, or contiguous data never allocated, would read as fill
  /// values: declared extents cost a file nothing, the reader their size; checked in files opened read-only,
  /// not where a writer reads back its own data). read_slab and read_strings alike.
  template <Numeric T>
  [[nodiscard]] std::vector<T> read(const DataTransfer& xfer = {}) const {
    const Dims extents = shape();
    std::vector<T> out(readable_block(Dims(extents.size(), 0), extents, sizeof(T)));
    read_numeric(out.data(), out.size(), kDTypeOf<T>, xfer);
    return out;
  }

  /// Writes the block starting at `offset` with extents `count` (same rank as the dataset, inside it)
  /// from `data` (row-major, product(count) values). With a collective `xfer` (mpi/hdf5_mpio.h) every rank
  /// must call it, possibly with an empty block.
  template <NumericRange R>
  void write_slab(const Dims& offset, const Dims& count, const R& data, const DataTransfer& xfer = {}) {
    write_slab_numeric(offset, count, std::ranges::data(data), std::ranges::size(data), kDTypeOf<Value<R>>, xfer);
  }
  /// Reads the block starting at `offset` with extents `count`, row-major. Collective like write_slab.
  template <Numeric T>
  [[nodiscard]] std::vector<T> read_slab(const Dims& offset, const Dims& count, const DataTransfer& xfer = {}) const {
    std::vector<T> out(readable_block(offset, count, sizeof(T)));
    read_slab_numeric(offset, count, out.data(), out.size(), kDTypeOf<T>, xfer);
    return out;
  }

  /// Grows (or shrinks) the first dimension of a resizable dataset to `first_extent`.
  /// Throws LibraryError when the dataset is not resizable.
  void extend(std::uint64_t first_extent);
  /// Appends rows along the first dimension of a resizable dataset: `data` holds k whole rows
  /// (k * product(shape()[1:]) values, else InvalidInput); the dataset grows by k.
  template <NumericRange R>
  void append(const R& data) {
    append_numeric(std::ranges::data(data), std::ranges::size(data), kDTypeOf<Value<R>>);
  }

  /// Writes a whole string dataset (variable- or fixed-length; a string longer than the fixed length
  /// throws InvalidInput).
  void write_strings(std::span<const std::string> data);
  /// Reads a whole string dataset (variable- or fixed-length; fixed-length padding is removed).
  [[nodiscard]] std::vector<std::string> read_strings() const;

  /// Product of `dims` (1 for rank 0).
  [[nodiscard]] static std::uint64_t product(const Dims& dims) noexcept;
  /// Product of `extents` as a count of values of `element_size` bytes, checked: throws FormatError
  /// naming this dataset when the product overflows or the values take more than kMaxReadBytes.
  [[nodiscard]] std::size_t readable_count(const Dims& extents, std::size_t element_size) const;

 private:
  friend class Group;
  template <class R>
  using Value = std::remove_cv_t<std::ranges::range_value_t<R>>;
  explicit Dataset(Handle handle) noexcept : Object(std::move(handle)) {}

  /// readable_count(count, element_size) after checking that the file stores the block at `offset` with
  /// extents `count` (a block outside the extents is left to the read to refuse).
  [[nodiscard]] std::size_t readable_block(const Dims& offset, const Dims& count, std::size_t element_size) const;
  void write_numeric(const void* data, std::size_t n, DType type, const DataTransfer& xfer);
  void read_numeric(void* data, std::size_t n, DType type, const DataTransfer& xfer) const;
  void write_slab_numeric(const Dims& offset, const Dims& count, const void* data, std::size_t n, DType type,
                          const DataTransfer& xfer);
  void read_slab_numeric(const Dims& offset, const Dims& count, void* data, std::size_t n, DType type,
                         const DataTransfer& xfer) const;
  void append_numeric(const void* data, std::size_t n, DType type);
};

// ---------------------------------------------------------------------------------------------------
// Groups and files
// ---------------------------------------------------------------------------------------------------

/// An open group. Names may be relative paths ("a/b/c"); created groups get missing parents too.
///
/// Opening refuses what would let a file reach outside itself (the archive readers rely on it, docs/archive.md
/// "What readers refuse"), with FormatError "FILE: PATH is CAUSE":
/// - a link on the way that is not a hard link: soft links and external links (to other files) are never
///   followed (open_group, open_dataset, exists, copy_to);
/// - a dataset whose raw data lies outside the file: external storage (H5Pset_external) or a virtual
///   dataset (VDS), whose sources are other datasets, possibly in other files;
/// - a dataset whose filter pipeline holds a filter this HDF5 cannot decode ("dataset PATH uses compression
///   filter 32000 (lzf) which gimforge cannot read; rewrite it with gzip or none"). HDF5's dynamic filter
///   plugins are never loaded (File::open turns plugin loading off).
class Group : public Object {
 public:
  /// Creates group `name` (and missing intermediate groups). Throws LibraryError if it exists.
  Group create_group(std::string_view name);
  /// Opens existing group `name`. Throws LibraryError when absent or not a group.
  [[nodiscard]] Group open_group(std::string_view name) const;
  /// Opens group `name`, creating it (and missing parents) when absent.
  Group require_group(std::string_view name);
  /// True when a link `name` exists (every component of a relative path is checked, so "a/b" on a
  /// group without "a" is false rather than an error).
  [[nodiscard]] bool exists(std::string_view name) const;
  /// Names of the direct children (groups, datasets, ...), in name order.
  [[nodiscard]] std::vector<std::string> children() const;

  /// Creates dataset `name` of `type` with extents `shape` (rank >= 1) and storage `options`.
  /// Throws InvalidInput for inconsistent options, LibraryError when HDF5 refuses (e.g. name taken).
  Dataset create_dataset(std::string_view name, DataType type, const Dims& shape, const DatasetOptions& options = {});
  /// Opens existing dataset `name`. Throws LibraryError when absent or not a dataset, FormatError when it
  /// is reached through a link that is not a hard link, stores data outside the file or needs a filter
  /// this build cannot decode (see the class comment).
  [[nodiscard]] Dataset open_dataset(std::string_view name) const;

  /// Creates dataset `name` with extents `shape` and writes `data` into it (see create_dataset, write).
  /// With MPI-IO every rank calls it with the same arguments; pass a collective `xfer` for filtered
  /// (compressed) datasets, which parallel HDF5 writes only collectively.
  template <NumericRange R>
  Dataset write_dataset(std::string_view name, const Dims& shape, const R& data, const DatasetOptions& options = {},
                        const DataTransfer& xfer = {}) {
    Dataset ds = create_dataset(name, DataType::of<std::remove_cv_t<std::ranges::range_value_t<R>>>(), shape, options);
    ds.write(data, xfer);
    return ds;
  }
  /// Creates a 1-D string dataset `name` of `type` (var_string() or fixed_string(n)) holding `data`.
  Dataset write_strings(std::string_view name, std::span<const std::string> data,
                        DataType type = DataType::var_string(), const DatasetOptions& options = {});
  /// Copies object `name` of this group (a group with everything below it, or a dataset: data, layout,
  /// filters, attributes) to `destination` as `new_name` (missing intermediate groups are created); the
  /// destination may be in another file. Throws LibraryError when HDF5 refuses (e.g. the name is taken),
  /// FormatError when the object or anything below it is a link other than a hard link or a dataset that
  /// open_dataset refuses (nothing is copied then).
  void copy_to(std::string_view name, Group& destination, std::string_view new_name) const;

 protected:
  explicit Group(Handle handle) noexcept : Object(std::move(handle)) {}
};

/// How File::create treats an existing file.
enum class CreateMode {
  kTruncate,   ///< overwrite it
  kExclusive,  ///< fail (IoError) when it exists
};

/// How File::open accesses the file.
enum class OpenMode { kReadOnly, kReadWrite };

/// An open HDF5 file; it is also its root group ("/"), so groups, datasets and file attributes are
/// reached directly through it. With an MPI-IO FileAccess, create/open/close are collective.
class File : public Group {
 public:
  /// Creates `path`. Throws IoError "PATH: cannot create HDF5 file: ..." on failure.
  [[nodiscard]] static File create(const std::filesystem::path& path, CreateMode mode = CreateMode::kTruncate,
                                   const FileAccess& access = {});
  /// Opens existing `path`. Throws IoError "PATH: no such file" when it is absent and
  /// "PATH: cannot open HDF5 file: ..." when HDF5 cannot open it (e.g. not an HDF5 file).
  [[nodiscard]] static File open(const std::filesystem::path& path, OpenMode mode = OpenMode::kReadOnly,
                                 const FileAccess& access = {});

  /// Writes buffered data to disk. Throws LibraryError on failure.
  void flush();
  /// Closes the file now and reports failure (IoError) instead of ignoring it like the destructor.
  /// Objects opened from the file should be closed first. The File is unusable afterwards.
  void close();

 private:
  explicit File(Handle handle) noexcept : Group(std::move(handle)) {}
};

}  // namespace gimforge::h5
