/// \file relief_archive.cpp
/// Relief maps in the archive (see relief_archive.h and docs/archive.md).
#include "io/relief_archive.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string_view>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge::io {
namespace {

constexpr const RepresentationKind& kRelief = kReliefMaps;
constexpr const char* kMethod = "relief";

/// Limits of build_relief_map (kernels/relief/relief_map.h): grid 1..1024, texture 2..1024, at most 2³¹ texels.
constexpr std::int64_t kMaxGrid = 1024;
constexpr std::int64_t kMaxTexture = 1024;
constexpr std::uint64_t kMaxTexels = std::uint64_t{1} << 31;
/// How far stored projection parameters may be from the recomputed ones (they are exact multiples of 1/2).
constexpr double kParamTolerance = 1e-12;
/// Maps of up to this many texels per chunk (e.g. 16 layers of 64 × 64 texels).
constexpr std::uint64_t kChunkTexels = 65536;

/// Attributes of /relief/<name> that are not record numbers.
constexpr std::array<std::string_view, 10> kStructural{"n",           "texture",     "grey_cells",
                                                        "layers",      "white_cells", "black_cells",
                                                        "origin",      "cell_size",   "inside_method",
                                                        "watertight_inside_test"};

constexpr const char* kCaseNames = "0,1,2a,2b,3a,3b,4a,4b,5,6";
constexpr const char* kProjectionNames = "parallel,planar,perspective,axial";
constexpr const char* kParamColumns = "px,py,pz,dx,dy,dz";
constexpr const char* kLevelColumns = "n,grey_cells,domain_faces,samples,occluded";

std::string_view dtype_name(h5::DType t) {
  switch (t) {
    case h5::DType::kUInt8: return "uint8";
    case h5::DType::kUInt16: return "uint16";
    case h5::DType::kInt32: return "int32";
    case h5::DType::kInt64: return "int64";
    case h5::DType::kFloat32: return "float32";
    case h5::DType::kFloat64: return "float64";
    case h5::DType::kString: return "string";
    case h5::DType::kInt8: return "int8";
    case h5::DType::kUInt32: return "uint32";
  }
  return "unknown";
}

/// The direction column of projection_params: Parallel the unit direction of projection, Axial the unit
/// direction of the axis, Planar the unit normal of the plane, Perspective zero.
Vec3 param_direction(const CellProjection& p) {
  switch (p.type) {
    case ProjectionType::Parallel: return p.direction;
    case ProjectionType::Axial:
    case ProjectionType::Planar: return Vec3::Unit(p.axis);
    case ProjectionType::Perspective: break;
  }
  return Vec3::Zero();
}

/// Storage of a per-texel map of `layers` layers of T × T texels with `channels` channels (0: none):
/// chunks of whole layers (up to kChunkTexels texels), shuffle + gzip 4, as the image datasets.
h5::DatasetOptions map_storage(std::uint64_t layers, std::uint64_t texture, std::uint64_t channels) {
  if (layers == 0) return {};
  const std::uint64_t per_chunk = std::clamp<std::uint64_t>(kChunkTexels / (texture * texture), 1, layers);
  h5::Dims chunk{per_chunk, texture, texture};
  if (channels > 0) chunk.push_back(channels);
  return {.chunk = chunk, .deflate = 4, .shuffle = true};
}

h5::Dims map_shape(std::uint64_t layers, std::uint64_t texture, std::uint64_t channels) {
  h5::Dims shape{layers, texture, texture};
  if (channels > 0) shape.push_back(channels);
  return shape;
}

/// "relief map: cause" (ReliefMap::check) without its prefix.
std::string check_cause(const InvalidInput& e) {
  std::string_view what = e.what();
  constexpr std::string_view prefix = "relief map: ";
  if (what.starts_with(prefix)) what.remove_prefix(prefix.size());
  return std::string(what);
}

/// Reads the datasets of one relief group, checking each before use. Errors read "WHERE: CAUSE", WHERE
/// being "ARCHIVE: relief map 'NAME'" (or what the caller of read_relief_map(group, where) says).
class Reader {
 public:
  Reader(const Archive& archive, const std::string& name)
      : where_(fmt::format("{}: {} '{}'", archive.path().string(), kRelief.what, name)),
        g_(open_representation(archive, kRelief, name)) {}
  Reader(const h5::Group& group, std::string_view where) : where_(where), g_(group.open_group(".")) {}

  [[nodiscard]] const h5::Group& group() const { return g_; }

  [[nodiscard]] FormatError error(std::string_view cause) const { return FormatError(fmt::format("{}: {}", where_, cause)); }

  /// Integer attribute in [lo, hi].
  [[nodiscard]] std::int64_t int_attribute(std::string_view key, std::int64_t lo, std::int64_t hi) const {
    const auto v = g_.attribute<std::int64_t>(key);
    if (v < lo || v > hi) throw error(fmt::format("attribute {} = {} is out of range [{}, {}]", key, v, lo, hi));
    return v;
  }

  /// Dataset `item`, which must exist and be a dataset.
  [[nodiscard]] h5::Dataset open(std::string_view item) const {
    if (!g_.exists(item)) throw error(fmt::format("no dataset '{}'", item));
    try {
      return g_.open_dataset(item);
    } catch (const LibraryError& e) {
      throw error(dataset_open_failure(item, e));
    }
  }

  /// Dataset `item`, checked to have shape `shape` and element type `type`.
  [[nodiscard]] h5::Dataset dataset(std::string_view item, h5::DType type, const h5::Dims& shape) const {
    h5::Dataset ds = open(item);
    if (ds.shape() != shape)
      throw error(fmt::format("dataset '{}' has shape ({}), expected ({})", item, fmt::join(ds.shape(), ", "),
                              fmt::join(shape, ", ")));
    const h5::DType got = ds.dtype();
    if (got != type)
      throw error(fmt::format("dataset '{}' is {}, expected {}", item, dtype_name(got), dtype_name(type)));
    return ds;
  }

  /// The first extent of dataset `item`, which must have rank `rank` (and the trailing extents `tail`).
  [[nodiscard]] std::uint64_t rows(std::string_view item, std::size_t rank, const h5::Dims& tail = {}) const {
    const h5::Dataset ds = open(item);
    const h5::Dims shape = ds.shape();
    if (shape.size() != rank || !std::equal(tail.begin(), tail.end(), shape.begin() + 1))
      throw error(fmt::format("dataset '{}' has rank {} or trailing extents other than expected", item, shape.size()));
    return shape.front();
  }

 private:
  std::string where_;
  h5::Group g_;
};

/// Reads the cell table into `map` (cells, external_faces, projections, first_layer) and checks it against
/// the recomputed projections.
void read_cells(const Reader& r, ReliefMap& map, std::uint64_t G) {
  const std::uint64_t n = map.n;
  const std::vector<std::uint32_t> ijk = r.dataset("cells", h5::DType::kUInt32, {G, 3}).read<std::uint32_t>();
  map.external_faces = r.dataset("external_faces", h5::DType::kUInt8, {G}).read<std::uint8_t>();
  const std::vector<std::uint8_t> cases = r.dataset("case", h5::DType::kUInt8, {G}).read<std::uint8_t>();
  const std::vector<std::uint8_t> types = r.dataset("projection", h5::DType::kUInt8, {G}).read<std::uint8_t>();
  const std::vector<std::uint8_t> domain = r.dataset("domain_faces", h5::DType::kUInt8, {G}).read<std::uint8_t>();
  const std::vector<double> params =
      r.dataset("projection_params", h5::DType::kFloat64, {G, 6}).read<double>();

  map.cells.resize(G);
  map.projections.resize(G);
  map.first_layer.assign(G + 1, 0);
  for (std::size_t g = 0; g < G; ++g) {
    const std::uint32_t i = ijk[3 * g], j = ijk[3 * g + 1], k = ijk[3 * g + 2];
    if (i >= n || j >= n || k >= n)
      throw r.error(fmt::format("grey cell {} at (i, j, k) = ({}, {}, {}) lies outside the {}x{}x{} grid", g, i, j, k,
                                n, n, n));
    const std::uint64_t linear = (k * n + j) * n + i;
    if (g > 0 && linear <= map.cells[g - 1])
      throw r.error(fmt::format("grey cell {} at ({}, {}, {}) is out of order (cells must be listed once, by "
                                "increasing linear index (k*n + j)*n + i)",
                                g, i, j, k));
    map.cells[g] = static_cast<std::uint32_t>(linear);
    const std::uint8_t ef = map.external_faces[g];
    const auto where = [&] { return fmt::format("grey cell {} at ({}, {}, {})", g, i, j, k); };
    if ((ef & ~kAllCellFaces) != 0) throw r.error(fmt::format("{}: external faces {:#x} has bits beyond the six faces", where(), ef));
    const CellProjection p = cell_projection(ef);
    if (cases[g] >= kNumReliefCases || static_cast<ReliefCase>(cases[g]) != p.base_case) {
      const std::string stored = cases[g] < kNumReliefCases
                                     ? std::string(relief_case_name(static_cast<ReliefCase>(cases[g])))
                                     : fmt::format("#{} (not a case)", cases[g]);
      throw r.error(fmt::format("{}: stored case {} disagrees with its external faces {:#x} (case {})", where(),
                                stored, ef, relief_case_name(p.base_case)));
    }
    if (types[g] > static_cast<std::uint8_t>(ProjectionType::Axial) || static_cast<ProjectionType>(types[g]) != p.type)
      throw r.error(fmt::format("{}: stored projection type {} disagrees with its external faces {:#x} ({})", where(),
                                types[g], ef, projection_type_name(p.type)));
    if (domain[g] != p.domain_faces)
      throw r.error(fmt::format("{}: stored domain faces {:#x} disagree with its external faces {:#x} ({:#x})",
                                where(), domain[g], ef, p.domain_faces));
    const Vec3 point(params[6 * g], params[6 * g + 1], params[6 * g + 2]);
    const Vec3 dir(params[6 * g + 3], params[6 * g + 4], params[6 * g + 5]);
    if (!point.allFinite() || !dir.allFinite() || (point - p.point).norm() > kParamTolerance ||
        (dir - param_direction(p)).norm() > kParamTolerance)
      throw r.error(fmt::format("{}: stored projection parameters ({}) disagree with the {} projection of case {}",
                                where(), fmt::join(params.begin() + static_cast<std::ptrdiff_t>(6 * g),
                                                   params.begin() + static_cast<std::ptrdiff_t>(6 * g + 6), ", "),
                                projection_type_name(p.type), relief_case_name(p.base_case)));
    map.projections[g] = p;
    map.first_layer[g + 1] = map.first_layer[g] + static_cast<std::uint32_t>(std::popcount(p.domain_faces));
  }
}

/// The first inconsistency of map.levels (the grids tried, the last one kept) with itself or the map; empty
/// when there is none or no level is recorded.
std::string levels_problem(const ReliefMap& map) {
  for (std::size_t k = 0; k < map.levels.size(); ++k) {
    const ReliefGridLevel& l = map.levels[k];
    if (l.n < 1 || l.n > kMaxGrid || l.occluded > l.samples)
      return fmt::format("grid level {} (n = {}, {} of {} samples occluded) is not a valid grid level", k, l.n,
                         l.occluded, l.samples);
  }
  if (map.levels.empty()) return {};
  const ReliefGridLevel& last = map.levels.back();
  if (last.n != map.n || last.grey_cells != map.cells.size() || last.domain_faces != map.num_layers())
    return fmt::format("the last grid level (n = {}, {} grey cells, {} domain faces) is not the stored grid (n = {}, "
                       "{} grey cells, {} domain faces)",
                       last.n, last.grey_cells, last.domain_faces, map.n, map.cells.size(), map.num_layers());
  return {};
}

/// Reads grid_levels (optional) into map.levels.
void read_levels(const Reader& r, ReliefMap& map) {
  if (!r.group().exists("grid_levels")) return;
  const std::uint64_t K = r.rows("grid_levels", 2, {5});
  if (K == 0) throw r.error("dataset 'grid_levels' is empty");
  const std::vector<std::int64_t> t = r.dataset("grid_levels", h5::DType::kInt64, {K, 5}).read<std::int64_t>();
  for (std::size_t k = 0; k < K; ++k) {
    const std::int64_t* row = &t[5 * k];
    if (row[0] < 1 || row[0] > kMaxGrid || std::any_of(row + 1, row + 5, [](std::int64_t v) { return v < 0; }) ||
        row[4] > row[3])
      throw r.error(fmt::format("row {} of 'grid_levels' ({}) is not a valid grid level", k, fmt::join(row, row + 5, ", ")));
    ReliefGridLevel level;
    level.n = static_cast<std::uint32_t>(row[0]);
    level.grey_cells = static_cast<std::size_t>(row[1]);
    level.domain_faces = static_cast<std::size_t>(row[2]);
    level.samples = static_cast<std::uint64_t>(row[3]);
    level.occluded = static_cast<std::uint64_t>(row[4]);
    map.levels.push_back(level);
  }
  if (const std::string problem = levels_problem(map); !problem.empty())
    throw r.error(fmt::format("dataset 'grid_levels': {}", problem));
}

}  // namespace

void write_relief_map(Archive& archive, const std::string& name, const ReliefMap& map, const ReliefRecord& record) {
  check_representation_name(kRelief, name);
  check_relief_map(name, map, record);
  h5::Group g = create_representation(archive, kRelief, name);
  write_relief_map(g, map, record);
}

void check_relief_map(const std::string& name, const ReliefMap& map, const ReliefRecord& record) {
  try {
    map.check();
  } catch (const InvalidInput& e) {
    throw InvalidInput(fmt::format("relief map '{}': {}", name, check_cause(e)));
  }
  if (const std::string problem = levels_problem(map); !problem.empty())
    throw InvalidInput(fmt::format("relief map '{}': {}", name, problem));
  for (const auto& [key, value] : record.numbers)
    if (key == "method" || key == "source" || std::find(kStructural.begin(), kStructural.end(), key) != kStructural.end())
      throw InvalidInput(fmt::format("record number '{}' would overwrite the attribute of that name", key));
}

void write_relief_map(h5::Group& g, const ReliefMap& map, const ReliefRecord& record) {
  const std::uint64_t G = map.cells.size();
  const std::uint64_t L = map.num_layers();
  const std::uint64_t T = map.texture;
  const auto n = static_cast<std::size_t>(map.n);

  std::vector<std::uint32_t> ijk;
  std::vector<std::uint8_t> cases, types, domain;
  std::vector<double> params;
  ijk.reserve(3 * G);
  params.reserve(6 * G);
  for (std::size_t row = 0; row < G; ++row) {
    const std::size_t linear = map.cells[row];
    ijk.insert(ijk.end(), {static_cast<std::uint32_t>(linear % n), static_cast<std::uint32_t>(linear / n % n),
                           static_cast<std::uint32_t>(linear / (n * n))});
    const CellProjection& p = map.projections[row];
    cases.push_back(static_cast<std::uint8_t>(p.base_case));
    types.push_back(static_cast<std::uint8_t>(p.type));
    domain.push_back(p.domain_faces);
    const Vec3 dir = param_direction(p);
    params.insert(params.end(), {p.point.x(), p.point.y(), p.point.z(), dir.x(), dir.y(), dir.z()});
  }

  h5::Dataset cells = g.write_dataset("cells", {G, 3}, ijk);
  cells.set_attribute("columns", "i,j,k");
  g.write_dataset("external_faces", {G}, map.external_faces);
  g.write_dataset("case", {G}, cases).set_attribute("names", kCaseNames);
  g.write_dataset("projection", {G}, types).set_attribute("names", kProjectionNames);
  g.write_dataset("domain_faces", {G}, domain);
  g.write_dataset("projection_params", {G, 6}, params).set_attribute("columns", kParamColumns);
  g.write_dataset("layer_cell", {L}, map.layer_cell);
  g.write_dataset("layer_face", {L}, map.layer_face);

  h5::Dataset distances = g.write_dataset("distances", map_shape(L, T, 0), map.distances, map_storage(L, T, 0));
  distances.set_attribute("scale", map.distance_scale);
  distances.set_attribute("offset", 0.0);
  distances.set_attribute("empty", static_cast<std::int64_t>(kEmptyTexel));
  g.write_dataset("normals", map_shape(L, T, 3), map.normals, map_storage(L, T, 3))
      .set_attribute("scale", 1.0 / 127.0);
  if (!map.colors.empty()) g.write_dataset("colors", map_shape(L, T, 3), map.colors, map_storage(L, T, 3));

  if (!map.levels.empty()) {
    std::vector<std::int64_t> levels;
    for (const ReliefGridLevel& l : map.levels)
      levels.insert(levels.end(), {static_cast<std::int64_t>(l.n), static_cast<std::int64_t>(l.grey_cells),
                                   static_cast<std::int64_t>(l.domain_faces), static_cast<std::int64_t>(l.samples),
                                   static_cast<std::int64_t>(l.occluded)});
    g.write_dataset("grid_levels", {map.levels.size(), 5}, levels).set_attribute("columns", kLevelColumns);
  }

  g.set_attribute("n", map.n);
  g.set_attribute("texture", map.texture);
  g.set_attribute("grey_cells", G);
  g.set_attribute("layers", L);
  g.set_attribute("white_cells", map.white_cells);
  g.set_attribute("black_cells", map.black_cells);
  g.set_attribute("watertight_inside_test", map.watertight_inside_test ? 1 : 0);
  g.set_attribute("inside_method", map.inside_method);
  const std::array<double, 3> origin{map.origin.x(), map.origin.y(), map.origin.z()};
  g.set_attribute("origin", std::span<const double>(origin));
  g.set_attribute("cell_size", map.cell_size);
  write_record(g, kMethod, record);
}

namespace {

/// The relief map behind `r`, every item checked (read_relief_map).
ReliefMap read_map(const Reader& r) {
  const h5::Group& g = r.group();

  ReliefMap map;
  map.n = static_cast<std::uint32_t>(r.int_attribute("n", 1, kMaxGrid));
  map.texture = static_cast<std::uint32_t>(r.int_attribute("texture", 2, kMaxTexture));
  const std::int64_t cells_in_grid = std::int64_t{map.n} * map.n * map.n;
  const auto G = static_cast<std::uint64_t>(r.int_attribute("grey_cells", 1, cells_in_grid));
  const auto L = static_cast<std::uint64_t>(r.int_attribute("layers", 1, 6 * static_cast<std::int64_t>(G)));
  const std::uint64_t T = map.texture;
  if (L * T * T > kMaxTexels)
    throw r.error(fmt::format("{} layers of {}x{} texels exceed the limit of {} texels", L, T, T, kMaxTexels));
  map.white_cells = static_cast<std::size_t>(r.int_attribute("white_cells", 0, cells_in_grid));
  map.black_cells = static_cast<std::size_t>(r.int_attribute("black_cells", 0, cells_in_grid));
  if (static_cast<std::int64_t>(G + map.white_cells + map.black_cells) != cells_in_grid)
    throw r.error(fmt::format("{} grey + {} white + {} black cells do not make the {}x{}x{} grid", G, map.white_cells,
                              map.black_cells, map.n, map.n, map.n));
  map.watertight_inside_test = r.int_attribute("watertight_inside_test", 0, 1) == 1;
  map.inside_method = g.attribute<std::string>("inside_method");
  const auto origin = g.attribute<std::vector<double>>("origin");
  if (origin.size() != 3 || !std::all_of(origin.begin(), origin.end(), [](double x) { return std::isfinite(x); }))
    throw r.error("attribute origin is not 3 finite numbers");
  map.origin = Vec3(origin[0], origin[1], origin[2]);
  map.cell_size = g.attribute<double>("cell_size");
  if (!std::isfinite(map.cell_size) || map.cell_size <= 0.0)
    throw r.error(fmt::format("attribute cell_size = {} is not a positive number", map.cell_size));
  // Every point the map describes lies within √3 cell sizes of the bounding cube origin + [0, n·cell_size]³
  // (a texel's surface point is P' − d·direction, d <= √3·cell_size): it must be finite also as the
  // float32 of a reconstructed mesh, so no product of these attributes overflows.
  for (int a = 0; a < 3; ++a)
    if (!(std::abs(origin[static_cast<std::size_t>(a)]) + (map.n + 2.0) * map.cell_size <=
          static_cast<double>(std::numeric_limits<float>::max())))
      throw r.error(fmt::format("origin ({}) + {} cells of cell_size = {} leave the range of float32 coordinates",
                                fmt::join(origin, ", "), map.n, map.cell_size));

  read_cells(r, map, G);
  if (map.first_layer.back() != L)
    throw r.error(fmt::format("the grey cells' domain faces make {} layers, attribute layers = {}",
                              map.first_layer.back(), L));
  map.layer_cell = r.dataset("layer_cell", h5::DType::kUInt32, {L}).read<std::uint32_t>();
  map.layer_face = r.dataset("layer_face", h5::DType::kUInt8, {L}).read<std::uint8_t>();

  const h5::Dataset distances = r.dataset("distances", h5::DType::kUInt16, map_shape(L, T, 0));
  map.distance_scale = distances.attribute<double>("scale");
  if (!std::isfinite(map.distance_scale) || map.distance_scale <= 0.0)
    throw r.error(fmt::format("distances attribute scale = {} is not a positive number", map.distance_scale));
  // docs/archive.md: scale = √3·cell_size/65534, so the longest projection segment is the largest code.
  if (const double want = distance_scale_for(map.cell_size);
      std::abs(map.distance_scale - want) > 1e-9 * want)
    throw r.error(fmt::format("distances attribute scale = {} disagrees with cell_size = {} (expected "
                              "sqrt(3) * cell_size / 65534 = {})",
                              map.distance_scale, map.cell_size, want));
  if (distances.attribute<double>("offset") != 0.0)
    throw r.error(fmt::format("distances attribute offset = {} (relief distances have offset 0)",
                              distances.attribute<double>("offset")));
  if (distances.attribute<std::int64_t>("empty") != kEmptyTexel)
    throw r.error(fmt::format("distances attribute empty = {}, expected {}", distances.attribute<std::int64_t>("empty"),
                              kEmptyTexel));
  map.distances = distances.read<std::uint16_t>();
  map.normals = r.dataset("normals", h5::DType::kInt8, map_shape(L, T, 3)).read<std::int8_t>();
  for (std::size_t t = 0; t < map.distances.size(); ++t) {
    const std::int8_t* c = &map.normals[3 * t];
    if (std::any_of(c, c + 3, [](std::int8_t x) { return x == -128; }))
      throw r.error(fmt::format("normal of texel {} has a component -128 (snorm8 uses -127..127)", t));
    if (map.distances[t] == kEmptyTexel && (c[0] != 0 || c[1] != 0 || c[2] != 0))
      throw r.error(fmt::format("empty texel {} has a non-zero normal", t));
  }
  if (g.exists("colors"))
    map.colors = r.dataset("colors", h5::DType::kUInt8, map_shape(L, T, 3)).read<std::uint8_t>();

  try {
    map.check();
  } catch (const InvalidInput& e) {
    throw r.error(check_cause(e));
  }
  read_levels(r, map);
  const RepresentationRecord record = read_record(g);
  if (const auto it = record.numbers.find("seconds_cells"); it != record.numbers.end()) map.seconds_cells = it->second;
  if (const auto it = record.numbers.find("seconds_sampling"); it != record.numbers.end())
    map.seconds_sampling = it->second;
  return map;
}

}  // namespace

ReliefMap read_relief_map(const Archive& archive, const std::string& name) {
  const Reader r(archive, name);
  check_method(r.group(), archive, kRelief, name, kMethod);
  return read_map(r);
}

ReliefMap read_relief_map(const h5::Group& group, std::string_view where) {
  const Reader r(group, where);
  if (!group.has_attribute("method") || group.attribute<std::string>("method") != kMethod)
    throw r.error(fmt::format("not a relief map (attribute method is not '{}')", kMethod));
  return read_map(r);
}

ReliefRecord read_relief_record(const Archive& archive, const std::string& name) {
  ReliefRecord record = read_record(open_representation(archive, kRelief, name));
  record.numbers.erase("cell_size");
  return record;
}

std::vector<std::string> relief_map_names(const Archive& archive) { return representation_names(archive, kRelief); }

}  // namespace gimforge::io
