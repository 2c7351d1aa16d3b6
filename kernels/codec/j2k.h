#pragma once
/// \file j2k.h
/// JPEG 2000 coding of images in memory (OpenJPEG, J2K codestreams), the codec layer of geometry-image
/// compression: quantization of a geometry image into 16-bit planes over its bounding cube (Gu et al. §4),
/// encoding at a target size (irreversible 9/7 or reversible 5/3 wavelet, one quality layer, rate
/// allocation by OpenJPEG's distortion–rate optimization; the comment segment OpenJPEG adds to every main
/// header is removed), decoding with every codec message captured.
///
/// Region-of-interest priority (adaptive geometry images §4, Fig. 11): JPEG 2000's max-shift scales the
/// ROI's wavelet coefficients above every background bit-plane so that all the ROI's bits come first.
/// OpenJPEG (2.5) takes a ROI only for a whole component (roi_compno / roi_shift), and its encoder writes the
/// RGN marker without scaling any coefficient (opj_t1_cblk_encode_processor never reads roishift), so a
/// spatial max-shift cannot be asked of it. encode_roi_priority keeps max-shift's order of bits with two
/// codestreams: the ROI's bounding window first, as many bytes as it takes to code it losslessly or as the
/// budget allows, then the whole image in what remains (at least `background_floor` of the budget, so the
/// surface outside the ROI stays a surface) with the window filled smoothly from around it (push–pull: a
/// smooth fill costs the wavelet coder next to nothing, the bytes go to what lies outside the window);
/// decoding pastes the window over the whole image.
#include <algorithm>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "kernels/core/mesh.h"

namespace gimforge {

/// `components` planes of width × height unsigned 16-bit samples, plane after plane (row-major).
struct Planes16 {
  std::uint32_t width{0};
  std::uint32_t height{0};
  std::uint32_t components{0};
  std::vector<std::uint16_t> samples;
};

/// How a geometry image's float positions became 16-bit planes: position = offset + scale · q.
struct Quantization {
  Vec3 offset{Vec3::Zero()};
  double scale{1.0};  ///< one scale for all axes (the bounding cube): the error is isotropic
};

/// Quantizes n·n interleaved xyz positions (row-major, as GeometryImage::positions) to three 16-bit planes
/// over their bounding cube. Throws InvalidInput for a size mismatch or a non-finite position.
[[nodiscard]] Planes16 quantize_positions(std::span<const float> xyz, std::uint32_t width, std::uint32_t height,
                                          Quantization& quantization);
/// The inverse: interleaved xyz floats.
[[nodiscard]] std::vector<float> dequantize_positions(const Planes16& planes, const Quantization& quantization);

struct J2kOptions {
  std::size_t target_bytes{0};  ///< 0: lossless (reversible 5/3); otherwise at most about this many bytes (9/7)
  bool reversible{false};       ///< 5/3 also at a target size
  int resolutions{0};           ///< wavelet resolutions (levels + 1), at most what the size allows; 0: up to 6
};

/// Encodes the planes as a J2K codestream. Throws InvalidInput (empty planes, a side below 2) or
/// NumericalError naming OpenJPEG's message when it fails.
[[nodiscard]] std::vector<std::uint8_t> encode_j2k(const Planes16& planes, const J2kOptions& options);

/// Decodes a J2K codestream of 16-bit planes. Throws FormatError with OpenJPEG's message for a damaged or
/// foreign codestream (another precision, signed samples, a side above 65536, components of different sizes).
/// With `expected_width` and `expected_height` (non-zero), a codestream whose header declares another size
/// is refused before anything is decoded (a few hostile bytes must not make the decoder allocate gigabytes);
/// likewise another number of components than `expected_components` (non-zero).
[[nodiscard]] Planes16 decode_j2k(std::span<const std::uint8_t> codestream, std::uint32_t expected_width = 0,
                                  std::uint32_t expected_height = 0, std::uint32_t expected_components = 0);

/// The ROI-priority coding of encode_roi_priority.
struct RoiCoded {
  std::uint32_t x0{0}, y0{0};                ///< the window's corner in the image (pixels)
  std::uint32_t width{0}, height{0};         ///< and its size
  std::uint32_t image_width{0}, image_height{0};  ///< the whole image's
  std::vector<std::uint8_t> window;          ///< codestream of the window, coded first
  std::vector<std::uint8_t> background;      ///< codestream of the whole image, in what the window left
  /// Bytes of `background`'s main header that the payload leaves out: the window's main header with the
  /// image's size in its SIZ marker is the same bytes (same planes, wavelet and levels), so the payload
  /// stores it once (0: stored whole). At a few hundred bytes a main header is a fifth of the budget.
  std::size_t shared_header{0};
  [[nodiscard]] std::size_t bytes() const { return window.size() + background.size() - std::min(shared_header, background.size()); }
};

/// The smallest budget encode_roi_priority takes: two codestreams of 128 bytes at least (below it the
/// window's codestream is mostly its main header, and plain coding keeps the ROI closer).
inline constexpr std::size_t kRoiLeastBudget = 256;

/// Codes `planes` within `budget` bytes with the ROI's pixels (`roi`, width·height flags) first: the ROI's
/// bounding window gets min(its lossless size, (1 − background_floor) · budget), the whole image the rest.
/// When the window is coded lossy with as many wavelet levels as the image (sides of 32 and more), the
/// image's main header is shared (shared_header).
/// Throws InvalidInput for an empty ROI, a mismatched mask or a budget too small for two codestreams (below
/// kRoiLeastBudget, or one that does not hold the image's smallest codestream beside the window's).
[[nodiscard]] RoiCoded encode_roi_priority(const Planes16& planes, std::span<const std::uint8_t> roi,
                                           std::size_t budget, double background_floor = 0.1);
/// Decodes both codestreams and pastes the window over the image.
[[nodiscard]] Planes16 decode_roi_priority(const RoiCoded& coded);

/// A RoiCoded as one payload (an archive's `geometry_code` with codec "j2k-roi"): the 4 bytes "ROI2", then
/// seven little-endian uint32 — the window's corner x0, y0, its width and height, the window codestream's
/// bytes L, the image's width and height — then the window's codestream (L bytes) and the whole image's.
/// When the image's codestream starts at a SOT marker (0xFF90) it comes without its main header
/// (RoiCoded::shared_header): a reader takes the window's main header with Xsiz and XTsiz set to the image's
/// width, Ysiz and YTsiz to its height. Readers also take payloads written before that: "ROI1", a 24-byte
/// header without the image's size, both codestreams whole.
inline constexpr std::size_t kRoiPayloadHeader = 32;
[[nodiscard]] std::vector<std::uint8_t> roi_payload(const RoiCoded& coded);
/// The window of such a payload, as flags over a `width` × `height` image (1 inside the window); empty when the
/// header does not describe a window inside the image.
[[nodiscard]] std::vector<std::uint8_t> roi_payload_window(std::span<const std::uint8_t> payload, std::uint32_t width,
                                                           std::uint32_t height);
/// Decodes such a payload to a `width` × `height` image of `components` planes. Throws FormatError naming
/// what is wrong (short, another magic, a window outside the image or of another size than its header
/// says, a codestream that does not decode to the declared size): the header is checked before anything is
/// decoded.
[[nodiscard]] Planes16 decode_roi_payload(std::span<const std::uint8_t> payload, std::uint32_t width, std::uint32_t height,
                                          std::uint32_t components);

}  // namespace gimforge
