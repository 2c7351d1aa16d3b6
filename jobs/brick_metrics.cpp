#include "jobs/brick_metrics.h"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "io/ply_ranges.h"
#include "kernels/core/errors.h"
#include "kernels/core/surface_sampling.h"
#include "kernels/scan/bricks.h"
#include "mpi/agree.h"

namespace gimforge::jobs {
namespace {

constexpr int kGatherTag = 73;
/// The ghost margin as a fraction of the answering mesh's bounding-box diagonal.
constexpr double kGhostMargin = 0.005;
/// Histogram cells along the box's longest side.
constexpr double kHistogramCells = 64.0;
/// Vertex samples answered per batch (bounds the memory of that pass).
constexpr std::size_t kVertexBatch = 1u << 20;
constexpr double kInf = std::numeric_limits<double>::infinity();

/// Seconds since `start`, for the debug log of each phase.
double since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

bool degenerate(const Face& t) { return t[0] == t[1] || t[1] == t[2] || t[0] == t[2]; }

/// The part [first, last) of `count` items that rank r of `size` takes.
std::pair<std::uint64_t, std::uint64_t> slice_of(std::uint64_t count, int r, int size) {
  const auto R = static_cast<std::uint64_t>(r), P = static_cast<std::uint64_t>(size);
  return {count * R / P, count * (R + 1) / P};
}

/// Rank 0: every rank's `mine` concatenated in rank order; elsewhere empty.
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

std::vector<double> flatten(std::span<const Vec3> points) {
  std::vector<double> out(3 * points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    for (int k = 0; k < 3; ++k) out[3 * i + static_cast<std::size_t>(k)] = points[i][k];
  return out;
}

std::vector<Vec3> unflatten(std::span<const double> v) {
  std::vector<Vec3> out(v.size() / 3);
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = Vec3(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
  return out;
}

/// What every rank knows about one mesh after a pass over all its faces and its slice of the vertices.
struct MeshScan {
  const io::PlyTriangleFile* file{nullptr};
  std::vector<std::uint8_t> referenced;  ///< per vertex: used by a face with three distinct vertices
  std::uint64_t faces{0};                ///< faces with three distinct vertices
  std::uint64_t vertices{0};             ///< referenced vertices
  BoundingBox box;                       ///< of the referenced vertices, in the file's frame
};

MeshScan scan_mesh(const mpi::Comm& comm, const io::PlyTriangleFile& file) {
  MeshScan m;
  m.file = &file;
  mpi::run_agreed(comm, [&] {
    m.referenced.assign(static_cast<std::size_t>(file.vertices()), 0);
    file.read_faces(0, file.faces(), [&](std::uint64_t, std::span<const Face> faces) {
      for (const Face& t : faces) {
        if (degenerate(t)) continue;
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
  return m;
}

/// A mesh of some of a file's faces: positions of the vertices they use (translated by −origin), faces
/// re-indexed into them.
struct Piece {
  TriMesh mesh;
};

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

/// Reads the positions of the vertices `piece`'s faces use (translated by −origin) and re-indexes the faces
/// into them (the faces hold file vertex indices before).
void fill_positions(const io::PlyTriangleFile& file, const Vec3& origin, Piece& piece) {
  VertexSet used(file.vertices());
  for (const Face& t : piece.mesh.faces)
    for (std::uint32_t v : t) used.insert(v);
  const std::vector<std::uint32_t> ids = used.finish();
  for (Face& t : piece.mesh.faces)
    for (std::uint32_t& v : t) v = used.rank(v);
  piece.mesh.positions = file.read_positions(ids);
  for (Vec3& p : piece.mesh.positions) p -= origin;
}

double longest_edge(const TriMesh& m, std::size_t f) {
  const Face& t = m.faces[f];
  return std::sqrt(std::max({(m.positions[t[1]] - m.positions[t[0]]).squaredNorm(),
                             (m.positions[t[2]] - m.positions[t[1]]).squaredNorm(),
                             (m.positions[t[0]] - m.positions[t[2]]).squaredNorm()}));
}

/// A mesh's samples in index order (on every rank) and its longest edge.
struct Sampled {
  std::vector<Vec3> points;
  double longest_edge{0.0};
};

/// The samples of X (see the file comment).
Sampled sample_everywhere(const mpi::Comm& comm, const MeshScan& x, const Vec3& origin, const HausdorffOptions& options) {
  Piece slice;
  SampleSlice samples;
  double largest = 0.0, edge = 0.0;
  std::vector<double> areas;
  mpi::run_agreed(comm, [&] {
    const auto [first, last] = slice_of(x.file->faces(), comm.rank(), comm.size());
    x.file->read_faces(first, last, [&](std::uint64_t, std::span<const Face> faces) {
      for (const Face& t : faces)
        if (!degenerate(t)) slice.mesh.faces.push_back(t);
    });
    fill_positions(*x.file, origin, slice);
    areas.resize(slice.mesh.faces.size());
    for (std::size_t f = 0; f < areas.size(); ++f) {
      areas[f] = triangle_area(slice.mesh, f);
      largest = std::isfinite(areas[f]) && std::isfinite(largest) ? std::max(largest, areas[f]) : kInf;
      edge = std::max(edge, longest_edge(slice.mesh, f));
    }
  });
  largest = comm.allreduce(largest, mpi::ReduceOp::kMax);
  if (!(largest > 0.0) || !std::isfinite(largest))  // the same on every rank: rank 0 says why
    mpi::run_agreed(comm, [&] {
      if (comm.rank() == 0)
        throw InvalidInput(fmt::format("{}: the surface has no area (the metric samples it by area)", x.file->shown()));
    });
  const AreaQuanta quantize(largest, x.faces);
  std::vector<std::uint64_t> totals(static_cast<std::size_t>(comm.size()), 0);
  for (const double area : areas) totals[static_cast<std::size_t>(comm.rank())] += quantize(area);
  totals = comm.allreduce(std::move(totals), mpi::ReduceOp::kSum);
  std::uint64_t before = 0, total = 0;
  for (int r = 0; r < comm.size(); ++r) {
    if (r < comm.rank()) before += totals[static_cast<std::size_t>(r)];
    total += totals[static_cast<std::size_t>(r)];
  }
  samples = sample_slice(slice.mesh, areas, quantize, before, total, {options.samples, options.seed});
  areas = {};
  slice = {};
  std::vector<double> all = gather_at_root(comm, flatten(samples.points));
  comm.broadcast(all, 0);
  if (all.size() != 3 * options.samples)  // the same on every rank
    mpi::run_agreed(comm, [&] {
      if (comm.rank() == 0)
        throw Error(fmt::format("metrics: {} samples of {} drawn, not {}", all.size() / 3, x.file->shown(), options.samples));
    });
  return {unflatten(all), comm.allreduce(edge, mpi::ReduceOp::kMax)};
}

/// The faces of Y that rank r holds (its brick and the ghost layer) and what certifies its answers.
struct Brick {
  Piece piece;
  BrickPartition partition;
  BoundingBox bounds;  ///< brick r's box
  double margin{0.0};  ///< g
  double longest_edge{0.0};

  /// Exact when d ≤ g − L − dist(p, bounds).
  [[nodiscard]] bool certified(const Vec3& p, double d) const {
    const Vec3 outside = (bounds.min - p).cwiseMax(p - bounds.max).cwiseMax(Vec3::Zero());
    return d <= margin - longest_edge - outside.norm();
  }
};

Brick load_brick(const mpi::Comm& comm, const MeshScan& y, double y_longest_edge, const Vec3& origin) {
  Brick b;
  b.longest_edge = y_longest_edge;
  const BoundingBox box{y.box.min - origin, y.box.max - origin};
  const Vec3 extent = box.max - box.min;
  const double cell = std::max(extent.maxCoeff(), std::numeric_limits<double>::min()) / kHistogramCells;
  std::array<std::uint32_t, 3> dims{};
  for (int k = 0; k < 3; ++k)
    dims[static_cast<std::size_t>(k)] = static_cast<std::uint32_t>(std::clamp(std::ceil(extent[k] / cell), 1.0, kHistogramCells));
  CentroidHistogram histogram(box, dims);
  const auto [first, last] = slice_of(y.file->vertices(), comm.rank(), comm.size());
  mpi::run_agreed(comm, [&] {
    y.file->read_vertices(first, last, [&](std::uint64_t at, std::span<const Vec3> p) {
      for (std::size_t i = 0; i < p.size(); ++i)
        if (y.referenced[at + i]) histogram.add(p[i] - origin);
    });
  });
  histogram.counts() = comm.allreduce(std::move(histogram.counts()), mpi::ReduceOp::kSum);
  b.partition = partition_bricks(histogram, static_cast<std::size_t>(comm.size()));
  const auto mine = static_cast<std::size_t>(comm.rank());
  b.bounds = b.partition.bounds(mine);
  // Wide enough that answers up to kGhostMargin of the diagonal are certified whatever the edge lengths.
  b.margin = kGhostMargin * box.diagonal() + 2.0 * b.longest_edge;
  const BoundingBox near{b.bounds.min - Vec3::Constant(b.margin), b.bounds.max + Vec3::Constant(b.margin)};
  mpi::run_agreed(comm, [&] {
    // Per vertex: 1 = in brick r, 2 = within the margin of it.
    std::vector<std::uint8_t> where(static_cast<std::size_t>(y.file->vertices()), 0);
    y.file->read_vertices(0, y.file->vertices(), [&](std::uint64_t at, std::span<const Vec3> p) {
      for (std::size_t i = 0; i < p.size(); ++i) {
        if (!y.referenced[at + i]) continue;
        const Vec3 q = p[i] - origin;
        const bool inside = (q.array() >= near.min.array()).all() && (q.array() <= near.max.array()).all();
        where[at + i] = static_cast<std::uint8_t>((b.partition.brick_of(q) == mine ? 1 : 0) | (inside ? 2 : 0));
      }
    });
    y.file->read_faces(0, y.file->faces(), [&](std::uint64_t, std::span<const Face> faces) {
      for (std::size_t i = 0; i < faces.size(); ++i) {
        const Face& t = faces[i];
        if (degenerate(t)) continue;
        const bool own = (where[t[0]] & 1) != 0;
        if (!own && ((where[t[0]] | where[t[1]] | where[t[2]]) & 2) == 0) continue;
        b.piece.mesh.faces.push_back(t);
      }
    });
    fill_positions(*y.file, origin, b.piece);
  });
  spdlog::debug("{}: rank {} holds {} faces (brick and ghosts) of {}", y.file->shown(), comm.rank(),
                b.piece.mesh.faces.size(), y.faces);
  return b;
}

/// Distances from `points` to the brick's faces (+∞ where the brick has none).
std::vector<double> local_distances(const TriangleBvh* bvh, std::span<const Vec3> points, std::string_view stage) {
  if (bvh == nullptr || points.empty()) return std::vector<double>(points.size(), kInf);
  return distances_to_surface(points, *bvh, {}, stage);
}

/// Answers the points no brick could certify: every rank measures them, the minimum is exact.
std::vector<double> answer_everywhere(const mpi::Comm& comm, const TriangleBvh* bvh, std::vector<double> points_flat,
                                      std::string_view stage) {
  std::vector<double> all = gather_at_root(comm, std::move(points_flat));
  comm.broadcast(all, 0);
  std::vector<double> d;
  mpi::run_agreed(comm, [&] { d = local_distances(bvh, unflatten(all), stage); });
  return comm.allreduce(std::move(d), mpi::ReduceOp::kMin);
}

OneSidedDistance one_direction(const mpi::Comm& comm, const EmbreeDevice& device, const MeshScan& x,
                               const std::vector<Vec3>& samples, const MeshScan& y, double y_longest_edge,
                               const Vec3& origin, const HausdorffOptions& options, std::string_view stage) {
  report_progress(comm.rank() == 0 ? options.progress : ProgressCallback{}, stage, 0.0);
  const auto start = std::chrono::steady_clock::now();
  const Brick brick = load_brick(comm, y, y_longest_edge, origin);
  spdlog::debug("{}: rank {} read its brick in {:.2f} s", stage, comm.rank(), since(start));
  const auto mine = static_cast<std::size_t>(comm.rank());
  // Area samples: this brick's, in index order.
  std::vector<Vec3> held;
  for (const Vec3& p : samples)
    if (brick.partition.brick_of(p) == mine) held.push_back(p);
  std::optional<TriangleBvh> bvh;
  std::vector<double> d;
  mpi::run_agreed(comm, [&] {
    if (!brick.piece.mesh.faces.empty()) bvh.emplace(device, brick.piece.mesh);
    d = local_distances(bvh ? &*bvh : nullptr, held, stage);
  });
  const TriangleBvh* target = bvh ? &*bvh : nullptr;
  spdlog::debug("{}: rank {} built its BVH and answered its samples at {:.2f} s", stage, comm.rank(), since(start));
  for (std::size_t i = 0; i < held.size(); ++i)
    if (!brick.certified(held[i], d[i])) d[i] = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> answers = gather_at_root(comm, std::move(d));
  // Rank 0 places them (it knows every sample's brick) and names the uncertified ones.
  std::vector<double> area(comm.rank() == 0 ? samples.size() : 0);
  std::vector<double> open_points;
  std::vector<std::size_t> open_index;
  if (comm.rank() == 0) {
    std::vector<std::vector<std::size_t>> of_brick(static_cast<std::size_t>(comm.size()));
    for (std::size_t i = 0; i < samples.size(); ++i) of_brick[brick.partition.brick_of(samples[i])].push_back(i);
    std::size_t at = 0;
    for (const auto& indices : of_brick)
      for (const std::size_t i : indices) {
        area[i] = answers[at++];
        if (std::isnan(area[i])) {
          open_index.push_back(i);
          for (int k = 0; k < 3; ++k) open_points.push_back(samples[i][k]);
        }
      }
  }
  const std::vector<double> forwarded = answer_everywhere(comm, target, std::move(open_points), stage);
  for (std::size_t k = 0; k < open_index.size(); ++k) area[open_index[k]] = forwarded[k];
  // Vertices of X in this brick, for the maximum.
  double vertex_max = 0.0;
  std::vector<double> open_vertices;
  mpi::run_agreed(comm, [&] {
    std::vector<Vec3> batch;
    const auto flush = [&] {
      const std::vector<double> dv = local_distances(target, batch, stage);
      for (std::size_t i = 0; i < batch.size(); ++i) {
        if (brick.certified(batch[i], dv[i])) {
          vertex_max = std::max(vertex_max, dv[i]);
        } else {
          for (int k = 0; k < 3; ++k) open_vertices.push_back(batch[i][k]);
        }
      }
      batch.clear();
    };
    if (options.include_vertices)
      x.file->read_vertices(0, x.file->vertices(), [&](std::uint64_t at, std::span<const Vec3> p) {
        for (std::size_t i = 0; i < p.size(); ++i) {
          if (!x.referenced[at + i]) continue;
          const Vec3 q = p[i] - origin;
          if (brick.partition.brick_of(q) == mine) batch.push_back(q);
          if (batch.size() == kVertexBatch) flush();
        }
      });
    flush();
  });
  spdlog::debug("{}: rank {} answered {} samples and its vertices at {:.2f} s; forwarded {} samples and {} vertices",
                stage, comm.rank(), held.size(), since(start), open_index.size(), open_vertices.size() / 3);
  for (const double dv : answer_everywhere(comm, target, std::move(open_vertices), stage))
    vertex_max = std::max(vertex_max, dv);
  vertex_max = comm.allreduce(vertex_max, mpi::ReduceOp::kMax);
  std::vector<double> summary(5, 0.0);
  mpi::run_agreed(comm, [&] {
    if (comm.rank() != 0) return;
    for (std::size_t i = 0; i < area.size(); ++i)
      if (!std::isfinite(area[i]))
        throw NumericalError(fmt::format("{}: no closest point found for sample {}", stage, i));
    OneSidedDistance s = summarize_distances(area, area.size());
    s.max = std::max(s.max, vertex_max);
    summary = {s.max, s.mean, s.rms, static_cast<double>(area.size()),
               options.include_vertices ? static_cast<double>(x.vertices) : 0.0};
  });
  comm.broadcast(summary, 0);
  report_progress(comm.rank() == 0 ? options.progress : ProgressCallback{}, stage, 1.0);
  OneSidedDistance out;
  out.max = summary[0];
  out.mean = summary[1];
  out.rms = summary[2];
  out.area_samples = static_cast<std::size_t>(summary[3]);
  out.vertex_samples = static_cast<std::size_t>(summary[4]);
  return out;
}

}  // namespace

bool readable_in_bricks(const std::filesystem::path& a, const std::filesystem::path& b) {
  return io::PlyTriangleFile::open(a).has_value() && io::PlyTriangleFile::open(b).has_value();
}

HausdorffResult brick_hausdorff(const mpi::Comm& comm, const EmbreeDevice& device, const std::filesystem::path& a,
                                const std::filesystem::path& b, const HausdorffOptions& options) {
  if (options.samples == 0) throw InvalidInput("symmetric_hausdorff: the number of samples must be positive");
  std::optional<io::PlyTriangleFile> fa, fb;
  mpi::run_agreed(comm, [&] {
    fa = io::PlyTriangleFile::open(a);
    fb = io::PlyTriangleFile::open(b);
    if (!fa || !fb) throw InvalidInput("brick_hausdorff: both meshes must be binary PLY triangle files");
  });
  const auto start = std::chrono::steady_clock::now();
  const MeshScan sa = scan_mesh(comm, *fa);
  const MeshScan sb = scan_mesh(comm, *fb);
  spdlog::debug("rank {}: scanned both files in {:.2f} s", comm.rank(), since(start));
  // A's local frame, as `metrics` translates both meshes (jobs/load_mesh.h local_frame_origin).
  const Vec3 center = sa.box.center();
  const Vec3 origin = center.allFinite() ? center : Vec3::Zero();
  Sampled xa = sample_everywhere(comm, sa, origin, options);
  Sampled xb = sample_everywhere(comm, sb, origin, options);
  spdlog::debug("rank {}: sampled both meshes at {:.2f} s", comm.rank(), since(start));
  const OneSidedDistance ab = one_direction(comm, device, sa, xa.points, sb, xb.longest_edge, origin, options, "distance A->B");
  xa.points = {};
  const OneSidedDistance ba = one_direction(comm, device, sb, xb.points, sa, xa.longest_edge, origin, options, "distance B->A");
  const BoundingBox local{sa.box.min - origin, sa.box.max - origin};
  return combine_directions(local.diagonal(), ab, ba);
}

}  // namespace gimforge::jobs
