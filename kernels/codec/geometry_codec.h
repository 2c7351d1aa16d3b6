#pragma once
/// \file geometry_codec.h
/// Coding the positions of an image representation at a target: JPEG 2000 of the 16-bit quantized planes
/// (OpenJPEG, j2k.h; Gu et al. §4 code the geometry image with an image coder) or the lattice-wavelet coder
/// (wavelet_coder.h; the spherical extension rules for octahedral images, Praun & Hoppe §6). Fusing a
/// geometry image's cut after decoding is the caller's (gim/gim_fuse.h): it needs the sideband.
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "kernels/codec/j2k.h"
#include "kernels/codec/lattice_wavelet.h"
#include "kernels/core/mesh.h"

namespace gimforge {

/// J2kRoi: JPEG 2000 with a region of interest first (adaptive geometry images §4, j2k.h encode_roi_priority).
enum class GeometryCodec : std::uint8_t { J2k, Wavelet, J2kRoi };

/// "j2k", "wavelet" or "j2k-roi": the `codec` attribute of a coded item.
[[nodiscard]] std::string_view codec_name(GeometryCodec codec);

/// Exactly one of: lossless (JPEG 2000's reversible 5/3 of the 16-bit planes; the wavelet coder has no
/// lossless mode), at most `bytes` payload bytes, or at least `psnr` dB (image space, WaveletCoded::psnr).
struct CodingTarget {
  bool lossless{false};
  std::size_t bytes{0};
  double psnr{0.0};
};

struct CodedGeometry {
  GeometryCodec codec{GeometryCodec::J2k};
  std::vector<std::uint8_t> payload;
  Quantization quantization;  ///< JPEG 2000: position = offset + scale · q
  double psnr{0.0};           ///< image-space PSNR of the decoded samples against the input (defined ones)
  std::vector<Vec3> decoded;  ///< the decoded image, as decode_geometry returns it
};

/// Codes a width × height image of positions (row-major). Samples that `mask` marks 0 (empty mask: all
/// defined) may be NaN: they are filled from their neighbours first and their error does not count. The
/// wavelet coder needs a square image of side 2^k·q + 1 and uses `extension` (Mirror for geometry images,
/// Sphere for octahedral ones); JPEG 2000 uses its own symmetric extension. Throws InvalidInput for a target
/// that is not exactly one, a lossless wavelet request, an image the codec cannot code; NumericalError
/// when the target cannot be met.
[[nodiscard]] CodedGeometry encode_geometry(std::span<const Vec3> image, std::uint32_t width, std::uint32_t height,
                                            std::span<const std::uint8_t> mask, GeometryCodec codec,
                                            LatticeExtension extension, const CodingTarget& target);

/// Codes a width × height image (every sample defined) within `bytes` payload bytes with the samples `roi`
/// flags (width·height, 0/1) first: the ROI's window up to lossless or most of the budget, the whole image in
/// the rest (j2k.h encode_roi_priority; the payload is roi_payload's). Throws InvalidInput for mismatched
/// sizes, an empty ROI or a budget too small for two codestreams (kRoiPayloadHeader + kRoiLeastBudget).
[[nodiscard]] CodedGeometry encode_geometry_roi_first(std::span<const Vec3> image, std::uint32_t width, std::uint32_t height,
                                                      std::span<const std::uint8_t> roi, std::size_t bytes);

/// Decodes a payload to width × height positions. Throws FormatError when the payload does not decode or
/// decodes to another size or extension than the caller expects.
[[nodiscard]] std::vector<Vec3> decode_geometry(GeometryCodec codec, std::span<const std::uint8_t> payload,
                                                const Quantization& quantization, std::uint32_t width,
                                                std::uint32_t height, LatticeExtension extension);

/// Interleaved xyz floats (n·3, as the archive's images) and points, one way and the other.
[[nodiscard]] std::vector<float> to_floats(std::span<const Vec3> image);
[[nodiscard]] std::vector<Vec3> to_points(std::span<const float> xyz);

/// Image-space PSNR (dB) of `decoded` against `original` over the samples `mask` marks defined (all when
/// empty): 20·log10(bounding-box diagonal of the defined originals / RMS sample distance); +inf when equal.
[[nodiscard]] double image_psnr(std::span<const Vec3> original, std::span<const Vec3> decoded,
                                std::span<const std::uint8_t> mask);

/// PSNR (dB) of the displacements `decoded − original` along the normals of `original` (central differences,
/// clamped at the edges of each face of `face_height` rows: stacked face images are not differenced across
/// faces), over the defined samples, against the diagonal of their bounding box: the part of a small
/// displacement that a surface distance sees. +inf when there is none.
[[nodiscard]] double normal_psnr(std::span<const Vec3> original, std::span<const Vec3> decoded, std::uint32_t width,
                                 std::uint32_t height, std::uint32_t face_height, std::span<const std::uint8_t> mask);

/// Fills the samples `mask` marks 0 layer by layer with the mean of their filled 4-neighbours (a smooth
/// fill costs a wavelet coder next to nothing). Throws InvalidInput when no sample is defined.
void fill_undefined(std::vector<Vec3>& image, std::uint32_t width, std::uint32_t height,
                    std::span<const std::uint8_t> mask);

}  // namespace gimforge
