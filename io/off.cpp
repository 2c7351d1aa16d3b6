// OFF: "[ST][C][N]OFF" keyword (or none), "vertices faces [edges]", one vertex per line
// (x y z [nx ny nz] [r g b [a]] [s t]), one face per line (n i1 .. in [r g b [a]]); '#' comments.
#include <algorithm>
#include <optional>

#include <fmt/format.h>

#include "io/formats_internal.h"
#include "io/text_parse.h"

namespace gimforge::io::detail {

namespace {

struct OffVariant {
  bool texcoords{false};
  bool colors{false};
  bool normals{false};
  bool unsupported{false};  ///< 4OFF (4-D) or nOFF (n-D)
};

/// Parses "[ST][C][N][4][n]OFF"; nullopt if `tok` is not an OFF keyword.
std::optional<OffVariant> parse_keyword(std::string_view tok) {
  if (!tok.ends_with("OFF")) return std::nullopt;
  tok.remove_suffix(3);
  OffVariant v;
  const auto take = [&](std::string_view prefix) {
    if (!tok.starts_with(prefix)) return false;
    tok.remove_prefix(prefix.size());
    return true;
  };
  v.texcoords = take("ST");
  v.colors = take("C");
  v.normals = take("N");
  v.unsupported = take("4");
  v.unsupported = take("n") || v.unsupported;
  if (!tok.empty()) return std::nullopt;
  return v;
}

class OffReader {
 public:
  explicit OffReader(const Source& src) : src_(src), lines_(src.data) {}

  TriMesh read(ReadInfo& info) {
    counts(header());
    vertices();
    FaceBuilder builder(src_, m_.faces, num_vertices_);
    faces(builder);
    if (next()) {
      fail_line(src_, line(),
                fmt::format("unexpected data after the last face (the header declares {} faces)", num_faces_));
    }
    info.encoding = "ascii";
    info.polygons = num_faces_;
    info.triangulated = builder.triangulated();
    return std::move(m_);
  }

 private:
  bool next() {
    std::string_view text;
    if (!lines_.next_content(text, '#')) return false;
    split_tokens(text, tok_);
    return true;
  }
  [[nodiscard]] std::size_t line() const { return lines_.line_number(); }

  /// Reads the keyword line; returns the index in tok_ where the counts start.
  std::size_t header() {
    if (!next()) fail_not_format(src_, MeshFormat::Off);
    std::int64_t number = 0;
    if (const auto v = parse_keyword(tok_[0])) {
      variant_ = *v;
      if (variant_.unsupported)
        fail_line(src_, line(), fmt::format("unsupported OFF variant {}", quote_token(tok_[0])));
      if (tok_.size() > 1 && tok_[1] == "BINARY") fail_line(src_, line(), "binary OFF ('OFF BINARY') is not supported: convert it to PLY or ASCII OFF");
    } else if (!parse_int(tok_[0], number)) {
      fail_not_format(src_, MeshFormat::Off);
    } else {
      return 0;  // no keyword: the first line holds the counts
    }
    if (tok_.size() > 1) return 1;
    if (!next()) fail(src_, "truncated OFF: the file ends before the vertex and face counts");
    return 0;
  }

  std::uint64_t count_at(std::size_t k, std::string_view what) const {
    const std::int64_t v = integer_at(src_, line(), tok_[k], fmt::format("the {} count", what));
    if (v < 0) fail_line(src_, line(), fmt::format("negative {} count ({})", what, v));
    return static_cast<std::uint64_t>(v);
  }

  void counts(std::size_t first) {
    const std::size_t n = tok_.size() - first;
    if (n != 2 && n != 3) {
      fail_line(src_, line(), fmt::format("expected the counts 'vertices faces edges', found {} values", n));
    }
    num_vertices_ = count_at(first, "vertex");
    num_faces_ = count_at(first + 1, "face");
    if (n == 3) (void)count_at(first + 2, "edge");
    if (num_vertices_ > UINT32_MAX) {
      fail_line(src_, line(), fmt::format("{} vertices is more than gimforge indexes (2^32-1)", num_vertices_));
    }
  }

  void vertices() {
    const std::size_t base = variant_.normals ? 6 : 3;
    const std::size_t expected = base + (variant_.colors ? 3 : 0) + (variant_.texcoords ? 2 : 0);
    // Reserve no more than the rest of the file could hold (a vertex line takes at least 6 bytes), so a
    // hostile count allocates nothing; a short file fails at the exact vertex where it ends.
    const std::uint64_t room = (src_.data.size() - lines_.offset()) / 6 + 1;
    m_.positions.reserve(std::min(num_vertices_, room));
    if (variant_.normals) m_.normals.reserve(std::min(num_vertices_, room));
    if (variant_.colors) m_.colors.reserve(std::min(num_vertices_, room));
    for (std::uint64_t i = 0; i < num_vertices_; ++i) {
      if (!next()) {
        fail(src_, fmt::format("truncated OFF: the file ends before vertex {} of {} (after line {})", i, num_vertices_,
                               line()));
      }
      const std::size_t n = tok_.size();
      if (n != expected && !(variant_.colors && n == expected + 1)) {
        fail_line(src_, line(), fmt::format("vertex {}: expected {} values, found {}", i, expected, n));
      }
      vertex(i, base);
    }
  }

  Vec3 numbers(std::size_t first, const std::string& what) const {
    return Vec3(number_at(src_, line(), tok_[first], what), number_at(src_, line(), tok_[first + 1], what),
                number_at(src_, line(), tok_[first + 2], what));
  }

  /// Integer colour components are 0..255, real ones 0..1.
  Vec3 color(std::size_t first, const std::string& what) const {
    std::int64_t v = 0;
    const bool integers = parse_int(tok_[first], v) && parse_int(tok_[first + 1], v) && parse_int(tok_[first + 2], v);
    return numbers(first, what) / (integers ? 255.0 : 1.0);
  }

  void vertex(std::uint64_t i, std::size_t base) {
    const std::string what = fmt::format("vertex {}", i);
    for (std::size_t k = 0; k < tok_.size(); ++k) (void)number_at(src_, line(), tok_[k], what);
    const Vec3 p = numbers(0, what);
    check_finite(src_, i, p, "coordinate", line());
    m_.positions.push_back(p);
    if (variant_.normals) {
      const Vec3 n = numbers(3, what);
      // A non-finite one drops them all (read_mesh).
      m_.normals.emplace_back(to_float(n.x()), to_float(n.y()), to_float(n.z()));
    }
    if (variant_.colors) m_.colors.push_back(unit_color(src_, i, color(base, what), line()));
  }

  void faces(FaceBuilder& builder) {
    m_.faces.reserve(std::min(num_faces_, (src_.data.size() - lines_.offset()) / 2 + 1));
    std::vector<std::int64_t> poly;
    for (std::uint64_t f = 0; f < num_faces_; ++f) {
      if (!next()) {
        fail(src_,
             fmt::format("truncated OFF: the file ends before face {} of {} (after line {})", f, num_faces_, line()));
      }
      const std::string what = fmt::format("face {}", f);
      const std::int64_t n = integer_at(src_, line(), tok_[0], what);
      builder.check_count(n, f, line());
      const std::size_t listed = tok_.size() - 1;
      if (static_cast<std::uint64_t>(n) > listed) {
        fail_line(src_, line(), fmt::format("face {} declares {} vertices but lists only {}", f, n, listed));
      }
      const std::size_t extra = listed - static_cast<std::size_t>(n);
      if (extra != 0 && extra != 3 && extra != 4) {
        fail_line(src_, line(),
                  fmt::format("face {}: {} values after its {} vertex indices (expected none, or a "
                              "colour of 3 or 4)",
                              f, extra, n));
      }
      poly.resize(static_cast<std::size_t>(n));
      for (std::size_t k = 0; k < poly.size(); ++k) poly[k] = integer_at(src_, line(), tok_[k + 1], what);
      for (std::size_t k = poly.size() + 1; k < tok_.size(); ++k) (void)number_at(src_, line(), tok_[k], what);
      builder.add(poly, f, line());
    }
  }

  const Source& src_;
  LineReader lines_;
  std::vector<std::string_view> tok_;
  OffVariant variant_;
  std::uint64_t num_vertices_{0};
  std::uint64_t num_faces_{0};
  TriMesh m_;
};

}  // namespace

bool looks_like_off(std::string_view data) {
  LineReader lines(data);
  std::string_view line;
  if (!lines.next_content(line, '#')) return false;
  std::vector<std::string_view> tok;
  split_tokens(line, tok);
  return parse_keyword(tok[0]).has_value();
}

TriMesh read_off(const Source& src, ReadInfo& info) {
  if (find_binary_byte(src.data, 4096)) {
    // "OFF BINARY" (Geomview's binary OFF) is an OFF file, only not one this reader takes.
    LineReader lines(src.data.substr(0, std::min<std::size_t>(src.data.size(), 256)));
    std::string_view line;
    std::vector<std::string_view> tok;
    if (lines.next_content(line, '#')) split_tokens(line, tok);
    if (tok.size() > 1 && parse_keyword(tok[0]).has_value() && tok[1] == "BINARY")
      fail(src, "binary OFF ('OFF BINARY') is not supported: convert it to PLY or ASCII OFF");
    fail_not_format(src, MeshFormat::Off);
  }
  return OffReader(src).read(info);
}

namespace {

/// A colour component as a real number: "1.0", never "1", which OFF readers take for 1/255.
std::string real_text(float v) {
  std::string t = fmt::format("{}", v);
  if (t.find_first_of(".eEn") == std::string::npos) t += ".0";
  return t;
}

}  // namespace

std::string off_bytes(const TriMesh& mesh) {
  std::string out = fmt::format("{}{}OFF\n# written by gimforge\n{} {} 0\n", mesh.has_colors() ? "C" : "",
                                mesh.has_normals() ? "N" : "", mesh.num_vertices(), mesh.num_faces());
  out.reserve(out.size() + 48 * mesh.num_vertices() + 24 * mesh.num_faces());
  for (std::size_t i = 0; i < mesh.num_vertices(); ++i) {
    const Vec3& p = mesh.positions[i];
    out += fmt::format("{} {} {}", exact_text(p.x()), exact_text(p.y()), exact_text(p.z()));
    if (mesh.has_normals()) {
      const Vec3f& n = mesh.normals[i];
      out += fmt::format(" {} {} {}", n.x(), n.y(), n.z());
    }
    if (mesh.has_colors()) {
      const Vec3f& c = mesh.colors[i];
      out += fmt::format(" {} {} {}", real_text(c.x()), real_text(c.y()), real_text(c.z()));
    }
    out += '\n';
  }
  for (const Face& f : mesh.faces) out += fmt::format("3 {} {} {}\n", f[0], f[1], f[2]);
  return out;
}

}  // namespace gimforge::io::detail
