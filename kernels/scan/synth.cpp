#include "kernels/scan/synth.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <tuple>
#include <unordered_map>

#include <fmt/format.h>

#include "kernels/core/errors.h"
#include "kernels/core/hash.h"

namespace gimforge {
namespace {

constexpr std::uint64_t kMaxIndexCount = std::numeric_limits<std::uint32_t>::max();  // Face holds uint32
constexpr std::uint32_t kMaxHoles = 10000;

/// A uniform number in [0, 1) from the hash of (seed, a, b).
double uniform(std::uint64_t seed, std::uint64_t a, std::uint64_t b = 0) {
  const std::uint64_t h = splitmix64(splitmix64(splitmix64(seed) ^ a) ^ (b * std::uint64_t{0xd1b54a32d192ed03}));
  return static_cast<double>(h >> 11) * 0x1p-53;
}

/// Six plane waves from `seed`: unit directions (in the xy plane when `planar`), wave numbers for wavelengths
/// in [shortest, 2·shortest], phases.
void make_waves(std::uint64_t seed, double shortest, bool planar, std::array<Vec3, 6>& dir, std::array<double, 6>& k,
                std::array<double, 6>& phase) {
  for (std::size_t i = 0; i < dir.size(); ++i) {
    Vec3 d = Vec3::Zero();
    for (std::uint64_t attempt = 0; !(d.norm() > 0.1); ++attempt) {
      d = Vec3(2.0 * uniform(seed, 10 * i, attempt) - 1.0, 2.0 * uniform(seed, 10 * i + 1, attempt) - 1.0,
               planar ? 0.0 : 2.0 * uniform(seed, 10 * i + 2, attempt) - 1.0);
      if (d.norm() > 1.0) d = Vec3::Zero();  // uniform directions: rejection from the cube
    }
    dir[i] = d.normalized();
    k[i] = 2.0 * std::numbers::pi / (shortest * (1.0 + uniform(seed, 10 * i + 3)));
    phase[i] = 2.0 * std::numbers::pi * uniform(seed, 10 * i + 4);
  }
}

double waves(const Vec3& p, const std::array<Vec3, 6>& dir, const std::array<double, 6>& k, const std::array<double, 6>& phase) {
  double sum = 0.0;
  for (std::size_t i = 0; i < dir.size(); ++i) sum += std::sin(k[i] * dir[i].dot(p) + phase[i]);
  return sum / std::sqrt(static_cast<double>(dir.size()));
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------
// SubdividedScan

SubdividedScan::SubdividedScan(const TriMesh& base, const SubdivideOptions& options) : options_(options), n_(options.segments) {
  if (n_ == 0) throw InvalidInput("synthetic scan: segments must be at least 1");
  if (base.faces.empty()) throw InvalidInput("synthetic scan: the base mesh has no faces");
  if (!(options.amplitude >= 0.0 && options.amplitude <= 1.0))
    throw InvalidInput(fmt::format("synthetic scan: amplitude {} is not in [0, 1] (a fraction of the bounding-box diagonal)",
                                   options.amplitude));
  if (!(options.wavelength >= 1e-9 && options.wavelength <= 1e3))
    throw InvalidInput(fmt::format("synthetic scan: wavelength {} is not in [1e-9, 1000] (a fraction of the bounding-box "
                                   "diagonal)", options.wavelength));
  if (!options.offset.allFinite()) throw InvalidInput("synthetic scan: the offset is not finite");
  positions_ = base.positions;
  faces_ = base.faces;
  const std::size_t nv = positions_.size();
  for (std::size_t f = 0; f < faces_.size(); ++f) {
    const Face& t = faces_[f];
    if (t[0] >= nv || t[1] >= nv || t[2] >= nv)
      throw InvalidInput(fmt::format("synthetic scan: base face {} has a vertex index out of range ({} vertices)", f, nv));
    if (has_repeated_index(t)) throw InvalidInput(fmt::format("synthetic scan: base face {} repeats a vertex", f));
  }
  for (const Vec3& p : positions_)
    if (!p.allFinite()) throw InvalidInput("synthetic scan: the base mesh has a non-finite vertex position");
  // Edges in the order of their first face; normals area-weighted.
  std::unordered_map<std::uint64_t, std::uint32_t> edge_id;
  edge_id.reserve(faces_.size() * 2);
  face_edges_.resize(faces_.size());
  normals_.assign(nv, Vec3::Zero());
  BoundingBox box;
  for (const Vec3& p : positions_) box.extend(p);
  for (std::size_t f = 0; f < faces_.size(); ++f) {
    const Face& t = faces_[f];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = t[static_cast<std::size_t>(k)], b = t[static_cast<std::size_t>((k + 1) % 3)];
      const std::uint32_t lo = std::min(a, b), hi = std::max(a, b);
      const auto [it, added] = edge_id.try_emplace((std::uint64_t{lo} << 32) | hi, static_cast<std::uint32_t>(edges_.size()));
      if (added) edges_.push_back({lo, hi});
      face_edges_[f][static_cast<std::size_t>(k)] = it->second;
    }
    const Vec3 area_normal = (positions_[t[1]] - positions_[t[0]]).cross(positions_[t[2]] - positions_[t[0]]);
    for (const std::uint32_t v : t) normals_[v] += area_normal;
  }
  for (Vec3& nrm : normals_) nrm = nrm.norm() > 0.0 ? Vec3(nrm.normalized()) : Vec3::Zero();
  const std::uint64_t n = n_;
  num_vertices_ = nv + edges_.size() * (n - 1) + faces_.size() * interior_per_face();
  if (num_vertices_ > kMaxIndexCount || num_faces() > kMaxIndexCount)
    throw InvalidInput(fmt::format("synthetic scan: {} vertices and {} faces exceed the 32-bit indices of a mesh "
                                   "(use fewer segments)", num_vertices_, num_faces()));
  const double diag = box.diagonal();
  if (!std::isfinite(diag)) throw InvalidInput("synthetic scan: the base mesh's bounding box is too large");
  amplitude_ = options.amplitude * diag;
  make_waves(options.seed, std::max(options.wavelength * diag, std::numeric_limits<double>::min()), false, wave_dir_,
             wave_number_, wave_phase_);
  // The waves are relative to the base box's centre: the scan of a translated base is the translated scan.
  for (Vec3& p : positions_) p -= box.center();
  options_.offset += box.center();
}

Vec3 SubdividedScan::displaced(const Vec3& p, const Vec3& normal) const {
  const double len = normal.norm();
  const Vec3 q = amplitude_ > 0.0 && len > 0.0 ? Vec3(p + amplitude_ * waves(p, wave_dir_, wave_number_, wave_phase_) / len * normal) : p;
  return q + options_.offset;
}

std::uint32_t SubdividedScan::vertex_index(std::size_t f, std::uint32_t i, std::uint32_t j) const {
  const Face& t = faces_[f];
  const std::uint32_t k = n_ - i - j;
  if (j == 0 && i == 0) return t[0];
  if (j == 0 && k == 0) return t[1];
  if (i == 0 && k == 0) return t[2];
  const auto on_edge = [&](std::uint32_t e, std::uint32_t from, std::uint32_t d) {
    const std::uint32_t along = edges_[e][0] == from ? d : n_ - d;  // measured from the lower index
    return static_cast<std::uint32_t>(positions_.size() + std::uint64_t{e} * (n_ - 1) + (along - 1));
  };
  if (j == 0) return on_edge(face_edges_[f][0], t[0], i);
  if (k == 0) return on_edge(face_edges_[f][1], t[1], j);
  if (i == 0) return on_edge(face_edges_[f][2], t[2], n_ - j);
  // Interior rows j = 1 … n − 2 hold i = 1 … n − 1 − j.
  const std::uint64_t n = n_;
  const std::uint64_t row_start = (j - 1) * (n - 1) - (std::uint64_t{j} - 1) * j / 2;
  return static_cast<std::uint32_t>(positions_.size() + edges_.size() * (n - 1) + f * interior_per_face() + row_start + (i - 1));
}

void SubdividedScan::vertices(std::uint64_t first, std::uint64_t count, std::vector<Vec3>& out) const {
  const std::uint64_t end = std::min(first + count, num_vertices_);
  const std::uint64_t n = n_;
  const std::uint64_t nv = positions_.size(), on_edges = nv + edges_.size() * (n - 1);
  out.reserve(out.size() + (end > first ? end - first : 0));
  std::uint64_t v = first;
  for (; v < end && v < nv; ++v) out.push_back(displaced(positions_[v], normals_[v]));
  for (; v < end && v < on_edges; ++v) {
    const std::uint64_t e = (v - nv) / (n - 1);
    const double t = static_cast<double>((v - nv) % (n - 1) + 1) / static_cast<double>(n);
    const auto [a, b] = edges_[e];
    out.push_back(displaced((1.0 - t) * positions_[a] + t * positions_[b], (1.0 - t) * normals_[a] + t * normals_[b]));
  }
  const std::uint64_t per_face = interior_per_face();
  if (v >= end || per_face == 0) return;
  std::uint64_t f = (v - on_edges) / per_face;
  std::uint64_t local = (v - on_edges) % per_face;
  std::uint64_t j = 1;
  while (local >= n - 1 - j) local -= n - 1 - j++;
  std::uint64_t i = local + 1;
  const double inv = 1.0 / static_cast<double>(n);
  for (; v < end; ++v) {
    const Face& tri = faces_[f];
    const double wb = static_cast<double>(i) * inv, wc = static_cast<double>(j) * inv, wa = static_cast<double>(n - i - j) * inv;
    out.push_back(displaced(wa * positions_[tri[0]] + wb * positions_[tri[1]] + wc * positions_[tri[2]],
                            wa * normals_[tri[0]] + wb * normals_[tri[1]] + wc * normals_[tri[2]]));
    if (++i > n - 1 - j) {  // next row, next face
      i = 1;
      if (++j > n - 2) {
        j = 1;
        ++f;
      }
    }
  }
}

void SubdividedScan::faces_of(std::size_t f, std::vector<Face>& out) const {
  for (std::uint32_t j = 0; j < n_; ++j)
    for (std::uint32_t i = 0; i + j < n_; ++i) {
      out.push_back({vertex_index(f, i, j), vertex_index(f, i + 1, j), vertex_index(f, i, j + 1)});
      if (i + j + 1 < n_) out.push_back({vertex_index(f, i + 1, j), vertex_index(f, i + 1, j + 1), vertex_index(f, i, j + 1)});
    }
}

// ---------------------------------------------------------------------------------------------------------
// TerrainScan

namespace {

/// The grid corners of triangle `half` (0: lower right, 1: upper left) of quad (x, y), counter-clockwise.
std::array<std::array<std::uint32_t, 2>, 3> quad_triangle(std::uint32_t x, std::uint32_t y, int half) {
  if (half == 0) return {{{x, y}, {x + 1, y}, {x + 1, y + 1}}};
  return {{{x, y}, {x + 1, y + 1}, {x, y + 1}}};
}

}  // namespace

TerrainScan::TerrainScan(const TerrainOptions& options) : options_(options) {
  const auto& o = options;
  if (o.nx == 0 || o.ny == 0) throw InvalidInput("synthetic terrain: the grid needs at least 1 × 1 quads");
  if (!(o.spacing >= 1e-9 && o.spacing <= 1e9))
    throw InvalidInput(fmt::format("synthetic terrain: spacing {} is not in [1e-9, 1e9]", o.spacing));
  for (const auto& [value, name, most] : {std::tuple{o.relief, "relief", 10.0}, std::tuple{o.noise, "noise", 100.0},
                                          std::tuple{o.hole_radius, "hole radius", 0.5}})
    if (!(value >= 0.0 && value <= most))
      throw InvalidInput(fmt::format("synthetic terrain: {} {} is not in [0, {}]", name, value, most));
  if (o.holes > kMaxHoles) throw InvalidInput(fmt::format("synthetic terrain: {} holes is more than {}", o.holes, kMaxHoles));
  if (!o.offset.allFinite()) throw InvalidInput("synthetic terrain: the offset is not finite");
  const std::uint64_t quads = std::uint64_t{o.nx} * o.ny;
  if (2 * quads > kMaxIndexCount || (std::uint64_t{o.nx} + 1) * (std::uint64_t{o.ny} + 1) > kMaxIndexCount)
    throw InvalidInput(fmt::format("synthetic terrain: {} × {} quads exceed the 32-bit indices of a mesh", o.nx, o.ny));
  side_ = std::max(o.nx, o.ny) * o.spacing;
  // Holes apart from each other by two cells at least (a quad is cut when its centre lies in a hole: one
  // round hole never leaves two quads that meet only at a corner, two close ones could); a hole that finds
  // no such place in 32 tries is not made.
  const double r = o.hole_radius * side_;
  for (std::uint32_t h = 0; h < o.holes; ++h)
    for (std::uint64_t attempt = 0; attempt < 32; ++attempt) {
      const double cx = (0.1 + 0.8 * uniform(o.seed, 1000 + h, 2 * attempt + 1)) * o.nx * o.spacing;
      const double cy = (0.1 + 0.8 * uniform(o.seed, 1000 + h, 2 * attempt + 2)) * o.ny * o.spacing;
      const double apart = 2.0 * r + 2.0 * o.spacing;
      if (std::any_of(holes_.begin(), holes_.end(), [&](const std::array<double, 3>& q) {
            return (cx - q[0]) * (cx - q[0]) + (cy - q[1]) * (cy - q[1]) < apart * apart;
          }))
        continue;
      holes_.push_back({cx, cy, r * r});
      break;
    }
  make_waves(o.seed, side_ / 8.0, true, wave_dir_, wave_number_, wave_phase_);
  row_start_.assign(std::size_t{o.ny} + 2, 0);
  for (std::uint32_t y = 0; y <= o.ny; ++y) {
    std::uint64_t used = 0;
    for (std::uint32_t x = 0; x <= o.nx; ++x) used += vertex_used(x, y) ? 1u : 0u;
    row_start_[std::size_t{y} + 1] = row_start_[y] + used;
  }
  num_vertices_ = row_start_.back();
  for (std::uint32_t y = 0; y < o.ny; ++y)
    for (std::uint32_t x = 0; x < o.nx; ++x) num_faces_ += quad_kept(x, y) ? 2u : 0u;
  if (num_faces_ == 0) throw InvalidInput("synthetic terrain: the holes remove every face (use a smaller --hole-radius)");
}

bool TerrainScan::quad_kept(std::uint32_t x, std::uint32_t y) const {
  const double cx = (x + 0.5) * options_.spacing;
  const double cy = (y + 0.5) * options_.spacing;
  return std::none_of(holes_.begin(), holes_.end(), [&](const std::array<double, 3>& h) {
    return (cx - h[0]) * (cx - h[0]) + (cy - h[1]) * (cy - h[1]) < h[2];
  });
}

bool TerrainScan::vertex_used(std::uint32_t x, std::uint32_t y) const {
  // A kept quad keeps both its triangles, and every corner of the quad lies on one of them.
  for (std::uint32_t qy = y == 0 ? 0 : y - 1; qy <= y && qy < options_.ny; ++qy)
    for (std::uint32_t qx = x == 0 ? 0 : x - 1; qx <= x && qx < options_.nx; ++qx)
      if (quad_kept(qx, qy)) return true;
  return false;
}

void TerrainScan::row_indices(std::uint32_t y, std::vector<std::uint32_t>& out) const {
  out.assign(std::size_t{options_.nx} + 1, std::numeric_limits<std::uint32_t>::max());
  std::uint64_t next = row_start_[y];
  for (std::uint32_t x = 0; x <= options_.nx; ++x)
    if (vertex_used(x, y)) out[x] = static_cast<std::uint32_t>(next++);
}

void TerrainScan::vertex_row(std::uint32_t y, std::vector<Vec3>& out) const {
  const auto& o = options_;
  for (std::uint32_t x = 0; x <= o.nx; ++x) {
    if (!vertex_used(x, y)) continue;
    const Vec3 p(x * o.spacing, y * o.spacing, 0.0);
    const double z = o.relief * side_ * waves(p, wave_dir_, wave_number_, wave_phase_) +
                     o.noise * o.spacing * (2.0 * uniform(o.seed, (std::uint64_t{y} << 32) | x, 7) - 1.0);
    out.push_back(Vec3(p.x(), p.y(), z) + o.offset);
  }
}

void TerrainScan::face_row(std::uint32_t y, std::vector<Face>& out) const {
  std::vector<std::uint32_t> low, high;
  row_indices(y, low);
  row_indices(y + 1, high);
  for (std::uint32_t x = 0; x < options_.nx; ++x) {
    if (!quad_kept(x, y)) continue;
    for (int half = 0; half < 2; ++half) {
      const auto t = quad_triangle(x, y, half);
      Face f{};
      for (std::size_t c = 0; c < 3; ++c) f[c] = (t[c][1] == y ? low : high)[t[c][0]];
      out.push_back(f);
    }
  }
}

}  // namespace gimforge
