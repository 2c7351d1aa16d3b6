// Surface-aware rounding of quantized positions (kernels/codec/surface_rounding.h): every code stays a corner
// of the sample's lattice cell, the surface moves less along its normal than nearest rounding moves it,
// equal positions stay equal, and where samples are closer than the lattice nearest rounding is kept.
#include <gtest/gtest.h>

#include <cmath>

#include "kernels/codec/surface_rounding.h"
#include "kernels/core/errors.h"

using namespace gimforge;

namespace {

/// A gently curved, tilted sheet sampled on a w × h grid with the given spacing.
std::vector<float> sheet(std::uint32_t w, std::uint32_t h, double spacing) {
  std::vector<float> xyz(3 * std::size_t{w} * h);
  for (std::uint32_t j = 0; j < h; ++j)
    for (std::uint32_t i = 0; i < w; ++i) {
      const double x = spacing * i, y = spacing * j;
      const std::size_t k = 3 * (std::size_t{j} * w + i);
      xyz[k] = static_cast<float>(x + 0.1234);
      xyz[k + 1] = static_cast<float>(y - 0.0567);
      xyz[k + 2] = static_cast<float>(0.37 * x - 0.21 * y + 0.05 * std::sin(3.0 * x) * std::cos(2.0 * y));
    }
  return xyz;
}

Vec3 sheet_normal(double x, double y) {
  const Vec3 du(1.0, 0.0, 0.37 + 0.15 * std::cos(3.0 * x) * std::cos(2.0 * y));
  const Vec3 dv(0.0, 1.0, -0.21 - 0.10 * std::sin(3.0 * x) * std::sin(2.0 * y));
  return du.cross(dv).normalized();
}

PositionLattice lattice_for(double step) {
  PositionLattice l;
  l.offset = Vec3(-1.0, -1.0, -1.0);
  l.scale = Vec3(step, step * 1.3, step * 0.8);
  l.top = 4095.0;
  return l;
}

Vec3 decoded(const PositionLattice& l, const std::vector<std::uint16_t>& q, std::size_t k) {
  return l.offset + l.scale.cwiseProduct(Vec3(q[3 * k], q[3 * k + 1], q[3 * k + 2]));
}

}  // namespace

TEST(SurfaceRounding, MovesTheSurfaceLessThanNearestRoundingAndStaysNearTheSample) {
  const std::uint32_t w = 40, h = 30;
  const double spacing = 0.02;
  const std::vector<float> xyz = sheet(w, h, spacing);
  const PositionLattice lattice = lattice_for(spacing / 16);
  const std::vector<std::uint16_t> q = round_to_surface(xyz, {}, w, h, lattice);
  ASSERT_EQ(q.size(), xyz.size());
  double normal_surface = 0.0, normal_nearest = 0.0;
  for (std::uint32_t j = 0; j < h; ++j)
    for (std::uint32_t i = 0; i < w; ++i) {
      const std::size_t k = std::size_t{j} * w + i;
      const Vec3 p(xyz[3 * k], xyz[3 * k + 1], xyz[3 * k + 2]);
      const Vec3 e = decoded(lattice, q, k) - p;
      Vec3 nearest;
      for (Eigen::Index c = 0; c < 3; ++c) {
        EXPECT_LT(std::abs(e[c]), 2.0 * lattice.scale[c]) << "sample " << k << " went beyond the next lattice cell on axis " << c;
        nearest[c] = lattice.offset[c] + lattice.scale[c] * std::round((p[c] - lattice.offset[c]) / lattice.scale[c]) - p[c];
      }
      const Vec3 n = sheet_normal(spacing * i, spacing * j);
      normal_surface += std::pow(n.dot(e), 2);
      normal_nearest += std::pow(n.dot(nearest), 2);
    }
  // Nearest rounding: about s/√12 along the normal; the best of the 64 candidates is about three times closer
  // (the tangential weight keeps it from going farther for less).
  EXPECT_LT(std::sqrt(normal_surface), 0.4 * std::sqrt(normal_nearest));
}

TEST(SurfaceRounding, EqualPositionsGetEqualCodes) {
  const std::uint32_t w = 24, h = 24;
  const double spacing = 0.03;
  std::vector<float> xyz = sheet(w, h, spacing);
  // Glue a corner to an inner sample and the right column to the left one reversed (as a cut and its mate):
  // the copies have other grid neighbours, hence other normal estimates.
  for (std::size_t c = 0; c < 3; ++c) xyz[c] = xyz[3 * (std::size_t{5} * w + 7) + c];
  for (std::uint32_t j = 0; j < h; ++j)
    for (std::size_t c = 0; c < 3; ++c) xyz[3 * (std::size_t{j} * w + w - 1) + c] = xyz[3 * (std::size_t{h - 1 - j} * w) + c];
  const PositionLattice lattice = lattice_for(spacing / 20);
  const std::vector<std::uint16_t> q = round_to_surface(xyz, {}, w, h, lattice);
  for (std::uint32_t j = 0; j < h; ++j)
    for (std::size_t c = 0; c < 3; ++c)
      EXPECT_EQ(q[3 * (std::size_t{j} * w + w - 1) + c], q[3 * (std::size_t{h - 1 - j} * w) + c]) << "row " << j;
  for (std::size_t c = 0; c < 3; ++c) EXPECT_EQ(q[c], q[3 * (std::size_t{5} * w + 7) + c]);
  // −0 and +0 are one position (a reader's == says so): an image written elsewhere may mix them.
  std::vector<float> signed_zero = sheet(w, h, spacing);
  const std::size_t a = 3 * (std::size_t{4} * w + 3), b = 3 * (std::size_t{9} * w + 11);
  for (std::size_t c = 0; c < 3; ++c) signed_zero[b + c] = signed_zero[a + c];
  signed_zero[a] = 0.0f;
  signed_zero[b] = -0.0f;
  for (int shift = 0; shift < 64; ++shift) {  // lattices at many offsets: the two copies see other neighbours
    PositionLattice shifted = lattice;
    shifted.offset += Vec3(0.37, 0.53, 0.71) * (shift / 64.0) * lattice.scale.x();
    const std::vector<std::uint16_t> z = round_to_surface(signed_zero, {}, w, h, shifted);
    for (std::size_t c = 0; c < 3; ++c) EXPECT_EQ(z[a + c], z[b + c]) << "axis " << c << ", shift " << shift;
  }
}

TEST(SurfaceRounding, SamplesCloserThanTheLatticeRoundToNearest) {
  const std::uint32_t w = 12, h = 12;
  const double spacing = 0.001;
  const std::vector<float> xyz = sheet(w, h, spacing);
  const PositionLattice lattice = lattice_for(spacing * 8);  // cells much larger than the sample spacing
  const std::vector<std::uint16_t> q = round_to_surface(xyz, {}, w, h, lattice);
  for (std::size_t k = 0; k < std::size_t{w} * h; ++k)
    for (Eigen::Index c = 0; c < 3; ++c)
      EXPECT_EQ(q[3 * k + static_cast<std::size_t>(c)],
                static_cast<std::uint16_t>(std::round((double{xyz[3 * k + static_cast<std::size_t>(c)]} - lattice.offset[c]) / lattice.scale[c])));
}

TEST(SurfaceRounding, MaskedSamplesAreSkippedAndBadInputIsRefused) {
  const std::uint32_t w = 8, h = 6;
  std::vector<float> xyz = sheet(w, h, 0.05);
  std::vector<std::uint8_t> mask(std::size_t{w} * h, 1);
  mask[9] = 0;
  xyz[27] = std::numeric_limits<float>::quiet_NaN();  // sample 9, undefined
  const PositionLattice lattice = lattice_for(0.004);
  const std::vector<std::uint16_t> q = round_to_surface(xyz, mask, w, h, lattice);
  EXPECT_EQ(q[27], 0);
  EXPECT_EQ(q[28], 0);
  EXPECT_EQ(q[29], 0);
  EXPECT_THROW((void)round_to_surface(xyz, {}, w, h, lattice), InvalidInput);          // a defined NaN
  EXPECT_THROW((void)round_to_surface(xyz, mask, w, h + 1, lattice), InvalidInput);    // wrong size
  PositionLattice bad = lattice;
  bad.scale.x() = 0.0;
  EXPECT_THROW((void)round_to_surface(xyz, mask, w, h, bad), InvalidInput);
  bad = lattice;
  bad.top = 10.5;  // a code could round above it
  EXPECT_THROW((void)round_to_surface(xyz, mask, w, h, bad), InvalidInput);
}

TEST(SurfaceRounding, BlocksOfStackedFacesDoNotShareNormals) {
  // Two faces stacked (block_rows = h): the second is the first turned by 90° about x. Rounded alone, each
  // block equals the rounding of the stack.
  const std::uint32_t w = 16, h = 16;
  const std::vector<float> a = sheet(w, h, 0.025);
  std::vector<float> b(a.size());
  for (std::size_t k = 0; k < a.size() / 3; ++k) {
    b[3 * k] = a[3 * k];
    b[3 * k + 1] = -a[3 * k + 2];
    b[3 * k + 2] = a[3 * k + 1];
  }
  std::vector<float> both(a);
  both.insert(both.end(), b.begin(), b.end());
  const PositionLattice lattice = lattice_for(0.025 / 16);
  SurfaceRoundingOptions options;
  options.block_rows = h;
  const std::vector<std::uint16_t> q = round_to_surface(both, {}, w, 2 * h, lattice, options);
  const std::vector<std::uint16_t> qa = round_to_surface(a, {}, w, h, lattice), qb = round_to_surface(b, {}, w, h, lattice);
  EXPECT_TRUE(std::equal(qa.begin(), qa.end(), q.begin()));
  EXPECT_TRUE(std::equal(qb.begin(), qb.end(), q.begin() + static_cast<std::ptrdiff_t>(qa.size())));
}
