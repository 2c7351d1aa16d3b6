#include "kernels/codec/lattice_wavelet.h"

#include <algorithm>
#include <cmath>

namespace gimforge {
namespace {

// CDF 9/7 lifting (Daubechies & Sweldens 1998; JPEG 2000's irreversible filter). Low-pass DC gain 1.
constexpr double kAlpha = -1.586134342059924;
constexpr double kBeta = -0.052980118572961;
constexpr double kGamma = 0.882911075530934;
constexpr double kDelta = 0.443506852043971;
constexpr double kK = 1.230174104914001;
constexpr double kLowScale = 1.0 / kK;
constexpr double kHighScale = kK / 2.0;

constexpr std::array<double, 4> kSteps{kAlpha, kBeta, kGamma, kDelta};
constexpr std::array<int, 4> kParity{1, 0, 1, 0};  // predict the odd samples, update the even ones

/// The level-ℓ lattice inside the image: sample (x, y) of the lattice is image element (y·s)·side + x·s.
struct Lattice {
  std::span<Vec3> image;
  std::size_t side;
  std::size_t s;
  std::int64_t m;
  LatticeExtension ext;

  Vec3& at(std::int64_t x, std::int64_t y) const {
    return image[static_cast<std::size_t>(y) * s * side + static_cast<std::size_t>(x) * s];
  }
  const Vec3& extended(std::int64_t x, std::int64_t y) const {
    const LatticePoint p = extend(x, y, m, ext);
    return at(p.x, p.y);
  }
};

Lattice lattice_of(std::span<Vec3> image, std::uint32_t side, std::uint32_t level, LatticeExtension ext) {
  const std::size_t s = std::size_t{1} << level;
  return {image, side, s, static_cast<std::int64_t>((side - 1) / (2 * s)), ext};
}

/// One lifting step along x (rows) or y (columns): samples of `parity` += c · (sum of their two neighbours).
/// The neighbours are summed first, so mirrored samples (whose neighbours are swapped) get identical values.
void lift(const Lattice& L, bool along_x, int parity, double c) {
  const std::int64_t n = 2 * L.m;
  for (std::int64_t a = 0; a <= n; ++a)  // the row (along x) or column (along y)
    for (std::int64_t b = parity; b <= n; b += 2) {
      if (along_x) {
        const Vec3 sum = ((b == 0 || b == n) ? L.extended(b - 1, a) : L.at(b - 1, a)) +
                         ((b == 0 || b == n) ? L.extended(b + 1, a) : L.at(b + 1, a));
        L.at(b, a) += c * sum;
      } else {
        const Vec3 sum = ((b == 0 || b == n) ? L.extended(a, b - 1) : L.at(a, b - 1)) +
                         ((b == 0 || b == n) ? L.extended(a, b + 1) : L.at(a, b + 1));
        L.at(a, b) += c * sum;
      }
    }
}

void scale(const Lattice& L, bool along_x, bool inverse) {
  const std::int64_t n = 2 * L.m;
  for (std::int64_t a = 0; a <= n; ++a)
    for (std::int64_t b = 0; b <= n; ++b) {
      const double f = (b % 2 == 0) ? kLowScale : kHighScale;
      Vec3& v = along_x ? L.at(b, a) : L.at(a, b);
      v *= inverse ? 1.0 / f : f;
    }
}

void analyse(const Lattice& L, bool along_x) {
  for (std::size_t k = 0; k < kSteps.size(); ++k) lift(L, along_x, kParity[k], kSteps[k]);
  scale(L, along_x, false);
}
void synthesize(const Lattice& L, bool along_x) {
  scale(L, along_x, true);
  for (std::size_t k = kSteps.size(); k-- > 0;) lift(L, along_x, kParity[k], -kSteps[k]);
}

/// The 1D transform of a mirrored line, for the band norms.
void lift_line(std::vector<double>& x, std::size_t s, int parity, double c) {
  const auto n = static_cast<std::int64_t>((x.size() - 1) / s);
  const auto at = [&](std::int64_t k) -> double& {
    return x[static_cast<std::size_t>(k < 0 ? -k : (k > n ? 2 * n - k : k)) * s];
  };
  for (std::int64_t b = parity; b <= n; b += 2) at(b) += c * (at(b - 1) + at(b + 1));
}
void synthesize_line(std::vector<double>& x, std::size_t s) {
  const std::size_t count = (x.size() - 1) / s + 1;
  for (std::size_t k = 0; k < count; ++k) x[k * s] /= (k % 2 == 0) ? kLowScale : kHighScale;
  for (std::size_t k = kSteps.size(); k-- > 0;) lift_line(x, s, kParity[k], -kSteps[k]);
}

}  // namespace

std::uint32_t lattice_levels(std::uint32_t side) {
  if (side < 3 || side % 2 == 0) return 0;
  std::uint32_t m = (side - 1) / 2;
  std::uint32_t levels = 1;
  while (levels < 10 && m % 2 == 0) {
    m /= 2;
    ++levels;
  }
  return levels;
}

LatticePoint extend_lattice(std::int64_t x, std::int64_t y, std::int64_t n, LatticeExtension extension) {
  if (extension == LatticeExtension::Mirror) {
    if (x < 0) x = -x;
    if (x > n) x = 2 * n - x;
    if (y < 0) y = -y;
    if (y > n) y = 2 * n - y;
    return {x, y};
  }
  // 180° rotations about the midpoints (0, n/2), (n, n/2), (n/2, 0), (n/2, n) of the edges crossed.
  if (x < 0) return extend_lattice(-x, n - y, n, extension);
  if (x > n) return extend_lattice(2 * n - x, n - y, n, extension);
  if (y < 0) return {n - x, -y};
  if (y > n) return {n - x, 2 * n - y};
  return {x, y};
}

LatticePoint extend(std::int64_t x, std::int64_t y, std::int64_t m, LatticeExtension extension) {
  return extend_lattice(x, y, 2 * m, extension);
}

void forward_level(std::span<Vec3> image, std::uint32_t side, std::uint32_t level, LatticeExtension extension) {
  const Lattice L = lattice_of(image, side, level, extension);
  analyse(L, true);
  analyse(L, false);
}

void inverse_level(std::span<Vec3> image, std::uint32_t side, std::uint32_t level, LatticeExtension extension) {
  const Lattice L = lattice_of(image, side, level, extension);
  synthesize(L, false);
  synthesize(L, true);
}

void forward_lattice(std::span<Vec3> image, std::uint32_t side, std::uint32_t levels, LatticeExtension extension) {
  for (std::uint32_t l = 0; l < levels; ++l) forward_level(image, side, l, extension);
}

void inverse_lattice(std::span<Vec3> image, std::uint32_t side, std::uint32_t levels, LatticeExtension extension) {
  for (std::uint32_t l = levels; l-- > 0;) inverse_level(image, side, l, extension);
}

void symmetrize_level(std::span<Vec3> image, std::uint32_t side, std::uint32_t level, LatticeExtension extension) {
  if (extension != LatticeExtension::Sphere) return;
  const std::size_t s = std::size_t{1} << level;
  // The samples at stride s: a lattice of side n + 1 (n = 2m for a level's lattice; the coarsest low-pass
  // band may have n = 1: the four corners, one point of the sphere).
  const auto n = static_cast<std::int64_t>((side - 1) / s);
  const auto at = [&](std::int64_t x, std::int64_t y) -> Vec3& {
    return image[static_cast<std::size_t>(y) * s * side + static_cast<std::size_t>(x) * s];
  };
  const auto pair = [&](Vec3& a, Vec3& b) {
    const Vec3 mean = 0.5 * (a + b);
    a = mean;
    b = mean;
  };
  for (std::int64_t k = 1; 2 * k < n; ++k) {
    pair(at(0, k), at(0, n - k));
    pair(at(n, k), at(n, n - k));
    pair(at(k, 0), at(n - k, 0));
    pair(at(k, n), at(n - k, n));
  }
  Vec3& c0 = at(0, 0);
  Vec3& c1 = at(n, 0);
  Vec3& c2 = at(0, n);
  Vec3& c3 = at(n, n);
  const Vec3 mean = 0.25 * ((c0 + c3) + (c1 + c2));
  c0 = c1 = c2 = c3 = mean;
}

BandNorms band_norms(std::uint32_t levels) {
  // 1D synthesis functions on a mirrored line long enough that none reaches its ends.
  const std::size_t m = std::size_t{1} << (levels + 3);
  const auto norm_of = [&](std::size_t position, std::uint32_t from_level) {
    std::vector<double> x(2 * m + 1, 0.0);
    x[position] = 1.0;
    for (std::uint32_t l = from_level + 1; l-- > 0;) synthesize_line(x, std::size_t{1} << l);
    double sum = 0.0;
    for (const double v : x) sum += v * v;
    return std::sqrt(sum);
  };
  BandNorms norms;
  std::vector<double> low(levels), high(levels);
  for (std::uint32_t l = 0; l < levels; ++l) {
    const std::size_t s = std::size_t{1} << l;
    high[l] = norm_of(m - m % (2 * s) + s, l);  // an odd multiple of s near the middle
    low[l] = norm_of(m - m % (2 * s), l);       // an even multiple of s: low-pass after level l
  }
  for (std::uint32_t l = 0; l < levels; ++l) norms.detail.push_back({high[l] * low[l], low[l] * high[l], high[l] * high[l]});
  norms.low = levels == 0 ? 1.0 : low[levels - 1] * low[levels - 1];
  return norms;
}

}  // namespace gimforge
