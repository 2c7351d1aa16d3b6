// OBJ: "v x y z [w]" or "v x y z r g b"; "f" with v, v/vt, v//vn or v/vt/vn references (negative =
// relative to the vertices read so far), polygons fan-triangulated. Statements that carry no geometry we
// use (vt, vn, g, o, s, usemtl, mtllib, l, p, free-form ...) are skipped; unknown statements are errors.
#include <algorithm>
#include <array>
#include <cmath>

#include <fmt/format.h>

#include "io/formats_internal.h"
#include "io/text_parse.h"

namespace gimforge::io::detail {

namespace {

constexpr std::array<std::string_view, 37> kIgnored{
    "vt",     "vn",         "vp",        "g",     "o",     "s",     "usemtl",   "mtllib",   "l",    "p",
    "cstype", "deg",        "bmat",      "step",  "curv",  "curv2", "surf",     "parm",     "trim", "hole",
    "scrv",   "sp",         "end",       "con",   "mg",    "bevel", "c_interp", "d_interp", "lod",  "maplib",
    "usemap", "shadow_obj", "trace_obj", "ctech", "stech", "call",  "csh"};

bool is_ignored(std::string_view keyword) {
  return std::find(kIgnored.begin(), kIgnored.end(), keyword) != kIgnored.end();
}

/// Everything an OBJ file holds that we use, before indices are checked against the final vertex count
/// (positive indices may refer forward).
struct ObjData {
  std::vector<Vec3> positions;
  std::vector<Vec3> colors;           ///< one per vertex that had r g b, as written (finite)
  std::vector<std::int64_t> indices;  ///< all polygons one after another, 0-based
  std::vector<std::size_t> starts;    ///< polygon k is indices[starts[k], starts[k + 1])
  std::vector<std::size_t> lines;     ///< line of polygon k
};

/// The text after a UTF-8 byte-order mark, which some Windows tools write first.
std::string_view without_bom(std::string_view text) {
  constexpr std::string_view kBom = "\xEF\xBB\xBF";
  return text.starts_with(kBom) ? text.substr(kBom.size()) : text;
}

class ObjParser {
 public:
  explicit ObjParser(const Source& src) : src_(src), lines_(without_bom(src.data)) {}

  ObjData parse() {
    std::string_view line;
    while (lines_.next_content(line, '#')) {
      split_tokens(continued(line), tok_);
      if (tok_.empty()) continue;  // a lone backslash before a blank line
      const std::string_view kw = tok_[0];
      if (kw == "v") {
        vertex();
      } else if (kw == "f") {
        face();
      } else if (!is_ignored(kw)) {
        fail_line(src_, line_no(), fmt::format("unknown OBJ statement {}", quote_token(kw)));
      }
    }
    d_.starts.push_back(d_.indices.size());
    return std::move(d_);
  }

 private:
  [[nodiscard]] std::size_t line_no() const { return lines_.line_number(); }

  /// `line`, joined with the lines that follow while it ends in a backslash (the OBJ spec's continuation:
  /// `f 1 2 \` then `3 4`), in a buffer the tokens point into until the next line.
  std::string_view continued(std::string_view line) {
    line = trim(line);
    if (!line.ends_with('\\')) return line;
    joined_.clear();
    while (line.ends_with('\\')) {
      joined_.append(line.substr(0, line.size() - 1)).push_back(' ');
      std::string_view next;
      if (!lines_.next(next))
        fail_line(src_, line_no(), "the last line ends in a continuation backslash ('\\') with nothing after it");
      line = trim(strip_comment(next, '#'));
    }
    joined_.append(line);
    return joined_;
  }

  Vec3 numbers(std::size_t first, const std::string& what) const {
    return Vec3(number_at(src_, line_no(), tok_[first], what), number_at(src_, line_no(), tok_[first + 1], what),
                number_at(src_, line_no(), tok_[first + 2], what));
  }

  void vertex() {
    const std::size_t index = d_.positions.size();
    const std::size_t n = tok_.size() - 1;
    const std::string what = fmt::format("vertex {}", index);
    if (n != 3 && n != 4 && n != 6) {
      fail_line(src_, line_no(),
                fmt::format("{}: expected 3, 4 or 6 numbers (x y z [w] or x y z r g b), found {}", what, n));
    }
    const Vec3 p = numbers(1, what);
    check_finite(src_, index, p, "coordinate", line_no());
    d_.positions.push_back(p);
    if (n == 4) (void)number_at(src_, line_no(), tok_[4], what);
    if (n == 6) {
      const Vec3 rgb = numbers(4, what);
      check_finite(src_, index, rgb, "colour", line_no());
      d_.colors.push_back(rgb);
    }
  }

  void face() {
    const std::size_t face_no = d_.lines.size();
    d_.starts.push_back(d_.indices.size());
    d_.lines.push_back(line_no());
    for (std::size_t k = 1; k < tok_.size(); ++k) d_.indices.push_back(resolve(tok_[k], face_no));
  }

  /// The 0-based vertex index of a face corner "v", "v/vt", "v//vn" or "v/vt/vn".
  std::int64_t resolve(std::string_view corner, std::size_t face_no) const {
    const std::size_t slash = corner.find('/');
    if (slash != std::string_view::npos) check_references(corner, corner.substr(slash + 1), face_no);
    const std::int64_t raw = integer_at(src_, line_no(), corner.substr(0, slash), fmt::format("face {}", face_no));
    if (raw > 0) return raw - 1;  // forward references are checked once all vertices are known
    if (raw == 0) {
      fail_line(src_, line_no(),
                fmt::format("face {}: vertex index 0 is out of range (OBJ indices start at 1)", face_no));
    }
    const auto before = static_cast<std::int64_t>(d_.positions.size());
    if (raw < -before) {
      fail_line(
          src_, line_no(),
          fmt::format("face {}: vertex index {} is out of range (only {} vertices precede it)", face_no, raw, before));
    }
    return before + raw;
  }

  /// Checks the "vt", "vt/vn" or "/vn" after the vertex index (their values are not used).
  void check_references(std::string_view corner, std::string_view rest, std::size_t face_no) const {
    const std::size_t slash = rest.find('/');
    const std::string_view vt = rest.substr(0, slash);
    const std::string_view vn = slash == std::string_view::npos ? std::string_view{} : rest.substr(slash + 1);
    std::int64_t v = 0;
    const bool vt_ok = vt.empty() ? slash != std::string_view::npos : parse_int(vt, v);
    const bool vn_ok = slash == std::string_view::npos || parse_int(vn, v);
    if (!vt_ok || !vn_ok) {
      fail_line(src_, line_no(), fmt::format("face {}: malformed vertex reference {}", face_no, quote_token(corner)));
    }
  }

  const Source& src_;
  LineReader lines_;
  std::vector<std::string_view> tok_;
  std::string joined_;  // continued lines
  ObjData d_;
};

}  // namespace

bool looks_like_obj(std::string_view data) {
  static constexpr std::array<std::string_view, 9> kFirst{"v", "vn", "vt", "f", "o", "g", "s", "mtllib", "usemtl"};
  LineReader lines(data);
  std::string_view line;
  if (!lines.next_content(line, '#')) return false;
  std::vector<std::string_view> tok;
  split_tokens(line, tok);
  return std::find(kFirst.begin(), kFirst.end(), tok[0]) != kFirst.end();
}

TriMesh read_obj(const Source& src, ReadInfo& info) {
  if (find_binary_byte(src.data) || looks_like_ply(src.data) || looks_like_off(src.data) ||
      looks_like_ascii_stl(src.data)) {
    fail_not_format(src, MeshFormat::Obj);
  }
  ObjData d = ObjParser(src).parse();
  TriMesh m;
  m.positions = std::move(d.positions);
  if (!d.colors.empty() && d.colors.size() == m.positions.size()) {
    // OBJ's vertex colours have no standard range: most tools write 0..1, some 0..255. Whole numbers in
    // 0..255, some above 1, mean the latter for the whole file (as OFF's integer colours are read); anything
    // else is 0..1, clamped.
    double top = 0.0;
    bool bytes = true;
    for (const Vec3& c : d.colors) {
      top = std::max(top, c.maxCoeff());
      for (int k = 0; k < 3; ++k) bytes = bytes && c[k] >= 0.0 && c[k] <= 255.0 && c[k] == std::floor(c[k]);
    }
    const double scale = bytes && top > 1.0 ? 1.0 / 255.0 : 1.0;
    m.colors.reserve(d.colors.size());
    for (const Vec3& c : d.colors) m.colors.push_back(unit_color(src, 0, c * scale));
  }
  m.faces.reserve(d.lines.size());
  FaceBuilder builder(src, m.faces, m.positions.size(), 1);
  const std::span<const std::int64_t> all(d.indices);
  for (std::size_t k = 0; k < d.lines.size(); ++k) {
    builder.add(all.subspan(d.starts[k], d.starts[k + 1] - d.starts[k]), k, d.lines[k]);
  }
  info.encoding = "ascii";
  info.polygons = d.lines.size();
  info.triangulated = builder.triangulated();
  return m;
}

std::string obj_bytes(const TriMesh& mesh) {
  std::string out = "# written by gimforge\n";
  out.reserve(out.size() + 48 * mesh.num_vertices() + 24 * mesh.num_faces());
  for (std::size_t i = 0; i < mesh.num_vertices(); ++i) {
    const Vec3& p = mesh.positions[i];
    out += fmt::format("v {} {} {}", exact_text(p.x()), exact_text(p.y()), exact_text(p.z()));
    if (mesh.has_colors()) {
      const Vec3f& c = mesh.colors[i];
      out += fmt::format(" {} {} {}", c.x(), c.y(), c.z());
    }
    out += '\n';
  }
  for (const Vec3f& n : mesh.normals) out += fmt::format("vn {} {} {}\n", n.x(), n.y(), n.z());
  for (const Face& f : mesh.faces) {
    if (mesh.has_normals())
      out += fmt::format("f {0}//{0} {1}//{1} {2}//{2}\n", f[0] + 1ull, f[1] + 1ull, f[2] + 1ull);
    else
      out += fmt::format("f {} {} {}\n", f[0] + 1ull, f[1] + 1ull, f[2] + 1ull);
  }
  return out;
}

}  // namespace gimforge::io::detail
