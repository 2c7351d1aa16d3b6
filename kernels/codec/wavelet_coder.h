#pragma once
/// \file wavelet_coder.h
/// The image-wavelet coder of geometry images (Gu et al. §4–5 use Davis's coder; Praun & Hoppe §6 modify it
/// to apply their boundary-extension rules): the 9/7 lattice wavelet of lattice_wavelet.h, high-pass detail
/// expressed in local frames estimated from the low-pass surface (Khodakovsky et al. 2000), uniform
/// dead-zone quantization with one step per band (the step over the band's synthesis norm, the detail
/// component normal to the surface 3× finer, as Praun & Hoppe after Khodakovsky), and adaptive binary
/// arithmetic coding of the quantized coefficients with contexts from their neighbours and their parent.
///
/// Quantization runs coarse to fine in a closed loop: the frames of level ℓ come from the low-pass surface
/// the decoder will have (the coarser levels already quantized and inverted), so encoder and decoder use
/// the same frames and the distortion the encoder measures is the decoder's. Under the spherical rule the
/// coefficients are symmetrized at every level (symmetrize_level): the duplicated samples of the decoded
/// image are bit-identical, the decoded surface watertight without fusing.
///
/// Payload: "GFWV", version 1, extension, flags (bit 0: local frames), levels, side (uint32 LE), step
/// (float32), normal weight (uint8), CRC-32 of the header's first 17 bytes and the coded bytes (uint32), then
/// the range coder's bytes.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/codec/lattice_wavelet.h"
#include "kernels/core/mesh.h"

namespace gimforge {

struct WaveletCodeOptions {
  LatticeExtension extension{LatticeExtension::Mirror};
  /// Exactly one target: a quantization step (position units), at most this many payload bytes, or at
  /// least this image PSNR (dB; see WaveletCoded::psnr).
  double step{0.0};
  std::size_t target_bytes{0};
  double target_psnr{0.0};
  bool local_frames{true};
  std::uint8_t normal_weight{3};  ///< the normal component's step is the band step over this (1..16)
};

struct WaveletCoded {
  std::vector<std::uint8_t> payload;
  double step{0.0};
  /// 20·log10(D / e), D the diagonal of the image's bounding box, e the RMS distance between decoded and
  /// input samples (over the samples the mask marks defined): the image-space PSNR the rate control aims at.
  /// A sample's displacement bounds its point's distance to the other surface, so the surface PSNR
  /// (gimforge metrics) of the decoded image against the input image is about this or higher.
  double psnr{0.0};
  std::vector<Vec3> decoded;  ///< what decode_wavelet returns for the payload
  int trials{0};              ///< quantization steps tried by the rate control
};

/// Codes a side × side image (row-major, finite). `mask` (empty: all defined) marks the samples whose error
/// counts. Throws InvalidInput for a side without wavelet levels (not 2^k·q + 1 with k ≥ 1, or above 4097),
/// a non-finite sample, no or several targets, or a byte target below the header, and NumericalError when
/// no step meets the target (a byte budget too small even for the coarsest band). A PSNR target the finest
/// step misses gives the finest step's coding (its `psnr` below the target): the caller's fusing of a cut may
/// still meet it, and the caller checks.
[[nodiscard]] WaveletCoded encode_wavelet(std::span<const Vec3> image, std::uint32_t side,
                                          std::span<const std::uint8_t> mask, const WaveletCodeOptions& options);

struct WaveletDecoded {
  std::uint32_t side{0};
  LatticeExtension extension{LatticeExtension::Mirror};
  std::vector<Vec3> image;
};

/// Decodes a payload of encode_wavelet. Throws FormatError naming the cause ("not a wavelet payload",
/// "version 9 is not supported", "side 0 ...", "checksum mismatch", "truncated", "coefficient out of range")
/// for anything it cannot decode exactly as encoded; never reads outside `payload`.
/// With `expected_side` (non-zero), a payload of another side is refused from its header, before anything
/// is allocated.
[[nodiscard]] WaveletDecoded decode_wavelet(std::span<const std::uint8_t> payload, std::uint32_t expected_side = 0);

/// Largest side the decoder accepts (a 4097² image of doubles: 400 MB).
inline constexpr std::uint32_t kMaxWaveletSide = 4097;

/// Whether encode_wavelet takes a side × side image: odd, at least 3 and at most kMaxWaveletSide.
[[nodiscard]] bool wavelet_codable(std::uint32_t side);

/// Samples per side of the coarsest band of a codable side (its levels' lattice at stride 2^levels): 2 for
/// 2^k + 1, but (n + 1) for an octahedral image of odd n, whose one level leaves a band that is coded
/// without prediction, far worse than JPEG 2000 codes it.
[[nodiscard]] std::uint32_t wavelet_coarsest_side(std::uint32_t side);

}  // namespace gimforge
