#pragma once
/// \file compress.h
/// Compressing image representations (issue #19; Gu et al. §4–5, Praun & Hoppe §6): one item of an archive
/// written into another archive with its positions quantized (12 or 16 bits) or coded (JPEG 2000 or the
/// lattice-wavelet coder) at a byte or PSNR target. Readers decode such items transparently
/// (io/coded_image.h), geometry images with their cut fused and the fusing diffused (kernels/gim/gim_fuse.h).
/// `gimforge compress` and `batch --codec` call compress_item.
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "io/archive.h"
#include "io/representation.h"
#include "kernels/codec/geometry_codec.h"
#include "kernels/gim/geometry_image.h"
#include "kernels/mcgim/mcgim_image.h"
#include "kernels/sphere/sphere_convert.h"
#include "jobs/gim_store.h"
#include "kernels/core/embree_device.h"

namespace gimforge::jobs {

/// J2kRoi: JPEG 2000 with the item's region of interest (`convert --roi`) first, at a byte budget.
enum class CodecChoice : std::uint8_t { Auto, J2k, Wavelet, Quant12, Quant16, J2kRoi };

/// Parses "auto", "j2k", "wavelet", "quant12", "quant16", "j2k-roi"; throws InvalidInput naming the choices
/// otherwise.
[[nodiscard]] CodecChoice parse_codec(const std::string& text);
[[nodiscard]] std::string to_string(CodecChoice codec);

/// The codecs `choice` tries for an image whose wavelet form is square with `wavelet_side` samples per side
/// (0: it has none, e.g. a cube-domain spherical image). auto tries the wavelet coder only where it takes
/// that side (`wavelet_codable`: not above 4097); an explicit --codec wavelet it cannot take throws
/// InvalidInput naming `path`, and one whose coarsest band is large (an octahedral image of odd n) warns.
[[nodiscard]] std::vector<GeometryCodec> codec_candidates(CodecChoice choice, bool lossless, std::uint32_t wavelet_side,
                                                          const std::string& path);

struct CompressOptions {
  CodecChoice codec{CodecChoice::Auto};
  /// Exactly one for j2k, wavelet and auto: the item's stored bytes (every dataset, attribute and name of
  /// its group, io::stored_bytes), a PSNR (dB, image space, against the stored image), or lossless (j2k:
  /// the reversible 5/3 wavelet of the 16-bit planes). None for quant12 and quant16.
  std::uint64_t bytes{0};
  double psnr{0.0};
  bool lossless{false};
  /// Measure the surface PSNR of every candidate against the stored image (gimforge metrics' definition,
  /// `metric_samples` per direction); auto picks by it. Off: by the PSNR of the samples' displacements along
  /// the stored image's normals (the part of a small displacement the surface distance sees).
  bool measure{true};
  std::string bytes_option{"--bytes"};  ///< what messages call the byte budget (batch: "--rate")
  std::size_t metric_samples{200'000};
};

/// Throws InvalidInput when the options do not name one target where the codec needs one (or name one
/// for quant12 / quant16), or a byte budget below 1 KB.
void check_compress_options(const CompressOptions& options);

struct CodecTrial {
  std::string codec;
  std::uint64_t payload_bytes{0};
  double image_psnr{0.0};
  double surface_psnr{0.0};  ///< NaN when not measured
  double normal_psnr{0.0};   ///< of the displacements along the stored surface's normals (auto's choice without a metric)
};

struct CompressedItem {
  std::string path;            ///< "gim/NAME" or "spherical/NAME"
  std::string codec;           ///< the codec kept
  std::uint64_t bytes_before{0};  ///< stored bytes of the item in the input archive
  std::uint64_t geometry_bytes_before{0};  ///< of which its positions (`geometry`)
  std::uint64_t dropped_bytes{0};  ///< of which its normal map and colours, which coded items drop
  std::uint64_t bytes_after{0};   ///< and in the output archive
  double image_psnr{0.0};      ///< of the decoded (and fused) samples against the stored ones
  double surface_psnr{0.0};    ///< symmetric RMS Hausdorff PSNR of the reconstructions (NaN: not measured)
  double seam_gap{0.0};        ///< spherical: largest distance between decoded duplicates before merging (0: watertight)
  double roi_image_psnr{std::numeric_limits<double>::quiet_NaN()};  ///< gim with a ROI: image_psnr over the ROI's samples
  double seconds{0.0};
  std::vector<CodecTrial> trials;
};

/// Compresses item `ref` of `in` into `out` (open read-write) under the same kind and name. Geometry images,
/// spherical and multi-chart geometry images; the coded forms keep the sideband (gim), the mask (spherical)
/// or mask, charts and zipper (mcgim), the
/// local frame's origin and the fidelity of the original conversion, and drop normal maps, colours,
/// adaptive sample positions and the sphere parametrization (quant12 / quant16 keep normals and colours
/// quantized to 8 / 16 bits). Throws InvalidInput for another kind, an item that is already coded, or a
/// target the codecs cannot meet; FormatError from the readers.
CompressedItem compress_item(const EmbreeDevice& device, const io::Archive& in, const ImageRef& ref, io::Archive& out,
                             const CompressOptions& options);

/// The same for an image in memory (a batch item, `batch --codec`): writes the compressed item into the empty
/// group `g` (frame origin, sideband or mask, payload, the kept record). `path` names it in messages. `roi`:
/// the image's region of interest (n·n flags, the archive's roi_mask), which `--codec j2k-roi` needs.
CompressedItem compress_gim_image(const EmbreeDevice& device, const GeometryImage& image,
                                  const io::RepresentationRecord& record, const Vec3& origin, h5::Group& g,
                                  const CompressOptions& options, const std::string& path,
                                  std::span<const std::uint8_t> roi = {});
/// `roi`: a flat-octa image's region of interest (one flag per sample), for roi_image_psnr.
CompressedItem compress_spherical_image(const EmbreeDevice& device, const SphericalImage& image,
                                        const io::RepresentationRecord& record, const Vec3& origin, h5::Group& g,
                                        const CompressOptions& options, const std::string& path,
                                        std::span<const std::uint8_t> roi = {});

/// The same for a multi-chart geometry image (`--codec j2k`, auto or quant12/16; the wavelet coder takes square
/// images only): the mask, chart ids, zipper table and per-chart stretch are kept exactly, the normals dropped
/// (central differences of the positions, recomputed by readers); readers fuse a lossy code's zipper clusters.
CompressedItem compress_multichart_image(const EmbreeDevice& device, const MultiChartImage& image,
                                        std::span<const double> chart_stretch, const io::RepresentationRecord& record,
                                        const Vec3& origin, h5::Group& g, const CompressOptions& options,
                                        const std::string& path);

/// Writes item `ref` of `in` into `out` as float32 images (decoded, fused), the way convert writes them, for
/// readers without the codecs (h5py without OpenJPEG; the wavelet coder is gimforge's own). The record and
/// frame origin are kept; what compression dropped (normal maps, colours, the sphere parametrization) stays
/// absent. Throws InvalidInput for relief maps.
void decompress_item(const io::Archive& in, const ImageRef& ref, io::Archive& out);

/// A compressed item of a batch output (`batch --codec`: /batch/<output>/items/<k> of a gim, sphere or mcgim output).
struct BatchCodedItem {
  std::string output;
  std::uint64_t index{0};   ///< k: its position in /batch/<output>/names
  Method kind{Method::Gim};
  std::string name;         ///< what decompress calls it: "<output>.<k>"
};

/// The compressed items of the archive's batch outputs, after each output's summary has been checked
/// (io::read_batch_summary: `count`, items/0 .. items/<count − 1>, names). Outputs without `codec` are skipped.
[[nodiscard]] std::vector<BatchCodedItem> coded_batch_items(const io::Archive& in);

/// Writes one of them into `out` as a float32 item /gim/<name> or /spherical/<name>, decoded and fused.
void decompress_batch_item(const io::Archive& in, const BatchCodedItem& item, io::Archive& out);

}  // namespace gimforge::jobs
