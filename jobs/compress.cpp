#include "jobs/compress.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "io/batch_archive.h"
#include "io/coded_image.h"
#include "io/gim_archive.h"
#include "io/mcgim_archive.h"
#include "io/sphere_archive.h"
#include "jobs/pipeline.h"
#include "kernels/codec/geometry_codec.h"
#include "kernels/codec/wavelet_coder.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "kernels/gim/gim_fuse.h"
#include "kernels/mcgim/mcgim_fuse.h"
#include "kernels/sphere/sphere_convert.h"

namespace gimforge::jobs {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
/// What a coded item keeps of the original record: the fidelity of the conversion it came from.
constexpr std::array<const char*, 4> kKeptNumbers{"psnr", "hausdorff_rms", "hausdorff_max", "bbox_diagonal"};
/// Numbers written after the payload (their cost is reserved before it is coded).
constexpr std::array<const char*, 2> kLateNumbers{"compressed_image_psnr", "compressed_psnr"};
constexpr std::uint64_t kMinBudget = 1024;

std::uint64_t number_cost(std::string_view key) { return key.size() + sizeof(double); }

/// The bytes the payload dataset adds besides the payload: its name and its attributes.
std::uint64_t payload_overhead(GeometryCodec codec) {
  std::uint64_t cost = std::string_view("geometry_code").size() + std::string_view("codec").size() + codec_name(codec).size() +
                       std::string_view("crc32").size() + sizeof(std::int64_t);
  if (codec != GeometryCodec::Wavelet) cost += std::string_view("offset").size() + 3 * sizeof(double) + std::string_view("scale").size() + sizeof(double);
  return cost;
}


/// Above this many samples per side of the coarsest band, --codec wavelet warns (it has no prediction).
constexpr std::uint32_t kCoarsestSideWarning = 17;

struct Candidate {
  std::string failure;  ///< why this codec did not meet the target (then nothing else is set)
  CodedGeometry coded;
  std::vector<float> final_xyz;  ///< what the reader will return
  double image_psnr{0.0};
  double normal_psnr{0.0};
  double surface_psnr{kNaN};
};

/// The diagonal of the defined samples' bounding box.
double diagonal(std::span<const Vec3> points, std::span<const std::uint8_t> mask) {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (std::size_t k = 0; k < points.size(); ++k)
    if (mask.empty() || mask[k]) lo = lo.cwiseMin(points[k]), hi = hi.cwiseMax(points[k]);
  return (hi - lo).norm();
}

/// Codes `coded` with `codec` at the options' target within `payload_budget` bytes, then runs `finish` (the
/// reader's post-processing: fusing, and for multi-chart images adding the chart planes back) and measures
/// the result against `reference` (the stored image; `coded` itself but for multi-chart images). A PSNR
/// target is raised when fusing took the result below it.
Candidate try_codec(GeometryCodec codec, std::span<const Vec3> coded, std::span<const Vec3> reference, std::uint32_t width,
                    std::uint32_t height, std::uint32_t face_height, std::span<const std::uint8_t> mask, LatticeExtension ext,
                    const CompressOptions& options, std::uint64_t payload_budget,
                    const std::function<void(std::vector<float>&, const CodedGeometry&)>& finish,
                    std::span<const std::uint8_t> roi = {}) {
  CodingTarget target{options.lossless, options.bytes > 0 ? payload_budget : 0, options.psnr};
  // The coder's PSNR is against its own image's diagonal: a smaller one (residuals) needs fewer dB for the same
  // error. The shift is close, not exact (the residuals' 16-bit steps are not the result's): where the coder
  // cannot reach the shifted target, its lossless code is measured against the real one.
  const bool residual = coded.data() != reference.data();
  if (target.psnr > 0.0 && residual)
    target.psnr = std::max(1.0, target.psnr - 20.0 * std::log10(diagonal(reference, mask) / diagonal(coded, mask)));
  Candidate c;
  for (int attempt = 0;; ++attempt) {
    try {
      c.coded = codec == GeometryCodec::J2kRoi ? encode_geometry_roi_first(coded, width, height, roi, target.bytes)
                                               : encode_geometry(coded, width, height, mask, codec, ext, target);
    } catch (const NumericalError&) {
      if (!residual || target.lossless || codec != GeometryCodec::J2k) throw;
      target = CodingTarget{true, 0, 0.0};
      c.coded = encode_geometry(coded, width, height, mask, codec, ext, target);
    }
    c.final_xyz = to_floats(c.coded.decoded);
    finish(c.final_xyz, c.coded);
    const std::vector<Vec3> final_points = to_points(c.final_xyz);
    c.image_psnr = image_psnr(reference, final_points, mask);
    if (options.psnr <= 0.0 || c.image_psnr >= options.psnr) {
      c.normal_psnr = normal_psnr(reference, final_points, width, height, face_height, mask);
      break;
    }
    if (attempt == 3 || target.lossless)
      throw NumericalError(fmt::format("{}: {:.2f} dB after fusing{}, below --psnr {}", codec_name(codec), c.image_psnr,
                                       target.lossless ? " (lossless)" : "", options.psnr));
    target.psnr += options.psnr - c.image_psnr + 0.2;
  }
  if (payload_budget > 0 && c.coded.payload.size() > payload_budget)
    throw NumericalError(fmt::format("{}: {} payload bytes, above the {} the item leaves", codec_name(codec),
                                     c.coded.payload.size(), payload_budget));
  return c;
}

double surface_psnr(const EmbreeDevice& device, const TriMesh& a, const TriMesh& b, std::size_t samples) {
  HausdorffOptions h;
  h.samples = samples;
  return symmetric_hausdorff(device, MeshView(a.positions, a.faces), MeshView(b.positions, b.faces), h).psnr;
}

/// Picks the best candidate: the highest PSNR at a byte budget, the fewest bytes at a PSNR target.
std::size_t best_of(const std::vector<Candidate>& all, const CompressOptions& options, const std::string& path) {
  std::size_t best = all.size();
  std::string why;
  for (std::size_t i = 0; i < all.size(); ++i) {
    if (!all[i].failure.empty()) {
      why += (why.empty() ? "" : "; ") + all[i].failure;
      continue;
    }
    if (best == all.size()) {
      best = i;
      continue;
    }
    const auto score = [&](const Candidate& c) {
      return options.measure && std::isfinite(c.surface_psnr) ? c.surface_psnr : c.normal_psnr;
    };
    const bool better = options.psnr > 0.0 ? all[i].coded.payload.size() < all[best].coded.payload.size()
                                           : score(all[i]) > score(all[best]);
    if (better) best = i;
  }
  if (best == all.size()) throw NumericalError(fmt::format("{}: no codec meets the target ({})", path, why));
  return best;
}

void record_trials(CompressedItem& item, const std::vector<Candidate>& all) {
  for (const Candidate& c : all)
    if (c.failure.empty())
      item.trials.push_back(
          {std::string(codec_name(c.coded.codec)), c.coded.payload.size(), c.image_psnr, c.surface_psnr, c.normal_psnr});
}

/// try_codec, with a target it cannot meet recorded as the candidate's failure (auto tries the others).
Candidate attempt(GeometryCodec codec, const std::function<Candidate()>& run) {
  try {
    return run();
  } catch (const NumericalError& e) {
    Candidate c;
    c.coded.codec = codec;
    c.failure = e.what();
    return c;
  }
}

io::RepresentationRecord kept_record(const io::RepresentationRecord& full) {
  io::RepresentationRecord r;
  r.source = full.source;
  for (const char* key : kKeptNumbers)
    if (const auto it = full.numbers.find(key); it != full.numbers.end()) r.numbers[key] = it->second;
  return r;
}

std::uint64_t late_cost() {
  std::uint64_t cost = 0;
  for (const char* key : kLateNumbers) cost += number_cost(key);
  return cost;
}

void finish_item(h5::Group& g, CompressedItem& item, double image, double surface) {
  g.set_attribute(kLateNumbers[0], image);
  g.set_attribute(kLateNumbers[1], surface);
  item.image_psnr = image;
  item.surface_psnr = surface;
  item.bytes_after = io::stored_bytes(g);
}

/// Records the trials, writes the best candidate's payload and names its codec; returns it.
const Candidate& store_best(h5::Group& g, CompressedItem& item, const std::vector<Candidate>& all, const CompressOptions& options) {
  record_trials(item, all);
  const Candidate& best = all[best_of(all, options, item.path)];
  (void)io::write_coded_positions(g, best.coded);
  item.codec = codec_name(best.coded.codec);
  return best;
}

/// The payload budget left by what the group already stores, or an error naming the shortfall.
std::uint64_t payload_budget(const h5::Group& g, const CompressOptions& options, GeometryCodec codec,
                             const std::string& path) {
  if (options.bytes == 0) return 0;
  const std::uint64_t fixed = io::stored_bytes(g) + late_cost() + payload_overhead(codec);
  // The smallest useful payload: a codestream's headers and coarsest levels; ROI-first holds two.
  const std::uint64_t least = codec == GeometryCodec::J2kRoi ? kRoiPayloadHeader + kRoiLeastBudget : 256;
  if (options.bytes < fixed + least)
    throw InvalidInput(fmt::format("{}: {} {} leaves no room for the coded geometry: what the item stores besides it "
                                   "(sideband, mask, chart ids, zipper, attributes) takes {} bytes, and the coded "
                                   "geometry at least {} more (give at least {})",
                                   path, options.bytes_option, options.bytes, fixed, least, fixed + least));
  return options.bytes - fixed;
}

}  // namespace

std::vector<GeometryCodec> codec_candidates(CodecChoice choice, bool lossless, std::uint32_t wavelet_side,
                                            const std::string& path) {
  if (choice == CodecChoice::J2kRoi) return {GeometryCodec::J2kRoi};
  if (choice == CodecChoice::J2k || lossless) return {GeometryCodec::J2k};
  const bool codable = wavelet_side > 0 && wavelet_codable(wavelet_side);
  if (choice != CodecChoice::Wavelet) {
    if (codable) return {GeometryCodec::J2k, GeometryCodec::Wavelet};
    return {GeometryCodec::J2k};
  }
  if (!codable)
    throw InvalidInput(fmt::format("{}: the wavelet coder takes square images of side 2^k·q + 1 up to {} samples, "
                                   "not {}; use --codec j2k or auto",
                                   path, kMaxWaveletSide, wavelet_side));
  if (const std::uint32_t coarsest = wavelet_coarsest_side(wavelet_side); coarsest > kCoarsestSideWarning)
    spdlog::warn("{}: on a {} × {} image the wavelet coder's coarsest band keeps {} × {} samples, coded without "
                 "prediction: JPEG 2000 (--codec j2k or auto) codes it far better (octahedral images: n a multiple of "
                 "a power of two, such as 64, 96 or 128)",
                 path, wavelet_side, wavelet_side, coarsest, coarsest);
  return {GeometryCodec::Wavelet};
}

CompressedItem compress_gim_image(const EmbreeDevice& device, const GeometryImage& image,
                                  const io::RepresentationRecord& record, const Vec3& origin, h5::Group& g,
                                  const CompressOptions& options, const std::string& path, std::span<const std::uint8_t> roi) {
  check_compress_options(options);
  CompressedItem item;
  item.path = path;
  const std::uint32_t n = image.size;
  if (options.codec == CodecChoice::J2kRoi &&
      (roi.size() != std::size_t{n} * n || std::find(roi.begin(), roi.end(), std::uint8_t{1}) == roi.end()))
    throw InvalidInput(fmt::format("{}: --codec j2k-roi codes the region of interest of an image converted with "
                                   "--sampling adaptive --roi ...; this item has none (use --codec j2k)",
                                   path));
  const std::vector<Vec3> points = to_points(image.positions);
  write_frame_origin(g, origin);
  g.set_attribute("size", static_cast<std::int64_t>(n));
  io::write_sideband(g, image.sideband);
  if (options.codec == CodecChoice::Quant12 || options.codec == CodecChoice::Quant16) {
    const int bits = options.codec == CodecChoice::Quant12 ? 12 : 16;
    g.set_attribute("normal_size", static_cast<std::int64_t>(image.normal_size));
    const io::QuantizedPositions quantized = io::quantize_positions_in_box(n, n, image.positions, {}, bits);
    (void)io::write_quantized_positions(g, quantized);
    if (image.normal_size > 0)
      (void)io::write_quantized_real(g, "normals", {image.normal_size, image.normal_size, 3}, image.normals, -1.0, 1.0, bits == 12 ? 8 : 16);
    if (image.color_size > 0) (void)io::write_quantized_real(g, "colors", {n, n, 3}, image.colors, 0.0, 1.0, bits == 12 ? 8 : 16);
    io::write_record(g, "gim", record);
    item.codec = to_string(options.codec);
    const std::vector<float> back = quantized.dequantized({});
    const double psnr_image = image_psnr(points, to_points(back), {});
    if (!roi.empty()) item.roi_image_psnr = image_psnr(points, to_points(back), roi);
    const double psnr_surface =
        options.measure ? surface_psnr(device, reconstruct_geometry_image(image.positions, n, &image.sideband),
                                       reconstruct_geometry_image(back, n, &image.sideband), options.metric_samples)
                        : kNaN;
    finish_item(g, item, psnr_image, psnr_surface);
    return item;
  }
  g.set_attribute("normal_size", std::int64_t{0});
  io::write_record(g, "gim", kept_record(record));
  const auto fuse = [&](std::vector<float>& xyz, const CodedGeometry& coded) {
    // As the reader fuses (io/gim_archive.cpp): a ROI-first code's window is trusted.
    const std::vector<std::uint8_t> trusted =
        coded.codec == GeometryCodec::J2kRoi ? roi_payload_window(coded.payload, n, n) : std::vector<std::uint8_t>{};
    std::vector<Vec3> displacement;
    (void)fuse_cut(xyz, n, image.sideband, displacement, trusted);
    diffuse_fusing(xyz, n, displacement);
  };
  std::optional<TriMesh> stored;
  std::vector<Candidate> all;
  for (const GeometryCodec codec : codec_candidates(options.codec, options.lossless, n, item.path)) {
    const std::uint64_t budget = payload_budget(g, options, codec, item.path);
    Candidate c = attempt(codec, [&] {
      return try_codec(codec, points, points, n, n, n, {}, LatticeExtension::Mirror, options, budget, fuse, roi);
    });
    if (options.measure && c.failure.empty()) {
      if (!stored) stored = reconstruct_geometry_image(image.positions, n, &image.sideband);
      c.surface_psnr = surface_psnr(device, *stored, reconstruct_geometry_image(c.final_xyz, n, &image.sideband),
                                    options.metric_samples);
    }
    all.push_back(std::move(c));
  }
  const Candidate& best = store_best(g, item, all, options);
  if (!roi.empty()) item.roi_image_psnr = image_psnr(points, to_points(best.final_xyz), roi);
  finish_item(g, item, best.image_psnr, best.surface_psnr);
  return item;
}

namespace {

/// The largest distance between decoded samples that are one domain point.
double seam_gap(const DomainImage& layout, std::span<const float> xyz, std::span<const std::uint8_t> mask) {
  const std::vector<std::uint32_t> ids = layout.vertex_ids();
  std::vector<std::int64_t> first(layout.num_domain_points(), -1);
  double gap = 0.0;
  for (std::size_t k = 0; k < ids.size(); ++k) {
    if (mask[k] == 0) continue;
    std::int64_t& f = first[ids[k]];
    if (f < 0) {
      f = static_cast<std::int64_t>(k);
      continue;
    }
    const auto j = static_cast<std::size_t>(f);
    gap = std::max(gap, (Vec3(xyz[3 * k], xyz[3 * k + 1], xyz[3 * k + 2]) - Vec3(xyz[3 * j], xyz[3 * j + 1], xyz[3 * j + 2])).norm());
  }
  return gap;
}

}  // namespace

CompressedItem compress_spherical_image(const EmbreeDevice& device, const SphericalImage& image,
                                        const io::RepresentationRecord& record, const Vec3& origin, h5::Group& g,
                                        const CompressOptions& options, const std::string& path,
                                        std::span<const std::uint8_t> roi) {
  check_compress_options(options);
  if (options.codec == CodecChoice::J2kRoi)
    throw InvalidInput(fmt::format("{}: --codec j2k-roi codes geometry images converted with --roi (method gim); "
                                   "a spherical image is coded with --codec j2k, wavelet or auto", path));
  CompressedItem item;
  item.path = path;
  const DomainImage layout = image.layout();
  const h5::Dims shape = io::sphere_image_shape(layout, 3);
  const auto rows = static_cast<std::uint32_t>(shape[0]), cols = static_cast<std::uint32_t>(shape[1]);
  const bool octahedral = layout.domain() == SphericalDomain::Octahedron || layout.domain() == SphericalDomain::FlatOctahedron;
  if (options.codec == CodecChoice::Wavelet && !octahedral)
    throw InvalidInput(fmt::format("{}: the wavelet coder takes octahedral images (octa, flat-octa), not {}; use --codec j2k",
                                   item.path, to_string(layout.domain())));

  write_frame_origin(g, origin);
  io::write_sphere_layout(g, layout, false);
  // A coded item of a closed input stores no mask (all samples defined): at 513² even the gzip of ones costs
  // about 1 KB, half of a 2 KB budget. Quantized items keep it, as convert writes them.
  const bool quantized = options.codec == CodecChoice::Quant12 || options.codec == CodecChoice::Quant16;
  if (quantized || std::find(image.mask.begin(), image.mask.end(), std::uint8_t{0}) != image.mask.end())
    (void)io::write_image(g, "mask", io::sphere_image_shape(layout, 0), image.mask);
  const auto reread = [&](std::span<const float> xyz) {
    SphericalImage copy = image;
    copy.positions.assign(xyz.begin(), xyz.end());
    return reconstruct_spherical_geometry(copy);
  };
  const std::vector<Vec3> points = to_points(image.positions);
  std::vector<std::uint8_t> in_roi(roi.begin(), roi.end());  // the ROI's defined samples (roi_image_psnr)
  for (std::size_t k = 0; k < in_roi.size() && k < image.mask.size(); ++k) in_roi[k] = in_roi[k] != 0 && image.mask[k] != 0;
  if (quantized) {
    const int bits = options.codec == CodecChoice::Quant12 ? 12 : 16;
    const io::QuantizedPositions codes =
        io::quantize_positions_in_box(rows, cols, image.positions, image.mask, bits, static_cast<std::uint32_t>(layout.height()));
    {  // closed before finish_item counts the stored bytes: an open dataset's chunks may still be in the cache
      h5::Dataset ds = io::write_quantized_positions(g, codes);
      io::write_sphere_layout(ds, layout, true);
    }
    if (!image.colors.empty()) (void)io::write_quantized_real(g, "colors", shape, image.colors, 0.0, 1.0, bits == 12 ? 8 : 16);
    io::write_record(g, "sphere", record);
    item.codec = to_string(options.codec);
    const std::vector<float> back = codes.dequantized(image.mask);
    const double psnr_image = image_psnr(points, to_points(back), image.mask);
    if (!in_roi.empty()) item.roi_image_psnr = image_psnr(points, to_points(back), in_roi);
    const double psnr_surface = options.measure ? surface_psnr(device, reconstruct_spherical_geometry(image),
                                                               reread(back), options.metric_samples)
                                                : kNaN;
    item.seam_gap = seam_gap(layout, back, image.mask);
    finish_item(g, item, psnr_image, psnr_surface);
    return item;
  }
  io::write_record(g, "sphere", kept_record(record));
  const auto mask_out = [&](std::vector<float>& xyz, const CodedGeometry&) {
    for (std::size_t k = 0; k < image.mask.size(); ++k)
      if (image.mask[k] == 0) xyz[3 * k] = xyz[3 * k + 1] = xyz[3 * k + 2] = std::numeric_limits<float>::quiet_NaN();
  };
  std::optional<TriMesh> stored;
  std::vector<Candidate> all;
  for (const GeometryCodec codec : codec_candidates(options.codec, options.lossless, octahedral ? cols : 0, item.path)) {
    const std::uint64_t budget = payload_budget(g, options, codec, item.path);
    Candidate c = attempt(codec, [&] {
      return try_codec(codec, points, points, cols, rows, static_cast<std::uint32_t>(layout.height()), image.mask,
                       octahedral ? LatticeExtension::Sphere : LatticeExtension::Mirror, options, budget, mask_out);
    });
    if (options.measure && c.failure.empty()) {
      if (!stored) stored = reconstruct_spherical_geometry(image);
      c.surface_psnr = surface_psnr(device, *stored, reread(c.final_xyz), options.metric_samples);
    }
    all.push_back(std::move(c));
  }
  const Candidate& best = store_best(g, item, all, options);
  if (!in_roi.empty()) item.roi_image_psnr = image_psnr(points, to_points(best.final_xyz), in_roi);
  item.seam_gap = seam_gap(layout, best.final_xyz, image.mask);
  finish_item(g, item, best.image_psnr, best.surface_psnr);
  return item;
}

CompressedItem compress_multichart_image(const EmbreeDevice& device, const MultiChartImage& input,
                                        std::span<const double> chart_stretch, const io::RepresentationRecord& record,
                                        const Vec3& origin, h5::Group& g, const CompressOptions& options,
                                        const std::string& path) {
  check_compress_options(options);
  // Decoded positions move: the zipper quads keep the splits they have now (mcgim_image.h), so the decoded
  // image reconstructs to the same faces over the same clusters, its topology the stored image's.
  MultiChartImage image = input;
  image.zipper_diagonals = zipper_diagonal_bits(input);
  if (options.codec == CodecChoice::J2kRoi)
    throw InvalidInput(fmt::format("{}: --codec j2k-roi codes geometry images converted with --roi (method gim); "
                                   "a multi-chart image is coded with --codec j2k (or auto)", path));
  if (options.codec == CodecChoice::Wavelet)
    throw InvalidInput(fmt::format("{}: the wavelet coder takes square images of side 2^k·q + 1 (gim, octa, flat-octa); "
                                   "a multi-chart image's {} × {} rectangle is coded with --codec j2k (or auto)",
                                   path, image.width, image.height));
  CompressedItem item;
  item.path = path;
  write_frame_origin(g, origin);
  // Mask, chart ids and zipper table are kept exactly (gzip); the normals are dropped: they are central
  // differences of the positions (multichart_normals), which readers such as preview recompute.
  io::write_multichart_structure(g, image, chart_stretch);
  const auto reread = [&](std::span<const float> xyz) {
    MultiChartImage copy = image;
    copy.positions.assign(xyz.begin(), xyz.end());
    return reconstruct_multichart(copy);
  };
  const std::vector<Vec3> points = to_points(image.positions);
  if (options.codec == CodecChoice::Quant12 || options.codec == CodecChoice::Quant16) {
    const int bits = options.codec == CodecChoice::Quant12 ? 12 : 16;
    const io::QuantizedPositions quantized = io::quantize_positions_in_box(image.height, image.width, image.positions, image.mask, bits);
    (void)io::write_quantized_positions(g, quantized);
    io::write_record(g, "mcgim", record);
    item.codec = to_string(options.codec);
    // Equal floats quantize alike: a zipper cluster stays one value without fusing.
    const std::vector<float> back = quantized.dequantized(image.mask);
    const double psnr_image = image_psnr(points, to_points(back), image.mask);
    const double psnr_surface =
        options.measure ? surface_psnr(device, reconstruct_multichart(image), reread(back), options.metric_samples) : kNaN;
    finish_item(g, item, psnr_image, psnr_surface);
    return item;
  }
  io::write_record(g, "mcgim", kept_record(record));
  // The coder sees the positions minus their chart's quadric (mcgim_fuse.h): no steps between charts.
  const std::vector<float> planes = chart_planes(image, static_cast<std::uint32_t>(chart_stretch.size()));
  (void)g.write_dataset("chart_planes", {chart_stretch.size(), kPlaneFloats}, planes, h5::DatasetOptions{{}, 9, true, false});
  g.set_attribute("structure_crc32", std::int64_t{io::multichart_structure_crc(image, planes)});
  std::vector<float> residual = image.positions;
  apply_chart_planes(residual, image, planes, -1);
  const std::vector<Vec3> residual_points = to_points(residual);
  // What the reader does (io/mcgim_archive.h).
  const auto fuse = [&](std::vector<float>& xyz, const CodedGeometry&) {
    MultiChartImage copy = image;
    copy.positions = std::move(xyz);
    restore_decoded_multichart(copy, planes);
    xyz = std::move(copy.positions);
  };
  const GeometryCodec codec = GeometryCodec::J2k;
  const std::uint64_t budget = payload_budget(g, options, codec, item.path);
  std::vector<Candidate> all;
  all.push_back(attempt(codec, [&] {
    return try_codec(codec, residual_points, points, image.width, image.height, image.height, image.mask,
                     LatticeExtension::Mirror, options, budget, fuse);
  }));
  Candidate& c = all.back();
  if (options.measure && c.failure.empty())
    c.surface_psnr = surface_psnr(device, reconstruct_multichart(image), reread(c.final_xyz), options.metric_samples);
  const Candidate& best = store_best(g, item, all, options);
  finish_item(g, item, best.image_psnr, best.surface_psnr);
  return item;
}

CodecChoice parse_codec(const std::string& text) {
  if (text == "auto") return CodecChoice::Auto;
  if (text == "j2k") return CodecChoice::J2k;
  if (text == "wavelet") return CodecChoice::Wavelet;
  if (text == "quant12") return CodecChoice::Quant12;
  if (text == "quant16") return CodecChoice::Quant16;
  if (text == "j2k-roi") return CodecChoice::J2kRoi;
  throw InvalidInput(fmt::format("unknown codec '{}' (auto, j2k, wavelet, quant12, quant16, j2k-roi)", text));
}

std::string to_string(CodecChoice codec) {
  switch (codec) {
    case CodecChoice::Auto: return "auto";
    case CodecChoice::J2k: return "j2k";
    case CodecChoice::Wavelet: return "wavelet";
    case CodecChoice::Quant12: return "quant12";
    case CodecChoice::Quant16: return "quant16";
    case CodecChoice::J2kRoi: return "j2k-roi";
  }
  return "auto";
}

void check_compress_options(const CompressOptions& options) {
  if (options.psnr < 0.0 || options.psnr > 200.0 || std::isnan(options.psnr))  // before the targets: it was given
    throw InvalidInput(fmt::format("--psnr {} is outside (0, 200] dB", options.psnr));
  if (options.codec == CodecChoice::J2kRoi && (options.bytes == 0 || options.psnr != 0.0 || options.lossless))
    throw InvalidInput("--codec j2k-roi codes at a byte budget: give --bytes B alone (the ROI's window first, the image in the rest)");
  const int targets = (options.bytes > 0 ? 1 : 0) + (options.psnr > 0.0 ? 1 : 0) + (options.lossless ? 1 : 0);
  const bool quant = options.codec == CodecChoice::Quant12 || options.codec == CodecChoice::Quant16;
  if (quant && targets > 0)
    throw InvalidInput(fmt::format("--codec {} quantizes without a target: drop --bytes, --psnr and --lossless", to_string(options.codec)));
  if (!quant && targets != 1)
    throw InvalidInput(fmt::format("--codec {} needs exactly one target: --bytes B, --psnr P or --lossless", to_string(options.codec)));
  if (options.lossless && options.codec == CodecChoice::Wavelet)
    throw InvalidInput("--lossless: the wavelet coder is lossy only (use --codec j2k or auto)");
  if (options.bytes > 0 && options.bytes < kMinBudget)
    throw InvalidInput(fmt::format("--bytes {}: below {} bytes nothing but the item's attributes fits", options.bytes, kMinBudget));
}

namespace {

/// The record of a multi-chart item without the structural attributes its writers set themselves.
io::RepresentationRecord multichart_record(const h5::Group& group) {
  io::RepresentationRecord record = io::read_record(group);
  for (const char* key : {"width", "height", "num_charts"}) record.numbers.erase(key);
  return record;
}

/// Writes a decoded multi-chart image (item `group`, `where` in messages) as convert writes it: its record and
/// per-chart stretch, and its normals (recomputed where compression dropped them).
void write_multichart(io::Archive& out, const std::string& name, const MultiChartImage& image, const h5::Group& group,
                      std::string_view where) {
  io::McgimExtras extras = io::read_multichart_extras(group, where);
  if (extras.normals.empty()) extras.normals = multichart_normals(image);
  io::write_multichart_image(out, name, image, extras, multichart_record(group));
}

}  // namespace

CompressedItem compress_item(const EmbreeDevice& device, const io::Archive& in, const ImageRef& ref, io::Archive& out,
                             const CompressOptions& options) {
  check_compress_options(options);
  const auto start = std::chrono::steady_clock::now();
  if (ref.kind == Method::Relief)
    throw InvalidInput(fmt::format("{}:/{}: compress codes geometry images, spherical and multi-chart geometry images, not {} items",
                                   in.path().string(), ref.path(), representation(ref.kind).what));
  const io::RepresentationKind& kind = representation(ref.kind);
  const h5::Group source = io::open_representation(in, kind, ref.name);
  if (io::has_coded_positions(source))
    throw InvalidInput(fmt::format("{}:/{}: already coded; compress the archive it came from", in.path().string(), ref.path()));
  const std::uint64_t before = io::stored_bytes(source);
  const Vec3 origin = item_origin(in, ref.kind, ref.name);
  CompressedItem item;
  if (ref.kind == Method::Gim) {
    const GeometryImage image = io::read_geometry_image(in, ref.name);
    // The ROI decides what j2k-roi codes first; for the other codecs it only adds roi_image_psnr, and a damaged
    // mask then costs that figure, not the item.
    std::vector<std::uint8_t> roi;
    try {
      roi = io::read_roi_mask(source, in, io::kGeometryImages, ref.name, image.size);
    } catch (const FormatError& e) {
      if (options.codec == CodecChoice::J2kRoi) throw;
      spdlog::warn("{} (roi_image_psnr not reported)", e.what());
    }
    h5::Group g = io::create_representation(out, kind, ref.name);
    item = compress_gim_image(device, image, io::read_gim_record(in, ref.name), origin, g, options, ref.path(), roi);
  } else if (ref.kind == Method::Mcgim) {
    const MultiChartImage image = io::read_multichart_image(in, ref.name);
    const io::McgimExtras extras = io::read_multichart_extras(in, ref.name);
    h5::Group g = io::create_representation(out, kind, ref.name);
    item = compress_multichart_image(device, image, extras.chart_stretch, multichart_record(source), origin, g, options,
                                     ref.path());
  } else {
    const SphericalImage image = io::read_spherical_image(in, ref.name);
    std::vector<std::uint8_t> roi;  // a flat-octa image converted with --roi: roi_image_psnr, as for gim
    try {
      if (image.domain == SphericalDomain::FlatOctahedron)
        roi = io::read_roi_mask(source, in, io::kSphericalImages, ref.name, static_cast<std::uint64_t>(image.layout().width()));
    } catch (const FormatError& e) {
      spdlog::warn("{} (roi_image_psnr not reported)", e.what());
    }
    h5::Group g = io::create_representation(out, kind, ref.name);
    item = compress_spherical_image(device, image, io::read_spherical_record(in, ref.name), origin, g, options, ref.path(),
                                    roi);
  }
  item.bytes_before = before;
  item.geometry_bytes_before = io::dataset_stored_bytes(source, "geometry");
  if (options.codec != CodecChoice::Quant12 && options.codec != CodecChoice::Quant16)
    item.dropped_bytes = io::dataset_stored_bytes(source, "normals") + io::dataset_stored_bytes(source, "colors");
  item.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return item;
}

std::vector<BatchCodedItem> coded_batch_items(const io::Archive& in) {
  std::vector<BatchCodedItem> items;
  if (!in.root().exists("batch")) return items;
  for (const io::BatchOutputSummary& s : io::read_batch_summary(in.path())) {
    const auto codec = s.attributes.find("codec");
    const auto method = s.attributes.find("method");
    if (codec == s.attributes.end() || !s.groups || method == s.attributes.end()) continue;
    if (method->second != "gim" && method->second != "sphere" && method->second != "mcgim") continue;
    const Method kind = parse_method(method->second);
    for (std::uint64_t k = 0; k < s.count; ++k) items.push_back({s.output, k, kind, fmt::format("{}.{}", s.output, k)});
  }
  return items;
}

void decompress_batch_item(const io::Archive& in, const BatchCodedItem& item, io::Archive& out) {
  const std::string key = std::to_string(item.index);
  const std::string label = fmt::format("batch/{}/items/{}", item.output, key);
  const h5::Group group = in.root().open_group(label);
  const Vec3 origin = item_origin(group, fmt::format("{}:/{}", in.path().string(), label));
  io::RepresentationRecord record = io::read_record(group);
  if (item.kind == Method::Gim) {
    record.numbers.erase("size");
    record.numbers.erase("normal_size");
    record.numbers.erase("units_per_side");
    io::write_geometry_image(out, item.name, io::read_geometry_image(in, group, label), record);
  } else if (item.kind == Method::Mcgim) {
    write_multichart(out, item.name, io::read_multichart_image(in, group, label), group,
                     fmt::format("{}:/{}", in.path().string(), label));
  } else {
    record.numbers.erase("n");
    io::write_spherical_image(out, item.name, io::read_spherical_image(in, group, label), io::SphereParametrization{}, record);
  }
  h5::Group g = io::open_representation(out, representation(item.kind), item.name);
  write_frame_origin(g, origin);
}

void decompress_item(const io::Archive& in, const ImageRef& ref, io::Archive& out) {
  const Vec3 origin = item_origin(in, ref.kind, ref.name);
  if (ref.kind == Method::Gim || ref.kind == Method::Sphere || ref.kind == Method::Mcgim) {
    // An item stored in float32 already has nothing to decode: it is checked by reading it and copied whole,
    // with what a decoded item would lose (ROI, adaptive history, sphere parametrization, provenance).
    const h5::Group g = io::open_representation(in, representation(ref.kind), ref.name);
    if (!io::has_coded_positions(g) && g.exists("geometry") && g.open_dataset("geometry").dtype() == h5::DType::kFloat32) {
      if (ref.kind == Method::Gim) (void)io::read_geometry_image(in, ref.name);
      else if (ref.kind == Method::Sphere) (void)io::read_spherical_image(in, ref.name);
      else (void)io::read_multichart_image(in, ref.name);
      in.root().copy_to(ref.path(), out.root(), ref.path());
      return;
    }
  }
  if (ref.kind == Method::Gim) {
    GeometryImage image = io::read_geometry_image(in, ref.name);
    io::GimRecord record = io::read_gim_record(in, ref.name);
    record.numbers.erase("size");  // structural attributes the writer sets itself
    record.numbers.erase("normal_size");
    record.numbers.erase("units_per_side");
    io::write_geometry_image(out, ref.name, image, record);
  } else if (ref.kind == Method::Sphere) {
    const SphericalImage image = io::read_spherical_image(in, ref.name);
    io::SphereRecord record = io::read_spherical_record(in, ref.name);
    record.numbers.erase("n");
    io::write_spherical_image(out, ref.name, image, io::SphereParametrization{}, record);
  } else if (ref.kind == Method::Mcgim) {
    const h5::Group group = io::open_representation(in, io::kMultiChartImages, ref.name);
    write_multichart(out, ref.name, io::read_multichart_image(in, ref.name), group,
                     fmt::format("{}:/{}", in.path().string(), ref.path()));
  } else {
    throw InvalidInput(fmt::format("{}:/{}: decompress writes geometry images, spherical and multi-chart geometry images, not {} items",
                                   in.path().string(), ref.path(), representation(ref.kind).what));
  }
  h5::Group g = io::open_representation(out, representation(ref.kind), ref.name);
  write_frame_origin(g, origin);
}

}  // namespace gimforge::jobs
