#include "jobs/scan_bricks.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <bit>
#include <cmath>
#include <limits>
#include <span>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "io/input_file.h"
#include "kernels/core/edge_topology.h"
#include "kernels/core/errors.h"
#include "mpi/agree.h"

namespace gimforge::jobs {
namespace {

constexpr int kGatherTag = 73;

/// Histogram cells along the box's longest side.
constexpr double kHistogramCells = 64.0;

/// Sets of a file's vertices as bits, with the rank of each set bit (its index among the set ones): O(V/8)
/// memory instead of a sort and a search per corner.
class VertexSet {
 public:
  explicit VertexSet(std::uint64_t vertices) : bits_(static_cast<std::size_t>(vertices / 64 + 1), 0) {}
  void insert(std::uint32_t v) { bits_[v >> 6] |= std::uint64_t{1} << (v & 63u); }
  /// The members in increasing order; afterwards rank() works.
  [[nodiscard]] std::vector<std::uint32_t> finish() {
    before_.resize(bits_.size());
    std::vector<std::uint32_t> ids;
    std::uint32_t count = 0;
    for (std::size_t w = 0; w < bits_.size(); ++w) {
      before_[w] = count;
      for (std::uint64_t b = bits_[w]; b != 0; b &= b - 1)
        ids.push_back(static_cast<std::uint32_t>(64 * w + static_cast<std::size_t>(std::countr_zero(b))));
      count += static_cast<std::uint32_t>(std::popcount(bits_[w]));
    }
    return ids;
  }
  [[nodiscard]] std::uint32_t rank(std::uint32_t v) const {
    const std::uint64_t below = bits_[v >> 6] & ((std::uint64_t{1} << (v & 63u)) - 1);
    return before_[v >> 6] + static_cast<std::uint32_t>(std::popcount(below));
  }

 private:
  std::vector<std::uint64_t> bits_;
  std::vector<std::uint32_t> before_;
};

/// Reads the positions of the vertices `mesh`'s faces use (translated by −origin) and re-indexes the faces
/// into them (the faces hold file vertex indices before).
void fill_positions(const io::PlyTriangleFile& file, const Vec3& origin, TriMesh& mesh) {
  VertexSet used(file.vertices());
  for (const Face& t : mesh.faces)
    for (std::uint32_t v : t) used.insert(v);
  const std::vector<std::uint32_t> ids = used.finish();
  for (Face& t : mesh.faces)
    for (std::uint32_t& v : t) v = used.rank(v);
  mesh.positions = file.read_positions(ids);
  for (Vec3& p : mesh.positions) p -= origin;
}

}  // namespace

std::array<std::uint64_t, 2> slice_of(std::uint64_t count, int rank, int size) {
  const auto r = static_cast<std::uint64_t>(rank), p = static_cast<std::uint64_t>(size);
  return {count * r / p, count * (r + 1) / p};
}

ScannedMesh scan_mesh(const mpi::Comm& comm, const io::PlyTriangleFile& file) {
  ScannedMesh m;
  m.file = &file;
  mpi::run_agreed(comm, [&] {
    m.referenced.assign(static_cast<std::size_t>(file.vertices()), 0);
    file.read_faces(0, file.faces(), [&](std::uint64_t, std::span<const Face> faces) {
      for (const Face& t : faces) {
        if (has_repeated_index(t)) continue;
        ++m.faces;
        for (std::uint32_t v : t) m.referenced[v] = 1;
      }
    });
    if (m.faces == 0) throw InvalidInput(fmt::format("{}: no faces with three distinct vertices", file.shown()));
    const auto [first, last] = slice_of(file.vertices(), comm.rank(), comm.size());
    file.read_vertices(first, last, [&](std::uint64_t at, std::span<const Vec3> p) {
      for (std::size_t i = 0; i < p.size(); ++i)
        if (m.referenced[at + i]) m.box.extend(p[i]);
    });
  });
  for (const std::uint8_t r : m.referenced) m.vertices += r;
  std::vector<double> corners{m.box.min.x(), m.box.min.y(), m.box.min.z(), -m.box.max.x(), -m.box.max.y(), -m.box.max.z()};
  corners = comm.allreduce(std::move(corners), mpi::ReduceOp::kMin);
  m.box.min = Vec3(corners[0], corners[1], corners[2]);
  m.box.max = Vec3(-corners[3], -corners[4], -corners[5]);
  mpi::run_agreed(comm, [&] {  // the same box on every rank: rank 0 says it
    if (m.box.empty()) {
      // cannot happen: no faces were refused above
    } else if (auto small = io::small_extent_error(file.shown(), (m.box.max - m.box.min).stableNorm())) {
      throw *small;
    }
  });
  return m;
}

TriMesh read_face_slice(const ScannedMesh& mesh, int rank, int size, const Vec3& origin) {
  TriMesh out;
  const auto [first, last] = slice_of(mesh.file->faces(), rank, size);
  mesh.file->read_faces(first, last, [&](std::uint64_t at, std::span<const Face> faces) {
    for (std::size_t i = 0; i < faces.size(); ++i)
      if (!has_repeated_index(faces[i]) && (mesh.dropped.empty() || !mesh.is_dropped(at + i))) out.faces.push_back(faces[i]);
  });
  fill_positions(*mesh.file, origin, out);
  return out;
}

double longest_edge(MeshView m, std::size_t f) {
  const Face& t = m.faces[f];
  return std::sqrt(std::max({(m.positions[t[1]] - m.positions[t[0]]).squaredNorm(),
                             (m.positions[t[2]] - m.positions[t[1]]).squaredNorm(),
                             (m.positions[t[0]] - m.positions[t[2]]).squaredNorm()}));
}

double scan_longest_edge(const mpi::Comm& comm, const ScannedMesh& mesh, const Vec3& origin) {
  double edge = 0.0;
  mpi::run_agreed(comm, [&] {
    const TriMesh slice = read_face_slice(mesh, comm.rank(), comm.size(), origin);
    for (std::size_t f = 0; f < slice.num_faces(); ++f) edge = std::max(edge, longest_edge(slice, f));
  });
  return comm.allreduce(edge, mpi::ReduceOp::kMax);
}

bool BrickMesh::certified(const Vec3& p, double d) const {
  const Vec3 outside = (bounds.min - p).cwiseMax(p - bounds.max).cwiseMax(Vec3::Zero());
  return d <= margin - longest_edge - outside.norm();
}

CentroidHistogram brick_histogram(const BoundingBox& box) {
  const Vec3 extent = box.max - box.min;
  const double cell = std::max(extent.maxCoeff(), std::numeric_limits<double>::min()) / kHistogramCells;
  std::array<std::uint32_t, 3> dims{};
  for (int k = 0; k < 3; ++k)
    dims[static_cast<std::size_t>(k)] = static_cast<std::uint32_t>(std::clamp(std::ceil(extent[k] / cell), 1.0, kHistogramCells));
  return CentroidHistogram(box, dims);
}

std::size_t proxy_bricks(std::uint64_t faces, std::size_t target) {
  return std::clamp<std::size_t>(std::min<std::size_t>(static_cast<std::size_t>(faces / 250'000), target / 4096), 1, 64);
}

BrickPartition vertex_bricks(const mpi::Comm& comm, const ScannedMesh& mesh, const Vec3& origin, std::size_t bricks) {
  const io::PlyTriangleFile& file = *mesh.file;
  CentroidHistogram histogram = brick_histogram(BoundingBox{mesh.box.min - origin, mesh.box.max - origin});
  const auto [first, last] = slice_of(file.vertices(), comm.rank(), comm.size());
  mpi::run_agreed(comm, [&] {
    file.read_vertices(first, last, [&](std::uint64_t at, std::span<const Vec3> p) {
      for (std::size_t i = 0; i < p.size(); ++i)
        if (mesh.referenced[at + i]) histogram.add(p[i] - origin);
    });
  });
  histogram.counts() = comm.allreduce(std::move(histogram.counts()), mpi::ReduceOp::kSum);
  return partition_bricks(histogram, bricks);
}

BrickMesh read_brick(const mpi::Comm& comm, const ScannedMesh& mesh, const Vec3& origin, const BrickOptions& options) {
  const io::PlyTriangleFile& file = *mesh.file;
  BrickMesh b;
  b.longest_edge = options.longest_edge;
  const BoundingBox box{mesh.box.min - origin, mesh.box.max - origin};
  b.partition = vertex_bricks(comm, mesh, origin, static_cast<std::size_t>(comm.size()));
  const auto mine = static_cast<std::size_t>(comm.rank());
  b.bounds = b.partition.bounds(mine);
  b.margin = options.margin_fraction * box.diagonal() + 2.0 * b.longest_edge;
  const BoundingBox near{b.bounds.min - Vec3::Constant(b.margin), b.bounds.max + Vec3::Constant(b.margin)};
  mpi::run_agreed(comm, [&] {
    // Per vertex: 1 = in brick r, 2 = within the margin of it.
    std::vector<std::uint8_t> where(static_cast<std::size_t>(file.vertices()), 0);
    file.read_vertices(0, file.vertices(), [&](std::uint64_t at, std::span<const Vec3> p) {
      for (std::size_t i = 0; i < p.size(); ++i) {
        if (!mesh.referenced[at + i]) continue;
        const Vec3 q = p[i] - origin;
        const bool inside = (q.array() >= near.min.array()).all() && (q.array() <= near.max.array()).all();
        where[at + i] = static_cast<std::uint8_t>((b.partition.brick_of(q) == mine ? 1 : 0) | (inside ? 2 : 0));
      }
    });
    file.read_faces(0, file.faces(), [&](std::uint64_t at, std::span<const Face> faces) {
      for (std::size_t i = 0; i < faces.size(); ++i) {
        const Face& t = faces[i];
        if (has_repeated_index(t) || (!mesh.dropped.empty() && mesh.is_dropped(at + i))) continue;
        const bool own = (where[t[0]] & 1) != 0;
        if (!own && ((where[t[0]] | where[t[1]] | where[t[2]]) & 2) == 0) continue;
        b.mesh.faces.push_back(t);
        b.owned.push_back(own ? 1 : 0);
        if (options.face_ids) b.face_ids.push_back(at + i);
      }
    });
    fill_positions(file, origin, b.mesh);
  });
  spdlog::debug("{}: rank {} holds {} faces (brick and ghosts) of {}", file.shown(), comm.rank(), b.mesh.faces.size(),
                mesh.faces);
  return b;
}

std::vector<double> gather_at_root(const mpi::Comm& comm, std::vector<double> mine) {
  if (comm.rank() != 0) {
    comm.send(std::as_bytes(std::span<const double>(mine)), 0, kGatherTag);
    return {};
  }
  for (int r = 1; r < comm.size(); ++r) {
    const mpi::Message msg = comm.recv(r, kGatherTag);
    const std::size_t at = mine.size();
    mine.resize(at + msg.data.size() / sizeof(double));
    std::memcpy(mine.data() + at, msg.data.data(), msg.data.size());
  }
  return mine;
}

void require_unchanged(const mpi::Comm& comm, const std::filesystem::path& path, const std::string& shown,
                       const std::string& stamp) {
  mpi::run_agreed(comm, [&] {
    if (io::file_stamp(path) != stamp)
      throw InvalidInput(fmt::format("{}: changed while it was read (its size or modification time is not what it was "
                                     "when the conversion began), so the ranks read pieces of two files; convert it "
                                     "again once it is written",
                                     shown));
  });
}

bool drop_duplicate_faces(const mpi::Comm& comm, ScannedMesh& scanned, BrickMesh& brick) {
  std::vector<double> mine;
  mpi::run_agreed(comm, [&] {
    const std::size_t F = brick.mesh.faces.size();
    std::vector<std::array<std::uint32_t, 3>> key(F);
    for (std::size_t f = 0; f < F; ++f) {
      key[f] = brick.mesh.faces[f];
      std::sort(key[f].begin(), key[f].end());
    }
    std::vector<std::size_t> order(F);
    for (std::size_t f = 0; f < F; ++f) order[f] = f;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      return key[a] != key[b] ? key[a] < key[b] : brick.face_ids[a] < brick.face_ids[b];
    });
    for (std::size_t i = 1; i < F; ++i)
      if (key[order[i]] == key[order[i - 1]] && brick.owned[order[i]] != 0)
        mine.push_back(static_cast<double>(brick.face_ids[order[i]]));  // file indices < 2^53
  });
  std::vector<double> all = gather_at_root(comm, std::move(mine));
  comm.broadcast(all, 0);
  if (all.empty()) return false;
  scanned.dropped.assign(all.size(), 0);
  for (std::size_t i = 0; i < all.size(); ++i) scanned.dropped[i] = static_cast<std::uint64_t>(all[i]);
  std::sort(scanned.dropped.begin(), scanned.dropped.end());
  scanned.faces -= scanned.dropped.size();
  std::size_t kept = 0;
  for (std::size_t f = 0; f < brick.mesh.faces.size(); ++f) {
    if (scanned.is_dropped(brick.face_ids[f])) continue;
    brick.mesh.faces[kept] = brick.mesh.faces[f];
    brick.owned[kept] = brick.owned[f];
    brick.face_ids[kept] = brick.face_ids[f];
    ++kept;
  }
  brick.mesh.faces.resize(kept);
  brick.owned.resize(kept);
  brick.face_ids.resize(kept);
  return true;
}

std::string BrickTopology::first_defect() const {
  const auto plural = [](std::uint64_t n, const char* one, const char* many) { return n == 1 ? one : many; };
  if (nonmanifold_edges > 0)
    return fmt::format("{} non-manifold {} shared by more than two faces", nonmanifold_edges,
                       plural(nonmanifold_edges, "edge", "edges"));
  if (nonmanifold_vertices > 0)
    return fmt::format("{} non-manifold {} where separate fans of faces meet", nonmanifold_vertices,
                       plural(nonmanifold_vertices, "vertex", "vertices"));
  if (inconsistent_edges > 0)
    return fmt::format("inconsistent orientation: {} {} traversed in the same direction by both faces",
                       inconsistent_edges, plural(inconsistent_edges, "edge is", "edges are"));
  return {};
}

BrickTopology brick_topology(const mpi::Comm& comm, const BrickMesh& brick) {
  std::vector<double> counts(3, 0.0);
  mpi::run_agreed(comm, [&] {
    const TriMesh& mesh = brick.mesh;
    if (mesh.faces.empty()) return;
    if (brick.face_ids.size() != mesh.faces.size()) throw InvalidInput("brick_topology: the brick has no face ids");
    const EdgeTopology topo = build_edge_topology(mesh);
    const ManifoldCheck check = check_manifold(mesh, topo);
    // The face of the smallest file index around an edge (a vertex) is held whole wherever one of its faces is
    // owned, so exactly one rank owns it: that rank counts the edge (vertex).
    const auto counts_edge = [&](std::uint32_t e) {
      std::size_t least = topo.edge_halfedges[topo.edge_offsets[e]] / 3;
      for (std::uint32_t k = topo.edge_offsets[e]; k < topo.edge_offsets[e + 1]; ++k) {
        const std::size_t f = topo.edge_halfedges[k] / 3;
        if (brick.face_ids[f] < brick.face_ids[least]) least = f;
      }
      return brick.owned[least] != 0;
    };
    constexpr std::uint64_t kNone = std::numeric_limits<std::uint64_t>::max();
    std::vector<std::uint64_t> least_face(mesh.positions.size(), kNone);
    std::vector<std::uint8_t> least_owned(mesh.positions.size(), 0);
    for (std::size_t f = 0; f < mesh.faces.size(); ++f)
      for (const std::uint32_t v : mesh.faces[f])
        if (brick.face_ids[f] < least_face[v]) least_face[v] = brick.face_ids[f], least_owned[v] = brick.owned[f];
    for (const std::uint32_t e : check.nonmanifold_edges) counts[0] += counts_edge(e) ? 1.0 : 0.0;
    for (const std::uint32_t v : check.nonmanifold_vertices) counts[1] += least_owned[v] != 0 ? 1.0 : 0.0;
    for (const std::uint32_t e : check.inconsistent_edges) counts[2] += counts_edge(e) ? 1.0 : 0.0;
  });
  counts = comm.allreduce(std::move(counts), mpi::ReduceOp::kSum);
  return {static_cast<std::uint64_t>(counts[0]), static_cast<std::uint64_t>(counts[1]),
          static_cast<std::uint64_t>(counts[2])};
}

void warn_repairs(const ScannedMesh& m) {
  const std::uint64_t degenerate = m.file->faces() - m.faces - m.dropped.size();
  if (degenerate > 0)
    spdlog::warn("{}: repaired: removed {} degenerate face(s) (repeated vertex index)", m.file->shown(), degenerate);
  if (!m.dropped.empty()) spdlog::warn("{}: repaired: removed {} duplicate face(s)", m.file->shown(), m.dropped.size());
  if (m.vertices < m.file->vertices())
    spdlog::warn("{}: repaired: removed {} unreferenced vertex(es)", m.file->shown(), m.file->vertices() - m.vertices);
}

}  // namespace gimforge::jobs
