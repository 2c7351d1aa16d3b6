#include "io/stl_stream.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <unordered_map>
#include <vector>

#include <fmt/format.h>

#include "io/atomic_file.h"
#include "io/formats_internal.h"
#include "io/text_parse.h"
#include "kernels/core/errors.h"

namespace gimforge::io {
namespace {

namespace fs = std::filesystem;

constexpr std::size_t kHeader = 84;
constexpr std::size_t kFacet = 50;
constexpr std::size_t kChunk = std::size_t{1} << 20;  // facets per read

/// A file descriptor closed on scope exit.
struct Fd {
  int fd{-1};
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

/// Reads exactly `bytes` at `offset`; IoError naming the file otherwise.
void read_at(int fd, const fs::path& path, void* out, std::size_t bytes, std::uint64_t offset) {
  auto* p = static_cast<char*>(out);
  while (bytes > 0) {
    const ssize_t got = ::pread(fd, p, bytes, static_cast<off_t>(offset));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) throw IoError(fmt::format("{}: cannot read: {}", path.string(), got < 0 ? std::strerror(errno) : "unexpected end of file"));
    p += got;
    bytes -= static_cast<std::size_t>(got);
    offset += static_cast<std::uint64_t>(got);
  }
}

using detail::load_le;
using detail::put_le;

/// A temporary side file beside the output `ply`, removed on scope exit; errors name the output.
struct SideFile {
  fs::path path;
  fs::path ply;
  RemovedOnSignal pending{path};
  std::ofstream out;
  SideFile(fs::path p, fs::path output)
      : path(std::move(p)), ply(std::move(output)), out(path, std::ios::binary | std::ios::trunc) {
    if (!out) fail("cannot create a temporary file beside it");
  }
  [[noreturn]] void fail(const char* what) const {
    throw IoError(fmt::format("{}: {}: {}", ply.string(), what, std::strerror(errno)));
  }
  ~SideFile() {
    out.close();
    std::error_code ec;
    fs::remove(path, ec);
  }
  void write(const std::string& bytes) {
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!out) fail("cannot write a temporary file beside it");
  }
  void finish() {
    out.close();
    if (!out) fail("cannot write a temporary file beside it");
  }
};

void append_file(std::ofstream& out, const fs::path& from) {
  std::ifstream in(from, std::ios::binary);
  std::vector<char> buffer(std::size_t{1} << 22);
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    out.write(buffer.data(), in.gcount());
  }
  if (!in.eof()) throw IoError(fmt::format("{}: cannot read back", from.string()));
}

}  // namespace

bool is_streamable_binary_stl(const fs::path& path) noexcept {
  try {
    // read_mesh chooses the format by the extension: only a .stl is read as STL.
    std::string extension = path.extension().string();
    for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (extension != ".stl") return false;
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) return false;  // before open(): a FIFO would wait for a writer
    Fd f{::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC)};
    if (f.fd < 0) return false;
    const std::uintmax_t size = fs::file_size(path, ec);
    if (ec || size < kHeader) return false;
    std::vector<char> head(static_cast<std::size_t>(std::min<std::uintmax_t>(size, 65536)));
    read_at(f.fd, path, head.data(), head.size(), 0);
    const std::uint64_t n = load_le<std::uint32_t>(head.data() + 80);
    if (kHeader + kFacet * n != size) return false;
    const std::string_view data(head.data(), head.size());
    return !detail::looks_like_ascii_stl(data) || detail::find_binary_byte(data).has_value();
  } catch (...) {
    return false;
  }
}

StreamedMesh stream_stl_to_ply(const fs::path& stl, const fs::path& ply, const std::string& comment, bool double_precision) {
  Fd f{::open(stl.c_str(), O_RDONLY | O_CLOEXEC)};
  if (f.fd < 0) throw IoError(fmt::format("{}: cannot open: {}", stl.string(), std::strerror(errno)));
  char count[4];
  read_at(f.fd, stl, count, 4, 80);
  const std::uint64_t n = load_le<std::uint32_t>(count);
  if (n == 0) throw InvalidInput(fmt::format("{}: the mesh has no faces", stl.string()));
  if (comment.find_first_of("\r\n") != std::string::npos)
    throw InvalidInput(fmt::format("{}: cannot write PLY: the comment contains a line break", ply.string()));
  SideFile vertices(temporary_path(fs::path(ply.string() + ".vertices")), ply);
  SideFile faces(temporary_path(fs::path(ply.string() + ".faces")), ply);
  std::unordered_map<detail::CornerKey, std::uint32_t, detail::CornerKeyHash> weld;
  weld.reserve(static_cast<std::size_t>(std::min<std::uint64_t>(n / 2 + 1, std::uint64_t{1} << 24)));  // grows beyond
  std::vector<char> chunk;
  std::string vertex_bytes, face_bytes;
  const detail::Source src{stl.string(), {}};
  for (std::uint64_t first = 0; first < n; first += kChunk) {
    const auto count_here = static_cast<std::size_t>(std::min<std::uint64_t>(kChunk, n - first));
    chunk.resize(count_here * kFacet);
    read_at(f.fd, stl, chunk.data(), chunk.size(), kHeader + first * kFacet);
    vertex_bytes.clear();
    face_bytes.clear();
    for (std::size_t t = 0; t < count_here; ++t) {
      const char* corners = chunk.data() + t * kFacet + 12;
      std::array<std::uint32_t, 3> face{};
      for (std::size_t k = 0; k < 3; ++k) {
        const char* p = corners + 12 * k;
        const std::array<float, 3> c{load_le<float>(p), load_le<float>(p + 4), load_le<float>(p + 8)};
        const Vec3 v(static_cast<double>(c[0]), static_cast<double>(c[1]), static_cast<double>(c[2]));
        if (!v.allFinite()) detail::fail_non_finite(src, "triangle", first + t, v, "coordinate", 0);
        const auto [it, inserted] = weld.try_emplace(detail::corner_key(c[0], c[1], c[2]), static_cast<std::uint32_t>(weld.size()));
        if (inserted) {
          if (weld.size() > std::numeric_limits<std::uint32_t>::max())
            throw InvalidInput(fmt::format("{}: more distinct vertices than a PLY index holds", stl.string()));
          for (const float x : c)
            if (double_precision)
              put_le(vertex_bytes, static_cast<double>(x));
            else
              put_le(vertex_bytes, x);
        }
        face[k] = it->second;
      }
      face_bytes.push_back(3);
      for (const std::uint32_t i : face) put_le(face_bytes, i);
    }
    vertices.write(vertex_bytes);
    faces.write(face_bytes);
  }
  vertices.finish();
  faces.finish();
  const std::size_t nv = weld.size();
  weld = {};
  const char* coord = double_precision ? "double" : "float";
  std::string header = "ply\nformat binary_little_endian 1.0\n";
  if (!comment.empty()) header += fmt::format("comment {}\n", comment);
  header += fmt::format("element vertex {}\nproperty {} x\nproperty {} y\nproperty {} z\n", nv, coord, coord, coord);
  header += fmt::format("element face {}\nproperty list uchar {} vertex_indices\nend_header\n", n,
                        nv > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()) ? "uint" : "int");
  write_atomically(ply, [&](const fs::path& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw IoError(fmt::format("{}: cannot create", tmp.string()));
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    append_file(out, vertices.path);
    append_file(out, faces.path);
    out.close();
    if (!out) throw IoError(fmt::format("{}: cannot write", tmp.string()));
  });
  return {nv, n};
}

}  // namespace gimforge::io
