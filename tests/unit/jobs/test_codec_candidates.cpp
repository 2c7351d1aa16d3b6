// Which codecs `compress` tries for an image (jobs/compress.h, codec_candidates): auto leaves out the
// wavelet coder where it cannot code the side (a gim of 8193 or a spherical image of n > 2048 failed whole
// before, although JPEG 2000 had met the target), and an explicit --codec wavelet says why it cannot.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "jobs/compress.h"
#include "kernels/codec/wavelet_coder.h"
#include "kernels/core/errors.h"
#include "tests/unit/test_support.h"

namespace {

using namespace gimforge;
using jobs::CodecChoice;
using jobs::codec_candidates;
using Codecs = std::vector<GeometryCodec>;

TEST(CodecCandidates, AutoTriesTheWaveletCoderOnlyWhereItCodesTheSide) {
  EXPECT_EQ(codec_candidates(CodecChoice::Auto, false, 257, "a.h5:gim/x"), (Codecs{GeometryCodec::J2k, GeometryCodec::Wavelet}));
  EXPECT_EQ(codec_candidates(CodecChoice::Auto, false, kMaxWaveletSide, "a.h5:gim/x"),
            (Codecs{GeometryCodec::J2k, GeometryCodec::Wavelet}));
  EXPECT_EQ(codec_candidates(CodecChoice::Auto, false, 8193, "a.h5:gim/x"), Codecs{GeometryCodec::J2k});
  EXPECT_EQ(codec_candidates(CodecChoice::Auto, false, 0, "a.h5:spherical/x"), Codecs{GeometryCodec::J2k});
  EXPECT_EQ(codec_candidates(CodecChoice::Auto, true, 257, "a.h5:gim/x"), Codecs{GeometryCodec::J2k});
  EXPECT_EQ(codec_candidates(CodecChoice::J2k, false, 257, "a.h5:gim/x"), Codecs{GeometryCodec::J2k});
  EXPECT_EQ(codec_candidates(CodecChoice::J2kRoi, false, 257, "a.h5:gim/x"), Codecs{GeometryCodec::J2kRoi});
}

TEST(CodecCandidates, AnExplicitWaveletCoderThatCannotCodeTheSideSaysSo) {
  EXPECT_EQ(codec_candidates(CodecChoice::Wavelet, false, 257, "a.h5:gim/x"), Codecs{GeometryCodec::Wavelet});
  // An octahedral image of odd n has one level: coded, with a warning.
  EXPECT_EQ(codec_candidates(CodecChoice::Wavelet, false, 127, "a.h5:spherical/x"), Codecs{GeometryCodec::Wavelet});
  EXPECT_EQ(test::message_of<InvalidInput>([] { (void)codec_candidates(CodecChoice::Wavelet, false, 8193, "a.h5:gim/x"); }),
            "a.h5:gim/x: the wavelet coder takes square images of side 2^k·q + 1 up to 4097 samples, not 8193; use "
            "--codec j2k or auto");
}

TEST(CodecCandidates, TheCoarsestBandIsTwoSamplesOnPowersOfTwoAndNPlusOneForOddN) {
  EXPECT_EQ(wavelet_coarsest_side(257), 2u);   // gim 257
  EXPECT_EQ(wavelet_coarsest_side(129), 2u);   // octa n = 64
  EXPECT_EQ(wavelet_coarsest_side(97), 4u);    // octa n = 48: 96 = 2^5 · 3
  EXPECT_EQ(wavelet_coarsest_side(101), 26u);  // octa n = 50
  EXPECT_EQ(wavelet_coarsest_side(127), 64u);  // octa n = 63: one level
  EXPECT_TRUE(wavelet_codable(4097));
  EXPECT_FALSE(wavelet_codable(4099));
  EXPECT_FALSE(wavelet_codable(128));
}

}  // namespace
