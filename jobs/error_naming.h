#pragma once
/// \file error_naming.h
/// How a kernel's refusal reaches the command line: prefixed with the input's name, worded by option rather
/// than by internal function, and with the way around it that does work for this mesh — a wrap only where
/// a wrap can seal the mesh's holes.
#include <cstdint>
#include <functional>
#include <string>

#include "kernels/core/mesh.h"

namespace gimforge::jobs {

/// What a wrap (kernels/scan/wrap.h) can do for a mesh a single-chart method refused.
struct WrapAdvice {
  /// "--wrap 512" where the default closing seals every hole, "--wrap 512:C" where a closing C <= 16 does;
  /// empty where the widest hole is wider than any closing seals (an open sheet's rim: the outside would get
  /// in and the wrap be refused).
  std::string option;
  double widest_hole{0.0};  ///< widest_hole(mesh)
  double sealable{0.0};     ///< the widest hole the largest closing seals (--wrap 512:16)
};

/// The advice for `mesh`, from its widest hole against the voxel of a 512-voxel wrap of its bounding box.
[[nodiscard]] WrapAdvice wrap_advice(MeshView mesh);

/// What a loader refusal of a non-manifold or misoriented mesh appends: ", --wrap W converts a closed one-piece
/// wrap of it" with wrap_advice's option for `mesh`, the default wrap without it (a scan spread over ranks),
/// or nothing where no wrap seals the mesh.
[[nodiscard]] std::string wrap_clause(const TriMesh* mesh);

/// What follows "the relief map ... reconstructs to no triangles with area" on the command line: its texels,
/// cell_size / texture across, are coarser than the surface; a larger --texture or --grid (the finer of the
/// two is what a needle-thin mesh needs) makes them finer.
[[nodiscard]] std::string coarse_relief_hint(double cell_size, std::uint32_t texture);

/// Runs `f`; an error about the mesh it throws (topology, kernel input, numerical, library, cancellation) is
/// rethrown with its message prefixed by `source` and worded for the command line, as convert_mesh names
/// them. Other errors (files, peers) pass unchanged. `wrap`: the --wrap value when `f` works on a wrap of the
/// input ("SOURCE: its wrap (--wrap R): ...", and --wrap is not suggested again). `input`: the mesh `f`
/// converts, when the caller holds it whole: a refusal then suggests the wrap of wrap_advice, or none where
/// no wrap seals the mesh; without it (a huge scan spread over ranks), "--wrap 512".
void name_errors(const std::string& source, const std::function<void()>& f, const std::string& wrap = {},
                 const TriMesh* input = nullptr);

}  // namespace gimforge::jobs
