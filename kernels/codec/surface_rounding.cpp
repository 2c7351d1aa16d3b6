#include "kernels/codec/surface_rounding.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <unordered_map>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge {
namespace {

/// Equal float positions share one key (and −0 / +0 do not matter: both dequantize alike anyway).
struct PositionKey {
  std::array<std::uint32_t, 3> bits;
  bool operator==(const PositionKey&) const = default;
};
struct PositionKeyHash {
  std::size_t operator()(const PositionKey& k) const noexcept {
    std::uint64_t h = 0x9E3779B97F4A7C15ull;
    for (const std::uint32_t b : k.bits) h = (h ^ b) * 0x100000001B3ull + (h >> 29);
    return static_cast<std::size_t>(h);
  }
};

/// What the samples at one position agree on: the sum of their unit normals' outer products and the
/// shortest distance to a grid neighbour of any of them.
struct Group {
  Eigen::Matrix3d tensor{Eigen::Matrix3d::Zero()};
  int normals{0};
  double spacing{std::numeric_limits<double>::infinity()};
};

}  // namespace

std::vector<std::uint16_t> round_to_surface(std::span<const float> xyz, std::span<const std::uint8_t> mask,
                                            std::uint32_t width, std::uint32_t height, const PositionLattice& lattice,
                                            const SurfaceRoundingOptions& options) {
  const std::size_t samples = std::size_t{width} * height;
  if (xyz.size() != 3 * samples || (!mask.empty() && mask.size() != samples))
    throw InvalidInput(fmt::format("surface rounding: {} values and {} mask entries for a {} × {} image", xyz.size(),
                                   mask.size(), width, height));
  if (options.cell_radius < 1 || options.cell_radius > 4)
    throw InvalidInput(fmt::format("surface rounding: cell radius {} (1 to 4)", options.cell_radius));
  if (!(lattice.top >= 1.0 && lattice.top <= 65535.0) || !(lattice.scale.array() > 0.0).all() || !lattice.scale.allFinite() ||
      !lattice.offset.allFinite())
    throw InvalidInput("surface rounding: the lattice needs finite offsets, positive scales and 1 ≤ top ≤ 65535");
  const auto defined = [&](std::size_t k) { return mask.empty() || mask[k] != 0; };
  const auto at = [&](std::size_t k) { return Vec3(xyz[3 * k], xyz[3 * k + 1], xyz[3 * k + 2]); };
  for (std::size_t k = 0; k < samples; ++k)
    if (defined(k) && !at(k).allFinite())
      throw InvalidInput(fmt::format("surface rounding: sample {} is not finite", k));

  // One group per distinct position.
  std::unordered_map<PositionKey, std::uint32_t, PositionKeyHash> index;
  index.reserve(samples);
  std::vector<std::uint32_t> group_of(samples, 0);
  std::vector<Group> groups;
  for (std::size_t k = 0; k < samples; ++k) {
    if (!defined(k)) continue;
    const PositionKey key{{std::bit_cast<std::uint32_t>(xyz[3 * k]), std::bit_cast<std::uint32_t>(xyz[3 * k + 1]),
                           std::bit_cast<std::uint32_t>(xyz[3 * k + 2])}};
    const auto [it, fresh] = index.try_emplace(key, static_cast<std::uint32_t>(groups.size()));
    if (fresh) groups.emplace_back();
    group_of[k] = it->second;
  }

  // Normals from the grid: central differences where both neighbours are defined, one-sided otherwise.
  for (std::uint32_t j = 0; j < height; ++j)
    for (std::uint32_t i = 0; i < width; ++i) {
      const std::size_t k = std::size_t{j} * width + i;
      if (!defined(k)) continue;
      const Vec3 p = at(k);
      Group& g = groups[group_of[k]];
      const auto neighbour = [&](bool exists, std::size_t m) -> const float* {
        if (!exists || !defined(m)) return nullptr;
        const double d = (at(m) - p).norm();
        if (d > 0.0) g.spacing = std::min(g.spacing, d);
        return &xyz[3 * m];
      };
      const float* left = neighbour(i > 0, k - 1);
      const float* right = neighbour(i + 1 < width, k + 1);
      const std::uint32_t block = options.block_rows > 0 ? options.block_rows : height;
      const float* down = neighbour(j % block > 0, k - width);
      const float* up = neighbour(j + 1 < height && (j + 1) % block > 0, k + width);
      const auto difference = [&](const float* a, const float* b, Vec3& out) {
        const Vec3 pa = a != nullptr ? Vec3(a[0], a[1], a[2]) : p;
        const Vec3 pb = b != nullptr ? Vec3(b[0], b[1], b[2]) : p;
        out = pb - pa;
        return a != nullptr || b != nullptr;
      };
      Vec3 du, dv;
      if (!difference(left, right, du) || !difference(down, up, dv)) continue;
      const Vec3 n = du.cross(dv);
      const double length = n.norm();
      if (!(length > 0.0) || !std::isfinite(length)) continue;
      const Vec3 u = n / length;
      g.tensor += u * u.transpose();
      ++g.normals;
    }

  std::vector<std::uint16_t> codes(3 * samples, 0);
  for (std::size_t k = 0; k < samples; ++k) {
    if (!defined(k)) continue;
    const Vec3 p = at(k);
    const Group& g = groups[group_of[k]];
    const Eigen::Matrix3d tensor = g.normals > 0 ? Eigen::Matrix3d(g.tensor / g.normals) : Eigen::Matrix3d::Zero();
    const int per_axis = 2 * static_cast<int>(options.cell_radius);
    std::array<std::array<double, 8>, 3> choice{};
    std::array<double, 3> nearest{};
    for (Eigen::Index c = 0; c < 3; ++c) {
      const auto a = static_cast<std::size_t>(c);
      const double t = std::clamp((p[c] - lattice.offset[c]) / lattice.scale[c], 0.0, lattice.top);
      const double lo = std::floor(t);
      for (int m = 0; m < per_axis; ++m)
        choice[a][static_cast<std::size_t>(m)] =
            std::clamp(lo + static_cast<double>(m - static_cast<int>(options.cell_radius) + 1), 0.0, lattice.top);
      nearest[a] = std::round(t);
    }
    const auto move = [&](const Vec3& q) { return Vec3(lattice.offset + lattice.scale.cwiseProduct(q) - p); };
    const Vec3 q_nearest(nearest[0], nearest[1], nearest[2]);
    const double reach = std::max(move(q_nearest).norm(), options.max_move_fraction * (std::isfinite(g.spacing) ? g.spacing : 0.0));
    const auto cost = [&](const Vec3& e) { return e.dot(tensor * e) + options.tangent_weight * e.squaredNorm(); };
    Vec3 best = q_nearest;
    double best_cost = cost(move(q_nearest));
    if (g.normals > 0)
      for (int corner = 0; corner < per_axis * per_axis * per_axis; ++corner) {
        const Vec3 q(choice[0][static_cast<std::size_t>(corner % per_axis)],
                     choice[1][static_cast<std::size_t>((corner / per_axis) % per_axis)],
                     choice[2][static_cast<std::size_t>(corner / (per_axis * per_axis))]);
        const Vec3 e = move(q);
        if (e.norm() > reach) continue;
        const double c = cost(e);
        if (c < best_cost) {
          best_cost = c;
          best = q;
        }
      }
    for (std::size_t c = 0; c < 3; ++c) codes[3 * k + c] = static_cast<std::uint16_t>(best[static_cast<Eigen::Index>(c)]);
  }
  return codes;
}

}  // namespace gimforge
