#pragma once
/// \file coded_image.h
/// Quantized and coded positions of image representations (docs/archive.md, "Compressed items"; issue #19):
/// the storage that `gimforge compress` writes and every reader decodes transparently.
///   geometry       uint16 (H, W, 3)  quantized over the bounding box: position = offset + scale · q per
///                                    axis, with attributes `scale` and `offset` (float64[3]) and `bits` (12
///                                    or 16; q < 2^bits); undefined samples (mask 0) are stored as 0
///   geometry_code  uint8 (B)         a coded payload: attribute `codec` = "j2k" (JPEG 2000 of the 16-bit
///                                    planes, with `scale` and `offset` as above) or "wavelet" (the lattice
///                                    wavelet coder, kernels/codec/wavelet_coder.h); attribute `crc32`
///                                    (int64): the CRC-32 of the payload, checked before decoding
/// Normal maps and colours are quantized to 8 or 16 bits (`scale`, `offset` scalars).
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "io/archive.h"
#include "io/representation.h"
#include "kernels/codec/geometry_codec.h"

namespace gimforge::io {

/// Positions quantized per axis to `bits` (12 or 16) over the bounding box of the defined samples: position =
/// offset + scale · q per axis.
struct QuantizedPositions {
  std::uint64_t rows{0}, cols{0};
  int bits{12};
  std::vector<std::uint16_t> q;       ///< rows · cols · 3 codes (0 where the mask is 0)
  std::vector<double> offset, scale;  ///< 3 each
  /// The positions a reader gets back (NaN where `mask` is 0; empty mask: all defined).
  [[nodiscard]] std::vector<float> dequantized(std::span<const std::uint8_t> mask) const;
};

/// Quantizes rows × cols × 3 positions (`mask` empty: all defined), each sample rounded to the lattice point
/// near it that is nearest the surface's tangent plane (kernels/codec/surface_rounding.h; equal positions stay
/// equal); `block_rows` (non-zero) for an image of stacked faces, whose normals are not estimated across
/// faces. Throws InvalidInput for other bits or sizes, or a defined sample that is not finite.
[[nodiscard]] QuantizedPositions quantize_positions_in_box(std::uint64_t rows, std::uint64_t cols, std::span<const float> xyz,
                                                           std::span<const std::uint8_t> mask, int bits,
                                                           std::uint32_t block_rows = 0);

/// Writes them as `geometry` (uint16 with `offset`, `scale`, `bits`).
h5::Dataset write_quantized_positions(h5::Group& g, const QuantizedPositions& positions);

/// Writes a real image (normals in [−1, 1], colours in [0, 1]) quantized to 8 or 16 bits over [lo, hi],
/// as uint8 or uint16 with `scale` and `offset`. NaN values are stored as 0 (their samples are masked).
h5::Dataset write_quantized_real(h5::Group& g, std::string_view item, const h5::Dims& shape, std::span<const float> values,
                                 double lo, double hi, int bits);

/// Writes the coded payload `geometry_code` and its attributes.
h5::Dataset write_coded_positions(h5::Group& g, const CodedGeometry& coded);

/// What the positions of a representation were read from.
struct StoredPositions {
  std::vector<float> xyz;            ///< rows·cols·3; as stored for float32 (NaN possible), else decoded
  std::string storage{"float32"};   ///< "float32", "quant12", "quant16", "j2k", "j2k-roi" or "wavelet"
  /// A lossy code: readers fuse what it left apart (a geometry image's cut, a multi-chart zipper).
  [[nodiscard]] bool lossy_coded() const { return storage == "j2k" || storage == "wavelet" || storage == "j2k-roi"; }
  /// j2k-roi: the pixels of the window coded first (rows·cols flags), which fusing trusts; empty otherwise.
  std::vector<std::uint8_t> trusted;
};

/// True when the group stores its positions coded (`geometry_code`), so that its size comes from attributes.
[[nodiscard]] bool has_coded_positions(const h5::Group& g);

/// Reads the positions of representation `name` (rows × cols samples): the float32 or quantized `geometry`
/// or the coded `geometry_code` (decoded with the given extension rule). Throws FormatError naming the
/// archive, the item and the cause for a wrong shape or type, bad quantization attributes, q ≥ 2^bits, an
/// unknown codec or a payload that does not decode to rows × cols. The caller checks the samples it uses
/// (require_near_samples).
[[nodiscard]] StoredPositions read_positions(const h5::Group& g, const Archive& archive, const RepresentationKind& kind,
                                             const std::string& name, std::uint64_t rows, std::uint64_t cols,
                                             LatticeExtension extension);

/// "sample K has a coordinate of magnitude M, beyond ±1e+18: ..." for the first finite value of the interleaved
/// positions `xyz` beyond ±kMaxCoordinate (io/ply_ranges.h), where no input mesh lies (a reconstruction would be
/// refused as input), among the samples `mask` defines (all when empty); empty when there is none. NaN and
/// infinities are left to the caller's own checks.
[[nodiscard]] std::string far_sample_problem(std::span<const float> xyz, std::span<const std::uint8_t> mask = {});
/// Throws FormatError naming the archive, the item and the dataset the positions came from (`geometry`, or
/// `geometry_code` for a coded `storage`: StoredPositions::storage) for far_sample_problem(xyz, mask).
void require_near_samples(std::span<const float> xyz, std::span<const std::uint8_t> mask, std::string_view storage,
                          const Archive& archive, const RepresentationKind& kind, const std::string& name);

/// Reads a real image stored as float32 or quantized (uint8 / uint16 with `scale` and `offset`) as floats.
/// The caller checked the shape. Throws FormatError for another type or bad attributes.
[[nodiscard]] std::vector<float> read_real_image(const h5::Dataset& ds, const Archive& archive,
                                                 const RepresentationKind& kind, const std::string& name,
                                                 std::string_view item);

/// What an item stores, in bytes: every dataset's stored bytes (after compression filters), every
/// attribute's name and value (strings by their length), and every link name below the group, recursively.
/// What `compress --bytes` counts against the budget.
[[nodiscard]] std::uint64_t stored_bytes(const h5::Group& g);

/// The stored bytes of dataset `name` of `g` and of its attributes (0 when `g` has no such dataset).
[[nodiscard]] std::uint64_t dataset_stored_bytes(const h5::Group& g, std::string_view name);

}  // namespace gimforge::io
