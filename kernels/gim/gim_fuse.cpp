#include "kernels/gim/gim_fuse.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge {

FuseStats fuse_cut(std::span<float> positions, std::uint32_t n, const Sideband& sideband,
                   std::vector<Vec3>& displacement, std::span<const std::uint8_t> trusted) {
  const std::size_t pixels = std::size_t{n} * n;
  if (positions.size() != 3 * pixels || (!trusted.empty() && trusted.size() != pixels))
    throw InvalidInput(fmt::format("fusing: {} values and {} trusted flags for a {} × {} geometry image", positions.size(),
                                   trusted.size(), n, n));
  if (n < 2 || (n - 1) % sideband.units_per_side != 0)
    throw InvalidInput(fmt::format("fusing: n − 1 = {} is not a multiple of units_per_side = {}", n - 1,
                                   sideband.units_per_side));
  const std::vector<std::uint32_t> rep = boundary_classes(sideband, n);
  // Sum every class at its representative (only boundary pixels can be glued).
  std::vector<Vec3> sum(pixels, Vec3::Zero()), trusted_sum(pixels, Vec3::Zero());
  std::vector<std::uint32_t> count(pixels, 0), trusted_count(pixels, 0);
  const auto at = [&](std::size_t p) {
    return Vec3(positions[3 * p], positions[3 * p + 1], positions[3 * p + 2]);
  };
  const auto boundary = [&](std::size_t p) {
    const std::size_t i = p % n, j = p / n;
    return i == 0 || j == 0 || i + 1 == n || j + 1 == n;
  };
  for (std::size_t p = 0; p < pixels; ++p) {
    if (!boundary(p)) continue;
    sum[rep[p]] += at(p);
    ++count[rep[p]];
    if (!trusted.empty() && trusted[p] != 0) {
      trusted_sum[rep[p]] += at(p);
      ++trusted_count[rep[p]];
    }
  }
  displacement.assign(pixels, Vec3::Zero());
  FuseStats stats;
  double squares = 0.0;
  std::size_t moved = 0;
  for (std::size_t p = 0; p < pixels; ++p) {
    if (!boundary(p) || count[rep[p]] < 2) continue;
    if (rep[p] == p) ++stats.classes;
    const std::uint32_t r = rep[p];
    const Vec3 mean = trusted_count[r] > 0 ? Vec3(trusted_sum[r] / static_cast<double>(trusted_count[r]))
                                           : Vec3(sum[r] / static_cast<double>(count[r]));
    const Vec3 stored(static_cast<float>(mean.x()), static_cast<float>(mean.y()), static_cast<float>(mean.z()));
    displacement[p] = stored - at(p);
    for (Eigen::Index c = 0; c < 3; ++c) positions[3 * p + static_cast<std::size_t>(c)] = static_cast<float>(stored[c]);
    const double d = displacement[p].norm();
    stats.max_displacement = std::max(stats.max_displacement, d);
    squares += d * d;
    ++moved;
  }
  stats.rms_displacement = moved == 0 ? 0.0 : std::sqrt(squares / static_cast<double>(moved));
  return stats;
}

void diffuse_fusing(std::span<float> positions, std::uint32_t n, std::span<const Vec3> displacement,
                    std::uint32_t band) {
  const std::size_t pixels = std::size_t{n} * n;
  if (positions.size() != 3 * pixels || displacement.size() != pixels)
    throw InvalidInput(fmt::format("error diffusion: {} values and {} displacements for a {} × {} image",
                                   positions.size(), displacement.size(), n, n));
  if (n < 3) return;
  if (band == 0) band = std::max<std::uint32_t>(2, (n - 1) / 16);
  band = std::min(band, (n - 1) / 2);
  const auto weight = [&](std::uint32_t d) {
    if (d >= band) return 0.0;
    const double t = 1.0 - static_cast<double>(d) / band;
    return t * t;
  };
  const auto disp = [&](std::uint32_t i, std::uint32_t j) { return displacement[std::size_t{j} * n + i]; };
  for (std::uint32_t j = 1; j + 1 < n; ++j)
    for (std::uint32_t i = 1; i + 1 < n; ++i) {
      const double wl = weight(i), wr = weight(n - 1 - i), wb = weight(j), wt = weight(n - 1 - j);
      const double total = wl + wr + wb + wt;
      if (total == 0.0) continue;
      const Vec3 d = (wl * disp(0, j) + wr * disp(n - 1, j) + wb * disp(i, 0) + wt * disp(i, n - 1)) / std::max(1.0, total);
      const std::size_t p = std::size_t{j} * n + i;
      for (Eigen::Index c = 0; c < 3; ++c)
        positions[3 * p + static_cast<std::size_t>(c)] =
            static_cast<float>(double{positions[3 * p + static_cast<std::size_t>(c)]} + d[c]);
    }
}

}  // namespace gimforge
