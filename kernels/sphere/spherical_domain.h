#pragma once
/// \file spherical_domain.h
/// Spherical geometry images (Praun & Hoppe 2003): the polyhedral domains D (§4.2: octahedron,
/// tetrahedron, cube, flattened octahedron), their regular n-tessellations unfolded into image grids
/// (§4.1, D → I), the boundary extension rules that make the image a grid with spherical topology (§4.1),
/// and reconstruction of a watertight mesh from the image with the domain's own connectivity (§6,
/// "Rendering"), with level of detail by sub-sampling.
///
/// Image layouts (row-major (H, W, 3) per face, sample (row j, column i)):
/// - Octahedron, FlatOctahedron: one (2n+1) × (2n+1) image. With x = i − n, y = j − n the inner diamond
///   |x|+|y| ≤ n is the upper half of D and the four corner triangles fold onto the lower half; the image
///   boundary is the cut (4 edges from the lower pole to the equator vertices). (2n+1)² samples.
/// - Tetrahedron: one image of W = 2n columns × H = n+1 rows, periodic left-to-right (the redundant
///   column i = 2n equals column 0 and is not stored); two n × n squares, each split by its
///   anti-diagonal into two domain faces. (2n)(n+1) samples.
/// - Cube: 6 face images of (n+1) × (n+1) stacked face-major (face f occupies rows f(n+1)..f(n+1)+n of an
///   (6(n+1)) × (n+1) array). 6(n+1)² samples.
/// Samples on the cuts appear more than once in the image; they are the same domain point. The domain
/// has 2n²+2 (tetra), 4n²+2 (octa, flat-octa), 6n²+2 (cube) distinct points.
#include <array>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "kernels/core/mesh.h"

namespace gimforge {

/// The domain polyhedra of §4.1/§4.2.
enum class SphericalDomain { Octahedron, Tetrahedron, Cube, FlatOctahedron };

/// All domains, in declaration order (for loops in tests and drivers).
inline constexpr std::array<SphericalDomain, 4> kSphericalDomains{
    SphericalDomain::Octahedron, SphericalDomain::Tetrahedron, SphericalDomain::Cube,
    SphericalDomain::FlatOctahedron};

/// Name of a domain: "octa", "tetra", "cube", "flat-octa".
[[nodiscard]] std::string_view to_string(SphericalDomain domain);

/// Parses "octa", "tetra", "cube", "flat-octa". Throws InvalidInput for any other name.
[[nodiscard]] SphericalDomain parse_spherical_domain(std::string_view name);

/// One image sample: face (0 except for the cube, 0..5), column i, row j. Out-of-range i, j name a
/// sample of the extended lattice (§4.1 boundary extension) and are mapped back by DomainImage::resolve.
struct SampleIndex {
  std::int32_t face{0};
  std::int32_t i{0};
  std::int32_t j{0};
  friend bool operator==(const SampleIndex&, const SampleIndex&) = default;
};

/// The unfolding D ↔ I of one domain at tessellation n (§4.1): image sizes, the map from image samples to
/// points of D, and the boundary extension rules. Cheap to copy; all queries are O(1) except
/// resolve, which is O(1 + offset / n).
class DomainImage {
 public:
  /// Throws InvalidInput unless 1 ≤ n ≤ 2^14.
  DomainImage(SphericalDomain domain, std::uint32_t n);

  [[nodiscard]] SphericalDomain domain() const { return domain_; }
  /// Tessellation number: n + 1 samples on every domain edge (§3 "remeshing").
  [[nodiscard]] std::int32_t n() const { return n_; }
  /// Columns per face image: 2n+1 (octa, flat-octa), 2n (tetra), n+1 (cube).
  [[nodiscard]] std::int32_t width() const { return width_; }
  /// Rows per face image: 2n+1 (octa, flat-octa), n+1 (tetra, cube).
  [[nodiscard]] std::int32_t height() const { return height_; }
  /// Number of face images: 6 for the cube, 1 otherwise.
  [[nodiscard]] std::int32_t faces() const { return faces_; }
  /// Total stored samples: faces() · width() · height().
  [[nodiscard]] std::size_t num_samples() const;
  /// Distinct domain points: 2n²+2 (tetra), 4n²+2 (octa, flat-octa), 6n²+2 (cube).
  [[nodiscard]] std::size_t num_domain_points() const;

  /// True when s is a stored sample (face in range, 0 ≤ i < width, 0 ≤ j < height).
  [[nodiscard]] bool contains(const SampleIndex& s) const;
  /// Row-major linear index (face·height + j)·width + i of a stored sample. Precondition: contains(s).
  [[nodiscard]] std::size_t linear_index(const SampleIndex& s) const;
  /// Inverse of linear_index. Precondition: k < num_samples().
  [[nodiscard]] SampleIndex sample_at(std::size_t k) const;

  /// Boundary extension (§4.1): the stored sample that the lattice position (face, i, j) stands for, for
  /// any i, j. Octahedron and flat-octahedron: 180° rotation about the midpoint of the image edge that is
  /// crossed. Tetrahedron: periodic in i (period 2n), 180° rotation about (0, 0) and (0, n) across the
  /// bottom and top rows. Cube: the lattice is folded across the cube edge onto the adjacent face, so a
  /// position k rows outside a face edge is the sample k rows inside the neighbouring face; in the corner
  /// regions (both i and j outside) it folds across the column edge first, then the row edge.
  /// Throws InvalidInput for a face out of range.
  [[nodiscard]] SampleIndex resolve(std::int32_t face, std::int32_t i, std::int32_t j) const;

  /// Exact integer identity of the domain point of a stored sample: n times its point on D (for the
  /// flat octahedron, n times the point of the regular octahedron it unfolds like). Two stored samples are
  /// the same domain point iff their keys are equal. Precondition: contains(s).
  [[nodiscard]] Eigen::Vector3i lattice_key(const SampleIndex& s) const;

  /// The map I → D: the point of D of a stored sample. D is the octahedron |x|+|y|+|z| = 1, the
  /// tetrahedron with vertices (1,1,1), (1,−1,−1), (−1,1,−1), (−1,−1,1), the cube [−1,1]³, or the flattened
  /// octahedron (§4.1, Fig. 7b): the doubly covered diamond |x|+|y| ≤ 1, z = 0, onto which the square
  /// image folds isometrically (upper sheet = inner diamond, lower sheet = the four corner triangles).
  /// Precondition: contains(s).
  [[nodiscard]] Vec3 domain_point(const SampleIndex& s) const;

  /// A simple D → S map, the central (gnomonic) projection of §4.2 ("the simplest parametrization"),
  /// not the stretch-optimized map: the normalized domain point; for the flat octahedron the normalized
  /// point of the regular octahedron with the same unfolding. Precondition: contains(s).
  [[nodiscard]] Vec3 sphere_point(const SampleIndex& s) const;

  /// One vertex id per stored sample (indexed by linear_index): samples that are the same domain point
  /// share an id; ids are 0..num_domain_points()−1 in order of first appearance.
  [[nodiscard]] std::vector<std::uint32_t> vertex_ids() const;

 private:
  [[nodiscard]] SampleIndex resolve_octahedral(std::int32_t i, std::int32_t j) const;
  [[nodiscard]] SampleIndex resolve_tetrahedral(std::int32_t i, std::int32_t j) const;
  [[nodiscard]] SampleIndex resolve_cube(std::int32_t face, std::int32_t i, std::int32_t j) const;

  SphericalDomain domain_;
  std::int32_t n_;
  std::int32_t width_;
  std::int32_t height_;
  std::int32_t faces_;
};

/// Where the samples of domain_positions lie.
enum class DomainEmbedding { Polyhedron, Sphere };

/// The domain's own geometry image: domain_point (Polyhedron) or sphere_point (Sphere) of every stored
/// sample, indexed by linear_index (§4.1, Fig. 6 "D" and "S" rows).
[[nodiscard]] std::vector<Vec3> domain_positions(const DomainImage& image, DomainEmbedding embedding);

/// Tessellation numbers of the levels of detail by sub-sampling (§6 "Level-of-detail"): n, n/2, ... while
/// the level is an integer, ending at 1 when n is a power of two.
[[nodiscard]] std::vector<std::uint32_t> spherical_lod_levels(std::uint32_t n);

/// Reconstructs the triangle mesh of a spherical geometry image at level `level` (sub-sampling by
/// 2^level, §6 "Rendering" and "Level-of-detail"). `positions`: one point per stored sample (shape
/// (faces, height, width) row-major, as linear_index). Connectivity: for the tetrahedron and octahedron
/// the domain's own triangulation (cells split along the diagonal parallel to the domain face edge); for
/// the cube and flattened octahedron every cell is split along its shorter 3D diagonal, except that a
/// flat-octahedron cell touching an image-edge midpoint (a cone point of the fold) takes the diagonal
/// through it, so neighbouring cells never repeat a triangle. Samples that are the same domain point are
/// merged into one vertex (at the average of their positions), so the result is closed, manifold and of
/// genus 0 with num_domain_points() of the level's image vertices; faces are counter-clockwise in the
/// image, i.e. outward for the domain's own positions. Throws InvalidInput when positions has the wrong
/// size or n is not divisible by 2^level.
[[nodiscard]] TriMesh reconstruct_spherical_image(const DomainImage& image, std::span<const Vec3> positions,
                                                  std::uint32_t level = 0);

}  // namespace gimforge
