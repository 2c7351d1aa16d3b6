#include "io/mesh_header.h"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>

#include "io/input_file.h"
#include "io/mesh_io.h"

namespace gimforge::io {
namespace {

std::string read_prefix(const std::filesystem::path& path, std::size_t bytes) {
  require_regular_file(path, path.string());  // a FIFO's open would wait for a writer
  std::ifstream in(path, std::ios::binary);
  std::string data(bytes, '\0');
  in.read(data.data(), static_cast<std::streamsize>(bytes));
  data.resize(static_cast<std::size_t>(std::max<std::streamsize>(0, in.gcount())));
  return data;
}

std::uint64_t by_size(std::uint64_t file_bytes, std::uint64_t bytes_per_face) {
  return std::max<std::uint64_t>(1, file_bytes / bytes_per_face);
}

/// `element face N` of a PLY header, or 0.
std::uint64_t ply_faces(const std::string& head) {
  std::istringstream in(head);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    std::string a, b;
    unsigned long long n = 0;
    if ((words >> a >> b >> n) && a == "element" && b == "face") return n;
    if (line.rfind("end_header", 0) == 0) break;
  }
  return 0;
}

/// Face count of an OFF header ("OFF" then "V F E", comments skipped), or 0.
std::uint64_t off_faces(const std::string& head) {
  std::istringstream in(head);
  std::string line;
  bool magic = false;
  while (std::getline(in, line)) {
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream words(line);
    std::string first;
    if (!(words >> first)) continue;
    if (!magic) {
      if (first.find("OFF") == std::string::npos) return 0;
      magic = true;
      if (unsigned long long v = 0, f = 0; (words >> v >> f)) return f;  // "OFF V F E" on one line
      continue;
    }
    std::istringstream counts(line);
    unsigned long long v = 0, f = 0;
    return (counts >> v >> f) ? f : 0;
  }
  return 0;
}

}  // namespace

std::uint64_t estimate_triangles(const std::filesystem::path& path) noexcept {
  try {
    std::error_code ec;
    const std::uint64_t size = std::filesystem::file_size(path, ec);
    if (ec) return 0;
    const std::string head = read_prefix(path, 64 * 1024);
    switch (format_from_extension(path)) {
      case MeshFormat::Ply:
        if (const std::uint64_t n = ply_faces(head); n > 0) return n;
        return by_size(size, 15);
      case MeshFormat::Off:
        if (const std::uint64_t n = off_faces(head); n > 0) return n;
        return by_size(size, 30);
      case MeshFormat::Stl:
        if (head.size() >= 84) {  // binary STL, even one whose header starts with "solid"
          std::uint32_t n = 0;
          std::memcpy(&n, head.data() + 80, 4);
          if (84 + 50ull * n == size) return n;
        }
        return by_size(size, 250);
      case MeshFormat::Obj: return by_size(size, 30);
    }
  } catch (...) {  // unknown extension or I/O trouble: the conversion will report it
  }
  return 0;
}

}  // namespace gimforge::io
