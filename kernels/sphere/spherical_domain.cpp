#include "kernels/sphere/spherical_domain.h"

#include <cstdlib>
#include <unordered_map>

#include <fmt/format.h>

#include "kernels/core/errors.h"

namespace gimforge {

namespace {

using Vec3i = Eigen::Vector3i;

constexpr std::int32_t kMaxN = 1 << 14;

/// Orthonormal integer frame of a cube face: outward normal N, image axes U (columns) and V (rows),
/// with U × V = N so counter-clockwise image order is outward.
struct CubeFrame {
  Vec3i normal;
  Vec3i u;
  Vec3i v;
};

const std::array<CubeFrame, 6>& cube_frames() {
  static const std::array<CubeFrame, 6> frames{{
      {Vec3i(1, 0, 0), Vec3i(0, 1, 0), Vec3i(0, 0, 1)},
      {Vec3i(-1, 0, 0), Vec3i(0, 0, 1), Vec3i(0, 1, 0)},
      {Vec3i(0, 1, 0), Vec3i(0, 0, 1), Vec3i(1, 0, 0)},
      {Vec3i(0, -1, 0), Vec3i(1, 0, 0), Vec3i(0, 0, 1)},
      {Vec3i(0, 0, 1), Vec3i(1, 0, 0), Vec3i(0, 1, 0)},
      {Vec3i(0, 0, -1), Vec3i(0, 1, 0), Vec3i(1, 0, 0)},
  }};
  return frames;
}

std::int32_t cube_face_with_normal(const Vec3i& normal) {
  const auto& frames = cube_frames();
  for (std::size_t f = 0; f < frames.size(); ++f)
    if (frames[f].normal == normal) return static_cast<std::int32_t>(f);
  throw InvalidInput("cube_face_with_normal: not an axis direction");  // unreachable for unit axes
}

/// Regular tetrahedron vertices P, Q, R, T (all (±1,±1,±1) with an odd number of −1 signs removed).
const std::array<Vec3i, 4>& tetra_vertices() {
  static const std::array<Vec3i, 4> v{Vec3i(1, 1, 1), Vec3i(1, -1, -1), Vec3i(-1, 1, -1), Vec3i(-1, -1, 1)};
  return v;
}

/// n times the point at (a, b) ∈ [0, n]² of a square with corners c00, c10, c01, c11 split along its
/// anti-diagonal (c10–c01): two flat triangles.
Vec3i anti_diagonal_square_point(std::int32_t n, std::int32_t a, std::int32_t b, const Vec3i& c00,
                                 const Vec3i& c10, const Vec3i& c01, const Vec3i& c11) {
  if (a + b <= n) return n * c00 + a * (c10 - c00) + b * (c01 - c00);
  return n * c11 + (n - a) * (c01 - c11) + (n - b) * (c10 - c11);
}

/// Floor modulo for a positive period.
std::int32_t wrap(std::int32_t x, std::int32_t period) {
  const std::int32_t r = x % period;
  return r < 0 ? r + period : r;
}

std::int32_t sign(std::int32_t x) { return x < 0 ? -1 : 1; }

/// Packs a lattice key with coordinates in [−n, n] into one integer.
std::uint64_t pack_key(const Vec3i& k, std::int32_t n) {
  const auto span = static_cast<std::uint64_t>(2 * n + 1);
  const auto c = [n](std::int32_t x) { return static_cast<std::uint64_t>(x + n); };
  return (c(k.x()) * span + c(k.y())) * span + c(k.z());
}

}  // namespace

std::string_view to_string(SphericalDomain domain) {
  switch (domain) {
    case SphericalDomain::Octahedron: return "octa";
    case SphericalDomain::Tetrahedron: return "tetra";
    case SphericalDomain::Cube: return "cube";
    case SphericalDomain::FlatOctahedron: return "flat-octa";
  }
  return "unknown";
}

SphericalDomain parse_spherical_domain(std::string_view name) {
  for (SphericalDomain d : kSphericalDomains)
    if (to_string(d) == name) return d;
  throw InvalidInput(
      fmt::format("parse_spherical_domain: unknown domain '{}' (expected octa, tetra, cube or flat-octa)", name));
}

DomainImage::DomainImage(SphericalDomain domain, std::uint32_t n)
    : domain_(domain), n_(static_cast<std::int32_t>(n)), width_(0), height_(0), faces_(1) {
  if (n < 1 || n > static_cast<std::uint32_t>(kMaxN))
    throw InvalidInput(fmt::format("DomainImage: tessellation n = {} out of range [1, {}]", n, kMaxN));
  switch (domain) {
    case SphericalDomain::Octahedron:
    case SphericalDomain::FlatOctahedron: width_ = height_ = 2 * n_ + 1; break;
    case SphericalDomain::Tetrahedron:
      width_ = 2 * n_;
      height_ = n_ + 1;
      break;
    case SphericalDomain::Cube:
      width_ = height_ = n_ + 1;
      faces_ = 6;
      break;
  }
}

std::size_t DomainImage::num_samples() const {
  return static_cast<std::size_t>(faces_) * static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_);
}

std::size_t DomainImage::num_domain_points() const {
  const auto nn = static_cast<std::size_t>(n_) * static_cast<std::size_t>(n_);
  switch (domain_) {
    case SphericalDomain::Tetrahedron: return 2 * nn + 2;
    case SphericalDomain::Cube: return 6 * nn + 2;
    default: return 4 * nn + 2;
  }
}

bool DomainImage::contains(const SampleIndex& s) const {
  return s.face >= 0 && s.face < faces_ && s.i >= 0 && s.i < width_ && s.j >= 0 && s.j < height_;
}

std::size_t DomainImage::linear_index(const SampleIndex& s) const {
  return (static_cast<std::size_t>(s.face) * static_cast<std::size_t>(height_) + static_cast<std::size_t>(s.j)) *
             static_cast<std::size_t>(width_) +
         static_cast<std::size_t>(s.i);
}

SampleIndex DomainImage::sample_at(std::size_t k) const {
  const auto w = static_cast<std::size_t>(width_);
  const auto h = static_cast<std::size_t>(height_);
  return {static_cast<std::int32_t>(k / (w * h)), static_cast<std::int32_t>(k % w),
          static_cast<std::int32_t>((k / w) % h)};
}

SampleIndex DomainImage::resolve(std::int32_t face, std::int32_t i, std::int32_t j) const {
  if (face < 0 || face >= faces_)
    throw InvalidInput(fmt::format("DomainImage::resolve: face {} out of range [0, {})", face, faces_));
  switch (domain_) {
    case SphericalDomain::Tetrahedron: return resolve_tetrahedral(i, j);
    case SphericalDomain::Cube: return resolve_cube(face, i, j);
    default: return resolve_octahedral(i, j);
  }
}

SampleIndex DomainImage::resolve_octahedral(std::int32_t i, std::int32_t j) const {
  // Centred coordinates; a 180° rotation about the midpoint (±n, 0) maps x → ±2n − x, y → −y.
  std::int32_t x = i - n_;
  std::int32_t y = j - n_;
  while (std::abs(x) > n_ || std::abs(y) > n_) {
    if (std::abs(x) > n_) {
      x = 2 * n_ * sign(x) - x;
      y = -y;
    } else {
      y = 2 * n_ * sign(y) - y;
      x = -x;
    }
  }
  return {0, x + n_, y + n_};
}

SampleIndex DomainImage::resolve_tetrahedral(std::int32_t i, std::int32_t j) const {
  // Periodic in i (period 2n); 180° rotations about (0, 0) and (0, n) across the bottom and top rows.
  while (j < 0 || j > n_) {
    i = -i;
    j = j < 0 ? -j : 2 * n_ - j;
  }
  return {0, wrap(i, 2 * n_), j};
}

SampleIndex DomainImage::resolve_cube(std::int32_t face, std::int32_t i, std::int32_t j) const {
  // Work with n times the point on the plane of the face, extended beyond the face, and fold it over
  // the crossed cube edge onto the neighbouring face until it lies on a face.
  const auto& frames = cube_frames();
  Vec3i p = n_ * frames[static_cast<std::size_t>(face)].normal +
            (2 * i - n_) * frames[static_cast<std::size_t>(face)].u +
            (2 * j - n_) * frames[static_cast<std::size_t>(face)].v;
  std::int32_t f = face;
  for (;;) {
    const CubeFrame& fr = frames[static_cast<std::size_t>(f)];
    const std::int32_t a = p.dot(fr.u);
    const std::int32_t b = p.dot(fr.v);
    if (std::abs(a) <= n_ && std::abs(b) <= n_) return {f, (a + n_) / 2, (b + n_) / 2};
    const Vec3i crossed = std::abs(a) > n_ ? Vec3i(sign(a) * fr.u) : Vec3i(sign(b) * fr.v);
    const std::int32_t excess = std::abs(std::abs(a) > n_ ? a : b) - n_;
    p -= excess * (crossed + fr.normal);
    f = cube_face_with_normal(crossed);
  }
}

Eigen::Vector3i DomainImage::lattice_key(const SampleIndex& s) const {
  switch (domain_) {
    case SphericalDomain::Tetrahedron: {
      const auto& t = tetra_vertices();  // P, Q, R, T at (0,0), (n,0), (0,n), (n,n) of the first square
      if (s.i < n_) return anti_diagonal_square_point(n_, s.i, s.j, t[0], t[1], t[2], t[3]);
      return anti_diagonal_square_point(n_, s.i - n_, s.j, t[1], t[0], t[3], t[2]);
    }
    case SphericalDomain::Cube: {
      const CubeFrame& fr = cube_frames()[static_cast<std::size_t>(s.face)];
      return n_ * fr.normal + (2 * s.i - n_) * fr.u + (2 * s.j - n_) * fr.v;
    }
    default: {
      const std::int32_t x = s.i - n_;
      const std::int32_t y = s.j - n_;
      const std::int32_t z = n_ - std::abs(x) - std::abs(y);
      if (z >= 0) return {x, y, z};
      return {sign(x) * (n_ - std::abs(y)), sign(y) * (n_ - std::abs(x)), z};
    }
  }
}

Vec3 DomainImage::domain_point(const SampleIndex& s) const {
  Vec3 p = lattice_key(s).cast<double>() / static_cast<double>(n_);
  if (domain_ == SphericalDomain::FlatOctahedron) p.z() = 0.0;
  return p;
}

Vec3 DomainImage::sphere_point(const SampleIndex& s) const { return lattice_key(s).cast<double>().normalized(); }

std::vector<std::uint32_t> DomainImage::vertex_ids() const {
  std::unordered_map<std::uint64_t, std::uint32_t> ids;
  ids.reserve(num_domain_points());
  std::vector<std::uint32_t> out(num_samples());
  for (std::size_t k = 0; k < out.size(); ++k) {
    const auto [it, inserted] =
        ids.try_emplace(pack_key(lattice_key(sample_at(k)), n_), static_cast<std::uint32_t>(ids.size()));
    out[k] = it->second;
  }
  return out;
}

std::vector<Vec3> domain_positions(const DomainImage& image, DomainEmbedding embedding) {
  std::vector<Vec3> out(image.num_samples());
  for (std::size_t k = 0; k < out.size(); ++k) {
    const SampleIndex s = image.sample_at(k);
    out[k] = embedding == DomainEmbedding::Sphere ? image.sphere_point(s) : image.domain_point(s);
  }
  return out;
}

std::vector<std::uint32_t> spherical_lod_levels(std::uint32_t n) {
  std::vector<std::uint32_t> levels{n};
  while (levels.back() > 1 && levels.back() % 2 == 0) levels.push_back(levels.back() / 2);
  return levels;
}

namespace {

enum class Diagonal { Anti, Main };  ///< Anti joins c10–c01, Main joins c00–c11

/// The four corners of one cell of the sub-sampled image, as stored samples.
struct Cell {
  std::array<SampleIndex, 4> corner;  ///< c00, c10, c01, c11
};

class Reconstructor {
 public:
  Reconstructor(const DomainImage& image, std::span<const Vec3> positions, std::int32_t step)
      : image_(image), positions_(positions), step_(step), full_ids_(image.vertex_ids()) {}

  TriMesh run() {
    merge_vertices();
    for (std::int32_t f = 0; f < image_.faces(); ++f)
      for (std::int32_t j = 0; j + step_ < image_.height(); j += step_)
        for (std::int32_t i = 0; i < cell_columns(); i += step_) add_cell(cell_at(f, i, j));
    return std::move(mesh_);
  }

 private:
  /// Columns where cells start: the tetrahedron image wraps, so its last column starts a cell too.
  [[nodiscard]] std::int32_t cell_columns() const {
    return image_.domain() == SphericalDomain::Tetrahedron ? image_.width() : image_.width() - step_;
  }

  [[nodiscard]] bool on_level(const SampleIndex& s) const { return s.i % step_ == 0 && s.j % step_ == 0; }

  /// Level vertices: the domain points of the sub-sampled samples, at the average of their positions.
  void merge_vertices() {
    level_ids_.assign(image_.num_domain_points(), kUnused);
    std::vector<int> counts;
    for (std::size_t k = 0; k < full_ids_.size(); ++k) {
      if (!on_level(image_.sample_at(k))) continue;
      std::uint32_t& id = level_ids_[full_ids_[k]];
      if (id == kUnused) {
        id = static_cast<std::uint32_t>(mesh_.positions.size());
        mesh_.positions.push_back(Vec3::Zero());
        counts.push_back(0);
      }
      mesh_.positions[id] += positions_[k];
      ++counts[id];
    }
    for (std::size_t v = 0; v < counts.size(); ++v) mesh_.positions[v] /= static_cast<double>(counts[v]);
  }

  [[nodiscard]] Cell cell_at(std::int32_t f, std::int32_t i, std::int32_t j) const {
    return {{image_.resolve(f, i, j), image_.resolve(f, i + step_, j), image_.resolve(f, i, j + step_),
             image_.resolve(f, i + step_, j + step_)}};
  }

  [[nodiscard]] std::uint32_t vertex(const SampleIndex& s) const {
    return level_ids_[full_ids_[image_.linear_index(s)]];
  }

  [[nodiscard]] const Vec3& position(const SampleIndex& s) const { return mesh_.positions[vertex(s)]; }

  [[nodiscard]] Diagonal shorter_diagonal(const Cell& c) const {
    const double main = (position(c.corner[0]) - position(c.corner[3])).squaredNorm();
    const double anti = (position(c.corner[1]) - position(c.corner[2])).squaredNorm();
    return main < anti ? Diagonal::Main : Diagonal::Anti;
  }

  /// Octahedral triangulation: the diagonal parallel to the domain face edge |x|+|y| = n of the quadrant.
  [[nodiscard]] Diagonal octahedral_diagonal(const Cell& c) const {
    const std::int32_t cx = 2 * c.corner[0].i + step_ - 2 * image_.n();
    const std::int32_t cy = 2 * c.corner[0].j + step_ - 2 * image_.n();
    return (cx > 0) == (cy > 0) ? Diagonal::Anti : Diagonal::Main;
  }

  /// A flat-octahedron cell touching an image-edge midpoint (a fold cone point) must take the diagonal
  /// through it; the octahedral diagonal does.
  [[nodiscard]] bool touches_edge_midpoint(const Cell& c) const {
    const std::int32_t n = image_.n();
    for (const SampleIndex& s : c.corner) {
      const bool mid_col = s.i == n && (s.j == 0 || s.j == 2 * n);
      const bool mid_row = s.j == n && (s.i == 0 || s.i == 2 * n);
      if (mid_col || mid_row) return true;
    }
    return false;
  }

  [[nodiscard]] Diagonal diagonal(const Cell& c) const {
    switch (image_.domain()) {
      case SphericalDomain::Tetrahedron: return Diagonal::Anti;
      case SphericalDomain::Octahedron: return octahedral_diagonal(c);
      case SphericalDomain::Cube: return shorter_diagonal(c);
      case SphericalDomain::FlatOctahedron:
        return touches_edge_midpoint(c) ? octahedral_diagonal(c) : shorter_diagonal(c);
    }
    return Diagonal::Anti;
  }

  void add_cell(const Cell& c) {
    const std::uint32_t v00 = vertex(c.corner[0]);
    const std::uint32_t v10 = vertex(c.corner[1]);
    const std::uint32_t v01 = vertex(c.corner[2]);
    const std::uint32_t v11 = vertex(c.corner[3]);
    if (diagonal(c) == Diagonal::Anti) {
      add_face({v00, v10, v01});
      add_face({v10, v11, v01});
    } else {
      add_face({v00, v10, v11});
      add_face({v00, v11, v01});
    }
  }

  void add_face(const Face& f) {
    if (!has_repeated_index(f)) mesh_.faces.push_back(f);
  }

  static constexpr std::uint32_t kUnused = 0xffffffffu;
  const DomainImage& image_;
  std::span<const Vec3> positions_;
  std::int32_t step_;
  std::vector<std::uint32_t> full_ids_;
  std::vector<std::uint32_t> level_ids_;
  TriMesh mesh_;
};

}  // namespace

TriMesh reconstruct_spherical_image(const DomainImage& image, std::span<const Vec3> positions, std::uint32_t level) {
  if (positions.size() != image.num_samples())
    throw InvalidInput(fmt::format("reconstruct_spherical_image: {} positions for a {} image with {} samples",
                                   positions.size(), to_string(image.domain()), image.num_samples()));
  if (level >= 15 || image.n() % (1 << level) != 0)
    throw InvalidInput(fmt::format("reconstruct_spherical_image: level {} does not divide n = {}", level, image.n()));
  return Reconstructor(image, positions, std::int32_t{1} << level).run();
}

}  // namespace gimforge
