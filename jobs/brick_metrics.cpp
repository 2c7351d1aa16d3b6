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

#include "io/input_file.h"
#include "io/ply_ranges.h"
#include "jobs/distributed_metrics.h"
#include "jobs/scan_bricks.h"
#include "kernels/core/errors.h"
#include "kernels/core/surface_sampling.h"
#include "mpi/agree.h"

namespace gimforge::jobs {
namespace {

/// The ghost margin as a fraction of the answering mesh's bounding-box diagonal.
constexpr double kGhostMargin = 0.005;
/// Vertex samples answered per batch (bounds the memory of that pass).
constexpr std::size_t kVertexBatch = 1u << 20;
constexpr double kInf = std::numeric_limits<double>::infinity();

/// Seconds since `start`, for the debug log of each phase.
double since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace


namespace {

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

}  // namespace

/// The samples of X (see the file comment).
BrickSamples brick_samples(const mpi::Comm& comm, const ScannedMesh& x, const Vec3& origin, const HausdorffOptions& options) {
  TriMesh slice;
  SampleSlice samples;
  double largest = 0.0, edge = 0.0;
  std::vector<double> areas;
  mpi::run_agreed(comm, [&] {
    slice = read_face_slice(x, comm.rank(), comm.size(), origin);
    areas.resize(slice.faces.size());
    for (std::size_t f = 0; f < areas.size(); ++f) {
      areas[f] = triangle_area(slice, f);
      largest = std::isfinite(areas[f]) && std::isfinite(largest) ? std::max(largest, areas[f]) : kInf;
      edge = std::max(edge, longest_edge(slice, f));
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
  samples = sample_slice(slice, areas, quantize, before, total, {options.samples, options.seed});
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

namespace {

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

}  // namespace

std::vector<double> brick_distances(const mpi::Comm& comm, const BrickMesh& brick, const TriangleBvh* bvh,
                                    std::span<const Vec3> samples, std::string_view stage) {
  const auto mine = static_cast<std::size_t>(comm.rank());
  // This brick's samples, in index order.
  std::vector<Vec3> held;
  for (const Vec3& p : samples)
    if (brick.partition.brick_of(p) == mine) held.push_back(p);
  std::vector<double> d;
  mpi::run_agreed(comm, [&] { d = local_distances(bvh, held, stage); });
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
  const std::vector<double> forwarded = answer_everywhere(comm, bvh, std::move(open_points), stage);
  for (std::size_t k = 0; k < open_index.size(); ++k) area[open_index[k]] = forwarded[k];
  return area;
}

namespace {

OneSidedDistance one_direction(const mpi::Comm& comm, const EmbreeDevice& device, const ScannedMesh& x,
                               const std::vector<Vec3>& samples, const ScannedMesh& y, double y_longest_edge,
                               const Vec3& origin, const HausdorffOptions& options, std::string_view stage) {
  report_progress(comm.rank() == 0 ? options.progress : ProgressCallback{}, stage, 0.0);
  const auto start = std::chrono::steady_clock::now();
  const BrickMesh brick = read_brick(comm, y, origin, {kGhostMargin, y_longest_edge, false});
  spdlog::debug("{}: rank {} read its brick in {:.2f} s", stage, comm.rank(), since(start));
  const auto mine = static_cast<std::size_t>(comm.rank());
  std::optional<TriangleBvh> bvh;
  mpi::run_agreed(comm, [&] {
    if (!brick.mesh.faces.empty()) bvh.emplace(device, brick.mesh);
  });
  const TriangleBvh* target = bvh ? &*bvh : nullptr;
  std::vector<double> area = brick_distances(comm, brick, target, samples, stage);
  spdlog::debug("{}: rank {} answered its samples at {:.2f} s", stage, comm.rank(), since(start));
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
  spdlog::debug("{}: rank {} answered its vertices at {:.2f} s; forwarded {} vertices", stage, comm.rank(), since(start),
                open_vertices.size() / 3);
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
    s.vertex_samples = options.include_vertices ? x.vertices : 0;
    summary = to_summary(s);
  });
  comm.broadcast(summary, 0);
  report_progress(comm.rank() == 0 ? options.progress : ProgressCallback{}, stage, 1.0);
  return from_summary(summary);
}

}  // namespace

bool readable_in_bricks(const std::filesystem::path& a, const std::filesystem::path& b) {
  return io::PlyTriangleFile::open(a).has_value() && io::PlyTriangleFile::open(b).has_value();
}

HausdorffResult brick_hausdorff(const mpi::Comm& comm, const EmbreeDevice& device, const std::filesystem::path& a,
                                const std::filesystem::path& b, const HausdorffOptions& options,
                                const std::vector<std::uint64_t>& dropped_a, bool warn) {
  if (options.samples == 0) throw InvalidInput("symmetric_hausdorff: the number of samples must be positive");
  const std::string stamp_a = io::file_stamp(a), stamp_b = io::file_stamp(b);  // require_unchanged
  std::optional<io::PlyTriangleFile> fa, fb;
  mpi::run_agreed(comm, [&] {
    fa = io::PlyTriangleFile::open(a);
    fb = io::PlyTriangleFile::open(b);
    if (!fa || !fb) throw InvalidInput("brick_hausdorff: both meshes must be binary PLY triangle files");
  });
  const auto start = std::chrono::steady_clock::now();
  ScannedMesh sa = scan_mesh(comm, *fa);
  sa.dropped = dropped_a;
  sa.faces -= std::min<std::uint64_t>(sa.faces, dropped_a.size());
  const ScannedMesh sb = scan_mesh(comm, *fb);
  spdlog::debug("rank {}: scanned both files in {:.2f} s", comm.rank(), since(start));
  if (comm.rank() == 0 && warn)  // what `metrics` says when it loads a file whole (jobs/load_mesh.cpp)
    for (const ScannedMesh* m : {static_cast<const ScannedMesh*>(&sa), &sb}) warn_repairs(*m);
  // A's local frame, as `metrics` translates both meshes (jobs/load_mesh.h local_frame_origin).
  const Vec3 center = sa.box.center();
  const Vec3 origin = center.allFinite() ? center : Vec3::Zero();
  BrickSamples xa = brick_samples(comm, sa, origin, options);
  BrickSamples xb = brick_samples(comm, sb, origin, options);
  spdlog::debug("rank {}: sampled both meshes at {:.2f} s", comm.rank(), since(start));
  const OneSidedDistance ab = one_direction(comm, device, sa, xa.points, sb, xb.longest_edge, origin, options, "distance A->B");
  xa.points = {};
  const OneSidedDistance ba = one_direction(comm, device, sb, xb.points, sa, xa.longest_edge, origin, options, "distance B->A");
  require_unchanged(comm, a, fa->shown(), stamp_a);
  require_unchanged(comm, b, fb->shown(), stamp_b);
  const BoundingBox local{sa.box.min - origin, sa.box.max - origin};
  return combine_directions(local.diagonal(), ab, ba);
}

}  // namespace gimforge::jobs
