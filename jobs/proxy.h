#pragma once
/// \file proxy.h
/// Image methods on huge inputs (issue #17 item 4): the mesh is decimated to a proxy (quadric error,
/// kernels/scan/decimate.h), the method parametrizes and samples the proxy as it would the mesh, and every
/// sample of the result is then moved onto the full-resolution surface (kernels/scan/surface_transfer.h),
/// so the image carries the scan's detail and not the proxy's. A gim normal map and colours are taken from
/// the full surface at the moved points; mcgim normals are central differences of the moved positions.
#include <map>
#include <span>
#include <vector>
#include <string>

#include "jobs/pipeline.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"
#include "kernels/scan/surface_transfer.h"

namespace gimforge::jobs {

/// The proxy of `mesh` with at most `faces` faces; adds proxy_faces, proxy_vertices, proxy_rejected_faces,
/// proxy_bricks
/// and seconds_proxy to `numbers`. Throws as decimate_quadric, and InvalidInput when the proxy has no face.
/// `bricks`: 0 for proxy_bricks(faces of mesh, faces).
[[nodiscard]] TriMesh make_proxy(const TriMesh& mesh, std::size_t faces, std::size_t bricks,
                                 const ProgressCallback& progress, std::map<std::string, double>& numbers);

/// The proxy of `mesh` made from its closed one-piece wrap (kernels/scan/wrap.h: `resolution` voxels along
/// the longest side, a closing of `closing` voxels), decimated to `faces` faces in `bricks` bricks as
/// make_proxy does (not when the wrap has no more). Adds wrap_resolution, wrap_closing, wrap_voxel, wrap_faces, wrap_dropped_components,
/// wrap_dropped_faces, wrap_area_left_out, seconds_wrap and make_proxy's numbers (seconds_proxy: plus what it held before, a
/// decimation before the wrap); warns, naming `source` (unless empty), when pieces of the wrap are left out.
/// Throws as wrap_surface and make_proxy.
[[nodiscard]] TriMesh make_wrap_proxy(const TriMesh& mesh, std::uint32_t resolution, std::uint32_t closing,
                                      std::size_t faces, std::size_t bricks, const std::string& source,
                                      const ProgressCallback& progress,
                                      std::map<std::string, double>& numbers);

/// Warns, naming `source`, when numbers["proxy_rejected_faces"] > 0: faces the decimation could not insert.
void warn_proxy_rejections(const std::string& source, const std::map<std::string, double>& numbers);

/// Moves the samples of the image in `c` (gim, sphere or mcgim, made from `proxy`) onto `full`, with the
/// normals and colours that go with them; adds transfer_along_normal, transfer_closest, transfer_max_move,
/// transfer_rms_move and seconds_transfer to c.numbers. Throws as transfer_to_surface.
void transfer_to_full_surface(const EmbreeDevice& device, const TriMesh& proxy, const TriMesh& full, Conversion& c,
                              const ProgressCallback& progress);

/// The stages of transfer_to_full_surface, for a transfer split across ranks (jobs/brick_convert.h): the
/// point sets to move (the image's samples; gim: then its normal map's grid points), and writing their
/// transfer results back (colours from `full` when given and coloured).
[[nodiscard]] std::vector<std::vector<Vec3>> transfer_point_sets(const Conversion& c);
void apply_transfers(Conversion& c, std::span<const TransferResult> results, const TriMesh* full);

}  // namespace gimforge::jobs
