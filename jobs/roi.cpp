#include "jobs/roi.h"

#include <array>
#include <cmath>
#include <fstream>
#include <unordered_map>

#include <fmt/format.h>

#include "io/mesh_io.h"
#include "io/png_image.h"
#include "io/text_parse.h"
#include "kernels/core/errors.h"

namespace gimforge::jobs {
namespace {

/// Largest vertex list read (bytes): a list of every vertex of a 10^8-vertex scan fits.
constexpr std::uintmax_t kMaxVertexListBytes = std::uintmax_t{2} << 30;

std::vector<std::string_view> split(std::string_view s, char sep) {
  std::vector<std::string_view> out;
  for (std::size_t start = 0;;) {
    const std::size_t end = s.find(sep, start);
    out.push_back(s.substr(start, end == std::string_view::npos ? std::string_view::npos : end - start));
    if (end == std::string_view::npos) return out;
    start = end + 1;
  }
}

/// Exact position → vertex of `mesh` (the first of equal ones).
struct PositionKey {
  std::size_t operator()(const Vec3& p) const {
    std::size_t h = 0;
    for (int k = 0; k < 3; ++k) h = h * 1000003u ^ std::hash<double>{}(p[k]);
    return h;
  }
};

/// Flags of the loaded mesh's vertices from flags of the file's vertices `file_flags`.
std::vector<std::uint8_t> to_loaded(const LoadedMesh& m, const std::vector<std::uint8_t>& file_flags,
                                    const TriMesh* file_mesh) {
  if (m.repair.removed_unreferenced_vertices == 0) return file_flags;  // repair kept the numbering
  // Repair dropped unreferenced vertices and renumbered the rest (moving none): find them by position.
  std::unordered_map<Vec3, std::uint32_t, PositionKey> loaded;
  for (std::uint32_t v = 0; v < m.mesh.num_vertices(); ++v) loaded.emplace(m.mesh.positions[v], v);
  std::vector<std::uint8_t> out(m.mesh.num_vertices(), 0);
  for (std::size_t v = 0; v < file_flags.size(); ++v)
    if (file_flags[v])
      if (const auto it = loaded.find(file_mesh->positions[v]); it != loaded.end()) out[it->second] = 1;
  return out;
}

std::vector<std::uint8_t> read_vertex_list(const std::string& spec, const std::string& file, std::size_t vertices) {
  std::error_code ec;
  if (!std::filesystem::exists(file, ec))
    throw IoError(fmt::format("--roi {}: {}: no such file (a list of vertex indices was expected)", spec, file));
  if (!std::filesystem::is_regular_file(file, ec))
    throw IoError(fmt::format("--roi {}: {}: is not a regular file (a directory, pipe, device or socket)", spec, file));
  const std::uintmax_t bytes = std::filesystem::file_size(file, ec);
  if (ec) throw IoError(fmt::format("--roi {}: {}: {}", spec, file, ec.message()));
  if (bytes > kMaxVertexListBytes)
    throw InvalidInput(fmt::format("--roi {}: {}: larger than {} bytes", spec, file, kMaxVertexListBytes));
  std::ifstream in(file, std::ios::binary);
  if (!in) throw IoError(fmt::format("--roi {}: {}: cannot be read", spec, file));
  if (std::array<char, 3> bom{}; !in.read(bom.data(), 3) || bom != std::array<char, 3>{'\xEF', '\xBB', '\xBF'}) {
    in.clear();  // no UTF-8 byte-order mark (a Notepad file has one): read from the start
    in.seekg(0);
  }
  // Byte by byte (no line is held whole): tokens separated by white space or commas, '#' to the line's end.
  std::vector<std::uint8_t> flags(vertices, 0);
  std::size_t line = 1, selected = 0;
  std::string token;
  bool comment = false;
  const auto finish = [&] {
    if (token.empty()) return;
    std::int64_t v = 0;
    if (!io::detail::parse_int(token, v))
      throw InvalidInput(fmt::format("{}:{}: {} is not a vertex index", file, line, io::detail::quote_token(token)));
    if (v < 0 || static_cast<std::uint64_t>(v) >= vertices)
      throw InvalidInput(fmt::format("{}:{}: vertex {} is out of range (the mesh file has {} vertices, numbered from 0)",
                                     file, line, v, vertices));
    if (!flags[static_cast<std::size_t>(v)]) ++selected;
    flags[static_cast<std::size_t>(v)] = 1;
    token.clear();
  };
  std::array<char, 65536> buffer{};
  while (in.read(buffer.data(), buffer.size()) || in.gcount() > 0) {
    for (std::streamsize k = 0; k < in.gcount(); ++k) {
      const char ch = buffer[static_cast<std::size_t>(k)];
      if (ch == '\n') {
        finish();
        comment = false;
        ++line;
      } else if (comment) {
      } else if (ch == '#') {
        finish();
        comment = true;
      } else if (ch == ',' || io::detail::is_space(ch)) {
        finish();
      } else if (token.size() < 40) {
        token.push_back(ch);  // longer tokens are no index: parse_int refuses the first 40 bytes
      }
    }
  }
  finish();
  if (in.bad()) throw IoError(fmt::format("--roi {}: {}: read error", spec, file));
  if (selected == 0) throw InvalidInput(fmt::format("--roi {}: {} lists no vertex", spec, file));
  return flags;
}

}  // namespace

RoiSpec parse_roi_spec(const std::string& spec) {
  const auto fail = [&](const std::string& why) { throw InvalidInput(fmt::format("--roi {}: {}", spec, why)); };
  RoiSpec r;
  const std::size_t colon = spec.find(':');
  const std::string kind = spec.substr(0, colon);
  const std::string value = colon == std::string::npos ? std::string() : spec.substr(colon + 1);
  if (kind == "auto") {
    r.kind = RoiSpec::Kind::Auto;
    if (colon != std::string::npos && (!io::detail::parse_double(value, r.fraction) || !(r.fraction > 0.0 && r.fraction < 1.0)))
      fail("the fraction of the square after 'auto:' must be a number in (0, 1), e.g. auto:0.1");
    return r;
  }
  if (colon == std::string::npos || value.empty())
    fail("expected auto[:F], box:X0,Y0,Z0,X1,Y1,Z1, vertices:FILE, color:RRGGBB, scalar:NAME[>T] or mask:PNG");
  if (kind == "box") {
    r.kind = RoiSpec::Kind::Box;
    const std::vector<std::string_view> parts = split(value, ',');
    std::array<double, 6> c{};
    if (parts.size() != 6) fail(fmt::format("a box takes 6 numbers X0,Y0,Z0,X1,Y1,Z1 (found {})", parts.size()));
    for (std::size_t k = 0; k < 6; ++k)
      if (!io::detail::parse_double(io::detail::trim(parts[k]), c[k]) || !std::isfinite(c[k]))
        fail(fmt::format("{} is not a finite number", io::detail::quote_token(parts[k])));
    r.lo = Vec3(c[0], c[1], c[2]), r.hi = Vec3(c[3], c[4], c[5]);
    if (!(r.lo.array() <= r.hi.array()).all()) fail("the box's first corner must be its lowest (X0 <= X1, Y0 <= Y1, Z0 <= Z1)");
    return r;
  }
  if (kind == "vertices" || kind == "mask") {
    r.kind = kind == "mask" ? RoiSpec::Kind::Mask : RoiSpec::Kind::Vertices;
    r.file = value;
    return r;
  }
  if (kind == "color") {
    r.kind = RoiSpec::Kind::Color;
    const std::string hex = value.front() == '#' ? value.substr(1) : value;
    if (hex.size() != 6 || hex.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos)
      fail("a colour is six hex digits RRGGBB, e.g. color:ff0000");
    for (std::size_t k = 0; k < 3; ++k) r.color[k] = std::stoi(hex.substr(2 * k, 2), nullptr, 16);
    return r;
  }
  if (kind == "scalar") {
    r.kind = RoiSpec::Kind::Scalar;
    const std::size_t gt = value.find('>');
    r.property = value.substr(0, gt);
    if (r.property.empty() || r.property.find_first_of(" \t") != std::string::npos)
      fail("a vertex property name is expected after 'scalar:', e.g. scalar:quality>0.5");
    if (gt != std::string::npos &&
        (!io::detail::parse_double(value.substr(gt + 1), r.threshold) || !std::isfinite(r.threshold)))
      fail(fmt::format("the threshold after '>' must be a finite number ({})", io::detail::quote_token(value.substr(gt + 1))));
    return r;
  }
  fail(fmt::format("unknown kind '{}' (choose auto, box, vertices, color, scalar or mask)", kind));
  return r;
}

RoiSource resolve_roi(const MethodOptions& method, const LoadedMesh& m) {
  RoiSource roi;
  roi.enhance.gain = method.roi_gain;
  if (method.roi.empty()) return roi;
  const RoiSpec spec = parse_roi_spec(method.roi);
  const std::string& text = method.roi;
  const std::string mesh = m.path.string();
  const auto require_selected = [&](const std::vector<std::uint8_t>& flags) {
    for (std::uint8_t f : flags)
      if (f) return;
    throw InvalidInput(fmt::format("{}: --roi {} selects no vertex of the mesh", mesh, text));
  };
  switch (spec.kind) {
    case RoiSpec::Kind::Auto:
      roi.kind = RoiSource::Kind::Auto;
      roi.auto_fraction = spec.fraction;
      return roi;
    case RoiSpec::Kind::Mask: {
      const io::PngMask mask = io::read_png_mask(spec.file);
      if (mask.width < 2 || mask.height < 2)
        throw InvalidInput(fmt::format("--roi {}: a {} × {} picture; a mask needs at least 2 × 2 pixels", text,
                                       mask.width, mask.height));
      roi.kind = RoiSource::Kind::Picture;
      roi.picture_width = mask.width, roi.picture_height = mask.height;
      roi.picture = mask.inside;
      if (std::find(roi.picture.begin(), roi.picture.end(), 1) == roi.picture.end())
        throw InvalidInput(fmt::format("--roi {}: the mask has no white pixel (white, opaque pixels are the ROI)", text));
      return roi;
    }
    case RoiSpec::Kind::Box: {
      roi.kind = RoiSource::Kind::Vertices;
      roi.vertices.resize(m.mesh.num_vertices());
      for (std::size_t v = 0; v < roi.vertices.size(); ++v) {
        const Vec3& p = m.mesh.positions[v];
        roi.vertices[v] = (p.array() >= spec.lo.array()).all() && (p.array() <= spec.hi.array()).all() ? 1 : 0;
      }
      require_selected(roi.vertices);
      return roi;
    }
    case RoiSpec::Kind::Vertices:
    case RoiSpec::Kind::Color:
    case RoiSpec::Kind::Scalar: {
      roi.kind = RoiSource::Kind::Vertices;
      // The file's own vertices: the loaded mesh is the file's when repair dropped no vertex.
      std::optional<TriMesh> file;
      if (m.repair.removed_unreferenced_vertices != 0) file = io::read_mesh(m.path);
      const TriMesh& numbered = file ? *file : m.mesh;
      std::vector<std::uint8_t> flags;
      if (spec.kind == RoiSpec::Kind::Vertices) {
        flags = read_vertex_list(text, spec.file, numbered.num_vertices());
      } else if (spec.kind == RoiSpec::Kind::Scalar) {
        const std::vector<double> values = io::read_ply_vertex_scalar(m.path, spec.property);
        flags.assign(values.size(), 0);
        for (std::size_t v = 0; v < values.size(); ++v) flags[v] = values[v] > spec.threshold ? 1 : 0;
      } else {
        if (!numbered.has_colors())
          throw InvalidInput(fmt::format("{}: --roi {}: the mesh file has no vertex colours", mesh, text));
        flags.assign(numbered.num_vertices(), 0);
        for (std::size_t v = 0; v < flags.size(); ++v) {
          bool same = true;
          for (int k = 0; k < 3; ++k)
            same = same && std::lround(static_cast<double>(numbered.colors[v][k]) * 255.0) == spec.color[static_cast<std::size_t>(k)];
          flags[v] = same ? 1 : 0;
        }
      }
      roi.vertices = to_loaded(m, flags, &numbered);
      require_selected(roi.vertices);
      return roi;
    }
  }
  return roi;
}

RoiSource roi_for_proxy(const EmbreeDevice& device, const RoiSource& roi, const TriMesh& local, const TriMesh& proxy) {
  if (roi.kind != RoiSource::Kind::Vertices) return roi;
  RoiSource out = roi;
  out.vertices.assign(proxy.num_vertices(), 0);
  // The corner of a face closest to p (largest barycentric weight of the closest point).
  const auto corner_of = [](const TriMesh& mesh, const ClosestPoint& cp) {
    const Face& f = mesh.faces[cp.face];
    int corner = 0;
    for (int k = 1; k < 3; ++k)
      if (cp.barycentric[k] > cp.barycentric[corner]) corner = k;
    return f[static_cast<std::size_t>(corner)];
  };
  // Each proxy vertex takes the flag of the input's corner nearest to it ...
  const TriangleBvh on_input(device, local);
  for (std::size_t v = 0; v < proxy.num_vertices(); ++v)
    if (const ClosestPoint cp = on_input.closest_point(proxy.positions[v]); cp.found())
      out.vertices[v] = roi.vertices[corner_of(local, cp)];
  // ... and each flagged input vertex flags the proxy's corner nearest to it: a ROI smaller than the
  // proxy's faces does not vanish.
  const TriangleBvh on_proxy(device, proxy);
  for (std::size_t v = 0; v < local.num_vertices(); ++v)
    if (roi.vertices[v])
      if (const ClosestPoint cp = on_proxy.closest_point(local.positions[v]); cp.found()) out.vertices[corner_of(proxy, cp)] = 1;
  return out;
}

}  // namespace gimforge::jobs
