#pragma once
/// \file roi.h
/// The region of interest of adaptive geometry images (--roi, docs/adaptive.md "Region of interest"): the
/// forms a user gives it in, checked, and resolved against the loaded mesh into the kernel's RoiSource
/// (kernels/gim/gim_convert.h).
///
///   auto[:F]                 chosen on the normal image: the window of F of the square (default 0.1) where
///                            the normals vary most (kernels/adaptive/roi.h roi_auto)
///   box:X0,Y0,Z0,X1,Y1,Z1    the vertices inside the box, in the input's coordinates
///   vertices:FILE            the vertices listed in FILE: 0-based indices into the mesh file's vertices,
///                            separated by white space or commas; '#' starts a comment
///   color:RRGGBB             the vertices of the mesh file painted this colour (hex, e.g. color:ff0000)
///   scalar:NAME[>T]          the vertices whose PLY vertex property NAME exceeds T (default 0), e.g.
///                            scalar:quality>0.5
///   mask:PNG                 a picture over the parameter square as `preview` draws the normal image (row 0
///                            the top, v = 1): white (opaque) pixels are the ROI
/// The vertex forms select the faces touching a chosen vertex.
#include <string>

#include "jobs/load_mesh.h"
#include "jobs/method.h"
#include "kernels/core/embree_device.h"
#include "kernels/gim/gim_convert.h"

namespace gimforge::jobs {

struct RoiSpec {
  enum class Kind { Auto, Box, Vertices, Color, Mask, Scalar };
  Kind kind{Kind::Auto};
  double fraction{0.1};  ///< Auto
  Vec3 lo{Vec3::Zero()};  ///< Box
  Vec3 hi{Vec3::Zero()};
  std::string file;      ///< Vertices, Mask
  std::array<int, 3> color{};  ///< Color, 0..255
  std::string property;  ///< Scalar: the PLY vertex property
  double threshold{0.0};  ///< Scalar: vertices with a value above it
};

/// Parses a --roi value. Throws InvalidInput "--roi VALUE: <why>" naming what is wrong.
[[nodiscard]] RoiSpec parse_roi_spec(const std::string& spec);

/// The kernel's ROI for `method` (none when method.roi is empty) on the loaded mesh `m`: reads the files of
/// vertices: and mask:, maps the file's vertex numbers to the loaded mesh's (repair may have dropped
/// unreferenced vertices: the file is then read again and its vertices found by position). Throws
/// InvalidInput (a bad index, no vertex selected, a mesh without colours) or IoError/FormatError (files),
/// one line naming the file or the option.
[[nodiscard]] RoiSource resolve_roi(const MethodOptions& method, const LoadedMesh& m);

/// The ROI of `roi` (vertex flags of `local`) for the proxy that stands in for `local`: each proxy vertex
/// takes the flag of the corner nearest to its closest point on `local`, and each flagged vertex of `local`
/// flags the proxy's corner nearest to its closest point on the proxy (a small ROI does not vanish). Other
/// kinds are returned as they are.
[[nodiscard]] RoiSource roi_for_proxy(const EmbreeDevice& device, const RoiSource& roi, const TriMesh& local,
                                   const TriMesh& proxy);

}  // namespace gimforge::jobs
