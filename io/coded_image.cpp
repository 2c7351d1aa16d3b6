#include "io/coded_image.h"

#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include <fmt/format.h>

#include "io/hdf5_internal.h"
#include "io/ply_ranges.h"
#include "kernels/codec/surface_rounding.h"
#include "kernels/core/errors.h"
#include "kernels/core/hash.h"

namespace gimforge::io {
namespace {

constexpr std::string_view kCodeItem = "geometry_code";
/// Largest coded payload read (a lossless 8193² image is below 400 MB).
constexpr std::uint64_t kMaxPayload = std::uint64_t{1} << 30;

std::uint16_t quantize_value(double v, double offset, double scale, double top) {
  return static_cast<std::uint16_t>(std::clamp(std::round((v - offset) / scale), 0.0, top));
}

/// The dequantization attributes of a quantized dataset: `offset` (`channels` values or one) and `scale`,
/// checked so that offset + scale · (2^bits − 1) stays a finite float.
struct Dequant {
  std::vector<double> offset;
  std::vector<double> scale;
};
Dequant read_dequant(const h5::Dataset& ds, const Archive& archive, const RepresentationKind& kind,
                     const std::string& name, std::string_view item, std::size_t channels, double top) {
  Dequant d;
  const auto bad = [&](std::string_view cause) {
    return representation_error(archive, kind, name, fmt::format("dataset '{}': {}", item, cause));
  };
  if (!ds.has_attribute("scale") || !ds.has_attribute("offset")) throw bad("quantized without 'scale' and 'offset'");
  try {
    d.scale = ds.attribute<std::vector<double>>("scale");
    d.offset = ds.attribute<std::vector<double>>("offset");
  } catch (const FormatError&) {
    throw bad("'scale' or 'offset' is not float64");
  }
  for (std::vector<double>* v : {&d.offset, &d.scale}) {
    if (v->size() == 1 && channels > 1) v->assign(channels, v->front());
    if (v->size() != channels) throw bad(fmt::format("'offset' and 'scale' need 1 or {} values, not {}", channels, v->size()));
  }
  const double limit = static_cast<double>(std::numeric_limits<float>::max());
  for (std::size_t c = 0; c < channels; ++c)
    if (!(d.scale[c] > 0.0) || !std::isfinite(d.scale[c]) || !(std::abs(d.offset[c]) + d.scale[c] * top < limit))
      throw bad(fmt::format("scale {} and offset {} leave the range of float32 values", d.scale[c], d.offset[c]));
  return d;
}

template <class T>
std::vector<float> dequantize_dataset(const h5::Dataset& ds, const Dequant& d, std::size_t channels, double top,
                                      const Archive& archive, const RepresentationKind& kind, const std::string& name,
                                      std::string_view item) {
  const std::vector<T> q = ds.read<T>();
  std::vector<float> out(q.size());
  for (std::size_t k = 0; k < q.size(); ++k) {
    if (static_cast<double>(q[k]) > top)
      throw representation_error(archive, kind, name,
                                 fmt::format("dataset '{}': value {} at {} is above 2^bits − 1 = {}", item, q[k], k, top));
    out[k] = static_cast<float>(d.offset[k % channels] + d.scale[k % channels] * static_cast<double>(q[k]));
  }
  return out;
}

int read_bits(const h5::Dataset& ds, const Archive& archive, const RepresentationKind& kind, const std::string& name,
              std::string_view item, int fallback) {
  if (!ds.has_attribute("bits")) return fallback;
  const auto bits = ds.attribute_in_range("bits", 1, 16);
  if (bits != 8 && bits != 12 && bits != 16)
    throw representation_error(archive, kind, name, fmt::format("dataset '{}': bits = {} (expected 8, 12 or 16)", item, bits));
  return static_cast<int>(bits);
}

/// A float32 image holds positions as they are: quantization attributes on it mean a damaged or edited item
/// (a probe's float32 copy of a 12-bit image read back as coordinates 0..4095, silently).
std::vector<float> read_float_image(const h5::Dataset& ds, const Archive& archive, const RepresentationKind& kind,
                                    const std::string& name, std::string_view item) {
  for (const char* key : {"bits", "scale", "offset"})
    if (ds.has_attribute(key))
      throw representation_error(archive, kind, name, fmt::format("dataset '{}' is float32 but carries the quantization "
                                                                  "attribute '{}' (a damaged or edited item)", item, key));
  return ds.read<float>();
}

std::uint64_t attribute_bytes(hid_t object) {
  std::uint64_t total = 0;
  const auto count = H5Aget_num_attrs(object);
  for (int i = 0; i < count; ++i) {
    const hid_t a = H5Aopen_by_idx(object, ".", H5_INDEX_NAME, H5_ITER_INC, static_cast<hsize_t>(i), H5P_DEFAULT, H5P_DEFAULT);
    if (a < 0) continue;
    const ssize_t name_length = H5Aget_name(a, 0, nullptr);
    total += name_length > 0 ? static_cast<std::uint64_t>(name_length) : 0;
    const hid_t type = H5Aget_type(a);
    if (type >= 0 && H5Tis_variable_str(type) > 0) {
      char* text = nullptr;
      const hid_t space = H5Aget_space(a);
      if (H5Sget_simple_extent_npoints(space) == 1 && H5Aread(a, type, &text) >= 0 && text != nullptr) {
        total += std::char_traits<char>::length(text);
        H5free_memory(text);
      }
      H5Sclose(space);
    } else {
      total += H5Aget_storage_size(a);
    }
    if (type >= 0) H5Tclose(type);
    H5Aclose(a);
  }
  return total;
}

}  // namespace

QuantizedPositions quantize_positions_in_box(std::uint64_t rows, std::uint64_t cols, std::span<const float> xyz,
                                             std::span<const std::uint8_t> mask, int bits, std::uint32_t block_rows) {
  const std::uint64_t samples = rows * cols;
  if (rows > 65536 || cols > 65536 || (bits != 12 && bits != 16) || xyz.size() != 3 * samples || (!mask.empty() && mask.size() != samples))
    throw InvalidInput(fmt::format("quantized positions: {} bits, {} values and {} mask entries for {} samples", bits,
                                   xyz.size(), mask.size(), samples));
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (std::size_t k = 0; k < samples; ++k) {
    if (!mask.empty() && mask[k] == 0) continue;
    const Vec3 v(xyz[3 * k], xyz[3 * k + 1], xyz[3 * k + 2]);
    if (!v.allFinite()) throw InvalidInput(fmt::format("quantized positions: sample {} is not finite", k));
    lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
  }
  if (!lo.allFinite()) lo = hi = Vec3::Zero();
  // Each axis over its extent in the bounding box (Gu et al. §4): a flat model keeps its bits on every axis.
  const double top = std::ldexp(1.0, bits) - 1.0;
  QuantizedPositions b;
  b.rows = rows, b.cols = cols, b.bits = bits;
  b.offset = {lo.x(), lo.y(), lo.z()};
  b.scale.resize(3);
  for (Eigen::Index c = 0; c < 3; ++c) {
    const double extent = hi[c] - lo[c];
    b.scale[static_cast<std::size_t>(c)] = extent > 0.0 ? extent / top : 1.0;
  }
  // Each sample takes the lattice point near it that is nearest the surface's tangent plane
  // (kernels/codec/surface_rounding.h): the decoder is the same, the surface moves less.
  const PositionLattice lattice{Vec3(b.offset[0], b.offset[1], b.offset[2]), Vec3(b.scale[0], b.scale[1], b.scale[2]), top};
  SurfaceRoundingOptions rounding;
  rounding.block_rows = block_rows;
  b.q = round_to_surface(xyz, mask, static_cast<std::uint32_t>(cols), static_cast<std::uint32_t>(rows), lattice, rounding);
  return b;
}

std::vector<float> QuantizedPositions::dequantized(std::span<const std::uint8_t> mask) const {
  std::vector<float> out(q.size());
  for (std::size_t k = 0; k < out.size(); ++k)
    out[k] = !mask.empty() && mask[k / 3] == 0 ? std::numeric_limits<float>::quiet_NaN()
                                                : static_cast<float>(offset[k % 3] + scale[k % 3] * static_cast<double>(q[k]));
  return out;
}

/// What readers check (read_dequant): offset + scale · top stays a float32. Coordinates near ±3.4·10^38 can
/// be float32 and still not be stored so.
void check_dequantization(std::span<const double> offset, std::span<const double> scale, double top, std::string_view item) {
  const double limit = static_cast<double>(std::numeric_limits<float>::max());
  for (std::size_t c = 0; c < offset.size(); ++c) {
    const double sc = scale[scale.size() == 1 ? 0 : c];
    if (!(sc > 0.0) || !std::isfinite(sc) || !(std::abs(offset[c]) + sc * top < limit))
      throw InvalidInput(fmt::format("{}: values from {:g} over a range of {:g} cannot be stored quantized (offset + "
                                     "scale · {:g} leaves float32); keep the item in float32",
                                     item, offset[c], sc * top, top));
  }
}

h5::Dataset write_quantized_positions(h5::Group& g, const QuantizedPositions& b) {
  if (b.q.size() != 3 * b.rows * b.cols || b.offset.size() != 3 || b.scale.size() != 3)
    throw InvalidInput(fmt::format("quantized positions: {} codes for a {} × {} image", b.q.size(), b.cols, b.rows));
  check_dequantization(b.offset, b.scale, std::ldexp(1.0, b.bits) - 1.0, "quantized positions");
  const std::uint64_t rows = b.rows, cols = b.cols;
  const int bits = b.bits;
  h5::Dataset ds = write_image(g, "geometry", {rows, cols, 3}, b.q);
  ds.set_attribute("offset", std::span<const double>(b.offset));
  ds.set_attribute("scale", std::span<const double>(b.scale));
  ds.set_attribute("bits", static_cast<std::int64_t>(bits));
  return ds;
}

h5::Dataset write_quantized_real(h5::Group& g, std::string_view item, const h5::Dims& shape, std::span<const float> values,
                                 double lo, double hi, int bits) {
  if (bits != 8 && bits != 16) throw InvalidInput(fmt::format("quantized '{}': {} bits (8 or 16)", item, bits));
  const double top = std::ldexp(1.0, bits) - 1.0;
  const double scale = (hi - lo) / top;
  check_dequantization(std::span<const double>(&lo, 1), std::span<const double>(&scale, 1), top, item);
  const auto q = [&](float v) { return std::isfinite(v) ? quantize_value(double{v}, lo, scale, top) : std::uint16_t{0}; };
  h5::Dataset ds = [&] {
    if (bits == 8) {
      std::vector<std::uint8_t> out(values.size());
      std::transform(values.begin(), values.end(), out.begin(), [&](float v) { return static_cast<std::uint8_t>(q(v)); });
      return write_image(g, item, shape, out);
    }
    std::vector<std::uint16_t> out(values.size());
    std::transform(values.begin(), values.end(), out.begin(), q);
    return write_image(g, item, shape, out);
  }();
  ds.set_attribute("offset", lo);
  ds.set_attribute("scale", scale);
  ds.set_attribute("bits", static_cast<std::int64_t>(bits));
  return ds;
}

h5::Dataset write_coded_positions(h5::Group& g, const CodedGeometry& coded) {
  h5::Dataset ds = g.write_dataset(kCodeItem, {coded.payload.size()}, coded.payload);
  ds.set_attribute("codec", codec_name(coded.codec));
  ds.set_attribute("crc32", static_cast<std::int64_t>(crc32(coded.payload.data(), coded.payload.size())));
  if (coded.codec != GeometryCodec::Wavelet) {
    const std::vector<double> offset{coded.quantization.offset.x(), coded.quantization.offset.y(),
                                     coded.quantization.offset.z()};
    check_dequantization(offset, std::span<const double>(&coded.quantization.scale, 1), 65535.0, "coded positions");
    ds.set_attribute("offset", std::span<const double>(offset));
    ds.set_attribute("scale", coded.quantization.scale);
  }
  return ds;
}

bool has_coded_positions(const h5::Group& g) { return g.exists(kCodeItem); }

StoredPositions read_positions(const h5::Group& g, const Archive& archive, const RepresentationKind& kind,
                               const std::string& name, std::uint64_t rows, std::uint64_t cols,
                               LatticeExtension extension) {
  StoredPositions out;
  if (has_coded_positions(g)) {
    const h5::Dataset ds = open_item(g, archive, kind, name, kCodeItem);
    const h5::Dims shape = ds.shape();
    // No codec makes more than the 16-bit planes plus headers: a larger payload is refused unread.
    const std::uint64_t most = std::min<std::uint64_t>(kMaxPayload, 2 * rows * cols * 3 * 2 + 65536);
    if (shape.size() != 1 || shape[0] > most || ds.dtype() != h5::DType::kUInt8)
      throw representation_error(archive, kind, name,
                                 fmt::format("dataset 'geometry_code' is not a uint8 (B) payload of at most {} bytes "
                                             "(twice the 16-bit planes of a {} × {} image)",
                                             most, cols, rows));
    const std::string codec = ds.has_attribute("codec") ? ds.attribute<std::string>("codec") : std::string();
    if (codec != "j2k" && codec != "wavelet" && codec != "j2k-roi")
      throw representation_error(
          archive, kind, name,
          fmt::format("dataset 'geometry_code' has codec '{}' (this gimforge decodes j2k, j2k-roi and wavelet)", codec));
    // ROI-first coding exists for geometry images converted with a region of interest only.
    if (codec == "j2k-roi" && kind.group != "gim")
      throw representation_error(archive, kind, name,
                                 "dataset 'geometry_code' has codec 'j2k-roi', which only geometry images (gim) use");
    Quantization quantization;
    if (codec != "wavelet") {
      const Dequant d = read_dequant(ds, archive, kind, name, kCodeItem, 3, 65535.0);
      if (d.scale[0] != d.scale[1] || d.scale[0] != d.scale[2])
        throw representation_error(archive, kind, name, "dataset 'geometry_code': a JPEG 2000 payload has one 'scale'");
      quantization.offset = Vec3(d.offset[0], d.offset[1], d.offset[2]);
      quantization.scale = d.scale[0];
    }
    const std::vector<std::uint8_t> payload = ds.read<std::uint8_t>();
    // JPEG 2000 has no checksum of its own: a damaged payload would decode into a wrong surface.
    if (!ds.has_attribute("crc32") ||
        ds.attribute_in_range("crc32", 0, 0xFFFFFFFF) != static_cast<std::int64_t>(crc32(payload.data(), payload.size())))
      throw representation_error(archive, kind, name,
                                 "dataset 'geometry_code': checksum mismatch (attribute crc32 is missing or disagrees: "
                                 "the payload is damaged)");
    std::vector<Vec3> points;
    try {
      const GeometryCodec id = codec == "j2k" ? GeometryCodec::J2k : codec == "j2k-roi" ? GeometryCodec::J2kRoi : GeometryCodec::Wavelet;
      points = decode_geometry(id, payload, quantization,
                               static_cast<std::uint32_t>(cols), static_cast<std::uint32_t>(rows), extension);
    } catch (const FormatError& e) {
      throw representation_error(archive, kind, name, fmt::format("dataset 'geometry_code': {}", e.what()));
    }
    out.storage = codec;
    if (codec == "j2k-roi")
      out.trusted = roi_payload_window(payload, static_cast<std::uint32_t>(cols), static_cast<std::uint32_t>(rows));
    out.xyz.resize(3 * points.size());
    for (std::size_t k = 0; k < points.size(); ++k)
      for (Eigen::Index c = 0; c < 3; ++c) {
        const auto v = static_cast<float>(points[k][c]);
        if (!std::isfinite(v))
          throw representation_error(archive, kind, name,
                                     fmt::format("dataset 'geometry_code': decoded sample {} leaves the range of float32", k));
        out.xyz[3 * k + static_cast<std::size_t>(c)] = v;
      }
    return out;
  }
  const h5::Dataset ds = open_item(g, archive, kind, name, "geometry");
  check_shape(ds, archive, kind, name, "geometry", {rows, cols, 3});
  if (ds.dtype() == h5::DType::kFloat32) {
    out.xyz = read_float_image(ds, archive, kind, name, "geometry");
    return out;
  }
  if (ds.dtype() != h5::DType::kUInt16)
    throw representation_error(archive, kind, name, "dataset 'geometry' is neither float32 nor quantized uint16");
  const int bits = read_bits(ds, archive, kind, name, "geometry", 16);
  const double top = std::ldexp(1.0, bits) - 1.0;
  out.xyz = dequantize_dataset<std::uint16_t>(ds, read_dequant(ds, archive, kind, name, "geometry", 3, top), 3, top,
                                              archive, kind, name, "geometry");
  out.storage = bits == 12 ? "quant12" : "quant16";
  return out;
}

std::string far_sample_problem(std::span<const float> xyz, std::span<const std::uint8_t> mask) {
  for (std::size_t k = 0; k < xyz.size(); ++k)
    if ((mask.empty() || mask[k / 3] != 0) && std::isfinite(xyz[k]) && std::abs(double{xyz[k]}) > kMaxCoordinate)
      return fmt::format("sample {} has a coordinate of magnitude {:g}, beyond ±{:g}: no mesh gimforge reads lies there, "
                         "and its reconstruction would be refused as input",
                         k / 3, std::abs(double{xyz[k]}), kMaxCoordinate);
  return {};
}

void require_near_samples(std::span<const float> xyz, std::span<const std::uint8_t> mask, std::string_view storage,
                          const Archive& archive, const RepresentationKind& kind, const std::string& name) {
  if (const std::string problem = far_sample_problem(xyz, mask); !problem.empty())
    throw representation_error(archive, kind, name,
                               fmt::format("dataset '{}': {}",
                                           storage == "float32" || storage.starts_with("quant") ? "geometry" : kCodeItem,
                                           problem));
}

std::vector<float> read_real_image(const h5::Dataset& ds, const Archive& archive, const RepresentationKind& kind,
                                   const std::string& name, std::string_view item) {
  const h5::DType type = ds.dtype();
  if (type == h5::DType::kFloat32) return read_float_image(ds, archive, kind, name, item);
  if (type != h5::DType::kUInt8 && type != h5::DType::kUInt16)
    throw representation_error(archive, kind, name, fmt::format("dataset '{}' is neither float32 nor quantized", item));
  const int bits = read_bits(ds, archive, kind, name, item, type == h5::DType::kUInt8 ? 8 : 16);
  const double top = std::ldexp(1.0, bits) - 1.0;
  const Dequant d = read_dequant(ds, archive, kind, name, item, 1, top);
  return type == h5::DType::kUInt8 ? dequantize_dataset<std::uint8_t>(ds, d, 1, top, archive, kind, name, item)
                                   : dequantize_dataset<std::uint16_t>(ds, d, 1, top, archive, kind, name, item);
}

namespace {

/// A dataset's stored bytes (after filters) and its attributes'.
std::uint64_t dataset_bytes(const h5::Dataset& ds) { return H5Dget_storage_size(ds.id()) + attribute_bytes(ds.id()); }

/// stored_bytes below one group. Every object counts once (hard links may point back up: a cycle), at most
/// 16 groups deep (our items are 2 deep).
std::uint64_t stored_bytes_below(const h5::Group& g, std::set<haddr_t>& seen, int depth) {
  std::uint64_t total = attribute_bytes(g.id());
  for (const std::string& child : g.children()) {
    total += child.size();
    // Hard links only, checked before the object is looked at: H5Oget_info_by_name follows a soft or external
    // link (into another file, or a FIFO that never answers).
    h5::detail::require_hard_links(g.id(), child);
    H5O_info_t info;
    const bool got = [&] {
      const h5::detail::DeadlineScope deadline;
      return H5Oget_info_by_name(g.id(), child.c_str(), &info, H5P_DEFAULT) >= 0;
    }();
    if (!got) {
      H5Eclear2(H5E_DEFAULT);
      continue;
    }
    if (!seen.insert(info.addr).second) continue;
    if (info.type == H5O_TYPE_GROUP) {
      if (depth >= 16) throw FormatError(fmt::format("{}: groups nested more than 16 deep", g.path()));
      total += stored_bytes_below(g.open_group(child), seen, depth + 1);
    } else if (info.type == H5O_TYPE_DATASET) {
      total += dataset_bytes(g.open_dataset(child));
    }
  }
  return total;
}

}  // namespace

std::uint64_t dataset_stored_bytes(const h5::Group& g, std::string_view name) {
  return g.exists(name) ? dataset_bytes(g.open_dataset(name)) : 0;
}

std::uint64_t stored_bytes(const h5::Group& g) {
  // A dataset still open in the writer keeps its chunks in HDF5's cache, and H5Dget_storage_size counts
  // only what reached the file: flush a file open for writing first (a spherical quant12 item was counted
  // at 795 bytes for 57 KB stored).
  g.flush_file();
  std::set<haddr_t> seen;
  H5O_info_t self;
  if (H5Oget_info(g.id(), &self) >= 0) seen.insert(self.addr);
  return stored_bytes_below(g, seen, 0);
}

}  // namespace gimforge::io
