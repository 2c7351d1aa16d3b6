#include "kernels/core/hausdorff.h"

#include <atomic>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "kernels/core/errors.h"
#include "kernels/core/surface_sampling.h"

namespace gimforge {

std::vector<double> distances_in_blocks(std::span<const Vec3> points, const DistanceBlock& block,
                                        const ProgressCallback& progress, std::string_view stage) {
  std::vector<double> dist(points.size());
  constexpr std::size_t kBlock = kDistanceBlock;
  const std::size_t blocks = (points.size() + kBlock - 1) / kBlock;
  std::atomic<std::size_t> done{0};
  std::atomic<bool> cancelled{false};
  report_progress(progress, stage, 0.0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks, 1), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t b = range.begin(); b < range.end() && !cancelled.load(std::memory_order_relaxed); ++b) {
      const std::size_t first = b * kBlock, last = std::min(points.size(), first + kBlock);
      block(points.subspan(first, last - first), std::span<double>(dist).subspan(first, last - first));
      const std::size_t now = done.fetch_add(1, std::memory_order_relaxed) + 1;
      // Only the thread that completes a 1/64 step reports; the callback is called from worker threads.
      if (progress && (now * 64 / blocks) != ((now - 1) * 64 / blocks) &&
          !progress(stage, static_cast<double>(now) / static_cast<double>(blocks)))
        cancelled = true;
    }
  });
  if (cancelled) throw Cancelled(std::string(stage) + ": cancelled");
  for (std::size_t i = 0; i < dist.size(); ++i)
    if (!std::isfinite(dist[i]))
      throw NumericalError(fmt::format("{}: no closest point found for point {} ({}, {}, {}); the queries run in "
                                       "float32, whose squared distances overflow beyond ~10^18: scale such a mesh down",
                                       stage, i, points[i].x(), points[i].y(), points[i].z()));
  return dist;
}

std::vector<double> distances_to_surface(std::span<const Vec3> points, const TriangleBvh& target,
                                         const ProgressCallback& progress, std::string_view stage) {
  return distances_in_blocks(
      points,
      [&target](std::span<const Vec3> block, std::span<double> out) {
        std::uint32_t last_face = kNoFace;
        for (std::size_t i = 0; i < block.size(); ++i) {
          // The previous answer's face bounds this query from above: exact, and usually tight.
          const double bound = last_face == kNoFace ? std::numeric_limits<double>::infinity()
                                                    : target.distance_to_face(block[i], last_face);
          const ClosestPoint cp = target.closest_point(block[i], bound);
          out[i] = cp.distance;
          last_face = cp.face;
        }
      },
      progress, stage);
}

OneSidedDistance summarize_distances(std::span<const double> distances, std::size_t area_samples) {
  OneSidedDistance r;
  r.area_samples = area_samples;
  r.vertex_samples = distances.size() - area_samples;
  long double sum = 0.0L;
  long double sum2 = 0.0L;
  for (std::size_t i = 0; i < distances.size(); ++i) {
    const double d = distances[i];
    r.max = std::max(r.max, d);
    if (i < area_samples) {
      sum += d;
      sum2 += static_cast<long double>(d) * d;
    }
  }
  if (area_samples > 0) {
    r.mean = static_cast<double>(sum / static_cast<long double>(area_samples));
    r.rms = static_cast<double>(std::sqrt(sum2 / static_cast<long double>(area_samples)));
  }
  return r;
}

MeasuredPoints measured_points(MeshView from, const HausdorffOptions& options) {
  MeasuredPoints m;
  m.points = sample_surface(from, {options.samples, options.seed}).points;
  m.area_samples = m.points.size();
  if (options.include_vertices) {
    std::vector<char> referenced(from.positions.size(), 0);
    for (const Face& t : from.faces)
      for (std::uint32_t v : t) referenced[v] = 1;
    for (std::size_t v = 0; v < referenced.size(); ++v)
      if (referenced[v]) m.points.push_back(from.positions[v]);
  }
  return m;
}

OneSidedDistance one_sided_distance(MeshView from, const TriangleBvh& to, const HausdorffOptions& options,
                                    std::string_view stage) {
  const MeasuredPoints m = measured_points(from, options);
  const std::vector<double> dist = distances_to_surface(m.points, to, options.progress, stage);
  return summarize_distances(dist, m.area_samples);
}

HausdorffResult combine_directions(double diag, const OneSidedDistance& ab, const OneSidedDistance& ba) {
  HausdorffResult r;
  r.diag = diag;
  r.ab = ab;
  r.ba = ba;
  r.max = std::max(r.ab.max, r.ba.max);
  r.rms = std::sqrt((r.ab.rms * r.ab.rms + r.ba.rms * r.ba.rms) / 2.0);
  r.psnr = psnr_db(r.diag, r.rms);
  return r;
}

double psnr_db(double diag, double d) {
  return d > 0.0 ? 20.0 * std::log10(diag / d) : std::numeric_limits<double>::infinity();
}

HausdorffResult symmetric_hausdorff(const EmbreeDevice& device, MeshView a, MeshView b,
                                    const HausdorffOptions& options) {
  if (options.samples == 0) throw InvalidInput("symmetric_hausdorff: the number of samples must be positive");
  const TriangleBvh bvh_a(device, a);
  const TriangleBvh bvh_b(device, b);
  const OneSidedDistance ab = one_sided_distance(a, bvh_b, options, "distance A->B");
  const OneSidedDistance ba = one_sided_distance(b, bvh_a, options, "distance B->A");
  return combine_directions(bounding_box(a).diagonal(), ab, ba);
}

}  // namespace gimforge
