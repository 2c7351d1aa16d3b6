#include "io/ply_ranges.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <system_error>
#include <utility>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge::io {
namespace {

/// Records per chunk: a few MB of file bytes at a time.
constexpr std::uint64_t kChunk = 1u << 18;
/// The header is read from the file's first bytes (a longer header is refused as having no end_header).
constexpr std::size_t kHeaderBytes = 1u << 20;

template <class T>
T load(const char* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

}  // namespace

std::optional<PlyTriangleFile> PlyTriangleFile::open(const std::filesystem::path& path) {
  const std::string shown = path.string();
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);  // a FIFO: no wait for a writer
  if (fd < 0) throw IoError(fmt::format("{}: cannot open: {}", shown, std::strerror(errno)));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw IoError(fmt::format("{}: not a regular file", shown));
  }
  PlyTriangleFile file(fd, shown, {});
  const auto size = static_cast<std::uint64_t>(st.st_size);
  std::string head(static_cast<std::size_t>(std::min<std::uint64_t>(size, kHeaderBytes)), '\0');
  file.read_bytes(head.data(), head.size(), 0);
  const detail::Source src{shown, head};
  if (!detail::looks_like_ply(head)) return std::nullopt;
  const auto layout = detail::ply_fixed_layout(src);
  if (!layout) return std::nullopt;
  file.layout_ = *layout;
  // Triangles only: then the face records fill the file exactly. Longer files hold polygons (or junk)
  // for read_mesh to triangulate or report; shorter ones are cut off.
  // Counts the file cannot hold are refused before any product of them can wrap around.
  const bool fits = layout->vertices <= size / std::max<std::size_t>(layout->vertex_stride, 1) &&
                    layout->faces <= size / layout->face_stride();
  const std::uint64_t expected = fits ? layout->triangle_file_bytes() : 0;
  if (fits && size > expected) return std::nullopt;
  if (!fits || size < expected)
    throw FormatError(fmt::format("{}: truncated binary PLY: {} vertices and {} triangles need {} bytes, the file "
                                  "has {}",
                                  shown, layout->vertices, layout->faces,
                                  fits ? fmt::to_string(expected) : std::string("more"), size));
  return file;
}

PlyTriangleFile::PlyTriangleFile(PlyTriangleFile&& o) noexcept
    : fd_(std::exchange(o.fd_, -1)), shown_(std::move(o.shown_)), layout_(o.layout_) {}

PlyTriangleFile& PlyTriangleFile::operator=(PlyTriangleFile&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(o.fd_, -1);
    shown_ = std::move(o.shown_);
    layout_ = o.layout_;
  }
  return *this;
}

PlyTriangleFile::~PlyTriangleFile() {
  if (fd_ >= 0) ::close(fd_);
}

void PlyTriangleFile::read_bytes(char* out, std::size_t bytes, std::uint64_t offset) const {
  while (bytes > 0) {
    const ssize_t n = ::pread(fd_, out, bytes, static_cast<off_t>(offset));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      throw IoError(fmt::format("{}: cannot read {} bytes at offset {}: {}", shown_, bytes, offset,
                                n == 0 ? "the file ends there" : std::strerror(errno)));
    out += n;
    bytes -= static_cast<std::size_t>(n);
    offset += static_cast<std::uint64_t>(n);
  }
}

std::optional<InvalidInput> small_extent_error(std::string_view shown, double diagonal) {
  if (diagonal == 0.0)
    return InvalidInput(fmt::format("{}: the mesh is 0 across: all the vertices its faces use coincide (bounding-box "
                                    "diagonal 0), so it has no surface to convert or measure",
                                    shown));
  if (!(diagonal > 0.0 && diagonal < kMinDiagonal)) return std::nullopt;
  return InvalidInput(fmt::format("{}: the mesh is only {:.3g} across (bounding-box diagonal), below {:g}, where "
                                  "squared distances underflow single precision (scale the mesh up)",
                                  shown, diagonal, kMinDiagonal));
}

FormatError far_coordinate_error(std::string_view shown, std::uint64_t vertex, double magnitude) {
  return FormatError(fmt::format("{}: vertex {} has a coordinate of magnitude {:.3g}, beyond ±{:g}, where squared "
                                 "distances overflow single precision (scale the mesh down)",
                                 shown, vertex, magnitude, kMaxCoordinate));
}

void PlyTriangleFile::read_vertices(std::uint64_t first, std::uint64_t last,
                                    const std::function<void(std::uint64_t, std::span<const Vec3>)>& chunk) const {
  const detail::PlyFixedLayout& L = layout_;
  last = std::min(last, L.vertices);
  std::vector<char> bytes;
  std::vector<Vec3> positions;
  for (std::uint64_t begin = first; begin < last; begin += kChunk) {
    const std::uint64_t n = std::min(kChunk, last - begin);
    bytes.resize(static_cast<std::size_t>(n * L.vertex_stride));
    read_bytes(bytes.data(), bytes.size(), L.body_offset + begin * L.vertex_stride);
    positions.resize(static_cast<std::size_t>(n));
    for (std::size_t i = 0; i < positions.size(); ++i) {
      const char* r = bytes.data() + i * L.vertex_stride;
      for (int k = 0; k < 3; ++k) {
        const char* at = r + L.coord_offset[static_cast<std::size_t>(k)];
        positions[i][k] = L.coord_double ? load<double>(at) : static_cast<double>(load<float>(at));
      }
      if (!positions[i].allFinite())
        throw FormatError(fmt::format("{}: vertex {} has a non-finite coordinate ({}, {}, {})", shown_, begin + i,
                                      positions[i].x(), positions[i].y(), positions[i].z()));
      if (const double far = positions[i].cwiseAbs().maxCoeff(); far > kMaxCoordinate)
        throw far_coordinate_error(shown_, begin + i, far);
    }
    chunk(begin, positions);
  }
}

void PlyTriangleFile::read_faces(std::uint64_t first, std::uint64_t last,
                                 const std::function<void(std::uint64_t, std::span<const Face>)>& chunk) const {
  const detail::PlyFixedLayout& L = layout_;
  last = std::min(last, L.faces);
  const std::size_t stride = L.face_stride();
  const std::uint64_t faces_at = L.body_offset + L.vertices * L.vertex_stride;
  std::vector<char> bytes;
  std::vector<Face> faces;
  for (std::uint64_t begin = first; begin < last; begin += kChunk) {
    const std::uint64_t n = std::min(kChunk, last - begin);
    bytes.resize(static_cast<std::size_t>(n * stride));
    read_bytes(bytes.data(), bytes.size(), faces_at + begin * stride);
    faces.resize(static_cast<std::size_t>(n));
    for (std::size_t i = 0; i < faces.size(); ++i) {
      const char* r = bytes.data() + i * stride;
      const std::int64_t count = L.count_size == 1 ? std::int64_t{load<std::uint8_t>(r)} : std::int64_t{load<std::int32_t>(r)};
      if (count != 3)
        throw FormatError(fmt::format("{}: face {} has {} corners, but the file's size says every face is a triangle",
                                      shown_, begin + i, count));
      for (std::size_t k = 0; k < 3; ++k) {
        const char* at = r + L.count_size + 4 * k;
        const std::int64_t v = L.index_signed ? std::int64_t{load<std::int32_t>(at)} : std::int64_t{load<std::uint32_t>(at)};
        if (v < 0 || static_cast<std::uint64_t>(v) >= L.vertices)
          throw FormatError(fmt::format("{}: face {}: vertex index {} out of range (the file has {} vertices)",
                                        shown_, begin + i, v, L.vertices));
        faces[i][k] = static_cast<std::uint32_t>(v);
      }
    }
    chunk(begin, faces);
  }
}

std::vector<Vec3> PlyTriangleFile::read_positions(std::span<const std::uint32_t> ids) const {
  std::vector<Vec3> out;
  out.reserve(ids.size());
  if (ids.empty()) return out;
  std::size_t next = 0;
  // One pass over the vertex records that the ids span (the chunks without any are skipped).
  std::uint64_t begin = ids.front();
  if (ids.back() >= layout_.vertices)
    throw InvalidInput(fmt::format("{}: vertex {} asked for, the file has {}", shown_, ids.back(), layout_.vertices));
  while (next < ids.size()) {
    begin = std::max<std::uint64_t>(begin, ids[next]);
    const std::uint64_t end = std::min<std::uint64_t>(begin + kChunk, layout_.vertices);
    read_vertices(begin, end, [&](std::uint64_t first, std::span<const Vec3> positions) {
      while (next < ids.size() && ids[next] < first + positions.size()) out.push_back(positions[ids[next++] - first]);
    });
    begin = end;
  }
  return out;
}

}  // namespace gimforge::io
