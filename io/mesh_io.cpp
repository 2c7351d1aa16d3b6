// read_mesh / format dispatch, whole-file reading, writing through io::write_atomically, and the checks every
// reader shares.
#include "io/mesh_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <memory>
#include <new>
#include <stdexcept>
#include <system_error>

#include <fmt/format.h>

#include "io/atomic_file.h"
#include "io/formats_internal.h"
#include "io/input_file.h"
#include "io/text_parse.h"
#include "kernels/core/errors.h"

namespace gimforge::io {

namespace detail {

void fail(const Source& src, std::string_view cause) { throw FormatError(fmt::format("{}: {}", src.path, cause)); }

void fail_line(const Source& src, std::size_t line, std::string_view cause) {
  if (line == 0) fail(src, cause);
  throw FormatError(fmt::format("{}: line {}: {}", src.path, line, cause));
}

namespace {

const char* format_article(MeshFormat f) {
  switch (f) {
    case MeshFormat::Ply:
      return "a PLY";
    case MeshFormat::Obj:
      return "an OBJ";
    case MeshFormat::Off:
      return "an OFF";
    case MeshFormat::Stl:
      return "an STL";
  }
  return "a mesh";
}

}  // namespace

void fail_not_format(const Source& src, MeshFormat expected) {
  fail(src, fmt::format("not {} file ({})", format_article(expected), describe_contents(src.data, expected)));
}

void fail_non_finite(const Source& src, std::string_view item, std::uint64_t index, const Vec3& v,
                     std::string_view what, std::size_t line) {
  const auto bad = std::find_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); });
  const double value = bad == v.end() ? v.x() : *bad;
  fail_line(src, line, fmt::format("{} {} has a non-finite {} ({})", item, index, what, value));
}

double number_at(const Source& src, std::size_t line, std::string_view token, std::string_view what) {
  double v = 0.0;
  if (!parse_double(token, v)) {
    fail_line(src, line, fmt::format("{}: {} is not a number (non-numeric value)", what, quote_token(token)));
  }
  return v;
}

std::int64_t integer_at(const Source& src, std::size_t line, std::string_view token, std::string_view what) {
  std::int64_t v = 0;
  if (!parse_int(token, v)) {
    fail_line(src, line, fmt::format("{}: {} is not an integer (non-numeric value)", what, quote_token(token)));
  }
  return v;
}

Vec3f unit_color(const Source& src, std::uint64_t index, const Vec3& rgb, std::size_t line) {
  check_finite(src, index, rgb, "colour", line);
  return rgb.cwiseMax(0.0).cwiseMin(1.0).cast<float>();
}

void FaceBuilder::add(std::span<const std::int64_t> polygon, std::uint64_t face_no, std::size_t line) {
  check_count(static_cast<std::int64_t>(polygon.size()), face_no, line);
  for (const std::int64_t v : polygon) {
    if (v < 0 || static_cast<std::uint64_t>(v) >= num_vertices_) fail_index(v, face_no, line);
  }
  const auto at = [&](std::size_t k) { return static_cast<std::uint32_t>(polygon[k]); };
  for (std::size_t k = 2; k < polygon.size(); ++k) faces_.push_back(Face{at(0), at(k - 1), at(k)});
  if (polygon.size() > 3) ++triangulated_;
}

void FaceBuilder::fail_index(std::int64_t index, std::uint64_t face_no, std::size_t line) const {
  const std::int64_t shown = index + index_base_;
  if (index < 0) {
    fail_line(src_, line, fmt::format("face {}: vertex index {} is out of range (negative)", face_no, shown));
  }
  fail_line(src_, line,
            fmt::format("face {}: vertex index {} is out of range (the file has {} vertices)", face_no, shown,
                        num_vertices_));
}

void fail_face_size(const Source& src, std::int64_t count, std::uint64_t face_no, std::size_t line) {
  fail_line(src, line, fmt::format("face {} has {} vertices; a face needs at least 3", face_no, count));
}

void fan_triangulate(std::span<const std::uint32_t> polygon, std::vector<Face>& faces) {
  for (std::size_t k = 2; k < polygon.size(); ++k) faces.push_back(Face{polygon[0], polygon[k - 1], polygon[k]});
}

std::string describe_contents(std::string_view data, MeshFormat expected) {
  struct Probe {
    MeshFormat format;
    bool (*test)(std::string_view);
    const char* text;
  };
  static constexpr Probe probes[] = {
      {MeshFormat::Ply, looks_like_ply, "it looks like a PLY file"},
      {MeshFormat::Off, looks_like_off, "it looks like an OFF file"},
      {MeshFormat::Stl, looks_like_ascii_stl, "it looks like an ASCII STL file"},
      {MeshFormat::Obj, looks_like_obj, "it looks like an OBJ file"},
      {MeshFormat::Stl, looks_like_binary_stl, "its size fits a binary STL file"},
  };
  for (const Probe& p : probes) {
    if (p.format != expected && p.test(data)) return p.text;
  }
  if (const auto at = find_binary_byte(data, 4096)) {
    return fmt::format("it contains binary data: byte 0x{:02x} at offset {}", static_cast<unsigned char>(data[*at]),
                       *at);
  }
  const std::string_view first = trim(data.substr(0, data.find('\n')));
  return first.empty() ? std::string("its first line is blank") : fmt::format("it starts with {}", quote_token(first));
}

// ---- atomic write ----

namespace {

/// Closes a file descriptor when it goes out of scope.
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  [[nodiscard]] int get() const { return fd_; }
  /// Closes now and returns close()'s result.
  int close() {
    const int rc = ::close(fd_);
    fd_ = -1;
    return rc;
  }

 private:
  int fd_;
};

std::string errno_text(int err) { return std::generic_category().message(err); }

/// Writes all of `bytes`; returns 0 or the errno of the failure.
int write_all(int fd, std::string_view bytes) {
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd, bytes.data(), bytes.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
  return 0;
}

}  // namespace

void write_file_atomically(const std::filesystem::path& path, std::string_view bytes) {
  const std::string shown = path.string();
  write_atomically(
      path,
      [&](const std::filesystem::path& tmp) {
        Fd fd(::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
        if (fd.get() < 0) {
          throw IoError(fmt::format("{}: cannot create the temporary file '{}': {}", shown, tmp.string(),
                                    errno_text(errno)));
        }
        int err = write_all(fd.get(), bytes);
        if (fd.close() != 0 && err == 0) err = errno;
        if (err != 0) {
          throw IoError(fmt::format("{}: cannot write the temporary file '{}': {}", shown, tmp.string(),
                                    errno_text(err)));
        }
      },
      ParentDirectory::kMustExist);
}

std::string exact_text(double v) { return fmt::format("{}", v); }

}  // namespace detail

// ---- writing in the format the extension names ----

namespace {

/// The lower-case extension of `path` (".ply"), or "".
std::string lower_extension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](char c) { return static_cast<char>(std::tolower(static_cast<unsigned char>(c))); });
  return ext;
}

void check_mesh_writable(const std::string& shown, const TriMesh& mesh, MeshFormat format) {
  const std::size_t nv = mesh.num_vertices();
  const char* name = format_name(format);
  if (mesh.has_colors() && mesh.colors.size() != nv)
    throw InvalidInput(fmt::format("{}: cannot write {}: {} colours for {} vertices", shown, name, mesh.colors.size(), nv));
  if (mesh.has_normals() && mesh.normals.size() != nv)
    throw InvalidInput(fmt::format("{}: cannot write {}: {} normals for {} vertices", shown, name, mesh.normals.size(), nv));
  for (std::size_t f = 0; f < mesh.faces.size(); ++f)
    for (const std::uint32_t v : mesh.faces[f])
      if (v >= nv)
        throw InvalidInput(fmt::format("{}: cannot write {}: face {}: vertex index {} is out of range ({} vertices)",
                                       shown, name, f, v, nv));
  if (format == MeshFormat::Stl)
    detail::check_float32_resolves(shown, mesh, "write .ply, .obj or .off (STL is float32 by definition)");
  if (format == MeshFormat::Stl && mesh.num_faces() > UINT32_MAX)
    throw InvalidInput(fmt::format("{}: cannot write STL: {} faces is too many (at most {})", shown, mesh.num_faces(),
                                   UINT32_MAX));
}

}  // namespace

double float32_relative_spacing(const TriMesh& mesh) {
  BoundingBox box;
  double largest = 0.0;
  for (const Vec3& p : mesh.positions) {
    box.extend(p);
    largest = std::max(largest, p.cwiseAbs().maxCoeff());
  }
  if (!std::isfinite(largest) || largest == 0.0 || !(box.diagonal() > 0.0)) return 0.0;
  int e = 0;
  (void)std::frexp(largest, &e);
  return std::ldexp(1.0, e - 24) / box.diagonal();  // float32 values in [2^(e−1), 2^e) are 2^(e−24) apart
}

bool float32_exact(const TriMesh& mesh) {
  // Per coordinate, with an early exit: GCC 12 at -O2 vectorizes a loop of double → float → double round
  // trips stored back as double without the rounding (Eigen's p.cast<float>().cast<double>() and plain
  // std::array code alike; unit test Float32.ExactOnlyWhenEveryCoordinateIsAFloat).
  for (const Vec3& p : mesh.positions)
    for (int k = 0; k < 3; ++k)
      if (static_cast<double>(static_cast<float>(p[k])) != p[k]) return false;
  return true;
}

void detail::check_float32_resolves(const std::string& shown, const TriMesh& mesh, std::string_view instead) {
  if (float32_exact(mesh)) return;  // nothing to lose (read from floats)
  if (const double r = float32_relative_spacing(mesh); r > kFloat32Tolerance)
    throw InvalidInput(fmt::format("{}: 32-bit float coordinates would move this mesh's vertices by up to {:.2g} of its "
                                   "bounding-box diagonal (it lies far from the origin): {}",
                                   shown, r / 2.0, instead));
}

MeshFormat output_format(const std::filesystem::path& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".ply") return MeshFormat::Ply;
  if (ext == ".obj") return MeshFormat::Obj;
  if (ext == ".off") return MeshFormat::Off;
  if (ext == ".stl") return MeshFormat::Stl;
  throw InvalidInput(fmt::format("{}: cannot write a mesh as {} (the extension names the format; gimforge writes .ply, "
                                 ".obj, .off, .stl)",
                                 path.string(), ext.empty() ? std::string("a file without extension")
                                                            : detail::quote_token(path.extension().string())));
}

void write_mesh(const std::filesystem::path& path, const TriMesh& mesh, const PlyWriteOptions& ply) {
  const MeshFormat format = output_format(path);
  if (format == MeshFormat::Ply) return write_ply(path, mesh, ply);
  const std::string shown = path.string();
  check_mesh_writable(shown, mesh, format);
  try {
    const std::string bytes = format == MeshFormat::Obj   ? detail::obj_bytes(mesh)
                              : format == MeshFormat::Off ? detail::off_bytes(mesh)
                                                          : detail::stl_bytes(mesh);
    detail::write_file_atomically(path, bytes);
  } catch (const std::bad_alloc&) {
    throw IoError(fmt::format("{}: out of memory while writing {}", shown, format_name(format)));
  } catch (const std::length_error&) {
    throw IoError(fmt::format("{}: out of memory while writing {}", shown, format_name(format)));
  }
}

// ---- reading ----

namespace {

/// The bytes of a whole file.
struct FileBytes {
  std::unique_ptr<char[]> bytes;
  std::size_t size{0};
};

/// Reads the whole file with one open and (normally) one read().
FileBytes read_whole_file(const std::filesystem::path& path, const std::string& shown) {
  detail::Fd fd(::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC));  // a FIFO: refused below, not waited on
  if (fd.get() < 0) throw IoError(fmt::format("{}: cannot open: {}", shown, detail::errno_text(errno)));
  struct stat st {};
  if (::fstat(fd.get(), &st) != 0) throw IoError(fmt::format("{}: cannot stat: {}", shown, detail::errno_text(errno)));
  if (!S_ISREG(st.st_mode)) throw IoError(fmt::format("{}: is not a regular file", shown));
  FileBytes file;
  const auto size = static_cast<std::size_t>(st.st_size);
  file.bytes = std::make_unique_for_overwrite<char[]>(std::max<std::size_t>(size, 1));
  while (file.size < size) {
    const ssize_t n = ::read(fd.get(), file.bytes.get() + file.size, size - file.size);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw IoError(fmt::format("{}: read failed: {}", shown, detail::errno_text(errno)));
    if (n == 0) break;  // the file shrank while we read it: parse what is there
    file.size += static_cast<std::size_t>(n);
  }
  return file;
}

TriMesh read_format(MeshFormat format, const detail::Source& src, ReadInfo& info) {
  switch (format) {
    case MeshFormat::Ply:
      return detail::read_ply(src, info);
    case MeshFormat::Obj:
      return detail::read_obj(src, info);
    case MeshFormat::Off:
      return detail::read_off(src, info);
    case MeshFormat::Stl:
      return detail::read_stl(src, info);
  }
  throw IoError(fmt::format("{}: unknown mesh format", src.path));
}

TriMesh read_mesh_unguarded(const std::filesystem::path& path, const std::string& shown, ReadInfo& info,
                            std::string_view vertex_scalar) {
  require_regular_file(path, shown);  // io/input_file.h: stat only, a FIFO is refused, not waited on
  info.format = format_from_extension(path);
  const FileBytes file = read_whole_file(path, shown);
  info.file_bytes = file.size;
  const detail::Source src{shown, std::string_view(file.bytes.get(), file.size), vertex_scalar};
  if (file.size == 0) detail::fail(src, "file is empty (0 bytes)");
  TriMesh mesh = read_format(info.format, src, info);
  for (std::size_t i = 0; i < mesh.normals.size(); ++i)
    if (const Vec3f& n = mesh.normals[i]; !n.allFinite()) {
      info.dropped_normals = fmt::format("vertex {} has a non-finite normal ({}, {}, {})", i, n.x(), n.y(), n.z());
      mesh.normals = {};
      break;
    }
  return mesh;
}

/// Makes an arbitrary exception text fit on one line.
std::string one_line(std::string_view text) {
  std::string s(text);
  std::replace_if(
      s.begin(), s.end(), [](char c) { return c == '\n' || c == '\r'; }, ' ');
  return s;
}

/// read_mesh, and with `vertex_scalar` the values of that PLY vertex property in info.vertex_scalar.
TriMesh read_mesh_guarded(const std::filesystem::path& path, ReadInfo* info, std::string_view vertex_scalar) {
  const std::string shown = path.string();
  ReadInfo local;
  ReadInfo& out = info != nullptr ? *info : local;
  out = ReadInfo{};
  try {
    return read_mesh_unguarded(path, shown, out, vertex_scalar);
  } catch (const Error&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw IoError(fmt::format("{}: out of memory while reading the mesh (file is {} bytes)", shown, out.file_bytes));
  } catch (const std::length_error&) {
    throw IoError(fmt::format("{}: out of memory while reading the mesh (file is {} bytes)", shown, out.file_bytes));
  } catch (const std::filesystem::filesystem_error& e) {
    throw IoError(fmt::format("{}: {}", shown, e.code().message()));
  } catch (const std::exception& e) {
    throw IoError(fmt::format("{}: {}", shown, one_line(e.what())));
  }
}

}  // namespace

TriMesh read_mesh(const std::filesystem::path& path, ReadInfo* info) { return read_mesh_guarded(path, info, {}); }

std::vector<double> read_ply_vertex_scalar(const std::filesystem::path& path, const std::string& name) {
  if (format_from_extension(path) != MeshFormat::Ply)
    throw IoError(fmt::format("{}: per-vertex scalars are read from PLY files only", path.string()));
  if (name.empty()) throw IoError(fmt::format("{}: no vertex property named", path.string()));
  ReadInfo info;
  (void)read_mesh_guarded(path, &info, name);
  return std::move(info.vertex_scalar);
}

MeshFormat format_from_extension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](char c) { return static_cast<char>(std::tolower(static_cast<unsigned char>(c))); });
  if (ext == ".ply") return MeshFormat::Ply;
  if (ext == ".obj") return MeshFormat::Obj;
  if (ext == ".off") return MeshFormat::Off;
  if (ext == ".stl") return MeshFormat::Stl;
  const std::string shown = path.string();
  if (ext.empty()) {
    throw IoError(
        fmt::format("{}: no file extension, so the mesh format is unknown (gimforge reads .ply, .obj, "
                    ".off, .stl)",
                    shown));
  }
  throw IoError(fmt::format("{}: unknown mesh file extension {} (gimforge reads .ply, .obj, .off, .stl)", shown,
                            detail::quote_token(path.extension().string())));
}

const char* format_name(MeshFormat f) {
  switch (f) {
    case MeshFormat::Ply:
      return "PLY";
    case MeshFormat::Obj:
      return "OBJ";
    case MeshFormat::Off:
      return "OFF";
    case MeshFormat::Stl:
      return "STL";
  }
  return "unknown";
}

}  // namespace gimforge::io
