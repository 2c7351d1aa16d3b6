#include "kernels/codec/surface_rounding.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge {
namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

/// The bits of a coordinate with −0 read as +0 (they are the same position: a reader's == says so).
std::uint32_t coordinate_bits(float v) { return std::bit_cast<std::uint32_t>(v == 0.0f ? 0.0f : v); }

}  // namespace

std::vector<std::uint16_t> round_to_surface(std::span<const float> xyz, std::span<const std::uint8_t> mask,
                                            std::uint32_t width, std::uint32_t height, const PositionLattice& lattice,
                                            const SurfaceRoundingOptions& options) {
  const std::size_t samples = std::size_t{width} * height;
  if (xyz.size() != 3 * samples || (!mask.empty() && mask.size() != samples) || samples >= kNone)
    throw InvalidInput(fmt::format("surface rounding: {} values and {} mask entries for a {} × {} image", xyz.size(),
                                   mask.size(), width, height));
  if (options.cell_radius < 1 || options.cell_radius > 4)
    throw InvalidInput(fmt::format("surface rounding: cell radius {} (1 to 4)", options.cell_radius));
  if (!(lattice.top >= 1.0 && lattice.top <= 65535.0) || lattice.top != std::floor(lattice.top) ||
      !(lattice.scale.array() > 0.0).all() || !lattice.scale.allFinite() || !lattice.offset.allFinite())
    throw InvalidInput("surface rounding: the lattice needs finite offsets, positive scales and a whole 1 ≤ top ≤ 65535");
  const auto defined = [&](std::size_t k) { return mask.empty() || mask[k] != 0; };
  const auto at = [&](std::size_t k) { return Vec3(xyz[3 * k], xyz[3 * k + 1], xyz[3 * k + 2]); };
  std::size_t count = 0;
  for (std::size_t k = 0; k < samples; ++k)
    if (defined(k)) {
      if (!at(k).allFinite()) throw InvalidInput(fmt::format("surface rounding: sample {} is not finite", k));
      ++count;
    }

  // The canonical sample of every position: the first (in index order) with the same coordinates. Samples
  // at one position take the canonical sample's normal and spacing, hence one code. An open-addressing
  // table of sample indices (4 bytes a slot, at most half full) keeps this to 12 bytes a sample.
  std::vector<std::uint32_t> canonical(samples, kNone);
  {
    std::size_t slots = 16;
    while (slots < 2 * count) slots *= 2;
    std::vector<std::uint32_t> table(slots, kNone);
    const auto same = [&](std::size_t a, std::size_t b) {
      for (std::size_t c = 0; c < 3; ++c)
        if (coordinate_bits(xyz[3 * a + c]) != coordinate_bits(xyz[3 * b + c])) return false;
      return true;
    };
    for (std::size_t k = 0; k < samples; ++k) {
      if (!defined(k)) continue;
      std::uint64_t h = 0x9E3779B97F4A7C15ull;
      for (std::size_t c = 0; c < 3; ++c) h = (h ^ coordinate_bits(xyz[3 * k + c])) * 0xFF51AFD7ED558CCDull;
      h ^= h >> 33;
      for (std::size_t slot = static_cast<std::size_t>(h) & (slots - 1);; slot = (slot + 1) & (slots - 1)) {
        if (table[slot] == kNone) {
          table[slot] = static_cast<std::uint32_t>(k);
          canonical[k] = static_cast<std::uint32_t>(k);
          break;
        }
        if (same(table[slot], k)) {
          canonical[k] = table[slot];
          break;
        }
      }
    }
  }

  // The normal of the image's surface at sample k (central differences where both grid neighbours are
  // defined, one-sided otherwise; zero where none can be formed) and the distance to its nearest defined
  // neighbour that is not at its position (infinite when there is none).
  const std::uint32_t block = options.block_rows > 0 ? options.block_rows : height;
  const auto local = [&](std::size_t k, Vec3& normal, double& spacing) {
    const std::size_t i = k % width, j = k / width;
    const Vec3 p = at(k);
    spacing = std::numeric_limits<double>::infinity();
    const auto neighbour = [&](bool exists, std::size_t m, Vec3& out) {
      if (!exists || !defined(m)) return false;
      out = at(m);
      const double d = (out - p).norm();
      if (d > 0.0) spacing = std::min(spacing, d);
      return true;
    };
    Vec3 left, right, down, up;
    const bool l = neighbour(i > 0, k - 1, left), r = neighbour(i + 1 < width, k + 1, right);
    const bool d = neighbour(j % block > 0, k - width, down), u = neighbour(j + 1 < height && (j + 1) % block > 0, k + width, up);
    normal = Vec3::Zero();
    if (!(l || r) || !(d || u)) return;
    const Vec3 du = (r ? right : p) - (l ? left : p), dv = (u ? up : p) - (d ? down : p);
    const Vec3 n = du.cross(dv);
    const double length = n.norm();
    if (length > 0.0 && std::isfinite(length)) normal = n / length;
  };

  std::vector<std::uint16_t> codes(3 * samples, 0);
  const int per_axis = 2 * static_cast<int>(options.cell_radius);
  for (std::size_t k = 0; k < samples; ++k) {
    if (!defined(k)) continue;
    const Vec3 p = at(k);
    std::array<std::array<double, 8>, 3> choice{};
    Vec3 nearest;
    for (Eigen::Index c = 0; c < 3; ++c) {
      const auto a = static_cast<std::size_t>(c);
      const double t = std::clamp((p[c] - lattice.offset[c]) / lattice.scale[c], 0.0, lattice.top);
      const double lo = std::floor(t);
      for (int m = 0; m < per_axis; ++m)
        choice[a][static_cast<std::size_t>(m)] =
            std::clamp(lo + static_cast<double>(m - static_cast<int>(options.cell_radius) + 1), 0.0, lattice.top);
      nearest[c] = std::round(t);
    }
    const auto move = [&](const Vec3& q) { return Vec3(lattice.offset + lattice.scale.cwiseProduct(q) - p); };
    Vec3 best = nearest;
    Vec3 normal;
    double spacing = 0.0;
    local(canonical[k], normal, spacing);
    const double nearest_move = move(nearest).norm();
    const double reach = std::isfinite(spacing) ? options.max_move_fraction * spacing : 0.0;
    // Where no other candidate is within reach (samples as close as the lattice) or no normal is known,
    // the nearest lattice point it is.
    if (reach > nearest_move && normal != Vec3::Zero()) {
      const auto cost = [&](const Vec3& e) { return std::pow(normal.dot(e), 2) + options.tangent_weight * e.squaredNorm(); };
      double best_cost = cost(move(nearest));
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
    }
    for (std::size_t c = 0; c < 3; ++c) codes[3 * k + c] = static_cast<std::uint16_t>(best[static_cast<Eigen::Index>(c)]);
  }
  return codes;
}

}  // namespace gimforge
