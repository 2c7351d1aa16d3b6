#include "kernels/mcgim/chart_smooth.h"

#include <algorithm>
#include <array>

#include "kernels/core/edge_topology.h"
#include "kernels/core/embree_device.h"

namespace gimforge {
namespace {

/// A bound on the passes (each pass that moves anything shortens the total boundary, so they end anyway;
/// on the shared meshes they end within 8).
constexpr int kMaxPasses = 64;

/// One pass of the fan rule (chart_smooth.h) over every vertex; returns the faces moved.
std::size_t shorten_fans(const TriMesh& mesh, const std::vector<std::vector<std::uint32_t>>& vertex_faces,
                         const std::vector<std::uint8_t>& on_border,
                         const std::vector<std::array<std::uint32_t, 3>>& across, std::vector<std::uint32_t>& face_chart) {
  std::size_t moved = 0;
  std::vector<std::uint32_t> from_faces;
  for (std::uint32_t v = 0; v < mesh.positions.size(); ++v) {
    const std::vector<std::uint32_t>& fs = vertex_faces[v];
    if (on_border[v] || fs.size() < 3) continue;
    const std::uint32_t a = face_chart[fs[0]];
    std::uint32_t b = a;
    bool two = true;
    for (std::uint32_t f : fs) {
      const std::uint32_t c = face_chart[f];
      if (c == a) continue;
      if (b == a) b = c;
      else if (c != b) two = false;
    }
    if (!two || b == a) continue;
    for (int side = 0; side < 2; ++side) {
      const std::uint32_t from = side == 0 ? a : b, to = side == 0 ? b : a;
      from_faces.clear();
      for (std::uint32_t f : fs)
        if (face_chart[f] == from) from_faces.push_back(f);
      // Rim vertices: in `from` faces only (inside the fan's rim) or also in `to` faces at v (the fan's two
      // ends; more than two would be a second fan).
      std::array<std::uint32_t, 2> ends{};
      int num_ends = 0;
      bool ok = true;
      double rim = 0.0;
      std::uint32_t single_edge_face = kNoFace;
      for (std::uint32_t f : from_faces) {
        const Face& t = mesh.faces[f];
        int at = 0;
        while (t[static_cast<std::size_t>(at)] != v) ++at;
        const std::uint32_t p = t[static_cast<std::size_t>((at + 1) % 3)], q = t[static_cast<std::size_t>((at + 2) % 3)];
        rim += (mesh.positions[p] - mesh.positions[q]).norm();
        single_edge_face = across[f][static_cast<std::size_t>((at + 1) % 3)];
        for (std::uint32_t u : {p, q}) {
          bool in_to = false;
          for (std::uint32_t g : vertex_faces[u]) in_to = in_to || (face_chart[g] == to && std::find(fs.begin(), fs.end(), g) != fs.end());
          if (in_to) {
            if (num_ends == 2 && ends[0] != u && ends[1] != u) ok = false;
            else if (num_ends < 2 && (num_ends == 0 || ends[0] != u)) ends[static_cast<std::size_t>(num_ends++)] = u;
            continue;
          }
          for (std::uint32_t g : vertex_faces[u]) ok = ok && face_chart[g] == from;  // interior to `from`
          ok = ok && !on_border[u];
        }
      }
      if (!ok || num_ends != 2) continue;
      // One face: its third edge must lead on into `from`, or `from` would be that face alone.
      if (from_faces.size() == 1 && (single_edge_face == kNoFace || face_chart[single_edge_face] != from)) continue;
      const double before = (mesh.positions[v] - mesh.positions[ends[0]]).norm() + (mesh.positions[v] - mesh.positions[ends[1]]).norm();
      if (!(rim < 0.999 * before)) continue;
      for (std::uint32_t f : from_faces) face_chart[f] = to;
      moved += from_faces.size();
      break;
    }
  }
  return moved;
}

}  // namespace

BoundarySmoothing smooth_chart_boundaries(const TriMesh& mesh, std::vector<std::uint32_t>& face_chart) {
  BoundarySmoothing out;
  const EdgeTopology topo = build_edge_topology(mesh);
  const std::size_t nf = mesh.faces.size();
  std::vector<std::array<std::uint32_t, 3>> across(nf, {kNoFace, kNoFace, kNoFace});  // face across edge i → i+1
  for (std::size_t e = 0; e < topo.num_edges(); ++e) {
    if (topo.valence(e) != 2) continue;
    const std::uint32_t h0 = topo.edge_halfedges[topo.edge_offsets[e]], h1 = topo.edge_halfedges[topo.edge_offsets[e] + 1];
    across[h0 / 3][h0 % 3] = h1 / 3;
    across[h1 / 3][h1 % 3] = h0 / 3;
  }
  // Faces per vertex, to see whether a tip vertex has other faces in the same chart.
  std::vector<std::vector<std::uint32_t>> vertex_faces(mesh.positions.size());
  for (std::uint32_t f = 0; f < nf; ++f)
    for (std::uint32_t v : mesh.faces[f]) vertex_faces[v].push_back(f);
  std::vector<std::uint8_t> on_border(mesh.positions.size(), 0);
  for (std::size_t e = 0; e < topo.num_edges(); ++e)
    if (topo.valence(e) == 1) {
      const std::uint32_t h = topo.edge_halfedges[topo.edge_offsets[e]];
      on_border[mesh.faces[h / 3][h % 3]] = 1;
      on_border[mesh.faces[h / 3][(h + 1) % 3]] = 1;
    }
  for (int pass = 0; pass < kMaxPasses; ++pass) {
    std::size_t moved_now = 0;
    for (std::uint32_t f = 0; f < nf; ++f) {
      const std::uint32_t a = face_chart[f];
      for (int i = 0; i < 3; ++i) {
        // Edges i+1 and i+2 meet at the tip vertex faces[f][(i+2)%3]; both must border the same chart b ≠ a.
        const std::uint32_t g1 = across[f][static_cast<std::size_t>((i + 1) % 3)], g2 = across[f][static_cast<std::size_t>((i + 2) % 3)];
        if (g1 == kNoFace || g2 == kNoFace) continue;
        const std::uint32_t b = face_chart[g1];
        if (b == a || face_chart[g2] != b) continue;
        const std::uint32_t g0 = across[f][static_cast<std::size_t>(i)];
        if (g0 == kNoFace || face_chart[g0] != a) continue;  // an ear hangs on its chart by one edge
        const std::uint32_t tip = mesh.faces[f][static_cast<std::size_t>((i + 2) % 3)];
        bool alone = true;
        for (std::uint32_t g : vertex_faces[tip]) alone = alone && (g == f || face_chart[g] != a);
        if (!alone) continue;
        face_chart[f] = b;
        ++moved_now;
        break;
      }
    }
    const std::size_t teeth_now = moved_now;
    const std::size_t fans_now = shorten_fans(mesh, vertex_faces, on_border, across, face_chart);
    out.teeth += teeth_now;
    out.fan_faces += fans_now;
    moved_now += fans_now;
    out.passes = pass + 1;
    if (moved_now == 0) break;
  }
  return out;
}

}  // namespace gimforge
