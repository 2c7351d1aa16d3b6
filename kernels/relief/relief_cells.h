#pragma once
/// \file relief_cells.h
/// Cubic cell classification for relief mapping on cubic cell complexes (Apaza & Andújar, §3.1 and
/// §3.3.1): the axis-aligned bounding cube of a mesh M is split into N×N×N cubic cells, and each cell is
///
/// - **grey (G)**: "those with non-empty intersection with the boundary of M" — here: the closed cell box
///   and at least one closed triangle of M overlap (exact separating-axis test, triangle_box_overlap);
/// - **black (B)**: "those inside M";
/// - **white (W)**: "those outside M".
///
/// and each G cell's six faces are classified as the paper defines them:
///
/// > "A face of a G cell shared with a W cell will be referred to as *external face*. Otherwise it will be
/// > called *internal face*. A G cell has between zero and six external faces. G cells with at least one
/// > external face will be referred to as *border G cells* (BG cells for short). Likewise, G cells with no
/// > external faces will be referred to as *interior G cells* (IG cells)."
///
/// A face on the boundary of the grid has no neighbouring cell; the space beyond the bounding cube is
/// outside M, so such a face counts as shared with a W cell (external). This is what makes the paper's
/// N = 1 grid one G cell with six external faces (its case 0; Table 1, "Pensatore": 1 G cell, 6 domain
/// faces). The *domain faces* of §3.2 are the external faces of BG cells and the (six) internal faces of IG
/// cells: CellGrid::domain_faces.
///
/// Inside / outside of the cells that are not grey: the non-grey cells fall into connected regions
/// (face-adjacent cells); a segment between the centres of two face-adjacent non-grey cells meets no
/// triangle, so for a closed surface every region is wholly inside or wholly outside. Two tests decide:
///
/// - **watertight input** (every edge shared by exactly two faces, is_closed_edge_manifold): OpenVDB's
///   exterior flood fill, tools::traceExteriorBoundaries — the step that gives tools::meshToVolume level
///   sets their sign — run on the voxelization of M by the grey cells (voxel = cell, the grey cells are
///   the boundary layer) and read at up to 16 sampled cells per region: a region is black when the fill
///   does not reach it from outside the grid. A region with a cell on the grid boundary is white in any
///   case (the bounding cube contains M); samples that disagree with their region's class are counted in
///   CellGrid::ambiguous_cells (none on any test or shared mesh). A meshToVolume level set with voxels
///   equal to the cells decides by the same fill over a boundary layer that holds every grey cell and
///   some voxels near them; running the fill on the exact grey cells avoids voxelizing every triangle
///   again, which costs more than ten times the rest of the classification. Like meshToVolume, it counts
///   an enclosed cavity (or the space inside a nested shell) as inside.
/// - **fallback for meshes with holes, boundaries or non-manifold edges**: per cell, six parity votes —
///   the parity of the number of surface crossings on the axis-parallel rays from the cell towards −x, +x,
///   −y, +y, −z and +z (a closed surface gives six equal votes; a hole changes only the rays through it).
///   The crossings are found by rasterizing every triangle onto the three families of axis-parallel
///   scanlines (one line per cell row, offset inside the cells) with a watertight fill rule, so no BVH is
///   built. A cell is black with 4 or more inside votes, white with 2 or fewer; a 3–3 tie takes its
///   region's total vote. `watertight_inside_test` is then false and `inside_method` says so.
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"

namespace gimforge {

/// Class of a cubic cell (§3.1).
enum class CellClass : std::uint8_t { White, Grey, Black };

/// Which inside test decides the black / white cells.
enum class InsideTest : std::uint8_t {
  Automatic,    ///< OpenVDB exterior flood fill when the mesh is watertight, parity votes otherwise
  ParityVotes,  ///< always the six-ray parity votes (on closed meshes they differ from the flood fill only
                ///< in enclosed cavities and nested shells, which parity counts as outside)
};

/// Cell faces as bits of CellGrid::external_faces: bit f is the face on axis f/2 (x, y, z), on the low
/// (f even) or high (f odd) side.
enum CellFace : std::uint8_t {
  kFaceMinusX = 1u << 0,
  kFacePlusX = 1u << 1,
  kFaceMinusY = 1u << 2,
  kFacePlusY = 1u << 3,
  kFaceMinusZ = 1u << 4,
  kFacePlusZ = 1u << 5,
};
/// All six face bits.
inline constexpr std::uint8_t kAllCellFaces = 0x3f;

/// Whether the face set `bits` (CellFace bits) holds face `face` (0..5).
[[nodiscard]] constexpr bool has_cell_face(std::uint8_t bits, int face) {
  return ((static_cast<unsigned>(bits) >> static_cast<unsigned>(face)) & 1u) != 0;
}

/// Parity-vote scanlines (InsideTest::ParityVotes and the fallback): the line along axis a through the
/// cell row (j, k) of the two other axes u = (a + 1) % 3 and v = (a + 2) % 3 passes through
/// u = (origin[u] + j·cell_size) + kParityLineOffsetU·cell_size and
/// v = (origin[v] + k·cell_size) + kParityLineOffsetV·cell_size, evaluated in this order. The offsets are
/// irrational-looking so that lines miss the vertices and edges of grid-aligned meshes; lines that do hit
/// an edge or a vertex exactly are counted once by the watertight fill rule.
inline constexpr double kParityLineOffsetU = 0.5 + 0.0381966011250105;
inline constexpr double kParityLineOffsetV = 0.5 - 0.0527864045000421;

/// Options of classify_cells.
struct CellGridOptions {
  std::uint32_t n{16};     ///< cells per axis, 1..1024
  double padding{1e-3};    ///< relative enlargement of the bounding cube: side = (1 + padding)·longest extent
  InsideTest inside_test{InsideTest::Automatic};
  ProgressCallback progress{};  ///< stage "relief cells"
};

/// The classified N×N×N grid. Cell (i, j, k) spans origin + cell_size·([i, i+1] × [j, j+1] × [k, k+1]);
/// cell planes are computed as origin + index·cell_size everywhere, so neighbouring cells share exactly
/// the same plane.
struct CellGrid {
  std::uint32_t n{0};
  Vec3 origin{Vec3::Zero()};  ///< minimum corner of the bounding cube
  double cell_size{0.0};      ///< bounding cube = origin + [0, n·cell_size]³

  std::vector<CellClass> cells;  ///< n³ classes, linear index (k·n + j)·n + i
  /// Linear indices of the grey cells, increasing; the per-grey-cell arrays below follow this order.
  std::vector<std::uint32_t> grey_cells;
  /// Per grey cell: the faces of the mesh that overlap it (exact test), increasing face indices. Every
  /// face of the mesh is listed in at least one grey cell.
  std::vector<std::vector<std::uint32_t>> grey_triangles;
  /// Per grey cell: bit f (CellFace) set when face f is an external face (shared with a white cell or on
  /// the grid boundary).
  std::vector<std::uint8_t> external_faces;
  /// Per grey cell: 1 = border grey (BG, at least one external face), 0 = interior grey (IG).
  std::vector<std::uint8_t> border;

  bool watertight_inside_test{true};  ///< true: OpenVDB flood fill; false: the parity votes decided black / white
  std::string inside_method;          ///< how black / white were decided, one line for reports
  std::size_t regions{0};             ///< connected regions of non-grey cells (face adjacency)
  /// Flood fill: sampled cells whose result disagreed with their region's class (expected 0).
  /// Parity votes: non-grey cells whose six votes were not unanimous (near holes and open boundaries).
  std::size_t ambiguous_cells{0};

  /// Linear index of cell (i, j, k).
  [[nodiscard]] std::size_t index(std::uint32_t i, std::uint32_t j, std::uint32_t k) const {
    return (static_cast<std::size_t>(k) * n + j) * n + i;
  }
  /// (i, j, k) of a linear index.
  [[nodiscard]] std::array<std::uint32_t, 3> coords(std::size_t linear) const {
    const auto nn = static_cast<std::size_t>(n);
    return {static_cast<std::uint32_t>(linear % nn), static_cast<std::uint32_t>(linear / nn % nn),
            static_cast<std::uint32_t>(linear / (nn * nn))};
  }
  [[nodiscard]] CellClass at(std::uint32_t i, std::uint32_t j, std::uint32_t k) const { return cells[index(i, j, k)]; }
  /// Minimum / maximum corner and centre of a cell.
  [[nodiscard]] Vec3 cell_min(std::size_t linear) const;
  [[nodiscard]] Vec3 cell_max(std::size_t linear) const;
  [[nodiscard]] Vec3 cell_center(std::size_t linear) const;
  /// Position of grey cell `linear` in grey_cells, or grey_cells.size() when it is not grey. O(log G).
  [[nodiscard]] std::size_t grey_index(std::size_t linear) const;
  /// §3.2 domain faces of the grey cell grey_cells[g]: its external faces if it is a BG cell, all six
  /// (internal) faces if it is an IG cell.
  [[nodiscard]] std::uint8_t domain_faces(std::size_t g) const {
    return border[g] ? external_faces[g] : kAllCellFaces;
  }
  /// Number of cells of class c.
  [[nodiscard]] std::size_t count(CellClass c) const;
};

/// Classifies the cells of an N×N×N grid over the bounding cube of `mesh` (§3.1, §3.3.1; see the file
/// comment for the definitions and the inside tests). Multi-threaded (TBB); the result does not depend
/// on the number of threads. All faces take part, degenerate ones included (a zero-area face still
/// overlaps the cells it touches). Cost: O(F + grey-cell/face pairs + parity-line crossings + n³) time,
/// n³ bytes for `cells` plus n³ bytes of scratch.
/// Throws InvalidInput for n == 0 or n > 1024, a negative, non-finite or overflowing padding, a mesh
/// without faces, 2³² − 1 faces or more, an out-of-range vertex index, a non-finite coordinate, or a mesh
/// whose vertices all coincide; LibraryError if OpenVDB fails; Cancelled through options.progress.
[[nodiscard]] CellGrid classify_cells(MeshView mesh, const CellGridOptions& options = {});

/// classify_cells for a mesh whose faces are split into parts held by different processes (each face in
/// exactly one part; jobs/brick_relief.h), in two steps:
/// 1. cell_face_parts, per part: what its faces contribute — the cells they overlap, the (cell, face) pairs
///    in the part's face numbering and, when the parity votes decide, the crossings' toggles;
/// 2. the parts combined — grey by bitwise or, toggles and line parities by bitwise xor (the pairs stay with
///    their part) — and finish_cell_grid on every process: the same classes, grey cells, external faces and
///    report as classify_cells of the whole mesh, and grey_triangles listing this part's faces only.
/// classify_cells is these two steps on one part.
struct CellFaceParts {
  std::uint32_t n{0};
  Vec3 origin{Vec3::Zero()};                   ///< CellGrid::origin
  double cell_size{0.0};                       ///< CellGrid::cell_size
  std::vector<std::uint8_t> grey;              ///< n³: 1 where a face overlaps the cell
  std::vector<std::uint8_t> toggles;           ///< n³ parity toggles, bit a for axis a (empty without parity)
  std::array<std::vector<std::uint8_t>, 3> line_parity;  ///< per axis, n² line parities (empty without parity)
  std::vector<std::uint64_t> pairs;            ///< (cell << 32) | face, sorted: the part's overlaps
};

/// Step 1 for `part`. `box` is the bounding box of the vertices the faces of the *whole* mesh use (it places
/// the grid); `parity`: record the toggles (needed unless the flood fill decides: options.inside_test is
/// Automatic and the whole mesh is_closed_edge_manifold). A part may have no faces. Throws InvalidInput as
/// classify_cells does (options, indices, coordinates, a box of zero extent).
[[nodiscard]] CellFaceParts cell_face_parts(MeshView part, const BoundingBox& box, const CellGridOptions& options,
                                            bool parity);

/// Step 2: the grid from the combined parts (see CellFaceParts); `closed_edge_manifold` says whether the
/// whole mesh is. Throws InvalidInput when the parts do not fit the options; LibraryError if OpenVDB fails.
[[nodiscard]] CellGrid finish_cell_grid(CellFaceParts parts, bool closed_edge_manifold, const CellGridOptions& options);

/// True when the closed triangle (a, b, c) and the closed axis-aligned box [box_min, box_max] intersect
/// (touching counts). Separating-axis test of Akenine-Möller ("Fast 3D triangle-box overlap testing",
/// 2001): the three box normals, the triangle normal and the nine cross products of triangle edges with
/// the box axes. The box-normal tests compare coordinates exactly; on the other ten axes a separation
/// within 1e-12 of the coordinate magnitude counts as touching, so rounding can only err towards overlap.
/// Degenerate triangles (segments, points) are handled exactly by the same axes. Precondition:
/// box_min <= box_max component-wise, finite inputs.
[[nodiscard]] bool triangle_box_overlap(const Vec3& box_min, const Vec3& box_max, const Vec3& a, const Vec3& b,
                                        const Vec3& c);

/// True when every edge of a non-degenerate face of `mesh` is shared by exactly two faces (closed and
/// edge-manifold): the condition under which classify_cells uses the flood-fill inside test. Vertex
/// manifoldness and orientation do not matter to it. Precondition: indices in range. O(V + F).
[[nodiscard]] bool is_closed_edge_manifold(MeshView mesh);

}  // namespace gimforge
