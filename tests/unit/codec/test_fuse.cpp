// Fusing the cut of a decoded geometry image (kernels/gim/gim_fuse.h, Gu et al. §5): fusing makes every class
// of glued boundary points one value, and error diffusion lowers the step it leaves next to the cut. Also the
// whole chain on a geometry image coded with JPEG 2000 and with the wavelet coder (kernels/codec/geometry_codec.h).
#include <gtest/gtest.h>

#include <cmath>

#include "kernels/codec/geometry_codec.h"
#include "kernels/core/errors.h"
#include "kernels/gim/gim_fuse.h"

using namespace gimforge;

namespace {

/// The sideband of a square whose boundary folds in half: perimeter unit t is glued to 4·units − t (one cut
/// path and its mate, as a genus-0 surface cut along one path).
Sideband folded(std::uint32_t units) {
  Sideband sb;
  sb.units_per_side = units;
  sb.paths = {{1, 0, 2 * units}, {-1, 2 * units, 2 * units}};
  sb.check();
  return sb;
}

/// A smooth image whose glued boundary points agree (fused once), and the same image with smooth
/// "codec" errors that differ between mates.
struct Pair {
  std::vector<float> original, decoded;
};
Pair make_pair_of_images(std::uint32_t n, const Sideband& sb) {
  Pair p;
  p.original.resize(3 * std::size_t{n} * n);
  p.decoded.resize(p.original.size());
  for (std::uint32_t j = 0; j < n; ++j)
    for (std::uint32_t i = 0; i < n; ++i) {
      const double u = static_cast<double>(i) / (n - 1), v = static_cast<double>(j) / (n - 1);
      const std::size_t k = 3 * (std::size_t{j} * n + i);
      p.original[k] = static_cast<float>(std::cos(3 * u) * (1 + v));
      p.original[k + 1] = static_cast<float>(std::sin(2 * v) + u * u);
      p.original[k + 2] = static_cast<float>(u * v);
    }
  std::vector<Vec3> ignored;
  (void)fuse_cut(p.original, n, sb, ignored);
  for (std::uint32_t j = 0; j < n; ++j)
    for (std::uint32_t i = 0; i < n; ++i) {
      const double u = static_cast<double>(i) / (n - 1), v = static_cast<double>(j) / (n - 1);
      const std::size_t k = 3 * (std::size_t{j} * n + i);
      for (std::size_t c = 0; c < 3; ++c)
        p.decoded[k + c] = p.original[k + c] + static_cast<float>(0.01 * std::sin(4 * u + 3 * v + static_cast<double>(c)));
    }
  return p;
}

/// RMS over the boundary pixels (corners excluded) of the error of the step to the inward neighbour.
double step_error(const std::vector<float>& a, const std::vector<float>& o, std::uint32_t n) {
  double sum = 0.0;
  std::size_t count = 0;
  const auto add = [&](std::uint32_t i, std::uint32_t j, std::uint32_t ii, std::uint32_t jj) {
    const std::size_t p = 3 * (std::size_t{j} * n + i), q = 3 * (std::size_t{jj} * n + ii);
    for (std::size_t c = 0; c < 3; ++c) {
      const double e = (double{a[p + c]} - double{a[q + c]}) - (double{o[p + c]} - double{o[q + c]});
      sum += e * e;
    }
    ++count;
  };
  for (std::uint32_t k = 1; k + 1 < n; ++k) {
    add(0, k, 1, k);
    add(n - 1, k, n - 2, k);
    add(k, 0, k, 1);
    add(k, n - 1, k, n - 2);
  }
  return std::sqrt(sum / static_cast<double>(count));
}

double rms(const std::vector<float>& a, const std::vector<float>& b) {
  double sum = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) sum += (double{a[i]} - double{b[i]}) * (double{a[i]} - double{b[i]});
  return std::sqrt(sum / static_cast<double>(a.size() / 3));
}

bool mates_equal(const std::vector<float>& image, std::uint32_t n, const Sideband& sb) {
  const std::vector<std::uint32_t> rep = boundary_classes(sb, n);
  for (std::size_t p = 0; p < rep.size(); ++p)
    for (std::size_t c = 0; c < 3; ++c)
      if (image[3 * p + c] != image[3 * std::size_t{rep[p]} + c]) return false;
  return true;
}

}  // namespace

TEST(FuseCut, MakesMatesEqualAndDiffusionLowersTheStepItLeaves) {
  const std::uint32_t n = 65;
  const Sideband sb = folded(8);
  Pair p = make_pair_of_images(n, sb);
  ASSERT_TRUE(mates_equal(p.original, n, sb));
  ASSERT_FALSE(mates_equal(p.decoded, n, sb));
  std::vector<float> fused = p.decoded;
  std::vector<Vec3> displacement;
  const FuseStats stats = fuse_cut(fused, n, sb, displacement);
  EXPECT_TRUE(mates_equal(fused, n, sb));
  EXPECT_GT(stats.classes, 100u);
  EXPECT_GT(stats.max_displacement, 1e-3);
  std::vector<float> diffused = fused;
  diffuse_fusing(diffused, n, displacement);
  EXPECT_TRUE(mates_equal(diffused, n, sb));  // boundary pixels keep their fused values
  const double before = step_error(fused, p.original, n), after = step_error(diffused, p.original, n);
  EXPECT_LT(after, 0.5 * before) << "step error " << before << " -> " << after;
  EXPECT_LT(rms(diffused, p.original), rms(fused, p.original));
}

TEST(FuseCut, TrustedPixelsGiveTheirClassItsValue) {
  // A ROI-first code decodes its window better: a class with a member in the window takes that member's
  // value; classes without one take their mean as before.
  const std::uint32_t n = 65;
  const Sideband sb = folded(8);
  const Pair p = make_pair_of_images(n, sb);
  std::vector<std::uint8_t> trusted(std::size_t{n} * n, 0);
  for (std::uint32_t i = 0; i < n / 3; ++i) trusted[i] = 1;  // the left third of the bottom side
  std::vector<float> fused = p.decoded, plain = p.decoded;
  std::vector<Vec3> d;
  (void)fuse_cut(fused, n, sb, d, trusted);
  (void)fuse_cut(plain, n, sb, d);
  EXPECT_TRUE(mates_equal(fused, n, sb));
  const std::vector<std::uint32_t> rep = boundary_classes(sb, n);
  std::size_t kept = 0, averaged = 0;
  for (std::size_t q = 0; q < rep.size(); ++q) {
    bool any = false;
    for (std::size_t r = 0; r < rep.size(); ++r) any = any || (rep[r] == rep[q] && trusted[r] != 0);
    if (rep[q] == q && trusted[q] != 0 && any) {
      bool alone = true;  // the only trusted member of its class: it keeps its decoded value
      for (std::size_t r = 0; r < rep.size(); ++r) alone = alone && (r == q || rep[r] != rep[q] || trusted[r] == 0);
      if (alone) {
        for (std::size_t c = 0; c < 3; ++c) EXPECT_EQ(fused[3 * q + c], p.decoded[3 * q + c]) << q;
        ++kept;
      }
    } else if (!any && rep[q] != q) {
      for (std::size_t c = 0; c < 3; ++c) EXPECT_EQ(fused[3 * q + c], plain[3 * q + c]) << q;
      ++averaged;
    }
  }
  EXPECT_GT(kept, 5u);
  EXPECT_GT(averaged, 50u);
  EXPECT_THROW((void)fuse_cut(fused, n, sb, d, std::vector<std::uint8_t>(10, 1)), InvalidInput);
}

TEST(FuseCut, RefusesMismatchedSizes) {
  std::vector<float> image(3 * 64 * 64);
  std::vector<Vec3> d;
  EXPECT_THROW((void)fuse_cut(image, 64, folded(8), d), InvalidInput);  // 63 is not a multiple of 8
  EXPECT_THROW((void)fuse_cut(std::span<float>(image).first(10), 65, folded(8), d), InvalidInput);
}

TEST(GeometryCodec, CodedGeometryImagesAreWatertightAfterFusing) {
  const std::uint32_t n = 65;
  const Sideband sb = folded(8);
  const Pair p = make_pair_of_images(n, sb);
  std::vector<Vec3> image(std::size_t{n} * n);
  for (std::size_t k = 0; k < image.size(); ++k) image[k] = Vec3(p.original[3 * k], p.original[3 * k + 1], p.original[3 * k + 2]);
  // ROI-first JPEG 2000 of a band across the image (it meets the cut on two sides).
  std::vector<std::uint8_t> roi(image.size(), 0);
  for (std::uint32_t j = 20; j < 40; ++j)
    for (std::uint32_t i = 0; i < n; ++i) roi[std::size_t{j} * n + i] = 1;
  for (const GeometryCodec codec : {GeometryCodec::J2k, GeometryCodec::Wavelet, GeometryCodec::J2kRoi}) {
    const CodedGeometry c = codec == GeometryCodec::J2kRoi
                                ? encode_geometry_roi_first(image, n, n, roi, 2000)
                                : encode_geometry(image, n, n, {}, codec, LatticeExtension::Mirror, CodingTarget{false, 2000, 0.0});
    EXPECT_EQ(c.codec, codec);
    EXPECT_LE(c.payload.size(), 2000u);
    const std::vector<Vec3> decoded = decode_geometry(codec, c.payload, c.quantization, n, n, LatticeExtension::Mirror);
    for (std::size_t k = 0; k < decoded.size(); ++k) ASSERT_EQ(decoded[k], c.decoded[k]) << "what the encoder measured";
    std::vector<float> xyz(3 * decoded.size());
    for (std::size_t k = 0; k < decoded.size(); ++k)
      for (Eigen::Index q = 0; q < 3; ++q) xyz[3 * k + static_cast<std::size_t>(q)] = static_cast<float>(decoded[k][q]);
    EXPECT_FALSE(mates_equal(xyz, n, sb)) << codec_name(codec);  // the coder opens the cut
    std::vector<Vec3> displacement;
    (void)fuse_cut(xyz, n, sb, displacement);
    diffuse_fusing(xyz, n, displacement);
    EXPECT_TRUE(mates_equal(xyz, n, sb)) << codec_name(codec);
  }
}

TEST(GeometryCodec, NormalPsnrSeesTheNormalPartOfADisplacementOnly) {
  // A plane z = 0 sampled on a 9 × 9 grid: moving every sample along x (tangent) costs nothing on the
  // surface, moving it along z (normal) costs all of it — also at the edges, where differences are clamped.
  const std::uint32_t n = 9;
  std::vector<Vec3> plane(n * n), tangent(n * n), normal(n * n);
  for (std::uint32_t j = 0; j < n; ++j)
    for (std::uint32_t i = 0; i < n; ++i) {
      const std::size_t k = std::size_t{j} * n + i;
      plane[k] = Vec3(i, j, 0.0);
      tangent[k] = plane[k] + Vec3(0.01, 0.0, 0.0);
      normal[k] = plane[k] + Vec3(0.0, 0.0, 0.01);
    }
  EXPECT_TRUE(std::isinf(normal_psnr(plane, tangent, n, n, n, {})));
  const double expected = 20.0 * std::log10(std::sqrt(2.0) * 8.0 / 0.01);
  EXPECT_NEAR(normal_psnr(plane, normal, n, n, n, {}), expected, 1e-9);
  EXPECT_TRUE(std::isinf(image_psnr(plane, plane, {})));
  EXPECT_NEAR(image_psnr(plane, tangent, {}), expected, 1e-9);  // the sample PSNR sees both alike
}

TEST(GeometryCodec, LosslessJpeg2000IsExactOnTheQuantizedPlanesAndPsnrTargetsHold) {
  const std::uint32_t n = 65;
  const Pair p = make_pair_of_images(n, folded(8));
  std::vector<Vec3> image(std::size_t{n} * n);
  for (std::size_t k = 0; k < image.size(); ++k) image[k] = Vec3(p.original[3 * k], p.original[3 * k + 1], p.original[3 * k + 2]);
  const CodedGeometry lossless = encode_geometry(image, n, n, {}, GeometryCodec::J2k, LatticeExtension::Mirror, CodingTarget{true, 0, 0.0});
  EXPECT_GT(lossless.psnr, 95.0);  // 16-bit quantization only
  const std::vector<Vec3> again = decode_geometry(GeometryCodec::J2k, lossless.payload, lossless.quantization, n, n, LatticeExtension::Mirror);
  EXPECT_EQ(again, lossless.decoded);
  for (const GeometryCodec codec : {GeometryCodec::J2k, GeometryCodec::Wavelet}) {
    const CodedGeometry c = encode_geometry(image, n, n, {}, codec, LatticeExtension::Mirror, CodingTarget{false, 0, 60.0});
    EXPECT_GE(c.psnr, 60.0) << codec_name(codec);
    EXPECT_GE(image_psnr(image, decode_geometry(codec, c.payload, c.quantization, n, n, LatticeExtension::Mirror), {}), 60.0);
  }
  EXPECT_THROW((void)encode_geometry(image, n, n, {}, GeometryCodec::Wavelet, LatticeExtension::Mirror, CodingTarget{true, 0, 0.0}),
               InvalidInput);
}
