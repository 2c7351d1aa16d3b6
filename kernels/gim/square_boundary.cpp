#include "kernels/gim/square_boundary.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

#include <fmt/format.h>

#include "kernels/core/edge_topology.h"
#include "kernels/core/errors.h"

namespace gimforge {
namespace {

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  return (std::uint64_t{std::min(a, b)} << 32) | std::max(a, b);
}
std::uint64_t halfedge_key(std::uint32_t a, std::uint32_t b) { return (std::uint64_t{a} << 32) | b; }

/// The cut-paths of ρ' (without their layout): split at cut-nodes (cut-valence != 2), mates matched.
/// Also returns the cut-valence of each loop position's original vertex in `valence`.
std::vector<CutPath> find_paths(const CutMesh& cut, std::vector<std::uint32_t>& valence) {
  const std::size_t n = cut.boundary.size();
  auto orig = [&](std::size_t i) { return cut.original_vertex[cut.boundary[i % n]]; };
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> edges_of_key;
  for (std::uint32_t i = 0; i < n; ++i) edges_of_key[edge_key(orig(i), orig(i + 1))].push_back(i);
  std::unordered_map<std::uint32_t, std::uint32_t> cut_valence;
  for (const auto& [key, list] : edges_of_key) {
    ++cut_valence[static_cast<std::uint32_t>(key >> 32)];
    ++cut_valence[static_cast<std::uint32_t>(key & 0xffffffffu)];
  }
  valence.resize(n);
  std::vector<std::uint32_t> nodes;
  for (std::uint32_t i = 0; i < n; ++i) {
    valence[i] = cut_valence[orig(i)];
    if (valence[i] != 2) nodes.push_back(i);
  }
  if (nodes.empty()) nodes.push_back(0);  // a single closed cut loop: any vertex starts it
  std::vector<CutPath> paths;
  std::vector<std::int32_t> path_of_edge(n, -1);
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    const std::uint32_t first = nodes[k];
    const std::uint32_t last = k + 1 < nodes.size() ? nodes[k + 1] : nodes[0] + static_cast<std::uint32_t>(n);
    CutPath p;
    p.first = first;
    p.edges = last - first;
    for (std::uint32_t e = first; e < last; ++e) {
      path_of_edge[e % n] = static_cast<std::int32_t>(paths.size());
      p.length += (cut.disk.positions[cut.boundary[(e + 1) % n]] - cut.disk.positions[cut.boundary[e % n]]).norm();
    }
    paths.push_back(p);
  }
  for (CutPath& p : paths) {
    const auto& list = edges_of_key[edge_key(orig(p.first), orig(p.first + 1))];
    if (list.size() == 2) {
      const std::uint32_t other = list[0] == p.first % n ? list[1] : list[0];
      p.mate = path_of_edge[other];
    }
  }
  for (std::size_t i = 0; i < paths.size(); ++i) {
    const CutPath& p = paths[i];
    if (p.mate >= 0 && (paths[static_cast<std::size_t>(p.mate)].mate != static_cast<std::int32_t>(i) ||
                        paths[static_cast<std::size_t>(p.mate)].edges != p.edges))
      throw TopologyError(fmt::format("cut-path {} and its mate {} do not match", i, p.mate));
  }
  return paths;
}

/// Integer grid units per path: proportional to 3D length, >= 1, mates equal, summing to `total`.
void allot_units(std::vector<CutPath>& paths, std::uint32_t total) {
  double length = 0.0;
  for (const CutPath& p : paths) length += p.length;
  if (paths.size() > total)
    throw TopologyError(fmt::format("the cut has {} cut-paths but the square perimeter only {} grid units",
                                    paths.size(), total));
  std::vector<double> ideal(paths.size());
  std::int64_t used = 0;
  for (std::size_t i = 0; i < paths.size(); ++i) {
    const CutPath& p = paths[i];
    const double len = p.mate >= 0 ? 0.5 * (p.length + paths[static_cast<std::size_t>(p.mate)].length) : p.length;
    ideal[i] = length > 0.0 ? total * len / length : static_cast<double>(total) / static_cast<double>(paths.size());
    paths[i].units = static_cast<std::uint32_t>(std::max(1.0, std::round(ideal[i])));
    used += paths[i].units;
  }
  // Redistribute the residual one unit per unpaired path or one unit per mate pair, where rounding
  // hurt most; mates are always treated together.
  std::int64_t residual = static_cast<std::int64_t>(total) - used;
  for (int guard = 0; residual != 0 && guard < 1 << 20; ++guard) {
    const bool grow = residual > 0;
    std::int64_t best = -1;
    double best_score = -INFINITY;
    for (std::size_t i = 0; i < paths.size(); ++i) {
      const CutPath& p = paths[i];
      if (p.mate >= 0 && p.mate < static_cast<std::int32_t>(i)) continue;  // the pair is represented once
      const std::int64_t step = p.mate >= 0 ? 2 : 1;
      if (step > std::abs(residual) || (!grow && p.units <= 1)) continue;
      const double score = grow ? ideal[i] - p.units : p.units - ideal[i];
      if (score > best_score) best_score = score, best = static_cast<std::int64_t>(i);
    }
    if (best < 0) break;
    CutPath& p = paths[static_cast<std::size_t>(best)];
    const std::int64_t step = p.mate >= 0 ? 2 : 1;
    p.units = grow ? p.units + 1 : p.units - 1;
    if (p.mate >= 0) paths[static_cast<std::size_t>(p.mate)].units = p.units;
    residual += grow ? -step : step;
  }
  if (residual != 0)
    throw TopologyError(fmt::format("cannot allot {} perimeter units to {} cut-paths with mates equal", total,
                                    paths.size()));
}

/// Start units along the perimeter, rotated so that no valence-1 cut-node lands on a corner if possible.
void lay_out(std::vector<CutPath>& paths, const std::vector<std::uint32_t>& valence, std::uint32_t units_per_side) {
  for (std::uint32_t rotation = 0; rotation < units_per_side; ++rotation) {
    std::uint32_t at = rotation;
    bool ok = true;
    for (CutPath& p : paths) {
      p.start_unit = at;
      if (valence[p.first] == 1 && at % units_per_side == 0) ok = false;
      at += p.units;
    }
    if (ok) return;
  }
  // Every rotation puts a valence-1 node on a corner (only possible with very few units): keep rotation 0.
  std::uint32_t at = 0;
  for (CutPath& p : paths) {
    p.start_unit = at;
    at += p.units;
  }
}

/// Fractions of arc length at each vertex of a path (0 .. 1), from its own loop positions.
std::vector<double> arc_fractions(const CutMesh& cut, const CutPath& p) {
  const std::size_t n = cut.boundary.size();
  std::vector<double> f(p.edges + 1, 0.0);
  for (std::uint32_t k = 0; k < p.edges; ++k)
    f[k + 1] = f[k] + (cut.disk.positions[cut.boundary[(p.first + k + 1) % n]] -
                       cut.disk.positions[cut.boundary[(p.first + k) % n]]).norm();
  for (double& x : f) x = f.back() > 0.0 ? x / f.back() : 0.0;
  f.back() = 1.0;
  return f;
}

/// Perimeter coordinate of vertex k of path p (grid units, unwrapped).
double coordinate(const CutPath& p, const std::vector<double>& fractions, std::uint32_t k) {
  return p.start_unit + fractions[k] * p.units;
}

/// A coordinate within rounding of a square corner is the corner, so corners are exact vertices.
double snap_to_corner(double c, std::uint32_t units_per_side) {
  const double corner = std::round(c / units_per_side) * units_per_side;
  return std::abs(c - corner) < 1e-9 * units_per_side ? corner : c;
}

/// A point inserted on a boundary edge: fraction along the edge (in loop direction), 3D point, perimeter.
struct EdgeSplit {
  double t;
  Vec3 point;
  double perimeter;
};

}  // namespace

Vec2 perimeter_point(double c, std::uint32_t units_per_side) {
  const double u = static_cast<double>(units_per_side);
  c = std::fmod(c, 4.0 * u);
  if (c < 0.0) c += 4.0 * u;
  const int side = std::min(3, static_cast<int>(c / u));
  const double s = (c - side * u) / u;
  switch (side) {
    case 0: return {s, 0.0};
    case 1: return {1.0, s};
    case 2: return {1.0 - s, 1.0};
    default: return {0.0, 1.0 - s};
  }
}

SquareBoundary map_boundary_to_square(const CutMesh& cut, const SquareBoundaryOptions& options) {
  const std::uint32_t U = options.units_per_side;
  const std::size_t n = cut.boundary.size();
  if (n < 3) throw TopologyError(fmt::format("the cut boundary has {} vertices; a disk needs at least 3", n));
  std::vector<std::uint32_t> valence;
  std::vector<CutPath> paths = find_paths(cut, valence);
  allot_units(paths, 4 * U);
  lay_out(paths, valence, U);

  // Perimeter coordinate of every loop position; mates mirror their canonical partner exactly.
  std::vector<double> perim(n, 0.0);
  std::vector<std::vector<double>> fractions(paths.size());
  for (std::size_t i = 0; i < paths.size(); ++i) {
    const CutPath& p = paths[i];
    const bool canonical = p.mate < 0 || p.mate > static_cast<std::int32_t>(i);
    if (canonical) {
      fractions[i] = arc_fractions(cut, p);
    } else {
      const auto& partner = fractions[static_cast<std::size_t>(p.mate)];
      fractions[i].resize(partner.size());
      for (std::size_t k = 0; k < partner.size(); ++k) fractions[i][k] = 1.0 - partner[partner.size() - 1 - k];
    }
    for (std::uint32_t k = 0; k < p.edges; ++k) perim[(p.first + k) % n] = snap_to_corner(coordinate(p, fractions[i], k), U);
  }

  // Splits of boundary edges that span a square corner, mirrored onto the mate edge.
  std::vector<std::vector<EdgeSplit>> splits(n);
  std::size_t corner_splits = 0;
  for (std::size_t i = 0; i < paths.size(); ++i) {
    const CutPath& p = paths[i];
    for (std::uint32_t k = 0; k < p.edges; ++k) {
      const double c0 = snap_to_corner(coordinate(p, fractions[i], k), U);
      const double c1 = snap_to_corner(coordinate(p, fractions[i], k + 1), U);
      const double corner = std::floor(c0 / U + 1.0) * U;  // first corner strictly after c0
      if (!(corner < c1) || corner - c0 < 1e-9 * U || c1 - corner < 1e-9 * U) continue;
      const double t = (corner - c0) / (c1 - c0);
      const std::size_t e = (p.first + k) % n;
      const Vec3& a = cut.disk.positions[cut.boundary[e]];
      const Vec3& b = cut.disk.positions[cut.boundary[(e + 1) % n]];
      const Vec3 point = (1.0 - t) * a + t * b;
      splits[e].push_back({t, point, corner});
      ++corner_splits;
      if (p.mate >= 0) {
        const CutPath& q = paths[static_cast<std::size_t>(p.mate)];
        const std::uint32_t mk = p.edges - 1 - k;  // the mate edge traverses the same edge backwards
        const std::size_t me = (q.first + mk) % n;
        const auto& qf = fractions[static_cast<std::size_t>(p.mate)];
        const double qc = q.start_unit + (qf[mk] + (1.0 - t) * (qf[mk + 1] - qf[mk])) * q.units;
        splits[me].push_back({1.0 - t, point, qc});
      }
    }
  }

  SquareBoundary out;
  out.units_per_side = U;
  out.disk = cut.disk;
  out.original_vertex = cut.original_vertex;
  out.corner_splits = corner_splits;
  // Halfedge -> face, to find the face on each boundary edge and the faces of interior edges.
  std::unordered_map<std::uint64_t, std::uint32_t> face_of;
  face_of.reserve(3 * out.disk.faces.size());
  for (std::uint32_t f = 0; f < out.disk.faces.size(); ++f)
    for (int c = 0; c < 3; ++c)
      face_of[halfedge_key(out.disk.faces[f][static_cast<std::size_t>(c)], out.disk.faces[f][static_cast<std::size_t>((c + 1) % 3)])] = f;
  // A new vertex at fraction t of the segment from vertex a to vertex b (attributes interpolated).
  auto add_vertex = [&](const Vec3& p, std::uint32_t a, std::uint32_t b, float t) {
    out.disk.positions.push_back(p);
    if (out.disk.has_colors()) out.disk.colors.push_back((1.0f - t) * out.disk.colors[a] + t * out.disk.colors[b]);
    if (out.disk.has_normals())
      out.disk.normals.push_back(((1.0f - t) * out.disk.normals[a] + t * out.disk.normals[b]).normalized());
    out.original_vertex.push_back(kInvalidIndex);
    return static_cast<std::uint32_t>(out.disk.positions.size() - 1);
  };
  auto set_face = [&](std::uint32_t f, const Face& t) {
    out.disk.faces[f] = t;
    for (int c = 0; c < 3; ++c) face_of[halfedge_key(t[static_cast<std::size_t>(c)], t[static_cast<std::size_t>((c + 1) % 3)])] = f;
  };
  auto add_face = [&](const Face& t) {
    out.disk.faces.push_back(t);
    set_face(static_cast<std::uint32_t>(out.disk.faces.size() - 1), t);
  };
  for (std::size_t e = 0; e < n; ++e) {
    const std::uint32_t a = cut.boundary[e];
    const std::uint32_t b = cut.boundary[(e + 1) % n];
    out.boundary.push_back(a);
    out.perimeter.push_back(perim[e]);
    if (splits[e].empty()) continue;
    auto& s = splits[e];
    std::sort(s.begin(), s.end(), [](const EdgeSplit& x, const EdgeSplit& y) { return x.t < y.t; });
    const auto it = face_of.find(halfedge_key(a, b));
    if (it == face_of.end()) throw TopologyError(fmt::format("boundary edge {}-{} has no face", a, b));
    const std::uint32_t f = it->second;
    const Face old = out.disk.faces[f];
    const std::uint32_t x = old[0] != a && old[0] != b ? old[0] : old[1] != a && old[1] != b ? old[1] : old[2];
    face_of.erase(halfedge_key(a, b));
    std::uint32_t prev = a;
    bool first = true;
    for (const EdgeSplit& sp : s) {
      const std::uint32_t m = add_vertex(sp.point, a, b, static_cast<float>(sp.t));
      out.boundary.push_back(m);
      out.perimeter.push_back(sp.perimeter);
      if (first) set_face(f, {prev, m, x}); else add_face({prev, m, x});
      first = false;
      prev = m;
    }
    add_face({prev, b, x});
  }
  out.paths = std::move(paths);
  // Re-index path starts onto the extended loop: a path starts at its first node, which is a loop vertex.
  std::vector<std::uint32_t> position(out.disk.positions.size(), kInvalidIndex);
  for (std::uint32_t i = 0; i < out.boundary.size(); ++i) position[out.boundary[i]] = i;
  const std::size_t m = out.boundary.size();
  for (std::size_t i = 0; i < out.paths.size(); ++i) {
    CutPath& p = out.paths[i];
    const std::uint32_t start = position[cut.boundary[p.first]];
    const std::uint32_t end = position[cut.boundary[(p.first + p.edges) % n]];
    p.first = start;
    p.edges = static_cast<std::uint32_t>((end + m - start) % m);
    if (p.edges == 0) p.edges = static_cast<std::uint32_t>(m);  // a single path covering the whole loop
  }
  out.boundary_uv.resize(m);
  for (std::size_t i = 0; i < m; ++i) out.boundary_uv[i] = perimeter_point(out.perimeter[i], U);

  // Interior edges joining two boundary vertices on the same side of the square would flatten the region
  // they cut off (a triangle with all three vertices on one side is the simplest case, Gu et al. §3.1):
  // split each at its midpoint, which becomes an interior vertex, so Tutte/Floater maps stay bijective.
  std::vector<char> on_boundary(out.disk.positions.size(), 0);
  std::vector<double> perim_of(out.disk.positions.size(), -1.0);
  for (std::size_t i = 0; i < m; ++i) on_boundary[out.boundary[i]] = 1, perim_of[out.boundary[i]] = out.perimeter[i];
  auto sides = [&](std::uint32_t v) {  // bit mask of the square sides vertex v lies on
    const double c = perim_of[v];
    unsigned mask = 0;
    for (unsigned side = 0; side < 4; ++side)
      if (c >= side * U && c <= (side + 1) * U) mask |= 1u << side;
    if (c == 0.0) mask |= 1u << 3;
    return mask;
  };
  auto is_boundary_edge = [&](std::uint32_t a, std::uint32_t b) { return face_of.count(halfedge_key(b, a)) == 0; };
  auto is_chord = [&](std::uint32_t a, std::uint32_t b) {
    return on_boundary[a] && on_boundary[b] && (sides(a) & sides(b)) != 0 && !is_boundary_edge(a, b);
  };
  for (std::uint32_t f = 0; f < out.disk.faces.size(); ++f) {
    for (int c = 0; c < 3; ++c) {
      const Face t = out.disk.faces[f];
      const std::uint32_t u = t[static_cast<std::size_t>(c)], w = t[static_cast<std::size_t>((c + 1) % 3)];
      if (!is_chord(u, w)) continue;
      const std::uint32_t x = t[static_cast<std::size_t>((c + 2) % 3)];
      const std::uint32_t g = face_of.at(halfedge_key(w, u));
      const Face o = out.disk.faces[g];
      const std::uint32_t y = o[0] != u && o[0] != w ? o[0] : o[1] != u && o[1] != w ? o[1] : o[2];
      const std::uint32_t mid = add_vertex(0.5 * (out.disk.positions[u] + out.disk.positions[w]), u, w, 0.5f);
      on_boundary.push_back(0);
      perim_of.push_back(-1.0);
      face_of.erase(halfedge_key(u, w));
      face_of.erase(halfedge_key(w, u));
      set_face(f, {u, mid, x});
      add_face({mid, w, x});
      set_face(g, {w, mid, y});
      add_face({mid, u, y});
      ++out.side_splits;
      c = -1;  // face f changed: examine its edges again
    }
  }
  return out;
}

}  // namespace gimforge
