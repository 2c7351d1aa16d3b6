#pragma once
/// \file local_hausdorff.h
/// Local Hausdorff distances between a parametrized surface and the reconstruction of its sample grid
/// (adaptive geometry images §3.2), kept up to date while samples move (§3.3).
///
/// Both meshes live over the same parameter square: the original (the cut disk, one uv per vertex) and the
/// reconstruction of an n × n grid of samples (uv and 3D position per sample; every quad split along its
/// shorter 3D diagonal, as reconstruct_geometry_image does). For every face of each mesh the directed
/// distance to the other is its largest value over a barycentric lattice of the face (corners and edges
/// included), with the point p* that attains it and the face f* of the other mesh closest to p*:
/// - D1, original → reconstruction: the original's vertices, and the points of a lattice on every face
///   wider than the uniform grid spacing h (a point every h or closer), each against the reconstruction
///   triangles of the quads within h of its parameter point. (The paper's Fig. 3 takes, per face, the
///   triangles under the face's footprint enlarged twice; per point the candidate set stays small for faces
///   much wider than a quad, and a moved sample re-measures only the points near it. Over a face smaller
///   than a quad the distance to the locally flat reconstruction is affine: largest at a corner.)
/// - D2, reconstruction → original: the 15 points of the level-4 lattice of every reconstruction triangle,
///   over the whole original, through Embree (the original never moves).
/// The global figures — the max, and the RMS from each face's mean squared distance (the composite linear
/// rule on a lattice, the exact mean of an affine distance over a face smaller than a quad) weighted by its
/// area — estimate what `gimforge metrics` measures between the same two meshes.
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "kernels/core/embree_device.h"
#include "kernels/core/mesh.h"
#include "kernels/param/stretch.h"

namespace gimforge {

/// How the sides of the parameter square are glued (a cut), in perimeter coordinates c (0..4: bottom left
/// to right, right side upwards, top right to left, left side downwards). Empty functions: nothing glued.
struct PerimeterGlue {
  std::function<double(double)> mate;    ///< the coordinate c is glued to; NaN on the original boundary
  std::function<bool(double)> node;      ///< c is a cut-node (where cut-paths meet): its samples stay
  std::function<Vec3(double)> position;  ///< the surface point at c
};

/// The point of the unit square's perimeter at coordinate c (sides, as PerimeterGlue; taken modulo 4).
[[nodiscard]] Vec2 square_perimeter_point(double c);

struct LocalHausdorffOptions {
  /// Points of the original near a glued side also take the reconstruction across the cut as candidates;
  /// sample adjustment slides boundary samples along the sides (sample_adjust.h).
  PerimeterGlue glue;
};

/// The directed distance of one face to the other mesh.
struct FaceDistance {
  double distance{0.0};          ///< max over the face's lattice
  double mean_squared{0.0};      ///< mean of the squared distance over the lattice
  Vec3 bary{1.0, 0.0, 0.0};      ///< p* in barycentric coordinates of the face
  std::uint32_t target{0};       ///< f*: the other mesh's face closest to p*
};

/// Global figures of one direction.
struct DirectedSummary {
  double max{0.0};
  double rms{0.0};
};

/// Which set a face belongs to: D1 (original faces) or D2 (reconstruction triangles).
enum class Direction : std::uint8_t { OriginalToGrid, GridToOriginal };

class LocalHausdorff {
 public:
  /// Measures both directions (parallel). `original_uv` holds one parameter point per original vertex;
  /// `sample_uv` and `sample_pos` n·n values, row-major. Throws InvalidInput for mismatched sizes.
  LocalHausdorff(const EmbreeDevice& device, MeshView original, std::span<const Vec2> original_uv, std::uint32_t n,
                 std::vector<Vec2> sample_uv, std::vector<Vec3> sample_pos, const LocalHausdorffOptions& options = {});
  ~LocalHausdorff();
  LocalHausdorff(const LocalHausdorff&) = delete;
  LocalHausdorff& operator=(const LocalHausdorff&) = delete;

  [[nodiscard]] std::uint32_t size() const;
  [[nodiscard]] const std::vector<Vec2>& sample_uv() const;
  [[nodiscard]] const std::vector<Vec3>& sample_pos() const;
  /// The reconstruction triangle t (two per quad) as sample indices, and its count.
  [[nodiscard]] Face triangle(std::uint32_t t) const;
  [[nodiscard]] std::uint32_t triangles() const;
  [[nodiscard]] MeshView original() const;

  [[nodiscard]] const FaceDistance& face(Direction d, std::uint32_t f) const;
  [[nodiscard]] std::size_t faces(Direction d) const;
  [[nodiscard]] DirectedSummary summary(Direction d) const;
  /// The face of direction d with the largest distance.
  [[nodiscard]] std::uint32_t argmax(Direction d) const;

  /// What a move changed: the entries re-measured with their previous values, for the objective and undo.
  struct Change {
    std::vector<std::uint32_t> samples;
    std::vector<Vec2> old_uv;
    std::vector<Vec3> old_pos;
    std::vector<std::pair<Direction, std::uint32_t>> entries;
    std::vector<FaceDistance> old_values;
    std::vector<std::uint32_t> quads;
    std::vector<std::uint8_t> old_diagonals;
    std::vector<std::uint32_t> probes;  ///< D1 lattice points re-measured
    std::vector<double> old_probe_d2;
    std::vector<std::uint32_t> old_probe_tri;
    bool folded{false};  ///< the move was refused (and undone) because it folds the grid
    /// Largest distance of the re-measured entries before and after the move.
    double max_before{0.0};
    double max_after{0.0};
  };
  /// Moves `samples` to new parameter points and positions and re-measures every entry the move can
  /// change. A move that would fold the grid (a quad around a moved sample no longer sound in the
  /// parameter square, grid_quad.h: convex with a margin, also in float32, no side shorter than 1/16 of the
  /// uniform spacing; or a reconstruction triangle that was not turned against its quad's previous normal
  /// and now is — a triangle turned already, on a quad across a crease, does not block moves) is refused:
  /// the state is left as it was and `folded` is set.
  Change move(std::span<const std::uint32_t> samples, std::span<const Vec2> uv, std::span<const Vec3> pos);
  /// Checks every original point measured farther than `threshold` against the whole reconstruction
  /// (Embree). A point whose closest reconstruction point lies outside its candidate boxes (near a
  /// cut-node, or where the surface folds close to a part far away in the parameter square) gets a box
  /// there from then on. Then the original faces within half of the largest D1 (or above `threshold`) are
  /// searched on a finer lattice (45 points) against the whole reconstruction; where the largest distance
  /// lies between a face's points, a point is added there. Returns how many boxes and points were added.
  std::size_t verify(double threshold);
  /// Undoes a move returned by `move` (the latest one first).
  void undo(const Change& change);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gimforge
