// The OpenVDB inside test of classify_cells (the only translation unit that includes OpenVDB; the rest
// of the classification is in relief_cells_grid.cpp).
#include <fmt/format.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>

#include "kernels/core/errors.h"
#include "kernels/relief/relief_cells_detail.h"

namespace gimforge::detail {

std::vector<std::uint8_t> exterior_flood_fill(std::span<const std::uint32_t> grey_cells, std::uint32_t n,
                                              std::span<const std::array<std::uint32_t, 3>> queries) {
  std::vector<std::uint8_t> inside(queries.size(), 0);
  if (queries.empty()) return inside;
  try {
    // Index space = cell coordinates. traceExteriorBoundaries treats values <= 0.75 as the boundary layer
    // (in meshToVolume: squared distances of voxels the surface passes through) and negates the values of
    // the voxels it reaches from outside the leaf nodes' extent without crossing that layer.
    constexpr float kFree = 1.0f;
    constexpr float kBoundary = 0.0f;
    openvdb::FloatTree tree(kFree);
    openvdb::tree::ValueAccessor<openvdb::FloatTree> access(tree);
    const auto nn = static_cast<std::size_t>(n);
    for (const std::uint32_t linear : grey_cells) {
      const openvdb::Coord ijk(static_cast<openvdb::Int32>(linear % nn), static_cast<openvdb::Int32>(linear / nn % nn),
                               static_cast<openvdb::Int32>(linear / (nn * nn)));
      access.setValueOn(ijk, kBoundary);
    }
    // The queried cells must lie in leaf nodes: the trace does not reach into tiles.
    const auto coord = [](const std::array<std::uint32_t, 3>& c) {
      return openvdb::Coord(static_cast<openvdb::Int32>(c[0]), static_cast<openvdb::Int32>(c[1]),
                            static_cast<openvdb::Int32>(c[2]));
    };
    for (const auto& q : queries) access.touchLeaf(coord(q));
    openvdb::tools::traceExteriorBoundaries(tree);
    access.clear();
    for (std::size_t q = 0; q < queries.size(); ++q) inside[q] = access.getValue(coord(queries[q])) < 0.0f ? 0 : 1;
  } catch (const openvdb::Exception& e) {
    throw LibraryError(fmt::format("OpenVDB: relief cells: exterior flood fill failed: {}", e.what()));
  }
  return inside;
}

}  // namespace gimforge::detail
