#pragma once
/// \file synth.h
/// Synthetic scans of any size, generated in pieces (issue #17, test data): a base mesh subdivided 1-to-n²
/// with a deterministic displacement along its normals, and an open, noisy height field with holes. Both are
/// defined index by index (vertex i, face f), so a writer can stream tens of millions of faces without ever
/// holding them, and any part can be regenerated identically. Coordinates are doubles; an offset (UTM-like
/// georeferencing) is added last.
#include <cstddef>
#include <array>
#include <cstdint>
#include <vector>

#include "kernels/core/mesh.h"

namespace gimforge {

/// The displacement of a subdivided scan: d(p) = amplitude · (Σ_k sin(2π/λ_k · u_k·p + φ_k)) / √K over K = 6
/// plane waves whose directions u_k and phases φ_k come from `seed`, with wavelengths λ_k spread over
/// [wavelength, 2·wavelength]. Lengths are fractions of the base mesh's bounding-box diagonal.
struct SubdivideOptions {
  std::uint32_t segments{2};     ///< n: every base edge is cut into n pieces, every face into n² faces
  double amplitude{0.002};       ///< displacement amplitude / bbox diagonal, in [0, 1] (0: the flat subdivision)
  double wavelength{0.01};       ///< shortest wave / bbox diagonal, in [1e-9, 1000]
  std::uint64_t seed{1};
  Vec3 offset{Vec3::Zero()};     ///< added to every output position
};

/// The subdivided, displaced scan of one base mesh. Vertex numbering: the base vertices first (same order),
/// then n − 1 vertices per base edge (edges in the order of their first face, each from its lower to its
/// higher vertex index), then (n − 1)(n − 2)/2 vertices per base face. Faces: n² per base face, base faces
/// in order, each patch's faces in the same orientation as its base face. A vertex on a base edge is computed
/// from that edge alone, so both faces of an edge share it exactly: a closed manifold base gives a closed
/// manifold scan with the base's genus and components.
class SubdividedScan {
 public:
  /// Throws InvalidInput for segments 0, a base mesh without faces, a face with a repeated or out-of-range
  /// index, an amplitude or wavelength out of its range, or more than 2³² − 1 vertices or faces in the result.
  SubdividedScan(const TriMesh& base, const SubdivideOptions& options);

  [[nodiscard]] std::uint64_t num_vertices() const { return num_vertices_; }
  [[nodiscard]] std::uint64_t num_faces() const { return std::uint64_t{faces_.size()} * n_ * n_; }
  [[nodiscard]] std::size_t num_base_faces() const { return faces_.size(); }

  /// Appends the positions of vertices [first, first + count) to `out`.
  void vertices(std::uint64_t first, std::uint64_t count, std::vector<Vec3>& out) const;
  /// Appends the n² faces of base face `f` to `out`.
  void faces_of(std::size_t f, std::vector<Face>& out) const;

 private:
  [[nodiscard]] Vec3 displaced(const Vec3& p, const Vec3& normal) const;
  /// (n − 1)(n − 2)/2: the vertices inside one base face.
  [[nodiscard]] std::uint64_t interior_per_face() const { return n_ < 3 ? 0 : (std::uint64_t{n_} - 1) * (n_ - 2) / 2; }
  [[nodiscard]] std::uint32_t vertex_index(std::size_t f, std::uint32_t i, std::uint32_t j) const;

  SubdivideOptions options_;
  std::uint32_t n_{0};
  std::vector<Vec3> positions_;                       ///< base positions
  std::vector<Vec3> normals_;                         ///< base vertex normals (area-weighted, unit)
  std::vector<Face> faces_;                           ///< base faces
  std::vector<std::array<std::uint32_t, 2>> edges_;   ///< base edges, lower index first
  std::vector<std::array<std::uint32_t, 3>> face_edges_;  ///< edges of face f: (v0 v1), (v1 v2), (v2 v0)
  std::uint64_t num_vertices_{0};
  std::array<Vec3, 6> wave_dir_{};
  std::array<double, 6> wave_number_{};
  std::array<double, 6> wave_phase_{};
  double amplitude_{0.0};
};

/// An open terrain: an nx × ny grid of quads (two triangles each) over [0, nx·spacing] × [0, ny·spacing],
/// heights = smooth relief (sum of plane waves) + uniform noise per vertex, with round holes cut out (quads
/// whose centre lies in a hole, and the vertices no face uses, are left out; holes keep two cells apart, so
/// the result is a 2-manifold). All from `seed`.
struct TerrainOptions {
  std::uint32_t nx{256};
  std::uint32_t ny{256};
  double spacing{1.0};
  double relief{0.05};   ///< relief amplitude / side length (max(nx, ny)·spacing), in [0, 10]
  double noise{0.1};     ///< per-vertex noise amplitude / spacing, in [0, 100]
  std::uint32_t holes{8};    ///< at most 10,000
  double hole_radius{0.03};  ///< hole radius / side length, in [0, 0.5]
  std::uint64_t seed{1};
  Vec3 offset{Vec3::Zero()};
};

/// The terrain, generated row by row. Vertex numbering: the used grid vertices in row-major order (row 0
/// first). Faces: per quad row, per quad, its two triangles (those not in a hole), counter-clockwise from +z.
class TerrainScan {
 public:
  /// Counts the used vertices (one pass over the grid). Throws InvalidInput for nx or ny 0, a spacing
  /// outside [1e-9, 1e9], an amplitude, radius or hole count out of its range, more than 2³² − 1 vertices or
  /// faces, or holes that remove every face.
  explicit TerrainScan(const TerrainOptions& options);

  [[nodiscard]] std::uint64_t num_vertices() const { return num_vertices_; }
  [[nodiscard]] std::uint64_t num_faces() const { return num_faces_; }

  /// Appends the used vertices of grid row y (0 ≤ y ≤ ny) to `out`, in order.
  void vertex_row(std::uint32_t y, std::vector<Vec3>& out) const;
  /// Appends the faces of quad row y (0 ≤ y < ny) to `out`.
  void face_row(std::uint32_t y, std::vector<Face>& out) const;

 private:
  /// Whether quad (x, y) is kept: its centre is in no hole (holes cut whole quads).
  [[nodiscard]] bool quad_kept(std::uint32_t x, std::uint32_t y) const;
  [[nodiscard]] bool vertex_used(std::uint32_t x, std::uint32_t y) const;
  /// The output index of each grid vertex of row y (UINT32_MAX where unused).
  void row_indices(std::uint32_t y, std::vector<std::uint32_t>& out) const;

  TerrainOptions options_;
  double side_{0.0};
  std::vector<std::array<double, 3>> holes_;   ///< centre x, centre y, radius²
  std::vector<std::uint64_t> row_start_;       ///< index of the first used vertex of each grid row; ny + 2 entries
  std::uint64_t num_vertices_{0};
  std::uint64_t num_faces_{0};
  std::array<Vec3, 6> wave_dir_{};
  std::array<double, 6> wave_number_{};
  std::array<double, 6> wave_phase_{};
};

}  // namespace gimforge
