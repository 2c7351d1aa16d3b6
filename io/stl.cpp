// STL: binary (80-byte header, uint32 count, 50 bytes per triangle) or ASCII (solid/facet/outer loop/
// vertex/endloop/endfacet/endsolid). STL stores corners, not indices: corners are welded by their exact
// value (-0 counts as +0) — the float32 of a binary file, the double a text file's number parses to, as
// OBJ and OFF keep them (an ASCII STL at georeferenced coordinates keeps its decimals) — and vertices are
// numbered in order of first appearance, so the result is deterministic. Facet normals and attribute bytes
// are ignored.
#include <bit>
#include <cctype>
#include <type_traits>
#include <unordered_map>

#include <fmt/format.h>

#include "io/formats_internal.h"
#include "io/text_parse.h"

namespace gimforge::io::detail {

namespace {

constexpr std::size_t kBinaryHeader = 84;
constexpr std::size_t kBinaryTriangle = 50;

/// A binary file's corner (float32) or a text file's (double).
template <class Scalar>
using Corner = std::array<Scalar, 3>;

/// The bits of a double corner, -0 as +0 (corner_key of formats_internal.h for floats).
using WideCornerKey = std::array<std::uint64_t, 3>;

/// Gives each distinct corner position a vertex index, appending new positions.
template <class Scalar>
class Welder {
 public:
  Welder(std::vector<Vec3>& positions, std::size_t expected) : positions_(positions) { map_.reserve(expected); }

  std::uint32_t index_of(const Corner<Scalar>& c) {
    const auto [it, inserted] = map_.try_emplace(key(c), static_cast<std::uint32_t>(positions_.size()));
    if (inserted)
      positions_.emplace_back(static_cast<double>(c[0]), static_cast<double>(c[1]), static_cast<double>(c[2]));
    return it->second;
  }

 private:
  static constexpr bool kFloat = std::is_same_v<Scalar, float>;
  using Key = std::conditional_t<kFloat, CornerKey, WideCornerKey>;

  static Key key(const Corner<Scalar>& c) {
    if constexpr (kFloat) {
      return corner_key(c[0], c[1], c[2]);
    } else {
      const auto bits = [](double v) { return std::bit_cast<std::uint64_t>(v == 0.0 ? 0.0 : v); };
      return {bits(c[0]), bits(c[1]), bits(c[2])};
    }
  }

  std::vector<Vec3>& positions_;
  std::unordered_map<Key, std::uint32_t, CornerKeyHash> map_;
};

template <class Scalar>
void check_corner(const Source& src, std::string_view item, std::uint64_t index, const Corner<Scalar>& c,
                  std::size_t line = 0) {
  const Vec3 v(static_cast<double>(c[0]), static_cast<double>(c[1]), static_cast<double>(c[2]));
  if (!v.allFinite()) fail_non_finite(src, item, index, v, "coordinate", line);
}

std::uint32_t binary_count(std::string_view data) { return load_le<std::uint32_t>(data.data() + 80); }

TriMesh read_binary(const Source& src, ReadInfo& info) {
  const std::uint32_t n = binary_count(src.data);
  TriMesh m;
  m.faces.reserve(n);
  Welder<float> welder(m.positions, n / 2 + 1);
  for (std::uint32_t t = 0; t < n; ++t) {
    const char* corners = src.data.data() + kBinaryHeader + std::size_t{t} * kBinaryTriangle + 12;
    Face face{};
    for (std::size_t k = 0; k < 3; ++k) {
      const char* p = corners + 12 * k;
      const Corner<float> c{load_le<float>(p), load_le<float>(p + 4), load_le<float>(p + 8)};
      check_corner(src, "triangle", t, c);
      face[k] = welder.index_of(c);
    }
    m.faces.push_back(face);
  }
  info.encoding = "binary";
  info.float32_coordinates = true;
  info.polygons = n;
  return m;
}

bool iequals(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
         });
}

/// ASCII STL, one statement per line.
class AsciiStlParser {
 public:
  AsciiStlParser(const Source& src, TriMesh& m) : src_(src), lines_(src.data), mesh_(m), welder_(m.positions, 1024) {}

  void parse() {
    while (next(false)) {
      expect("solid", 0, std::string_view::npos);
      while (next(true) && !is("endsolid")) facet();
    }
  }

  [[nodiscard]] std::size_t facets() const { return facets_; }
  [[nodiscard]] std::size_t triangulated() const { return triangulated_; }

 private:
  /// Reads the next non-blank line; at the end of the file returns false, or fails when `required`.
  bool next(bool required) {
    std::string_view text;
    if (lines_.next_content(text)) {
      split_tokens(text, tok_);
      return true;
    }
    if (required) {
      fail(src_, fmt::format("malformed ASCII STL: the file ends inside a solid (missing 'endsolid' after line {})",
                             lines_.line_number()));
    }
    return false;
  }

  [[nodiscard]] bool is(std::string_view keyword) const { return iequals(tok_[0], keyword); }

  /// Checks that the line is `keyword` with between min_args and max_args arguments.
  void expect(std::string_view keyword, std::size_t min_args, std::size_t max_args) const {
    const std::size_t args = tok_.size() - 1;
    if (!is(keyword)) {
      fail_line(src_, lines_.line_number(),
                fmt::format("malformed ASCII STL: expected '{}', found {}", keyword, quote_token(tok_[0])));
    }
    if (args < min_args || args > max_args) {
      fail_line(src_, lines_.line_number(), fmt::format("malformed ASCII STL: '{}' with {} values", keyword, args));
    }
  }

  Corner<double> numbers(std::size_t first) const {
    const std::string what = fmt::format("facet {}", facets_);
    Corner<double> c{};
    for (std::size_t k = 0; k < 3; ++k) c[k] = number_at(src_, lines_.line_number(), tok_[first + k], what);
    return c;
  }

  void facet() {
    expect("facet", 4, 4);
    if (!iequals(tok_[1], "normal")) {
      fail_line(src_, lines_.line_number(),
                fmt::format("malformed ASCII STL: expected 'facet normal', found 'facet {}'", quote_token(tok_[1])));
    }
    (void)numbers(2);
    next(true);
    expect("outer", 1, 1);
    if (!iequals(tok_[1], "loop")) {
      fail_line(src_, lines_.line_number(), "malformed ASCII STL: expected 'outer loop'");
    }
    corners_.clear();
    while (next(true) && !is("endloop")) {
      expect("vertex", 3, 3);
      const Corner<double> c = numbers(1);
      check_corner(src_, "facet", facets_, c, lines_.line_number());
      corners_.push_back(welder_.index_of(c));
    }
    expect("endloop", 0, 0);
    check_face_size(src_, static_cast<std::int64_t>(corners_.size()), facets_, lines_.line_number());
    fan_triangulate(corners_, mesh_.faces);
    if (corners_.size() > 3) ++triangulated_;
    next(true);
    expect("endfacet", 0, 0);
    ++facets_;
  }

  const Source& src_;
  LineReader lines_;
  TriMesh& mesh_;
  Welder<double> welder_;
  std::vector<std::string_view> tok_;
  std::vector<std::uint32_t> corners_;
  std::size_t facets_{0};
  std::size_t triangulated_{0};
};

TriMesh read_ascii(const Source& src, ReadInfo& info) {
  TriMesh m;
  AsciiStlParser parser(src, m);
  parser.parse();
  info.encoding = "ascii";
  info.polygons = parser.facets();
  info.triangulated = parser.triangulated();
  return m;
}

[[noreturn]] void fail_binary_size(const Source& src) {
  if (src.data.size() < kBinaryHeader) {
    fail(src, fmt::format("not an STL file: it does not start with 'solid' and is too short for a binary STL ({} "
                          "bytes; the binary header alone is 84)",
                          src.data.size()));
  }
  const std::uint64_t n = binary_count(src.data);
  fail(src, fmt::format("binary STL size mismatch: the header declares {} triangles, which need 84 + 50*{} = {} "
                        "bytes, but the file is {} bytes{}",
                        n, n, kBinaryHeader + kBinaryTriangle * n, src.data.size(),
                        kBinaryHeader + kBinaryTriangle * n > src.data.size() ? " (truncated)" : ""));
}

}  // namespace

bool looks_like_ascii_stl(std::string_view data) {
  const std::size_t start = data.find_first_not_of(" \t\r\n\f\v");
  if (start == std::string_view::npos) return false;
  const std::string_view t = data.substr(start);
  return t.starts_with("solid") && (t.size() == 5 || is_space(t[5]) || t[5] == '\n');
}

bool looks_like_binary_stl(std::string_view data) {
  return data.size() >= kBinaryHeader &&
         kBinaryHeader + kBinaryTriangle * std::uint64_t{binary_count(data)} == data.size();
}

TriMesh read_stl(const Source& src, ReadInfo& info) {
  // Binary files may start with "solid" too: text all the way through means ASCII, otherwise the size decides.
  const bool text = !find_binary_byte(src.data).has_value();
  if (looks_like_ascii_stl(src.data) && text) return read_ascii(src, info);
  if (looks_like_binary_stl(src.data)) return read_binary(src, info);
  if (text) fail_not_format(src, MeshFormat::Stl);
  fail_binary_size(src);
}

std::string stl_bytes(const TriMesh& mesh) {
  std::string out(80, ' ');
  constexpr std::string_view kHeader = "binary STL written by gimforge";  // never "solid ...": that means ASCII
  std::copy(kHeader.begin(), kHeader.end(), out.begin());
  out.reserve(84 + 50 * mesh.num_faces());
  put_le(out, static_cast<std::uint32_t>(mesh.num_faces()));
  for (const Face& f : mesh.faces) {
    const Vec3& a = mesh.positions[f[0]];
    const Vec3& b = mesh.positions[f[1]];
    const Vec3& c = mesh.positions[f[2]];
    const Vec3 cross = (b - a).cross(c - a);
    const double length = cross.norm();
    const Vec3 n = length > 0.0 ? Vec3(cross / length) : Vec3(Vec3::Zero());
    for (const Vec3* v : {&n, &a, &b, &c})
      for (int k = 0; k < 3; ++k) put_le(out, to_float((*v)[k]));
    put_le(out, std::uint16_t{0});
  }
  return out;
}

}  // namespace gimforge::io::detail
