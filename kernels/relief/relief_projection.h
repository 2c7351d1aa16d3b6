#pragma once
/// \file relief_projection.h
/// The per-cell projections of relief mapping on cubic cell complexes (Apaza & Andújar, §3.2).
///
/// Every grey cell projects the points inside it onto its *domain faces* (its external faces when it is
/// a border-grey cell, all six internal faces when it is an interior-grey cell). The 2⁶ configurations of
/// internal / external faces fall, under rotations, into ten base cases; the paper assigns each one a
/// projection type and its parameters, and so does cell_projection():
///
/// | case | internal faces (I) / external faces (E)     | projection  | parameters (paper's choice)                      |
/// |------|---------------------------------------------|-------------|--------------------------------------------------|
/// | 0    | 6 E                                         | perspective | CoP = cell centre                                |
/// | 1    | 1 I (face F)                                | perspective | CoP = midpoint of F                              |
/// | 2a   | 2 I, adjacent (one internal edge e)         | perspective | CoP = midpoint of e                              |
/// | 2b   | 2 I, opposite (F₁, F₂)                      | axial       | axis through the midpoints of F₁ and F₂          |
/// | 3a   | 3 I, not sharing a vertex (edges e₁, e₂)    | axial       | axis through the midpoints of e₁ and e₂          |
/// | 3b   | 3 I meeting at a vertex v                   | perspective | CoP = v                                          |
/// | 4a   | 2 E, opposite (F₁, F₂)                      | planar      | plane through the centre, parallel to F₁ and F₂  |
/// | 4b   | 2 E, adjacent (one external edge)           | axial       | axis = the cell edge opposite the external edge  |
/// | 5    | 1 E (face F)                                | parallel    | DoP = outward normal of F                        |
/// | 6    | 6 I (interior grey cell)                    | perspective | CoP = cell centre (as case 0)                    |
///
/// An *internal edge* is an edge whose two faces are internal. With these parameters every point of the
/// cell projects onto a domain face of the cell (tests/unit/relief/test_relief_projection.cpp checks it for all
/// 64 configurations): the centre of projection, the axis, or the plane lies on the internal faces (or
/// inside the cell), so projection rays leave the cell only through domain faces.
///
/// Coordinates are those of the *unit cell* [0,1]³ (world point = cell_min + cell_size · local point).
/// A face f (CellFace bit index, 0..5) lies on axis a = f / 2 at coordinate f % 2; its texture coordinates
/// are (u, v) = (p[(a + 1) % 3], p[(a + 2) % 3]), both in [0, 1].
///
/// The projection of a point P is the point P' where the projection ray through P leaves the cell; the
/// stored *distance* is |P − P'|. A domain-face point P' and a distance d give back P = P' − d · dir(P'),
/// where dir is the unit projection direction at P' (projection_ray), which is how reconstruction and ray
/// casting invert the map.
#include <array>
#include <cstdint>
#include <string_view>

#include "kernels/core/mesh.h"

namespace gimforge {

/// The ten base cases of §3.2 (Figure 4).
enum class ReliefCase : std::uint8_t { k0, k1, k2a, k2b, k3a, k3b, k4a, k4b, k5, k6 };
inline constexpr int kNumReliefCases = 10;

/// The four projection types of §3.2 (Figure 2).
enum class ProjectionType : std::uint8_t { Parallel, Planar, Perspective, Axial };

/// "0", "1", "2a", "2b", "3a", "3b", "4a", "4b", "5", "6".
[[nodiscard]] std::string_view relief_case_name(ReliefCase c);
/// "parallel", "planar", "perspective", "axial".
[[nodiscard]] std::string_view projection_type_name(ProjectionType t);

/// The projection of one grey cell, in unit-cell coordinates.
struct CellProjection {
  ReliefCase base_case{ReliefCase::k0};
  ProjectionType type{ProjectionType::Perspective};
  std::uint8_t domain_faces{0};  ///< CellFace bits of the faces the cell projects onto
  /// Parallel: axis of the direction of projection; Planar: axis of the plane's normal; Axial: direction
  /// of the axis; Perspective: 0 (unused).
  std::uint8_t axis{0};
  /// Perspective: the centre of projection; Axial: a point of the axis; Planar: a point of the plane (the
  /// cell centre); Parallel: the centre of the domain face.
  Vec3 point{Vec3::Constant(0.5)};
  /// Parallel: the unit direction of projection (±e_axis, towards the domain face); zero otherwise.
  Vec3 direction{Vec3::Zero()};
};

/// The base case and projection of a grey cell whose external faces are `external_faces` (CellFace
/// bits; 0 means an interior grey cell, case 6, whose domain faces are all six faces).
[[nodiscard]] CellProjection cell_projection(std::uint8_t external_faces);

/// The base case of a configuration of external faces (as cell_projection(external_faces).base_case).
[[nodiscard]] ReliefCase relief_case(std::uint8_t external_faces);

/// A point of the unit cell projected onto a domain face.
struct FaceProjection {
  int face{-1};          ///< CellFace bit index 0..5 of the domain face hit
  double u{0.0};         ///< face coordinates in [0, 1] (see the file comment)
  double v{0.0};
  double distance{0.0};  ///< |P − P'| in unit-cell units
};

/// Projects point `p` of the unit cell (clamped to [0,1]³) with projection `proj`. Returns false (and
/// leaves `out` unspecified) for the measure-zero set of points where the projection direction is
/// undefined: the centre of projection itself (perspective) or a point of the axis (axial).
[[nodiscard]] bool project_point(const CellProjection& proj, const Vec3& p, FaceProjection& out);

/// Point of face `face` (0..5) at face coordinates (u, v), in unit-cell coordinates.
[[nodiscard]] Vec3 face_point(int face, double u, double v);

/// The projection ray through a point `on_face` of a domain face: the unit direction of projection at it
/// (pointing out of the cell, from surface point P to P') and the length of the ray's segment inside the
/// cell, from `on_face` back to the centre of projection (perspective), the axis (axial), the plane
/// (planar) or the opposite face (parallel). Every point P = on_face − t · direction, 0 <= t < length,
/// lies in the cell and projects to `on_face`; every point of the cell projecting to `on_face` is one of
/// them. (The end point t = length is the centre or an axis point, where project_point returns false, or
/// for planar projections a point of the plane, which project_point sends to the high-side face.) length is 0 (and direction zero) only where on_face is the centre or on the axis, which never
/// happens on a domain face.
struct ProjectionRay {
  Vec3 direction{Vec3::Zero()};
  double length{0.0};
};
[[nodiscard]] ProjectionRay projection_ray(const CellProjection& proj, const Vec3& on_face);

/// The longest projection segment of any cell in unit-cell units (the cell diagonal, √3: perspective
/// from a vertex to the opposite vertex); quantized distances are scaled by it.
inline constexpr double kMaxProjectionLength = 1.7320508075688772;

}  // namespace gimforge
