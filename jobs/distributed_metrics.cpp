#include "jobs/distributed_metrics.h"

#include <cstddef>
#include <cstring>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "kernels/core/errors.h"
#include "mpi/agree.h"

namespace gimforge::jobs {
namespace {

constexpr int kDistancesTag = 71;

/// The points [first, last) this rank answers: whole blocks, split as evenly as blocks allow.
std::pair<std::size_t, std::size_t> my_share(std::size_t points, int rank, int size) {
  const std::size_t blocks = (points + kDistanceBlock - 1) / kDistanceBlock;
  const auto r = static_cast<std::size_t>(rank), n = static_cast<std::size_t>(size);
  const std::size_t first = std::min(points, blocks * r / n * kDistanceBlock);
  const std::size_t last = std::min(points, blocks * (r + 1) / n * kDistanceBlock);
  return {first, last};
}

/// One direction: this rank's distances, gathered on rank 0 in index order and summarized there; the
/// summary is then broadcast.
OneSidedDistance one_direction(const mpi::Comm& comm, MeshView from, const TriangleBvh& to, const HausdorffOptions& options,
                               std::string_view stage) {
  MeasuredPoints m;
  std::vector<double> mine;
  mpi::run_agreed(comm, [&] {
    m = measured_points(from, options);
    const auto [first, last] = my_share(m.points.size(), comm.rank(), comm.size());
    const ProgressCallback progress = comm.rank() == 0 ? options.progress : ProgressCallback{};
    mine = distances_to_surface(std::span<const Vec3>(m.points).subspan(first, last - first), to, progress, stage);
  });
  std::vector<double> summary(5, 0.0);
  if (comm.rank() == 0) {
    std::vector<double> all(m.points.size());
    std::copy(mine.begin(), mine.end(), all.begin());
    for (int r = 1; r < comm.size(); ++r) {
      const auto [first, last] = my_share(all.size(), r, comm.size());
      const mpi::Message msg = comm.recv(r, kDistancesTag);
      if (msg.data.size() != (last - first) * sizeof(double))
        throw Error(fmt::format("{}: rank {} sent {} bytes of distances, not {}", stage, r, msg.data.size(),
                                (last - first) * sizeof(double)));
      std::memcpy(all.data() + first, msg.data.data(), msg.data.size());
    }
    const OneSidedDistance d = summarize_distances(all, m.area_samples);
    summary = {d.max, d.mean, d.rms, static_cast<double>(d.area_samples), static_cast<double>(d.vertex_samples)};
  } else {
    comm.send(std::as_bytes(std::span<const double>(mine)), 0, kDistancesTag);
  }
  comm.broadcast(summary, 0);
  OneSidedDistance d;
  d.max = summary[0];
  d.mean = summary[1];
  d.rms = summary[2];
  d.area_samples = static_cast<std::size_t>(summary[3]);
  d.vertex_samples = static_cast<std::size_t>(summary[4]);
  return d;
}

}  // namespace

HausdorffResult distributed_hausdorff(const mpi::Comm& comm, const EmbreeDevice& device, MeshView a, MeshView b,
                                      const HausdorffOptions& options) {
  if (comm.size() == 1) return symmetric_hausdorff(device, a, b, options);
  if (options.samples == 0) throw InvalidInput("symmetric_hausdorff: the number of samples must be positive");
  std::optional<TriangleBvh> bvh_a, bvh_b;
  mpi::run_agreed(comm, [&] {
    bvh_a.emplace(device, a);
    bvh_b.emplace(device, b);
  });
  const OneSidedDistance ab = one_direction(comm, a, *bvh_b, options, "distance A->B");
  const OneSidedDistance ba = one_direction(comm, b, *bvh_a, options, "distance B->A");
  return combine_directions(bounding_box(a).diagonal(), ab, ba);
}

}  // namespace gimforge::jobs
