#include "kernels/core/surface_sampling.h"

#include <algorithm>
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

SurfaceSamples sample_surface(MeshView mesh, const SurfaceSamplingOptions& options) {
  const std::size_t nf = mesh.faces.size();
  std::vector<double> cdf(nf + 1, 0.0);
  for (std::size_t f = 0; f < nf; ++f) cdf[f + 1] = cdf[f] + triangle_area(mesh, f);
  const double total = cdf[nf];
  if (!(total > 0.0) || !std::isfinite(total))
    throw InvalidInput(fmt::format("sample_surface: the surface has no area to sample (total area {})", total));

  const std::size_t n = options.samples;
  SurfaceSamples out;
  out.points.resize(n);
  out.faces.resize(n);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t i = range.begin(); i < range.end(); ++i) {
      const std::uint64_t s = 3 * static_cast<std::uint64_t>(i);
      const double target = (static_cast<double>(i) + uniform01(options.seed, s)) / static_cast<double>(n) * total;
      // First face whose cumulative end exceeds the target (zero-area faces are never chosen).
      auto it = std::upper_bound(cdf.begin() + 1, cdf.end(), target);
      if (it == cdf.end()) --it;
      std::size_t f = static_cast<std::size_t>(it - cdf.begin()) - 1;
      while (f > 0 && !(cdf[f + 1] > cdf[f])) --f;  // guard against rounding onto an empty face
      // Uniform point in the triangle (Osada et al. 2002).
      const double r1 = std::sqrt(uniform01(options.seed, s + 1));
      const double r2 = uniform01(options.seed, s + 2);
      const Face& t = mesh.faces[f];
      out.points[i] = (1.0 - r1) * mesh.positions[t[0]] + r1 * (1.0 - r2) * mesh.positions[t[1]] +
                      r1 * r2 * mesh.positions[t[2]];
      out.faces[i] = static_cast<std::uint32_t>(f);
    }
  });
  return out;
}

}  // namespace gimforge
