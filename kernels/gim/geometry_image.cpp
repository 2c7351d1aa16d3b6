#include "kernels/gim/geometry_image.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <unordered_set>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "kernels/core/edge_topology.h"
#include "kernels/core/errors.h"

namespace gimforge {
namespace {

/// Pixel index of perimeter grid index g (counter-clockwise from (0,0)) in an n×n image.
std::uint32_t perimeter_pixel(std::uint32_t g, std::uint32_t n) {
  const std::uint32_t side = g / (n - 1);
  const std::uint32_t s = g % (n - 1);
  switch (side) {
    case 0: return s;                            // bottom row, left to right
    case 1: return s * n + (n - 1);              // right column, bottom to top
    case 2: return (n - 1) * n + (n - 1 - s);    // top row, right to left
    default: return (n - 1 - s) * n;             // left column, top to bottom
  }
}

std::uint32_t grid_scale(const Sideband& sideband, std::uint32_t n) {
  if (sideband.units_per_side == 0 || sideband.units_per_side > Sideband::kMaxUnitsPerSide)
    throw InvalidInput(fmt::format("sideband: units_per_side {} is outside [1, 2^20]", sideband.units_per_side));
  if (n < 2 || (n - 1) % sideband.units_per_side != 0)
    throw InvalidInput(fmt::format("image size {}: n - 1 must be a positive multiple of {} (the cut-nodes lie on "
                                   "the grid of the {}x{} level)",
                                   n, sideband.units_per_side, sideband.units_per_side + 1,
                                   sideband.units_per_side + 1));
  return (n - 1) / sideband.units_per_side;
}

/// Area-weighted normals per disk vertex, accumulated over all copies of the same original vertex.
std::vector<Vec3> disk_normals(const SquareBoundary& b) {
  const auto& m = b.disk;
  std::uint32_t originals = 0;
  for (std::uint32_t o : b.original_vertex)
    if (o != kInvalidIndex) originals = std::max(originals, o + 1);
  auto key = [&](std::uint32_t v) { return b.original_vertex[v] != kInvalidIndex ? b.original_vertex[v] : originals + v; };
  std::vector<Vec3> acc(originals + m.positions.size(), Vec3::Zero());
  for (const Face& f : m.faces) {
    const Vec3 n = (m.positions[f[1]] - m.positions[f[0]]).cross(m.positions[f[2]] - m.positions[f[0]]);
    for (std::uint32_t v : f) acc[key(v)] += n;
  }
  std::vector<Vec3> normals(m.positions.size());
  for (std::uint32_t v = 0; v < normals.size(); ++v) {
    const Vec3& n = acc[key(v)];
    normals[v] = n.norm() > 0.0 ? Vec3(n.normalized()) : Vec3(0, 0, 1);
  }
  return normals;
}

/// Where a parameter point lies in the flat parameter mesh: face and barycentric coordinates.
struct ParamLocation {
  std::uint32_t face;
  Vec3 bary;
};

template <class Value>
Value interpolate(const TriMesh& disk, const std::vector<Value>& values, const ParamLocation& at) {
  const Face& f = disk.faces[at.face];
  return at.bary.x() * values[f[0]] + at.bary.y() * values[f[1]] + at.bary.z() * values[f[2]];
}

/// Locates every grid point of an m×m grid in the parameter domain (parallel): the uniform grid, or the
/// points `at` (m·m, row-major) when given.
std::vector<ParamLocation> locate_grid(const TriangleBvh& flat, std::uint32_t m, std::span<const Vec2> at = {}) {
  std::vector<ParamLocation> out(static_cast<std::size_t>(m) * m);
  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, m), [&](const tbb::blocked_range<std::uint32_t>& rows) {
    for (std::uint32_t j = rows.begin(); j < rows.end(); ++j) {
      for (std::uint32_t i = 0; i < m; ++i) {
        const std::size_t k = static_cast<std::size_t>(j) * m + i;
        const Vec3 p = at.empty() ? Vec3(static_cast<double>(i) / (m - 1), static_cast<double>(j) / (m - 1), 0.0)
                                  : Vec3(at[k].x(), at[k].y(), 0.0);
        const ClosestPoint cp = flat.closest_point(p);
        out[static_cast<std::size_t>(j) * m + i] = {cp.face, cp.barycentric};
      }
    }
  });
  return out;
}

/// Evaluates the boundary polyline at perimeter coordinate c (grid units of the coarsest level).
class BoundaryCurve {
 public:
  explicit BoundaryCurve(const SquareBoundary& b) : b_(b), total_(4.0 * b.units_per_side) {
    const std::size_t n = b.perimeter.size();
    start_ = static_cast<std::size_t>(std::min_element(b.perimeter.begin(), b.perimeter.end()) - b.perimeter.begin());
    for (std::size_t k = 0; k <= n; ++k) {
      const std::size_t i = (start_ + k) % n;
      coords_.push_back(k == n ? b.perimeter[i] + total_ : b.perimeter[i]);
      vertices_.push_back(b.boundary[i]);
    }
  }
  [[nodiscard]] Vec3 position(double c) const {
    c = std::fmod(c - coords_.front(), total_);
    if (c < 0.0) c += total_;
    c += coords_.front();
    auto it = std::upper_bound(coords_.begin(), coords_.end(), c);
    std::size_t k = it == coords_.begin() ? 0 : static_cast<std::size_t>(it - coords_.begin()) - 1;
    k = std::min(k, coords_.size() - 2);
    const double span = coords_[k + 1] - coords_[k];
    const double t = span > 0.0 ? std::clamp((c - coords_[k]) / span, 0.0, 1.0) : 0.0;
    return (1.0 - t) * b_.disk.positions[vertices_[k]] + t * b_.disk.positions[vertices_[k + 1]];
  }

 private:
  const SquareBoundary& b_;
  double total_;
  std::size_t start_{0};
  std::vector<double> coords_;
  std::vector<std::uint32_t> vertices_;
};

/// Perimeter grid index (at scale `scale` per unit) whose value a boundary grid point g takes: g itself on
/// canonical paths, the mirrored point of the partner on a mate (label < 0).
std::uint32_t canonical_perimeter_index(const Sideband& sb, std::uint32_t g, std::uint32_t scale) {
  const std::uint32_t total = 4 * sb.units_per_side * scale;
  for (const Sideband::Path& p : sb.paths) {
    const std::uint32_t a = p.start_unit * scale;
    const std::uint32_t offset = (g + total - a % total) % total;
    if (offset >= p.units * scale || p.label >= 0) continue;
    for (const Sideband::Path& q : sb.paths) {
      if (q.label != -p.label) continue;
      return (q.start_unit * scale + q.units * scale - offset) % total;
    }
  }
  return g;
}

}  // namespace

Sideband Sideband::from_boundary(const SquareBoundary& boundary) {
  Sideband sb;
  sb.units_per_side = boundary.units_per_side;
  std::int32_t next_label = 1;
  std::vector<std::int32_t> label(boundary.paths.size(), 0);
  for (std::size_t i = 0; i < boundary.paths.size(); ++i) {
    const std::int32_t mate = boundary.paths[i].mate;
    if (mate > static_cast<std::int32_t>(i)) {
      label[i] = next_label;
      label[static_cast<std::size_t>(mate)] = -next_label;
      ++next_label;
    }
  }
  // The square boundary lays paths out from a rotation, unwrapped: a last path may start at or past the
  // perimeter's end. The sideband stores perimeter positions, in [0, 4·units_per_side).
  const std::uint32_t total = 4 * boundary.units_per_side;
  for (std::size_t i = 0; i < boundary.paths.size(); ++i)
    sb.paths.push_back({label[i], total == 0 ? boundary.paths[i].start_unit : boundary.paths[i].start_unit % total,
                        boundary.paths[i].units});
  sb.check();
  return sb;
}

void Sideband::check() const {
  // Sidebands are read from archives, which come from other people: every number is range-checked before
  // it is used in arithmetic (a zero units_per_side divided by zero here once), sums are 64-bit, and the
  // mate search is one pass over a map rather than quadratic in the number of paths.
  if (units_per_side == 0 || units_per_side > kMaxUnitsPerSide)
    throw InvalidInput(fmt::format("sideband: units_per_side {} is outside [1, 2^20]", units_per_side));
  const std::uint64_t total = 4 * std::uint64_t{units_per_side};
  if (paths.size() > total)
    throw InvalidInput(fmt::format("sideband: {} paths cannot tile a perimeter of {} units", paths.size(), total));
  std::uint64_t sum = 0;
  struct Seen {
    std::size_t count = 0;
    std::uint32_t units = 0;
  };
  std::map<std::int32_t, Seen> labels;
  for (std::size_t i = 0; i < paths.size(); ++i) {
    const Path& p = paths[i];
    if (p.units == 0) throw InvalidInput(fmt::format("sideband: path {} has zero length", i));
    if (p.units > total || p.start_unit >= total)
      throw InvalidInput(fmt::format("sideband: path {} (start {}, {} units) leaves the perimeter of {} units", i,
                                     p.start_unit, p.units, total));
    if (p.label == std::numeric_limits<std::int32_t>::min())
      throw InvalidInput(fmt::format("sideband: path {} has label {}, which has no mate", i, p.label));
    if (i > 0 && p.start_unit != (std::uint64_t{paths[i - 1].start_unit} + paths[i - 1].units) % total)
      throw InvalidInput(fmt::format("sideband: path {} does not start where path {} ends", i, i - 1));
    sum += p.units;
    Seen& seen = labels[p.label];
    ++seen.count;
    seen.units = p.units;
  }
  for (const auto& [label, seen] : labels) {
    if (label == 0) continue;
    const auto mate = labels.find(-label);
    if (seen.count != 1 || mate == labels.end() || mate->second.count != 1)
      throw InvalidInput(fmt::format("sideband: label {} has no unique mate", label));
    if (mate->second.units != seen.units)
      throw InvalidInput(fmt::format("sideband: mates labelled ±{} differ in length", label > 0 ? label : -label));
  }
  if (sum != total) throw InvalidInput(fmt::format("sideband: paths cover {} of {} perimeter units", sum, total));
}

bool is_cut_node(const Sideband& sideband, double c) {
  const double at = c * sideband.units_per_side;
  const double unit = std::round(at);
  if (!(std::abs(at - unit) <= 1e-9)) return false;  // NaN included
  const auto total = 4 * static_cast<std::int64_t>(sideband.units_per_side);
  const auto u = ((static_cast<std::int64_t>(unit) % total) + total) % total;
  return std::any_of(sideband.paths.begin(), sideband.paths.end(),
                     [&](const Sideband::Path& p) { return static_cast<std::int64_t>(p.start_unit) == u; });
}

std::function<Vec3(double)> boundary_curve(const SquareBoundary& boundary) {
  auto keep = std::make_shared<SquareBoundary>(boundary);
  auto curve = std::make_shared<BoundaryCurve>(*keep);
  const double units = boundary.units_per_side;
  return [keep, curve, units](double c) { return curve->position(c * units); };
}

double glued_perimeter_coordinate(const Sideband& sideband, double c) {
  const double units = sideband.units_per_side;
  const double total = 4.0 * units;
  double at = std::fmod(c * units, total);
  if (at < 0.0) at += total;
  for (const Sideband::Path& p : sideband.paths) {
    double offset = std::fmod(at - p.start_unit, total);
    if (offset < 0.0) offset += total;
    if (offset > p.units) continue;
    if (p.label == 0) return std::numeric_limits<double>::quiet_NaN();
    for (const Sideband::Path& q : sideband.paths) {
      if (q.label != -p.label) continue;
      double m = std::fmod(q.start_unit + q.units - offset, total);
      if (m < 0.0) m += total;
      return m / units;
    }
  }
  return std::numeric_limits<double>::quiet_NaN();
}

std::vector<std::uint32_t> boundary_classes(const Sideband& sideband, std::uint32_t n) {
  const std::uint32_t scale = grid_scale(sideband, n);
  const std::uint32_t total = 4 * (n - 1);
  UnionFind sets(static_cast<std::size_t>(n) * n);
  std::map<std::int32_t, const Sideband::Path*> mates;  // label -k -> its path (one pass, not quadratic)
  for (const Sideband::Path& q : sideband.paths)
    if (q.label < 0) mates.emplace(q.label, &q);
  for (const Sideband::Path& p : sideband.paths) {
    if (p.label <= 0) continue;
    const auto it = mates.find(-p.label);
    if (it == mates.end()) continue;
    const Sideband::Path& q = *it->second;
    for (std::uint32_t t = 0; t <= p.units * scale; ++t) {
      const std::uint32_t g1 = (p.start_unit * scale + t) % total;
      const std::uint32_t g2 = (q.start_unit * scale + q.units * scale - t) % total;
      sets.unite(perimeter_pixel(g1, n), perimeter_pixel(g2, n));
    }
  }
  std::vector<std::uint32_t> smallest(static_cast<std::size_t>(n) * n, kInvalidIndex);
  for (std::uint32_t v = 0; v < smallest.size(); ++v) {
    std::uint32_t& s = smallest[sets.find(v)];
    s = std::min(s, v);
  }
  std::vector<std::uint32_t> rep(smallest.size());
  for (std::uint32_t v = 0; v < rep.size(); ++v) rep[v] = smallest[sets.find(v)];
  return rep;
}

GeometryImage sample_geometry_image(const EmbreeDevice& device, const SquareBoundary& boundary,
                                    std::span<const Vec2> uv, const GeometryImageOptions& options) {
  const TriMesh& disk = boundary.disk;
  if (uv.size() != disk.positions.size())
    throw InvalidInput(fmt::format("sample_geometry_image: {} parameter points for {} vertices", uv.size(),
                                   disk.positions.size()));
  GeometryImage gi;
  gi.sideband = Sideband::from_boundary(boundary);
  const std::uint32_t n = options.size;
  const std::uint32_t scale = grid_scale(gi.sideband, n);
  gi.size = n;

  // The flat parameter mesh (z = 0) locates grid points.
  std::vector<Vec3> flat_positions(uv.size());
  for (std::size_t v = 0; v < uv.size(); ++v) flat_positions[v] = Vec3(uv[v].x(), uv[v].y(), 0.0);
  const TriangleBvh flat(device, MeshView(flat_positions, disk.faces));

  if (!options.sample_uv.empty() && options.sample_uv.size() != static_cast<std::size_t>(n) * n)
    throw InvalidInput(fmt::format("sample_geometry_image: {} sample points for a {}x{} image", options.sample_uv.size(), n, n));
  for (const Vec2& p : options.sample_uv)
    if (!(p.x() >= 0.0 && p.x() <= 1.0 && p.y() >= 0.0 && p.y() <= 1.0))
      throw InvalidInput(fmt::format("sample_geometry_image: sample point ({}, {}) is outside the unit square", p.x(), p.y()));
  const std::vector<ParamLocation> at = locate_grid(flat, n, options.sample_uv);
  for (const Vec2& p : options.sample_uv) {
    gi.sample_uv.push_back(static_cast<float>(p.x()));
    gi.sample_uv.push_back(static_cast<float>(p.y()));
  }
  gi.positions.resize(static_cast<std::size_t>(n) * n * 3);
  auto store = [](std::vector<float>& img, std::size_t pixel, const Vec3& v) {
    for (int c = 0; c < 3; ++c) img[3 * pixel + static_cast<std::size_t>(c)] = static_cast<float>(v[c]);
  };
  for (std::size_t p = 0; p < at.size(); ++p) store(gi.positions, p, interpolate(disk, disk.positions, at[p]));

  // Boundary grid points: along the boundary polyline (at their perimeter coordinate, uniform or
  // adaptive); mates copy their partner's value.
  const BoundaryCurve curve(boundary);
  const auto coordinate = [&](std::uint32_t g) {
    if (options.sample_uv.empty()) return static_cast<double>(g) / scale;
    const Vec2& p = options.sample_uv[perimeter_pixel(g, n)];
    const std::uint32_t side = g / (n - 1);
    const double along = side == 0 ? p.x() : side == 1 ? p.y() : side == 2 ? 1.0 - p.x() : 1.0 - p.y();
    return (side + std::clamp(along, 0.0, 1.0)) * gi.sideband.units_per_side;
  };
  for (std::uint32_t g = 0; g < 4 * (n - 1); ++g) {
    const std::uint32_t source = canonical_perimeter_index(gi.sideband, g, scale);
    store(gi.positions, perimeter_pixel(g, n), curve.position(coordinate(source)));
  }

  if (disk.has_colors()) {
    std::vector<Vec3> colors(disk.colors.size());
    for (std::size_t v = 0; v < colors.size(); ++v) colors[v] = disk.colors[v].cast<double>();
    gi.color_size = n;
    gi.colors.resize(gi.positions.size());
    for (std::size_t p = 0; p < at.size(); ++p) store(gi.colors, p, interpolate(disk, colors, at[p]));
  }
  if (options.normal_size > 1) {
    const std::vector<Vec3> normals = disk_normals(boundary);
    const std::uint32_t m = options.normal_size;
    const std::vector<ParamLocation> nat = locate_grid(flat, m);
    gi.normal_size = m;
    gi.normals.resize(static_cast<std::size_t>(m) * m * 3);
    for (std::size_t p = 0; p < nat.size(); ++p) {
      const Vec3 nv = interpolate(disk, normals, nat[p]);
      store(gi.normals, p, nv.norm() > 0.0 ? Vec3(nv.normalized()) : Vec3(0, 0, 1));
    }
  }
  return gi;
}

std::vector<std::uint32_t> lod_sizes(std::uint32_t n, std::uint32_t units_per_side) {
  std::vector<std::uint32_t> sizes;
  for (std::uint32_t m = n; m >= units_per_side + 1 && (m - 1) % units_per_side == 0; m = (m - 1) / 2 + 1) {
    sizes.push_back(m);
    if ((m - 1) % 2 != 0 || m == units_per_side + 1) break;
  }
  return sizes;
}

TriMesh reconstruct_geometry_image(std::span<const float> positions, std::uint32_t n, const Sideband* sideband,
                                   std::uint32_t level) {
  if (n < 2 || positions.size() != static_cast<std::size_t>(n) * n * 3)
    throw InvalidInput(fmt::format("reconstruct: {} values do not form a {}x{}x3 image", positions.size(), n, n));
  if (level > 30 || (n - 1) % (1u << level) != 0 || (n - 1) / (1u << level) < 1)
    throw InvalidInput(fmt::format("reconstruct: level {} does not divide a {}x{} image", level, n, n));
  const std::uint32_t step = 1u << level;
  const std::uint32_t m = (n - 1) / step + 1;
  auto source = [&](std::uint32_t i, std::uint32_t j) { return (static_cast<std::size_t>(j) * step * n + i * step) * 3; };
  std::vector<std::uint32_t> rep(static_cast<std::size_t>(m) * m);
  if (sideband)
    rep = boundary_classes(*sideband, m);
  else
    for (std::uint32_t v = 0; v < rep.size(); ++v) rep[v] = v;

  // Vertices: one per class, at the average of its members.
  TriMesh mesh;
  std::vector<std::uint32_t> vertex_of(rep.size(), kInvalidIndex);
  std::vector<std::uint32_t> members;
  for (std::uint32_t p = 0; p < rep.size(); ++p) {
    if (vertex_of[rep[p]] == kInvalidIndex) {
      vertex_of[rep[p]] = static_cast<std::uint32_t>(mesh.positions.size());
      mesh.positions.emplace_back(Vec3::Zero());
      members.push_back(0);
    }
    const std::size_t s = source(p % m, p / m);
    mesh.positions[vertex_of[rep[p]]] += Vec3(positions[s], positions[s + 1], positions[s + 2]);
    ++members[vertex_of[rep[p]]];
  }
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) mesh.positions[v] /= members[v];
  auto id = [&](std::uint32_t i, std::uint32_t j) { return vertex_of[rep[static_cast<std::size_t>(j) * m + i]]; };
  // Fused boundaries fold around the tip of a cut (a valence-1 cut-node): the two quads beside the tip
  // share three vertices, and if both took the diagonal through the same pair they would emit one
  // triangle twice, facing opposite ways. A quad whose shorter diagonal would repeat an existing triangle
  // takes the other diagonal.
  std::unordered_set<std::uint64_t> emitted;
  auto key = [](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    std::array<std::uint64_t, 3> v{a, b, c};
    std::sort(v.begin(), v.end());
    return (v[0] * 0x9e3779b97f4a7c15ull) ^ (v[1] * 0xc2b2ae3d27d4eb4full) ^ (v[2] * 0x165667b19e3779f9ull);
  };
  auto degenerate = [](std::uint32_t a, std::uint32_t b, std::uint32_t c) { return a == b || b == c || a == c; };
  auto repeats = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    return !degenerate(a, b, c) && emitted.count(key(a, b, c)) > 0;
  };
  auto add = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    if (degenerate(a, b, c)) return;
    mesh.faces.push_back({a, b, c});
    emitted.insert(key(a, b, c));
  };
  for (std::uint32_t j = 0; j + 1 < m; ++j) {
    for (std::uint32_t i = 0; i + 1 < m; ++i) {
      const std::uint32_t a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
      bool use_ac =
          (mesh.positions[a] - mesh.positions[c]).squaredNorm() <= (mesh.positions[b] - mesh.positions[d]).squaredNorm();
      if (use_ac ? repeats(a, b, c) || repeats(a, c, d) : repeats(a, b, d) || repeats(b, c, d)) use_ac = !use_ac;
      if (use_ac) {
        add(a, b, c);
        add(a, c, d);
      } else {
        add(a, b, d);
        add(b, c, d);
      }
    }
  }
  return mesh;
}

}  // namespace gimforge
