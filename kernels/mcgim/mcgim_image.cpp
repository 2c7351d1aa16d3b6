#include "kernels/mcgim/mcgim_image.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>

#include <fmt/format.h>

#include "kernels/core/edge_topology.h"
#include "kernels/core/manifold_cut.h"
#include "kernels/core/errors.h"

namespace gimforge {
namespace {

Vec3 sample_position(const MultiChartImage& image, std::size_t s) {
  return {image.positions[3 * s], image.positions[3 * s + 1], image.positions[3 * s + 2]};
}

/// Walks the four-sample quads in row-major order and tells how each is split: by `image.zipper_diagonals`
/// for a pinned quad when it is given, else along the shorter diagonal.
class QuadSplits {
 public:
  explicit QuadSplits(const MultiChartImage& image)
      : image_(image), pinned_(image.zipper_diagonals.empty() ? std::vector<std::uint8_t>{} : pinned_quads(image)) {
    const auto count = static_cast<std::size_t>(std::count(pinned_.begin(), pinned_.end(), std::uint8_t{1}));
    if (!pinned_.empty() && image.zipper_diagonals.size() != (count + 7) / 8)
      throw InvalidInput(fmt::format("multi-chart image: {} bytes of zipper diagonals for {} pinned quads",
                                     image.zipper_diagonals.size(), count));
  }

  /// True for the split along (x, y)–(x + 1, y + 1); call once per four-sample quad, in row-major order.
  template <class Distance>
  bool main_diagonal(const Distance& distance2, std::size_t x, std::size_t y) {
    if (!pinned_.empty() && pinned_[y * (image_.width - 1) + x] != 0) {
      const bool other = ((static_cast<unsigned>(image_.zipper_diagonals[bit_ / 8]) >> (bit_ % 8)) & 1u) != 0;
      ++bit_;
      return !other;
    }
    const std::size_t s00 = y * image_.width + x;
    return distance2(s00, s00 + image_.width + 1) <= distance2(s00 + 1, s00 + image_.width);
  }

 private:
  const MultiChartImage& image_;
  std::vector<std::uint8_t> pinned_;
  std::size_t bit_{0};
};

/// Calls emit(a, b, c) with the samples of every triangle of the §3 rules, counter-clockwise; `distance2`
/// gives the squared 3D distance between two samples (for the shorter diagonal of a quad not pinned).
template <class Distance, class Emit>
void for_each_triangle(const MultiChartImage& image, const Distance& distance2, const Emit& emit) {
  const std::size_t w = image.width;
  QuadSplits splits(image);
  for (std::size_t y = 0; y + 1 < image.height; ++y)
    for (std::size_t x = 0; x + 1 < w; ++x) {
      const std::size_t s00 = y * w + x, s10 = s00 + 1, s01 = s00 + w, s11 = s01 + 1;
      const bool d00 = image.mask[s00] != 0, d10 = image.mask[s10] != 0, d01 = image.mask[s01] != 0,
                 d11 = image.mask[s11] != 0;
      const int n = int{d00} + int{d10} + int{d01} + int{d11};
      if (n < 3) continue;
      if (n == 4) {
        const bool main_diagonal = splits.main_diagonal(distance2, x, y);
        if (main_diagonal) {
          emit(s00, s10, s11);
          emit(s00, s11, s01);
        } else {
          emit(s00, s10, s01);
          emit(s10, s11, s01);
        }
      } else if (!d00) {
        emit(s10, s11, s01);
      } else if (!d10) {
        emit(s00, s11, s01);
      } else if (!d11) {
        emit(s00, s10, s01);
      } else {
        emit(s00, s10, s11);
      }
    }
}

/// Removes zipper folds: where unification collapses a thin strip, two faces over the same three vertices
/// remain, facing each other (a flap: each of its edges would have four faces) — both go; of two copies with
/// the same orientation one goes.
template <class Tri>
void drop_folds(std::vector<Tri>& faces) {
  std::map<std::array<std::uint32_t, 3>, std::vector<std::size_t>> by_set;
  for (std::size_t i = 0; i < faces.size(); ++i) {
    std::array<std::uint32_t, 3> key{faces[i][0], faces[i][1], faces[i][2]};
    std::sort(key.begin(), key.end());
    by_set[key].push_back(i);
  }
  std::vector<char> drop(faces.size(), 0);
  const auto orientation = [&](std::size_t i) {  // +1 when the face is an even permutation of its sorted key
    const auto& f = faces[i];
    const int inversions = int{f[0] > f[1]} + int{f[0] > f[2]} + int{f[1] > f[2]};
    return inversions % 2 == 0 ? 1 : -1;
  };
  for (const auto& [key, list] : by_set) {
    if (list.size() < 2) continue;
    int sum = 0;
    for (std::size_t i : list) sum += orientation(i);
    // Keep one face when the copies do not cancel (the net orientation), none when they do.
    bool kept = sum == 0;
    for (std::size_t i : list) {
      if (!kept && orientation(i) == (sum > 0 ? 1 : -1)) {
        kept = true;
        continue;
      }
      drop[i] = 1;
    }
  }
  std::size_t out = 0;
  for (std::size_t i = 0; i < faces.size(); ++i)
    if (!drop[i]) faces[out++] = faces[i];
  faces.resize(out);
}

}  // namespace

std::vector<std::uint8_t> pinned_quads(const MultiChartImage& image) {
  const std::size_t w = image.width, h = image.height, n = image.samples();
  if (w < 2 || h < 2) return {};
  std::vector<std::uint32_t> members(n, 0);
  for (std::size_t s = 0; s < n; ++s)
    if (image.mask[s] != 0) ++members[image.unified[s]];
  const auto corners = [&](std::size_t x, std::size_t y) {
    const std::size_t s00 = y * w + x;
    return std::array<std::size_t, 4>{s00, s00 + 1, s00 + w, s00 + w + 1};  // s00, s10, s01, s11
  };
  const auto key = [](std::uint32_t a, std::uint32_t b) {
    return (std::uint64_t{std::min(a, b)} << 32) | std::max(a, b);
  };
  // Two samples alone in their clusters are corners together of at most the quads around both: a diagonal
  // pair of such samples of one quad is in no other. Only pairs with a cluster of several samples can repeat.
  std::vector<std::uint64_t> pairs;  // once per quad that has the pair among its defined corners
  for (std::size_t y = 0; y + 1 < h; ++y)
    for (std::size_t x = 0; x + 1 < w; ++x) {
      const auto c = corners(x, y);
      int defined = 0;
      for (std::size_t s : c) defined += image.mask[s] != 0 ? 1 : 0;
      if (defined < 3) continue;
      const std::size_t first = pairs.size();
      for (std::size_t i = 0; i < 4; ++i)
        for (std::size_t j = i + 1; j < 4; ++j) {
          if (image.mask[c[i]] == 0 || image.mask[c[j]] == 0) continue;
          const std::uint32_t a = image.unified[c[i]], b = image.unified[c[j]];
          if (a != b && (members[a] > 1 || members[b] > 1)) pairs.push_back(key(a, b));
        }
      std::sort(pairs.begin() + static_cast<std::ptrdiff_t>(first), pairs.end());  // a pair counts once per quad
      pairs.erase(std::unique(pairs.begin() + static_cast<std::ptrdiff_t>(first), pairs.end()), pairs.end());
    }
  std::sort(pairs.begin(), pairs.end());
  const auto repeated = [&](std::uint32_t a, std::uint32_t b) {
    const auto [lo, hi] = std::equal_range(pairs.begin(), pairs.end(), key(a, b));
    return hi - lo > 1;
  };
  std::vector<std::uint8_t> pinned((w - 1) * (h - 1), 0);
  for (std::size_t y = 0; y + 1 < h; ++y)
    for (std::size_t x = 0; x + 1 < w; ++x) {
      const auto c = corners(x, y);
      if (image.mask[c[0]] == 0 || image.mask[c[1]] == 0 || image.mask[c[2]] == 0 || image.mask[c[3]] == 0) continue;
      std::array<std::uint32_t, 4> r{image.unified[c[0]], image.unified[c[1]], image.unified[c[2]], image.unified[c[3]]};
      const bool diagonals_repeat = repeated(r[0], r[3]) || repeated(r[1], r[2]);
      std::sort(r.begin(), r.end());
      const bool distinct = std::adjacent_find(r.begin(), r.end()) == r.end();
      pinned[y * (w - 1) + x] = !distinct || diagonals_repeat ? 1 : 0;
    }
  return pinned;
}

std::vector<std::uint8_t> zipper_diagonal_bits(const MultiChartImage& image) {
  if (!image.zipper_diagonals.empty()) return image.zipper_diagonals;  // the splits it has are the stored ones
  const std::vector<std::uint8_t> pinned = pinned_quads(image);
  std::vector<std::uint8_t> bits;
  std::size_t bit = 0;
  for (std::size_t q = 0; q < pinned.size(); ++q) {
    if (pinned[q] == 0) continue;
    const std::size_t s00 = (q / (image.width - 1)) * image.width + q % (image.width - 1), s11 = s00 + image.width + 1;
    const bool main_diagonal = (sample_position(image, s00) - sample_position(image, s11)).squaredNorm() <=
                               (sample_position(image, s00 + 1) - sample_position(image, s00 + image.width)).squaredNorm();
    if (bit % 8 == 0) bits.push_back(0);
    if (!main_diagonal) bits.back() = static_cast<std::uint8_t>(bits.back() | (1u << (bit % 8)));
    ++bit;
  }
  return bits;
}

std::size_t MultiChartImage::defined_samples() const {
  std::size_t n = 0;
  for (std::uint8_t m : mask) n += m != 0 ? 1u : 0u;
  return n;
}

std::size_t MultiChartImage::unique_vertices() const {
  std::size_t n = 0;
  for (std::size_t s = 0; s < unified.size(); ++s) n += mask[s] != 0 && unified[s] == s ? 1u : 0u;
  return n;
}

void check_multichart_structure(const MultiChartImage& image, std::string_view where) {
  const std::size_t n = image.samples();
  if (image.width == 0 || image.height == 0) throw FormatError(fmt::format("{}: the image is empty", where));
  if (image.positions.size() != 3 * n || image.mask.size() != n || image.chart.size() != n || image.unified.size() != n)
    throw FormatError(fmt::format("{}: the geometry, mask, chart and zipper arrays do not match {}x{}", where,
                                  image.width, image.height));
  for (std::size_t s = 0; s < n; ++s) {
    const auto [x, y] = std::pair{s % image.width, s / image.width};
    if (image.mask[s] > 1) throw FormatError(fmt::format("{}: mask value {} at ({}, {}) is not 0 or 1", where, image.mask[s], x, y));
    if (image.mask[s] == 0) {
      if (image.unified[s] != kNoSample || image.chart[s] != kNoChart)
        throw FormatError(fmt::format("{}: undefined sample ({}, {}) has a chart or cluster", where, x, y));
      continue;
    }
    if (image.chart[s] == kNoChart) throw FormatError(fmt::format("{}: defined sample ({}, {}) has no chart", where, x, y));
    const std::uint32_t r = image.unified[s];
    if (r >= n || image.mask[r] == 0 || image.unified[r] != r)
      throw FormatError(fmt::format("{}: sample ({}, {}) names a zipper representative {} that is not one", where, x, y, r));
  }
  if (!image.zipper_diagonals.empty()) {
    const std::vector<std::uint8_t> pinned = pinned_quads(image);
    const auto q = static_cast<std::size_t>(std::count(pinned.begin(), pinned.end(), std::uint8_t{1}));
    if (image.zipper_diagonals.size() != (q + 7) / 8)
      throw FormatError(fmt::format("{}: {} bytes of zipper diagonals for {} pinned quads (want {})", where,
                                    image.zipper_diagonals.size(), q, (q + 7) / 8));
    if (q % 8 != 0 && (static_cast<unsigned>(image.zipper_diagonals.back()) >> (q % 8)) != 0)
      throw FormatError(fmt::format("{}: the zipper diagonals' padding bits are not 0", where));
  }
}

void check_multichart_image(const MultiChartImage& image, std::string_view where) {
  check_multichart_structure(image, where);
  for (std::size_t s = 0; s < image.samples(); ++s) {
    const Vec3 p = sample_position(image, s);
    const auto [x, y] = std::pair{s % image.width, s / image.width};
    if (image.mask[s] == 0) {
      if (!p.array().isNaN().all()) throw FormatError(fmt::format("{}: undefined sample ({}, {}) has a position", where, x, y));
      continue;
    }
    if (!p.allFinite()) throw FormatError(fmt::format("{}: defined sample ({}, {}) is not finite", where, x, y));
    if (sample_position(image, image.unified[s]) != p)
      throw FormatError(fmt::format("{}: sample ({}, {}) lies elsewhere than its zipper representative {}", where, x, y,
                                    image.unified[s]));
  }
}

TriMesh reconstruct_multichart(const MultiChartImage& image, std::vector<std::uint32_t>* vertex_sample) {
  TriMesh mesh;
  std::vector<std::uint32_t> vertex(image.samples(), kNoSample);
  std::vector<std::uint32_t> samples_of_vertex;
  const auto distance2 = [&](std::size_t a, std::size_t b) {
    return (sample_position(image, a) - sample_position(image, b)).squaredNorm();
  };
  std::vector<std::array<std::uint32_t, 3>> corners;
  for_each_triangle(image, distance2, [&](std::size_t a, std::size_t b, std::size_t c) {
    const std::array<std::uint32_t, 3> t{image.unified[a], image.unified[b], image.unified[c]};
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) return;  // a zipper degenerate: a line, not a face
    corners.push_back(t);
  });
  drop_folds(corners);
  // Vertices in the order of their representative samples.
  std::vector<std::uint8_t> used(image.samples(), 0);
  for (const auto& t : corners)
    for (std::uint32_t s : t) used[s] = 1;
  for (std::size_t s = 0; s < used.size(); ++s)
    if (used[s]) {
      vertex[s] = static_cast<std::uint32_t>(mesh.positions.size());
      mesh.positions.push_back(sample_position(image, s));
      samples_of_vertex.push_back(static_cast<std::uint32_t>(s));
    }
  mesh.faces.reserve(corners.size());
  for (const auto& t : corners) mesh.faces.push_back({vertex[t[0]], vertex[t[1]], vertex[t[2]]});
  // A cluster the zipper pinched (two fans of faces meeting only at it) becomes one vertex per fan, so the
  // result stays a 2-manifold; each copy keeps the cluster's representative sample.
  std::vector<std::uint32_t> source;
  mesh = split_nonmanifold_vertices(mesh, &source);
  if (vertex_sample != nullptr) {
    vertex_sample->resize(source.size());
    for (std::size_t v = 0; v < source.size(); ++v) (*vertex_sample)[v] = samples_of_vertex[source[v]];
  }
  return mesh;
}

TriMesh split_nonmanifold_vertices(const TriMesh& mesh, std::vector<std::uint32_t>* source_vertex) {
  const EdgeTopology topo = build_edge_topology(mesh);
  if (check_manifold(mesh, topo).nonmanifold_vertices.empty()) {
    if (source_vertex != nullptr) {
      source_vertex->resize(mesh.positions.size());
      std::iota(source_vertex->begin(), source_vertex->end(), 0u);
    }
    return mesh;
  }
  return split_vertices_by_fans(mesh, topo, [](std::size_t) { return true; }, source_vertex);
}


std::vector<Face> triangulate_multichart(const MultiChartImage& image, std::span<const std::uint32_t> vertex_of_sample,
                                         std::span<const Vec3> positions) {
  std::vector<Face> faces;
  const auto at = [&](std::size_t s) -> const Vec3& { return positions[vertex_of_sample[image.unified[s]]]; };
  const auto distance2 = [&](std::size_t a, std::size_t b) { return (at(a) - at(b)).squaredNorm(); };
  for_each_triangle(image, distance2, [&](std::size_t a, std::size_t b, std::size_t c) {
    const Face f{vertex_of_sample[image.unified[a]], vertex_of_sample[image.unified[b]],
                 vertex_of_sample[image.unified[c]]};
    if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2]) return;
    faces.push_back(f);
  });
  drop_folds(faces);
  return faces;
}

std::vector<float> multichart_normals(const MultiChartImage& image) {
  const std::size_t w = image.width, h = image.height;
  std::vector<float> normals(3 * image.samples(), std::numeric_limits<float>::quiet_NaN());
  const auto defined = [&](std::size_t x, std::size_t y) { return x < w && y < h && image.mask[y * w + x] != 0; };
  for (std::size_t y = 0; y < h; ++y)
    for (std::size_t x = 0; x < w; ++x) {
      if (!defined(x, y)) continue;
      const std::size_t s = y * w + x;
      const auto p = [&](std::size_t xx, std::size_t yy) { return defined(xx, yy) ? sample_position(image, yy * w + xx) : sample_position(image, s); };
      const Vec3 du = p(x + 1, y) - p(x - 1, y);  // x − 1 wraps to a huge index: "undefined"
      const Vec3 dv = p(x, y + 1) - p(x, y - 1);
      const Vec3 n = du.cross(dv);
      const double len = n.norm();
      if (!(len > 0.0) || !std::isfinite(len)) continue;
      for (int c = 0; c < 3; ++c) normals[3 * s + static_cast<std::size_t>(c)] = static_cast<float>(n[c] / len);
    }
  return normals;
}

}  // namespace gimforge
