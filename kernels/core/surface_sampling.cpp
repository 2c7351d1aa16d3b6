#include "kernels/core/surface_sampling.h"

#include <algorithm>
#include <bit>
#include <cmath>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "kernels/core/errors.h"

namespace gimforge {
namespace {

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

}  // namespace

double uniform01(std::uint64_t seed, std::uint64_t stream) {
  // 53 random bits -> [0, 1).
  return static_cast<double>(splitmix64(seed ^ splitmix64(stream)) >> 11) * 0x1.0p-53;
}

AreaQuanta::AreaQuanta(double largest_area, std::uint64_t faces) {
  if (!(largest_area > 0.0) || !std::isfinite(largest_area) || faces == 0)
    throw InvalidInput(fmt::format("sample_surface: the surface has no area to sample (largest face area {}, {} faces)",
                                   largest_area, faces));
  int x = 0;
  (void)std::frexp(largest_area, &x);  // largest_area < 2^x
  const int faces_log2 = static_cast<int>(std::bit_width(faces - 1));  // faces <= 2^faces_log2
  exponent = 62 - faces_log2 - x;  // each face < 2^(62 - faces_log2), so the sum < 2^62
  scale = std::ldexp(1.0, exponent);
}

std::uint64_t AreaQuanta::operator()(double area) const {
  // scale is a power of two: the product is exact; +0.5 then truncation rounds to nearest (ties up).
  return static_cast<std::uint64_t>(area * scale + 0.5);
}

namespace {

/// The cumulative quanta (of `total`) where sample i of n lands: (i + u_i)/n · total, in [0, total).
std::uint64_t sample_target(std::size_t i, std::size_t n, std::uint64_t total, std::uint64_t seed) {
  const long double u = uniform01(seed, 3 * static_cast<std::uint64_t>(i));
  const long double t = (static_cast<long double>(i) + u) / static_cast<long double>(n) * static_cast<long double>(total);
  return t >= static_cast<long double>(total) ? total - 1 : static_cast<std::uint64_t>(t);
}

/// The first sample whose target is >= q (targets grow with the index).
std::size_t first_sample_at(std::uint64_t q, std::size_t n, std::uint64_t total, std::uint64_t seed) {
  std::size_t lo = 0, hi = n;
  while (lo < hi) {
    const std::size_t mid = lo + (hi - lo) / 2;
    if (sample_target(mid, n, total, seed) < q) lo = mid + 1; else hi = mid;
  }
  return lo;
}

}  // namespace

SampleSlice sample_slice(MeshView slice, std::span<const double> areas, const AreaQuanta& quantize,
                         std::uint64_t before, std::uint64_t total, const SurfaceSamplingOptions& options) {
  const std::size_t nf = slice.faces.size(), n = options.samples;
  if (areas.size() != nf) throw InvalidInput("sample_slice: one area per face is needed");
  std::vector<std::uint64_t> cum(nf + 1, 0);
  for (std::size_t f = 0; f < nf; ++f) cum[f + 1] = cum[f] + quantize(areas[f]);
  SampleSlice out;
  if (total == 0 || n == 0 || cum[nf] == 0) return out;
  const std::size_t first = first_sample_at(before, n, total, options.seed);
  const std::size_t last = first_sample_at(before + cum[nf], n, total, options.seed);
  out.points.resize(last - first);
  out.faces.resize(last - first);
  out.index.resize(last - first);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(first, last, 4096), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t i = range.begin(); i < range.end(); ++i) {
      const std::uint64_t s = 3 * static_cast<std::uint64_t>(i);
      const std::uint64_t target = sample_target(i, n, total, options.seed) - before;
      // The face whose cumulative range [cum[f], cum[f+1]) holds the target (never one without quanta).
      const auto it = std::upper_bound(cum.begin() + 1, cum.end(), target);
      const auto f = static_cast<std::size_t>(it - cum.begin()) - 1;
      // Uniform point in the triangle (Osada et al. 2002).
      const double r1 = std::sqrt(uniform01(options.seed, s + 1));
      const double r2 = uniform01(options.seed, s + 2);
      const Face& t = slice.faces[f];
      const std::size_t k = i - first;
      out.points[k] = (1.0 - r1) * slice.positions[t[0]] + r1 * (1.0 - r2) * slice.positions[t[1]] +
                      r1 * r2 * slice.positions[t[2]];
      out.faces[k] = static_cast<std::uint32_t>(f);
      out.index[k] = i;
    }
  });
  return out;
}

SurfaceSamples sample_surface(MeshView mesh, const SurfaceSamplingOptions& options) {
  const std::size_t nf = mesh.faces.size();
  std::vector<double> area(nf);
  double largest = 0.0;
  for (std::size_t f = 0; f < nf; ++f) {
    area[f] = triangle_area(mesh, f);
    if (!std::isfinite(area[f])) largest = area[f];
    if (std::isfinite(largest)) largest = std::max(largest, area[f]);
  }
  const AreaQuanta quantize(largest, nf);
  std::uint64_t total = 0;
  for (std::size_t f = 0; f < nf; ++f) total += quantize(area[f]);
  SampleSlice slice = sample_slice(mesh, area, quantize, 0, total, options);
  return {std::move(slice.points), std::move(slice.faces)};
}

}  // namespace gimforge
