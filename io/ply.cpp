// PLY reader: header parsing; one decoder for every encoding and scalar type (records read through a
// cursor: ASCII tokens or binary bytes of either endianness; unknown elements and properties skipped); a
// fast path for the common binary layout. The writer is io/ply_write.cpp.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <iterator>
#include <new>
#include <optional>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>

#include "io/formats_internal.h"
#include "io/text_parse.h"
#include "kernels/core/errors.h"

namespace gimforge::io {

namespace detail {

namespace {

// ---- Scalar types ----

enum class Scalar : std::uint8_t { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

struct ScalarInfo {
  std::string_view name;   ///< PLY's original name (char, uchar, ...)
  std::string_view alias;  ///< the sized name (int8, uint8, ...)
  std::size_t size;
  std::int64_t min;  ///< range of an integer type
  std::int64_t max;
};

constexpr std::array<ScalarInfo, 8> kScalars{{
    {"char", "int8", 1, INT8_MIN, INT8_MAX},
    {"uchar", "uint8", 1, 0, UINT8_MAX},
    {"short", "int16", 2, INT16_MIN, INT16_MAX},
    {"ushort", "uint16", 2, 0, UINT16_MAX},
    {"int", "int32", 4, INT32_MIN, INT32_MAX},
    {"uint", "uint32", 4, 0, UINT32_MAX},
    {"float", "float32", 4, 0, 0},
    {"double", "float64", 8, 0, 0},
}};

const ScalarInfo& info_of(Scalar t) { return kScalars[static_cast<std::size_t>(t)]; }
std::size_t size_of(Scalar t) { return info_of(t).size; }
bool is_float(Scalar t) { return t == Scalar::Float32 || t == Scalar::Float64; }

std::optional<Scalar> scalar_from_name(std::string_view name) {
  for (std::size_t i = 0; i < kScalars.size(); ++i) {
    if (name == kScalars[i].name || name == kScalars[i].alias) return static_cast<Scalar>(i);
  }
  return std::nullopt;
}

template <class T>
T load(const char* p, bool swap) {
  return load_bytes<T>(p, swap);
}

/// Loads a value of scalar type `t` and converts it to R. Float types reach R = int64 only through
/// callers that the header parser already restricted to integer types (list counts, indices).
template <class R>
R load_as(Scalar t, const char* p, bool swap) {
  switch (t) {
    case Scalar::Int8:
      return static_cast<R>(load<std::int8_t>(p, swap));
    case Scalar::UInt8:
      return static_cast<R>(load<std::uint8_t>(p, swap));
    case Scalar::Int16:
      return static_cast<R>(load<std::int16_t>(p, swap));
    case Scalar::UInt16:
      return static_cast<R>(load<std::uint16_t>(p, swap));
    case Scalar::Int32:
      return static_cast<R>(load<std::int32_t>(p, swap));
    case Scalar::UInt32:
      return static_cast<R>(load<std::uint32_t>(p, swap));
    case Scalar::Float32:
      return static_cast<R>(load<float>(p, swap));
    case Scalar::Float64:
      return static_cast<R>(load<double>(p, swap));
  }
  return R{};
}

double load_double(Scalar t, const char* p, bool swap) { return load_as<double>(t, p, swap); }

/// Only for integer types (the header parser rejects float list counts and float indices).
std::int64_t load_int(Scalar t, const char* p, bool swap) { return load_as<std::int64_t>(t, p, swap); }

// ---- Header ----

enum class Encoding { Ascii, BinaryLittle, BinaryBig };

const char* encoding_name(Encoding e) {
  switch (e) {
    case Encoding::Ascii:
      return "ascii";
    case Encoding::BinaryLittle:
      return "binary_little_endian";
    case Encoding::BinaryBig:
      return "binary_big_endian";
  }
  return "?";
}

/// Where a vertex property's value goes (index into the per-record value array).
/// Extra: the property Source::vertex_scalar names (read_ply_vertex_scalar).
enum class Slot : std::uint8_t { None, X, Y, Z, NX, NY, NZ, Red, Green, Blue, Extra };
constexpr std::size_t kSlots = 11;
constexpr std::array<std::string_view, kSlots> kSlotNames{"", "x", "y", "z", "nx", "ny", "nz", "red", "green", "blue", ""};

struct Property {
  std::string name;
  Scalar type{};  ///< the value type (list items for a list)
  bool is_list{false};
  Scalar count_type{};       ///< list length type
  Slot slot{Slot::None};     ///< vertex element only
  bool face_indices{false};  ///< the face element's vertex_indices list
};

enum class Role { Other, Vertex, Face };

struct Element {
  std::string name;
  std::uint64_t count{0};
  std::vector<Property> props;
  Role role{Role::Other};
};

struct Header {
  Encoding encoding{Encoding::Ascii};
  std::vector<Element> elements;
  std::size_t body_offset{0};  ///< first byte after the end_header line
  std::size_t lines{0};        ///< lines in the header, end_header included
  std::uint64_t num_vertices{0};
  std::uint64_t num_faces{0};
  bool normals{false};
  bool colors{false};
  bool extra{false};  ///< Slot::Extra is assigned
};

/// Parses the header and decides what each element and property is for.
class HeaderParser {
 public:
  explicit HeaderParser(const Source& src) : src_(src), lines_(src.data) {}

  Header parse() {
    std::string_view line;
    if (!lines_.next(line) || trim(line) != "ply") fail_not_format(src_, MeshFormat::Ply);
    std::vector<std::string_view> tok;
    while (lines_.next(line)) {
      if (const auto at = find_binary_byte(line)) {
        fail_line(src_, lines_.line_number(),
                  fmt::format("bad PLY header: binary byte 0x{:02x} before end_header (missing end_header?)",
                              static_cast<unsigned char>(line[*at])));
      }
      split_tokens(line, tok);
      if (tok.empty()) continue;
      if (tok[0] == "end_header") return finish(tok.size());
      parse_line(tok);
    }
    fail(src_, fmt::format("missing end_header: the PLY header never ends ({} lines read)", lines_.line_number()));
  }

 private:
  [[noreturn]] void bad(std::string_view cause) const {
    fail_line(src_, lines_.line_number(), fmt::format("bad PLY header: {}", cause));
  }

  void parse_line(const std::vector<std::string_view>& tok) {
    const std::string_view kw = tok[0];
    if (kw == "comment" || kw == "obj_info") return;
    if (kw == "format") return parse_format(tok);
    if (kw == "element") return parse_element(tok);
    if (kw == "property") return parse_property(tok);
    double number = 0.0;
    if (parse_double(kw, number)) {
      fail_line(src_, lines_.line_number(), "missing end_header: data before the PLY header has ended");
    }
    bad(fmt::format("unknown keyword {}", quote_token(kw)));
  }

  void parse_format(const std::vector<std::string_view>& tok) {
    if (have_format_) bad("a second format line");
    if (tok.size() != 3 || !tok[2].starts_with('1')) bad("expected 'format <encoding> 1.0'");
    have_format_ = true;
    if (tok[1] == "ascii") {
      h_.encoding = Encoding::Ascii;
    } else if (tok[1] == "binary_little_endian") {
      h_.encoding = Encoding::BinaryLittle;
    } else if (tok[1] == "binary_big_endian") {
      h_.encoding = Encoding::BinaryBig;
    } else {
      bad(fmt::format("unknown format {}", quote_token(tok[1])));
    }
  }

  void parse_element(const std::vector<std::string_view>& tok) {
    std::int64_t count = 0;
    if (tok.size() != 3) bad("expected 'element <name> <count>'");
    if (!parse_int(tok[2], count) || count < 0)
      bad(fmt::format("element count {} is not a count", quote_token(tok[2])));
    for (const Element& e : h_.elements) {
      if (e.name == tok[1]) bad(fmt::format("element {} declared twice", quote_token(tok[1])));
    }
    h_.elements.push_back(Element{std::string(tok[1]), static_cast<std::uint64_t>(count), {}, Role::Other});
  }

  Scalar scalar(std::string_view name) const {
    const auto t = scalar_from_name(name);
    if (!t) bad(fmt::format("unknown property type {}", quote_token(name)));
    return *t;
  }

  void parse_property(const std::vector<std::string_view>& tok) {
    if (h_.elements.empty()) bad("property before any element");
    Property p;
    if (tok.size() == 5 && tok[1] == "list") {
      p.is_list = true;
      p.count_type = scalar(tok[2]);
      p.type = scalar(tok[3]);
      if (is_float(p.count_type)) bad(fmt::format("list length type {} is not an integer type", quote_token(tok[2])));
    } else if (tok.size() == 3) {
      p.type = scalar(tok[1]);
    } else {
      bad("expected 'property <type> <name>' or 'property list <count type> <type> <name>'");
    }
    p.name = std::string(tok.back());
    Element& e = h_.elements.back();
    for (const Property& q : e.props) {
      if (q.name == p.name) bad(fmt::format("property {} declared twice in element '{}'", quote_token(p.name), e.name));
    }
    e.props.push_back(std::move(p));
  }

  Header finish(std::size_t tokens) {
    if (tokens != 1) bad("junk after end_header");
    if (!have_format_) fail(src_, "bad PLY header: no format line");
    h_.body_offset = lines_.offset();
    h_.lines = lines_.line_number();
    for (Element& e : h_.elements) {
      if (e.name == "vertex") assign_vertex(e);
      if (e.name == "face") assign_face(e);
    }
    if (std::none_of(h_.elements.begin(), h_.elements.end(), [](const Element& e) { return e.role == Role::Vertex; })) {
      fail(src_, "bad PLY header: no vertex element");
    }
    const bool faces = std::any_of(h_.elements.begin(), h_.elements.end(), [](const Element& e) { return e.role == Role::Face && e.count > 0; });
    for (const Element& e : h_.elements)  // a mesh of triangle strips only would read as "no faces"
      if (!faces && e.count > 0 && (e.name == "tristrips" || e.name == "trianglestrips"))
        fail(src_, "the surface is stored as triangle strips (element '" + e.name +
                       "'), which gimforge does not read; write it as a 'face' element");
    return std::move(h_);
  }

  Property* find(Element& e, std::string_view name) {
    const auto it = std::find_if(e.props.begin(), e.props.end(), [&](const Property& p) { return p.name == name; });
    return it == e.props.end() || it->is_list ? nullptr : &*it;
  }

  /// Gives slots first..first+2 to the three named properties if all three exist; returns whether they do.
  bool assign_triple(Element& e, std::size_t first) {
    std::array<Property*, 3> p{};
    for (std::size_t k = 0; k < 3; ++k) p[k] = find(e, kSlotNames[first + k]);
    if (std::find(p.begin(), p.end(), nullptr) != p.end()) return false;
    for (std::size_t k = 0; k < 3; ++k) p[k]->slot = static_cast<Slot>(first + k);
    return true;
  }

  void assign_vertex(Element& e) {
    e.role = Role::Vertex;
    for (const std::string_view name : {"x", "y", "z"}) {
      if (find(e, name) == nullptr)
        fail(src_, fmt::format("bad PLY header: the vertex element has no scalar '{}'", name));
    }
    assign_triple(e, static_cast<std::size_t>(Slot::X));
    h_.normals = assign_triple(e, static_cast<std::size_t>(Slot::NX));
    h_.colors = assign_triple(e, static_cast<std::size_t>(Slot::Red));
    if (const std::string_view extra = src_.vertex_scalar; !extra.empty()) {
      Property* p = find(e, extra);
      std::string names;
      for (const Property& q : e.props) names += (names.empty() ? "" : ", ") + q.name;
      if (p == nullptr || p->slot != Slot::None)
        fail(src_, fmt::format("the vertex element has no scalar property '{}' other than positions, normals and "
                               "colours (it has {})", extra, names));
      p->slot = Slot::Extra;
      h_.extra = true;
    }
    if (e.count > UINT32_MAX)
      fail(src_, fmt::format("bad PLY header: {} vertices is more than gimforge indexes (2^32-1)", e.count));
    h_.num_vertices = e.count;
  }

  void assign_face(Element& e) {
    e.role = Role::Face;
    const auto it = std::find_if(e.props.begin(), e.props.end(), [](const Property& p) {
      return p.is_list && (p.name == "vertex_indices" || p.name == "vertex_index");
    });
    if (it == e.props.end()) fail(src_, "bad PLY header: the face element has no list 'vertex_indices'");
    if (is_float(it->type)) {
      fail(src_, fmt::format("bad PLY header: face indices have type {}, not an integer type", info_of(it->type).name));
    }
    it->face_indices = true;
    h_.num_faces = e.count;
  }

  const Source& src_;
  LineReader lines_;
  Header h_;
  bool have_format_{false};
};

// ---- Size checks before anything is allocated ----

bool has_lists(const Element& e) {
  return std::any_of(e.props.begin(), e.props.end(), [](const Property& p) { return p.is_list; });
}

/// Smallest size of one record in bytes: lists counted as empty, and in ASCII each value as one
/// character and a separator.
std::uint64_t min_record_bytes(const Element& e, bool ascii) {
  std::uint64_t size = 0;
  for (const Property& p : e.props) size += ascii ? 2 : size_of(p.is_list ? p.count_type : p.type);
  return size;
}

[[noreturn]] void fail_truncated(const Source& src, const Element& e, std::uint64_t index) {
  fail(src, fmt::format("truncated binary PLY: {} {} of {} ends past the end of the file (file is {} bytes)", e.name,
                        index, e.count, src.data.size()));
}

/// Binary: rejects element counts that cannot fit in the bytes after the header (hostile or truncated
/// files) before any memory is reserved for them. ASCII files are not checked up front: their readers
/// reserve no more than reserve_hint() and report the exact record where the file ends.
void check_counts_fit(const Source& src, const Header& h) {
  if (h.encoding == Encoding::Ascii) return;
  std::uint64_t remaining = src.data.size() - h.body_offset;
  bool exact = true;  // no list before: `remaining` is exact, not an upper bound
  for (const Element& e : h.elements) {
    const std::uint64_t record = min_record_bytes(e, false);
    if (record == 0 || e.count <= remaining / record) {
      remaining -= e.count * record;
      exact = exact && !has_lists(e);
      continue;
    }
    if (exact && !has_lists(e)) fail_truncated(src, e, remaining / record);
    const std::uint64_t body = src.data.size() - h.body_offset;
    fail(src, fmt::format("truncated binary PLY: the header declares {} {} records of at least {} bytes each, after at "
                          "least {} bytes of the elements before them, but only {} bytes follow the header (file is {} bytes)",
                          e.count, e.name, record, body - remaining, body, src.data.size()));
  }
}

/// How many records of `e` to reserve memory for: the count (binary: checked to fit), or as many as the
/// bytes after the header could hold (ASCII).
std::uint64_t reserve_hint(const Source& src, const Header& h, const Element& e) {
  if (h.encoding != Encoding::Ascii || e.props.empty()) return e.count;
  return std::min(e.count, (src.data.size() - h.body_offset) / min_record_bytes(e, true) + 1);
}

// ---- Cursors: the same decoding code reads ASCII tokens or binary bytes through them ----

/// Reads binary records; every read is bounds-checked.
class BinaryCursor {
 public:
  BinaryCursor(const Source& src, std::size_t offset, bool swap) : src_(src), pos_(offset), swap_(swap) {}

  void begin_record(const Element& e, std::uint64_t index) {
    elem_ = &e;
    index_ = index;
  }
  void end_record() const {}
  void finish() const {}
  [[nodiscard]] std::size_t line() const { return 0; }
  [[nodiscard]] std::size_t offset() const { return pos_; }

  double read_double(Scalar t) { return load_double(t, take(size_of(t)), swap_); }
  std::int64_t read_int(Scalar t) { return load_int(t, take(size_of(t)), swap_); }

  /// Checks that `n` values of type `t` follow.
  void require_items(std::uint64_t n, Scalar t) const {
    if (n > (src_.data.size() - pos_) / size_of(t)) fail_truncated(src_, *elem_, index_);
  }
  void skip(Scalar t, std::uint64_t n) {
    require_items(n, t);
    pos_ += n * size_of(t);
  }

  [[noreturn]] void fail_record(std::string_view cause) const {
    fail(src_, fmt::format("{} {}: {}", elem_->name, index_, cause));
  }

 private:
  const char* take(std::size_t n) {
    if (src_.data.size() - pos_ < n) fail_truncated(src_, *elem_, index_);
    const char* p = src_.data.data() + pos_;
    pos_ += n;
    return p;
  }

  const Source& src_;
  std::size_t pos_;
  bool swap_;
  const Element* elem_{nullptr};
  std::uint64_t index_{0};
};

/// Reads ASCII records: one record per line, values checked against their declared types.
class AsciiCursor {
 public:
  AsciiCursor(const Source& src, const Header& h) : src_(src), lines_(src.data, h.body_offset, h.lines + 1) {}

  void begin_record(const Element& e, std::uint64_t index) {
    elem_ = &e;
    index_ = index;
    next_ = 0;
    std::string_view line;
    if (!lines_.next_content(line)) {
      fail(src_, fmt::format("truncated ASCII PLY: the file ends before {} {} of {} (after line {})", e.name, index,
                             e.count, lines_.line_number()));
    }
    split_tokens(line, tokens_);
  }

  void end_record() const {
    if (next_ < tokens_.size()) {
      fail_record(fmt::format("{} more values on the line than the header declares", tokens_.size() - next_));
    }
  }

  void finish() {
    std::string_view line;
    if (lines_.next_content(line)) {
      fail_line(src_, lines_.line_number(), "unexpected data after the last element the header declares");
    }
  }

  [[nodiscard]] std::size_t line() const { return lines_.line_number(); }

  double read_double(Scalar t) {
    const std::string_view tok = take();
    if (!is_float(t)) return static_cast<double>(checked_int(tok, t));
    double v = 0.0;
    if (!parse_double(tok, v)) fail_record(fmt::format("{} is not a number (non-numeric value)", quote_token(tok)));
    return t == Scalar::Float32 ? static_cast<double>(to_float(v)) : v;
  }

  std::int64_t read_int(Scalar t) { return checked_int(take(), t); }

  void require_items(std::uint64_t n, Scalar /*t*/) const {
    if (n > tokens_.size() - next_) {
      fail_record(fmt::format("a list of {} values, but the line has only {} more", n, tokens_.size() - next_));
    }
  }

  void skip(Scalar t, std::uint64_t n) {
    require_items(n, t);
    for (std::uint64_t k = 0; k < n; ++k) (void)read_double(t);
  }

  [[noreturn]] void fail_record(std::string_view cause) const {
    fail_line(src_, line(), fmt::format("{} {}: {}", elem_->name, index_, cause));
  }

 private:
  std::string_view take() {
    if (next_ >= tokens_.size()) fail_record("too few values on the line (the header declares more)");
    return tokens_[next_++];
  }

  std::int64_t checked_int(std::string_view tok, Scalar t) const {
    std::int64_t v = 0;
    const ScalarInfo& info = info_of(t);
    if (!parse_int(tok, v)) {
      fail_record(fmt::format("{} is not an integer (non-numeric value for a PLY {})", quote_token(tok), info.name));
    }
    if (v < info.min || v > info.max) fail_record(fmt::format("value {} does not fit the PLY type {}", v, info.name));
    return v;
  }

  const Source& src_;
  LineReader lines_;
  std::vector<std::string_view> tokens_;
  std::size_t next_{0};
  const Element* elem_{nullptr};
  std::uint64_t index_{0};
};

// ---- General decoding (any layout, through a cursor) ----

template <class Cursor>
void skip_property(Cursor& c, const Property& p) {
  if (!p.is_list) {
    (void)c.read_double(p.type);
    return;
  }
  const std::int64_t n = c.read_int(p.count_type);
  if (n < 0) c.fail_record(fmt::format("list '{}' has a negative length ({})", p.name, n));
  c.skip(p.type, static_cast<std::uint64_t>(n));
}

bool is_color(Slot s) { return s == Slot::Red || s == Slot::Green || s == Slot::Blue; }

/// Integer colours are 0..255 (0..65535 for the 16-bit types); float colours are already in [0,1].
double color_scale(Scalar t) {
  if (is_float(t)) return 1.0;
  return (t == Scalar::Int16 || t == Scalar::UInt16) ? 65535.0 : 255.0;
}

void store_vertex(const Source& src, const Header& h, std::uint64_t i, const std::array<double, kSlots>& v,
                  std::size_t line, TriMesh& m) {
  const auto at = [&](Slot s) { return v[static_cast<std::size_t>(s)]; };
  const Vec3 p(at(Slot::X), at(Slot::Y), at(Slot::Z));
  check_finite(src, i, p, "coordinate", line);
  m.positions.push_back(p);
  if (h.normals) {
    const Vec3 n(at(Slot::NX), at(Slot::NY), at(Slot::NZ));  // a non-finite one drops them all (read_mesh)
    m.normals.emplace_back(to_float(n.x()), to_float(n.y()), to_float(n.z()));
  }
  if (h.colors) m.colors.push_back(unit_color(src, i, Vec3(at(Slot::Red), at(Slot::Green), at(Slot::Blue)), line));
}

template <class Cursor>
void read_vertices(const Source& src, const Header& h, const Element& e, Cursor& c, TriMesh& m, std::vector<double>& extra) {
  const std::uint64_t expected = reserve_hint(src, h, e);
  m.positions.reserve(expected);
  if (h.normals) m.normals.reserve(expected);
  if (h.colors) m.colors.reserve(expected);
  std::array<double, kSlots> v{};
  for (std::uint64_t i = 0; i < e.count; ++i) {
    c.begin_record(e, i);
    for (const Property& p : e.props) {
      if (p.slot == Slot::None) {
        skip_property(c, p);
      } else {
        v[static_cast<std::size_t>(p.slot)] = c.read_double(p.type) / (is_color(p.slot) ? color_scale(p.type) : 1.0);
      }
    }
    c.end_record();
    store_vertex(src, h, i, v, c.line(), m);
    if (!h.extra) continue;
    const double x = v[static_cast<std::size_t>(Slot::Extra)];
    if (!std::isfinite(x)) fail_line(src, c.line(), fmt::format("vertex {} has a non-finite {} ({})", i, src.vertex_scalar, x));
    extra.push_back(x);
  }
}

/// Reads face record `i` (the cursor is at its start) and hands its polygon to the builder.
template <class Cursor>
void read_face_record(const Element& e, std::uint64_t i, Cursor& c, FaceBuilder& b, std::vector<std::int64_t>& poly) {
  c.begin_record(e, i);
  for (const Property& p : e.props) {
    if (!p.face_indices) {
      skip_property(c, p);
      continue;
    }
    const std::int64_t n = c.read_int(p.count_type);
    b.check_count(n, i, c.line());
    c.require_items(static_cast<std::uint64_t>(n), p.type);
    poly.resize(static_cast<std::size_t>(n));
    for (std::int64_t& index : poly) index = c.read_int(p.type);
  }
  c.end_record();
  b.add(poly, i, c.line());
}

template <class Cursor>
void skip_record(const Element& e, std::uint64_t i, Cursor& c) {
  c.begin_record(e, i);
  for (const Property& p : e.props) skip_property(c, p);
  c.end_record();
}

template <class Cursor>
void read_body(const Source& src, const Header& h, Cursor& c, TriMesh& m, FaceBuilder& b, std::vector<double>& extra) {
  std::vector<std::int64_t> poly;
  for (const Element& e : h.elements) {
    if (e.props.empty()) continue;  // records without properties occupy no bytes and no lines
    switch (e.role) {
      case Role::Vertex:
        read_vertices(src, h, e, c, m, extra);
        break;
      case Role::Face:
        for (std::uint64_t i = 0; i < e.count; ++i) read_face_record(e, i, c, b, poly);
        break;
      case Role::Other:
        for (std::uint64_t i = 0; i < e.count; ++i) skip_record(e, i, c);
        break;
    }
  }
  c.finish();
}

// ---------------------------------------------------------------------------------------------------
// Fast path: binary in the machine's byte order, vertex = fixed-size scalars with float/double x,y,z
// (optional float normals, uchar colours), then face = one list of int/uint indices
// ---------------------------------------------------------------------------------------------------

struct FastLayout {
  std::size_t stride{0};  ///< bytes per vertex record
  std::array<std::size_t, kSlots> offset{};
  Scalar coord{Scalar::Float32};
  Scalar count{Scalar::UInt8};
  Scalar index{Scalar::Int32};
};

bool slots_have_type(const Element& e, Slot first, Scalar t) {
  return std::all_of(e.props.begin(), e.props.end(), [&](const Property& p) {
    const auto s = static_cast<std::size_t>(p.slot);
    const auto f = static_cast<std::size_t>(first);
    return s < f || s >= f + 3 || p.type == t;
  });
}

std::optional<FastLayout> fast_layout(const Header& h) {
  const Encoding native = std::endian::native == std::endian::little ? Encoding::BinaryLittle : Encoding::BinaryBig;
  if (h.encoding != native || h.elements.size() != 2) return std::nullopt;
  const Element& v = h.elements[0];
  const Element& f = h.elements[1];
  if (v.role != Role::Vertex || f.role != Role::Face || f.props.size() != 1 || has_lists(v)) return std::nullopt;
  FastLayout L;
  for (const Property& p : v.props) {
    L.offset[static_cast<std::size_t>(p.slot)] = L.stride;
    L.stride += size_of(p.type);
  }
  L.coord = v.props[0].type;
  for (const Property& p : v.props) {
    if (p.slot == Slot::X) L.coord = p.type;
  }
  const bool coords_ok = is_float(L.coord) && slots_have_type(v, Slot::X, L.coord);
  const bool attrs_ok = slots_have_type(v, Slot::NX, Scalar::Float32) && slots_have_type(v, Slot::Red, Scalar::UInt8);
  L.count = f.props[0].count_type;
  L.index = f.props[0].type;
  const bool count_ok =
      L.count == Scalar::UInt8 || L.count == Scalar::Int8 || L.count == Scalar::Int32 || L.count == Scalar::UInt32;
  const bool index_ok = L.index == Scalar::Int32 || L.index == Scalar::UInt32;
  if (!coords_ok || !attrs_ok || !count_ok || !index_ok) return std::nullopt;
  return L;
}

template <class T>
T load_native(const char* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

template <class T>
Vec3 load_vec3(const char* record, const FastLayout& L, Slot first) {
  const auto s = static_cast<std::size_t>(first);
  return Vec3(static_cast<double>(load_native<T>(record + L.offset[s])),
              static_cast<double>(load_native<T>(record + L.offset[s + 1])),
              static_cast<double>(load_native<T>(record + L.offset[s + 2])));
}

template <class T>
void fast_positions(const Source& src, const FastLayout& L, const char* base, std::uint64_t n, TriMesh& m) {
  m.positions.resize(n);
  for (std::uint64_t i = 0; i < n; ++i) {
    const Vec3 p = load_vec3<T>(base + i * L.stride, L, Slot::X);
    if (!p.allFinite()) fail_non_finite(src, "vertex", i, p, "coordinate");
    m.positions[i] = p;
  }
}

void fast_attributes(const Header& h, const FastLayout& L, const char* base, TriMesh& m) {
  const std::uint64_t n = h.num_vertices;
  if (!h.normals && !h.colors) return;
  if (h.normals) m.normals.resize(n);
  if (h.colors) m.colors.resize(n);
  for (std::uint64_t i = 0; i < n; ++i) {
    const char* r = base + i * L.stride;
    if (h.normals) {
      m.normals[i] = load_vec3<float>(r, L, Slot::NX).cast<float>();  // a non-finite one drops them all (read_mesh)
    }
    if (h.colors) m.colors[i] = (load_vec3<std::uint8_t>(r, L, Slot::Red) / 255.0).cast<float>();
  }
}

template <class Index>
bool index_ok(Index v, std::uint64_t num_vertices) {
  return static_cast<std::uint64_t>(static_cast<std::int64_t>(v)) < num_vertices;
}

/// Triangles with valid indices are copied straight out of the buffer; anything else (polygons, bad
/// counts or indices, truncation) goes through the general record reader, which triangulates or reports.
template <class Count, class Index>
void fast_faces(const Source& src, const Element& e, std::uint64_t num_vertices, std::size_t offset, FaceBuilder& b,
                std::vector<Face>& faces) {
  constexpr std::size_t kTriangle = sizeof(Count) + 3 * sizeof(Index);
  const char* const begin = src.data.data();
  const char* const end = begin + src.data.size();
  const char* p = begin + offset;
  std::vector<std::int64_t> poly;
  faces.reserve(e.count);
  for (std::uint64_t i = 0; i < e.count; ++i) {
    if (static_cast<std::size_t>(end - p) >= kTriangle && load_native<Count>(p) == 3) {
      std::array<Index, 3> t;
      std::memcpy(t.data(), p + sizeof(Count), sizeof(t));
      if (index_ok(t[0], num_vertices) && index_ok(t[1], num_vertices) && index_ok(t[2], num_vertices)) {
        faces.push_back(
            Face{static_cast<std::uint32_t>(t[0]), static_cast<std::uint32_t>(t[1]), static_cast<std::uint32_t>(t[2])});
        p += kTriangle;
        continue;
      }
    }
    BinaryCursor c(src, static_cast<std::size_t>(p - begin), false);
    read_face_record(e, i, c, b, poly);
    p = begin + c.offset();
  }
}

template <class Count>
void fast_faces_for(const Source& src, const Header& h, const FastLayout& L, std::size_t offset, FaceBuilder& b,
                    TriMesh& m) {
  const Element& e = h.elements[1];
  if (L.index == Scalar::Int32) {
    fast_faces<Count, std::int32_t>(src, e, h.num_vertices, offset, b, m.faces);
  } else {
    fast_faces<Count, std::uint32_t>(src, e, h.num_vertices, offset, b, m.faces);
  }
}

void read_fast(const Source& src, const Header& h, const FastLayout& L, TriMesh& m, FaceBuilder& b) {
  const char* base = src.data.data() + h.body_offset;
  if (L.coord == Scalar::Float32) {
    fast_positions<float>(src, L, base, h.num_vertices, m);
  } else {
    fast_positions<double>(src, L, base, h.num_vertices, m);
  }
  fast_attributes(h, L, base, m);
  const std::size_t faces_at = h.body_offset + h.num_vertices * L.stride;  // fits: checked by check_counts_fit
  switch (L.count) {
    case Scalar::Int8:
      return fast_faces_for<std::int8_t>(src, h, L, faces_at, b, m);
    case Scalar::Int32:
      return fast_faces_for<std::int32_t>(src, h, L, faces_at, b, m);
    case Scalar::UInt32:
      return fast_faces_for<std::uint32_t>(src, h, L, faces_at, b, m);
    default:
      return fast_faces_for<std::uint8_t>(src, h, L, faces_at, b, m);
  }
}

}  // namespace

std::optional<PlyFixedLayout> ply_fixed_layout(const Source& src) {
  const Header h = HeaderParser(src).parse();
  const auto L = fast_layout(h);
  if (!L) return std::nullopt;
  PlyFixedLayout out{h.num_vertices, h.num_faces, h.body_offset, L->stride, {}, L->coord == Scalar::Float64,
                     size_of(L->count), L->index == Scalar::Int32};
  for (std::size_t k = 0; k < 3; ++k) out.coord_offset[k] = L->offset[static_cast<std::size_t>(Slot::X) + k];
  return out;
}

bool looks_like_ply(std::string_view data) { return data.starts_with("ply\n") || data.starts_with("ply\r\n"); }

TriMesh read_ply(const Source& src, ReadInfo& info) {
  const Header h = HeaderParser(src).parse();
  info.encoding = encoding_name(h.encoding);
  check_counts_fit(src, h);
  TriMesh m;
  for (const Element& e : h.elements) {
    if (e.role == Role::Face) m.faces.reserve(reserve_hint(src, h, e));
  }
  FaceBuilder builder(src, m.faces, h.num_vertices);
  if (h.encoding == Encoding::Ascii) {
    AsciiCursor c(src, h);
    read_body(src, h, c, m, builder, info.vertex_scalar);
  } else if (const auto layout = fast_layout(h); layout && !h.extra) {
    read_fast(src, h, *layout, m, builder);
  } else {
    const Encoding native = std::endian::native == std::endian::little ? Encoding::BinaryLittle : Encoding::BinaryBig;
    BinaryCursor c(src, h.body_offset, h.encoding != native);
    read_body(src, h, c, m, builder, info.vertex_scalar);
  }
  info.polygons = h.num_faces;
  info.triangulated = builder.triangulated();
  for (const Element& e : h.elements)
    if (e.role == Role::Vertex)
      info.float32_coordinates = std::count_if(e.props.begin(), e.props.end(), [](const Property& p) {
        return (p.slot == Slot::X || p.slot == Slot::Y || p.slot == Slot::Z) && p.type == Scalar::Float32;
      }) == 3;
  return m;
}

}  // namespace detail

}  // namespace gimforge::io
