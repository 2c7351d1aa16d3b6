#include "jobs/distributed_metrics.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "kernels/core/errors.h"
#include "mpi/agree.h"

namespace gimforge::jobs {
namespace {

constexpr int kDistancesTag = 71;

/// The points [first, last) that member `index` of a group of `members` ranks answers: whole blocks, split
/// as evenly as blocks allow.
std::pair<std::size_t, std::size_t> share(std::size_t points, int index, int members) {
  const std::size_t blocks = (points + kDistanceBlock - 1) / kDistanceBlock;
  const auto r = static_cast<std::size_t>(index), n = static_cast<std::size_t>(members);
  const std::size_t first = std::min(points, blocks * r / n * kDistanceBlock);
  const std::size_t last = std::min(points, blocks * (r + 1) / n * kDistanceBlock);
  return {first, last};
}

/// Ranks [0, ab) measure A→B, ranks [ab, size) B→A, so each rank builds one BVH (the other direction's
/// target). The split follows the estimated work of each direction: its BVH (≈ 0.5 per face) and its
/// queries (≈ 1 per point), relative costs measured on a 10M-face scan (BENCHMARKS.md).
int ab_ranks(int size, MeshView a, MeshView b, const HausdorffOptions& options) {
  const auto points = [&](MeshView m) {
    return static_cast<double>(options.samples) + (options.include_vertices ? static_cast<double>(m.positions.size()) : 0.0);
  };
  const double ab = 0.5 * static_cast<double>(b.faces.size()) + points(a);
  const double ba = 0.5 * static_cast<double>(a.faces.size()) + points(b);
  const long ranks = std::lround(static_cast<double>(size) * ab / (ab + ba));
  return static_cast<int>(std::clamp<long>(ranks, 1, size - 1));
}


}  // namespace

std::vector<double> to_summary(const OneSidedDistance& d) {
  return {d.max, d.mean, d.rms, static_cast<double>(d.area_samples), static_cast<double>(d.vertex_samples)};
}

OneSidedDistance from_summary(std::span<const double> v) {
  OneSidedDistance d;
  d.max = v[0];
  d.mean = v[1];
  d.rms = v[2];
  d.area_samples = static_cast<std::size_t>(v[3]);
  d.vertex_samples = static_cast<std::size_t>(v[4]);
  return d;
}

HausdorffResult distributed_hausdorff(const mpi::Comm& comm, const EmbreeDevice& device, MeshView a, MeshView b,
                                      const HausdorffOptions& options) {
  if (comm.size() == 1) return symmetric_hausdorff(device, a, b, options);
  if (options.samples == 0) throw InvalidInput("symmetric_hausdorff: the number of samples must be positive");
  const int ab = ab_ranks(comm.size(), a, b, options);
  const bool mine_ab = comm.rank() < ab;
  const int index = mine_ab ? comm.rank() : comm.rank() - ab, members = mine_ab ? ab : comm.size() - ab;
  const std::string_view stage = mine_ab ? "distance A->B" : "distance B->A";
  // This rank's share of its direction; rank 0 (A→B) also draws the B→A points, to place what it receives.
  MeasuredPoints points, other;
  std::vector<double> mine;
  mpi::run_agreed(comm, [&] {
    const TriangleBvh target(device, mine_ab ? b : a);
    points = measured_points(mine_ab ? a : b, options);
    if (comm.rank() == 0) other = measured_points(b, options);
    const auto [first, last] = share(points.points.size(), index, members);
    const ProgressCallback progress = comm.rank() == 0 ? options.progress : ProgressCallback{};
    mine = distances_to_surface(std::span<const Vec3>(points.points).subspan(first, last - first), target, progress, stage);
  });
  std::vector<double> summary(10, 0.0);
  if (comm.rank() == 0) {
    std::vector<double> d_ab(points.points.size()), d_ba(other.points.size());
    std::copy(mine.begin(), mine.end(), d_ab.begin());
    for (int r = 1; r < comm.size(); ++r) {
      const bool r_ab = r < ab;
      std::vector<double>& all = r_ab ? d_ab : d_ba;
      const auto [first, last] = share(all.size(), r_ab ? r : r - ab, r_ab ? ab : comm.size() - ab);
      const mpi::Message msg = comm.recv(r, kDistancesTag);
      if (msg.data.size() != (last - first) * sizeof(double))
        throw Error(fmt::format("metrics: rank {} sent {} bytes of distances, not {}", r, msg.data.size(),
                                (last - first) * sizeof(double)));
      std::memcpy(all.data() + first, msg.data.data(), msg.data.size());
    }
    const OneSidedDistance x = summarize_distances(d_ab, points.area_samples);
    const OneSidedDistance y = summarize_distances(d_ba, other.area_samples);
    summary = to_summary(x);
    const std::vector<double> other_summary = to_summary(y);
    summary.insert(summary.end(), other_summary.begin(), other_summary.end());
  } else {
    comm.send(std::as_bytes(std::span<const double>(mine)), 0, kDistancesTag);
  }
  comm.broadcast(summary, 0);
  return combine_directions(bounding_box(a).diagonal(), from_summary(std::span<const double>(summary).first(5)),
                            from_summary(std::span<const double>(summary).subspan(5)));
}

}  // namespace gimforge::jobs
