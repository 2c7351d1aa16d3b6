// The codec layer (kernels/codec/j2k.h): 16-bit quantization of positions, JPEG 2000 through OpenJPEG in
// memory (lossless exact, lossy within its bytes), clear errors for damaged codestreams, and ROI-priority
// coding that beats plain coding inside the ROI at equal bytes.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>

#include <cmath>
#include <random>

#include "kernels/codec/j2k.h"
#include "kernels/core/errors.h"

using namespace gimforge;

namespace {

/// Three planes of a smooth surface with fine detail everywhere (a bumpy height field over the square), with
/// `noise_level` (a fraction of the range) of noise on the heights.
Planes16 bumpy(std::uint32_t n, double noise_level = 0.01) {
  Planes16 p{n, n, 3, std::vector<std::uint16_t>(3 * std::size_t{n} * n)};
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> noise(-1.0, 1.0);
  for (std::uint32_t j = 0; j < n; ++j)
    for (std::uint32_t i = 0; i < n; ++i) {
      const double u = static_cast<double>(i) / (n - 1), v = static_cast<double>(j) / (n - 1);
      const double z = 0.5 + 0.2 * std::sin(9 * u) * std::cos(7 * v) + 0.05 * std::sin(40 * u + 30 * v) + noise_level * noise(rng);
      const std::size_t k = std::size_t{j} * n + i, plane = std::size_t{n} * n;
      p.samples[k] = static_cast<std::uint16_t>(u * 65535);
      p.samples[plane + k] = static_cast<std::uint16_t>(v * 65535);
      p.samples[2 * plane + k] = static_cast<std::uint16_t>(std::clamp(z, 0.0, 1.0) * 65535);
    }
  return p;
}

double rms_inside(const Planes16& a, const Planes16& b, const std::vector<std::uint8_t>& roi, bool inside) {
  double sum = 0.0;
  std::size_t count = 0;
  const std::size_t plane = std::size_t{a.width} * a.height;
  for (std::size_t c = 0; c < a.components; ++c)
    for (std::size_t k = 0; k < plane; ++k)
      if ((roi[k] != 0) == inside) {
        const double d = static_cast<double>(a.samples[c * plane + k]) - static_cast<double>(b.samples[c * plane + k]);
        sum += d * d, ++count;
      }
  return std::sqrt(sum / static_cast<double>(count));
}

}  // namespace

TEST(J2k, QuantizationRoundTripsWithinHalfAStep) {
  std::vector<float> xyz;
  for (int k = 0; k < 16; ++k) xyz.insert(xyz.end(), {static_cast<float>(k) * 0.1f, -2.0f + static_cast<float>(k), 400000.5f});
  Quantization q;
  const Planes16 planes = quantize_positions(xyz, 4, 4, q);
  EXPECT_EQ(planes.components, 3u);
  const std::vector<float> back = dequantize_positions(planes, q);
  for (std::size_t k = 0; k < xyz.size(); ++k) EXPECT_NEAR(back[k], xyz[k], 0.51 * q.scale + 1e-3) << k;
  xyz[5] = std::nanf("");
  EXPECT_THROW((void)quantize_positions(xyz, 4, 4, q), InvalidInput);
  EXPECT_THROW((void)quantize_positions(xyz, 5, 4, q), InvalidInput);
}

TEST(J2k, LosslessIsExactAndLossyKeepsItsBytes) {
  const Planes16 image = bumpy(65);
  const std::vector<std::uint8_t> lossless = encode_j2k(image, {});
  const Planes16 back = decode_j2k(lossless);
  EXPECT_EQ(back.width, 65u);
  EXPECT_EQ(back.components, 3u);
  EXPECT_EQ(back.samples, image.samples);
  double previous = std::numeric_limits<double>::infinity();
  for (std::size_t bytes : {600u, 1500u, 4000u}) {
    const std::vector<std::uint8_t> lossy = encode_j2k(image, {bytes, false});
    EXPECT_LE(lossy.size(), bytes);
    EXPECT_GT(lossy.size(), bytes / 2);
    const double error = rms_inside(image, decode_j2k(lossy), std::vector<std::uint8_t>(65 * 65, 1), true);
    EXPECT_LT(error, previous) << bytes;  // more bytes, less error
    previous = error;
  }
  EXPECT_THROW((void)encode_j2k(Planes16{1, 4, 1, std::vector<std::uint16_t>(4)}, {}), InvalidInput);
}

TEST(J2k, CodestreamsCarryNoCommentSegment) {
  // OpenJPEG writes "Created by OpenJPEG version ..." (39 bytes) into every main header; encode_j2k removes
  // it, so those bytes go to the image. The main header runs from SOC to the first SOT.
  const Planes16 image = bumpy(33);
  for (const J2kOptions& options : {J2kOptions{}, J2kOptions{500, false}}) {
    const std::vector<std::uint8_t> cs = encode_j2k(image, options);
    ASSERT_GE(cs.size(), 4u);
    EXPECT_EQ(cs[0], 0xFF);
    EXPECT_EQ(cs[1], 0x4F);
    std::size_t at = 2;
    std::vector<unsigned> markers;
    while (at + 4 <= cs.size()) {
      const unsigned m = (unsigned{cs[at]} << 8) | cs[at + 1];
      markers.push_back(m);
      if (m == 0xFF90) break;
      at += 2 + ((std::size_t{cs[at + 2]} << 8) | cs[at + 3]);
    }
    ASSERT_FALSE(markers.empty());
    EXPECT_EQ(markers.back(), 0xFF90u) << "the main header ends at a tile";
    EXPECT_EQ(std::count(markers.begin(), markers.end(), 0xFF64u), 0) << "a COM segment is left";
    EXPECT_EQ(decode_j2k(cs).width, 33u);
  }
}

TEST(J2k, DamagedCodestreamsGiveAFormatError) {
  const std::vector<std::uint8_t> good = encode_j2k(bumpy(33), {});
  // Another component count than the caller expects is refused from the header, before decoding.
  try {
    (void)decode_j2k(good, 33, 33, 4);
    FAIL() << "4 components accepted";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("3 components, expected 4"), std::string::npos) << e.what();
  }
  EXPECT_EQ(decode_j2k(good, 33, 33, 3).components, 3u);
  for (std::size_t keep : {std::size_t{0}, std::size_t{10}, good.size() / 3}) {
    const std::vector<std::uint8_t> cut(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(keep));
    EXPECT_THROW((void)decode_j2k(cut), FormatError) << keep;
  }
  std::vector<std::uint8_t> garbage(200, 0x5a);
  try {
    (void)decode_j2k(garbage);
    FAIL() << "garbage decoded";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("JPEG 2000 codestream of 200 bytes"), std::string::npos) << e.what();
  }
}

TEST(J2k, ACodestreamOfSeveralTilesOrNoneIsRefused) {
  // OpenJPEG fills the tiles a codestream declares but does not carry with zeros and reports success: a
  // SIZ declaring 2 × 2 tiles over a one-tile stream decoded to an image three quarters zero. The encoder
  // writes one tile; the decoder takes exactly one, present.
  const std::vector<std::uint8_t> good = encode_j2k(bumpy(33), {});
  ASSERT_GE(good.size(), 40u);
  ASSERT_TRUE(good[2] == 0xFF && good[3] == 0x51);  // SIZ right after SOC
  std::vector<std::uint8_t> tiled = good;
  for (std::size_t at : {std::size_t{24}, std::size_t{28}}) {  // XTsiz, YTsiz (big-endian) 33 → 17
    tiled[at] = tiled[at + 1] = tiled[at + 2] = 0;
    tiled[at + 3] = 17;
  }
  try {
    (void)decode_j2k(tiled, 33, 33, 3);
    FAIL() << "a codestream declaring 4 tiles decoded";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("4 tiles"), std::string::npos) << e.what();
  }
  // The main header alone and the end-of-codestream marker: no tile at all.
  std::size_t sot = 2;
  while (sot + 4 <= good.size() && !(good[sot] == 0xFF && good[sot + 1] == 0x90))
    sot += 2 + (std::size_t{good[sot + 2]} << 8 | good[sot + 3]);
  ASSERT_LT(sot + 4, good.size());
  std::vector<std::uint8_t> empty(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(sot));
  empty.push_back(0xFF), empty.push_back(0xD9);
  EXPECT_THROW((void)decode_j2k(empty, 33, 33, 3), FormatError);  // OpenJPEG: "Stream too short"
}

TEST(J2k, RoiFirstBeatsPlainCodingInsideTheRoiAtEqualBytes) {
  const std::uint32_t n = 129;
  const Planes16 image = bumpy(n);
  std::vector<std::uint8_t> roi(std::size_t{n} * n, 0);
  for (std::uint32_t j = 40; j < 80; ++j)
    for (std::uint32_t i = 30; i < 70; ++i) roi[j * n + i] = 1;
  for (std::size_t budget : {400u, 3000u, 8000u}) {
    const RoiCoded coded = encode_roi_priority(image, roi, budget);
    EXPECT_LE(coded.bytes(), budget);
    // The image's main header is the window's, resized, unless the window is coded losslessly (5/3).
    EXPECT_EQ(coded.shared_header > 0, budget == 400u) << budget;
    const Planes16 roi_first = decode_roi_priority(coded);
    const Planes16 plain = decode_j2k(encode_j2k(image, {budget, false}));
    EXPECT_LT(rms_inside(image, roi_first, roi, true), (budget == 400u ? 0.7 : 0.5) * rms_inside(image, plain, roi, true)) << budget;
    EXPECT_GT(rms_inside(image, roi_first, roi, false), rms_inside(image, plain, roi, false)) << budget;  // the price
  }
  // A window placed off the image (a damaged record) is refused, not written out of bounds.
  RoiCoded off = encode_roi_priority(image, roi, 3000);
  off.x0 = 0xfffffff0u;
  EXPECT_THROW((void)decode_roi_priority(off), FormatError);
  EXPECT_THROW((void)encode_roi_priority(image, std::vector<std::uint8_t>(std::size_t{n} * n, 0), 3000), InvalidInput);
  EXPECT_THROW((void)encode_roi_priority(image, roi, kRoiLeastBudget - 1), InvalidInput);
}

TEST(J2k, ASmallOrThinRoiWindowLeavesTheImageItsWaveletLevels) {
  // A window of a few pixels (coded losslessly) or a strip two pixels high has fewer wavelet levels than the
  // image: the image's codestream keeps its own, and outside the window it is about as close as plain coding
  // of the whole image in the bytes it got (with the window's levels it was 10 to 50 times farther).
  const std::uint32_t n = 129;
  const Planes16 image = bumpy(n, 0.0);
  for (const auto& [wx0, wy0, wx1, wy1] : {std::array<std::uint32_t, 4>{60, 60, 62, 62}, std::array<std::uint32_t, 4>{0, 64, n, 66}}) {
    std::vector<std::uint8_t> roi(std::size_t{n} * n, 0);
    for (std::uint32_t j = wy0; j < wy1; ++j)
      for (std::uint32_t i = wx0; i < wx1; ++i) roi[j * n + i] = 1;
    const RoiCoded coded = encode_roi_priority(image, roi, 1500);
    EXPECT_LE(coded.bytes(), 1500u);
    EXPECT_EQ(coded.shared_header, 0u) << wx1 - wx0;
    const Planes16 plain = decode_j2k(encode_j2k(image, {coded.background.size(), false}));
    EXPECT_LT(rms_inside(image, decode_roi_priority(coded), roi, false), 2.0 * rms_inside(image, plain, roi, false)) << wx1 - wx0;
  }
}

TEST(J2k, RoiPayloadRoundTripsAndItsHeaderIsCheckedFirst) {
  const std::uint32_t n = 65;
  const Planes16 image = bumpy(n);
  std::vector<std::uint8_t> roi(std::size_t{n} * n, 0);
  for (std::uint32_t j = 10; j < 45; ++j)
    for (std::uint32_t i = 20; i < 56; ++i) roi[j * n + i] = 1;
  // A lossy window with sides of 32 and more (the image's six resolutions): the header is shared.
  const RoiCoded coded = encode_roi_priority(image, roi, 700);
  ASSERT_GT(coded.shared_header, 0u);
  const std::vector<std::uint8_t> payload = roi_payload(coded);
  EXPECT_EQ(payload.size(), kRoiPayloadHeader + coded.bytes());
  EXPECT_EQ(std::string(payload.begin(), payload.begin() + 4), "ROI2");
  const Planes16 decoded = decode_roi_payload(payload, n, n, 3);
  EXPECT_EQ(decoded.samples, decode_roi_priority(coded).samples);
  // The same codestreams with the image's stored whole (as a lossless window stores it), and in the 24-byte
  // "ROI1" payload of earlier versions, decode to the same image.
  RoiCoded whole = coded;
  whole.shared_header = 0;
  const std::vector<std::uint8_t> whole_payload = roi_payload(whole);
  EXPECT_EQ(whole_payload.size(), payload.size() + coded.shared_header);
  EXPECT_EQ(decode_roi_payload(whole_payload, n, n, 3).samples, decoded.samples);
  EXPECT_EQ(roi_payload_window(whole_payload, n, n), roi_payload_window(payload, n, n));
  std::vector<std::uint8_t> legacy{'R', 'O', 'I', '1'};
  legacy.insert(legacy.end(), whole_payload.begin() + 4, whole_payload.begin() + 24);
  legacy.insert(legacy.end(), whole_payload.begin() + kRoiPayloadHeader, whole_payload.end());
  EXPECT_EQ(decode_roi_payload(legacy, n, n, 3).samples, decoded.samples);
  // Each header field damaged: one FormatError, before anything large is decoded.
  const auto damaged = [&](std::size_t at, std::uint32_t value) {
    std::vector<std::uint8_t> p = payload;
    for (int b = 0; b < 4; ++b) p[at + static_cast<std::size_t>(b)] = static_cast<std::uint8_t>(value >> (8 * b));
    return p;
  };
  const std::vector<std::vector<std::uint8_t>> bad{
      std::vector<std::uint8_t>(payload.begin(), payload.begin() + 10),  // short
      damaged(0, 0x33494f52),                                            // "ROI3"
      damaged(kRoiPayloadHeader, 0x12345678),                            // the window's SOC and SIZ gone
      damaged(24, n + 2),                                                // another image width
      damaged(28, n - 1),                                                // another image height
      damaged(4, n),                                                     // x0 past the image
      damaged(12, 0x7fffffff),                                           // a huge window width
      damaged(16, 1),                                                    // a window of one row
      damaged(20, static_cast<std::uint32_t>(payload.size())),           // the window takes every byte
      damaged(20, 40)};                                                  // the codestreams split elsewhere
  for (std::size_t k = 0; k < bad.size(); ++k) EXPECT_THROW((void)decode_roi_payload(bad[k], n, n, 3), FormatError) << k;
  EXPECT_THROW((void)decode_roi_payload(payload, n + 2, n, 3), FormatError);  // another image size
  EXPECT_THROW((void)decode_roi_payload(payload, n, n, 1), FormatError);      // another component count
  std::vector<std::uint8_t> short_legacy(legacy.begin(), legacy.begin() + 20);
  EXPECT_THROW((void)decode_roi_payload(short_legacy, n, n, 3), FormatError);
  EXPECT_THROW((void)encode_roi_priority(image, std::vector<std::uint8_t>(5, 1), 3000), InvalidInput);
}
