#include <algorithm>

#include <fmt/format.h>

#include "io/atomic_file.h"
#include "io/gim_archive.h"
#include "io/mcgim_archive.h"
#include "io/mesh_io.h"
#include "io/printable.h"
#include "io/relief_archive.h"
#include "io/sphere_archive.h"
#include "jobs/cli/commands.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/gim_store.h"
#include "jobs/load_mesh.h"
#include "jobs/pipeline.h"
#include "jobs/stored_image.h"
#include "kernels/core/errors.h"
#include "kernels/gim/geometry_image.h"
#include "kernels/relief/relief_map.h"
#include "kernels/sphere/sphere_convert.h"

namespace gimforge::cli {
namespace {

TriMesh reconstruct_gim(const io::Archive& archive, const jobs::ImageRef& ref, const ReconstructOptions& options) {
  const GeometryImage image = jobs::read_gim(archive, ref);
  if (image.sideband.paths.empty() && !options.no_fuse)
    throw InvalidInput(fmt::format("{}:/{}: the batch archive keeps no sideband for this item (written before batch "
                                   "archives stored one), so its cut cannot be glued: run the batch again into a new "
                                   "archive (-o NEW.h5), or reconstruct the open disk with --no-fuse",
                                   io::printable(options.archive), io::printable(ref.path())));
  const std::vector<std::uint32_t> sizes = lod_sizes(image.size, 64);  // crack-free: cut-nodes on the 65x65 grid
  if (!sizes.empty() && options.level >= sizes.size())  // (an image of another size: the kernel says what is wrong)
    throw InvalidInput(fmt::format("{}:/{}: level {} is out of range: a {}x{} geometry image has levels 0..{} ({}x{} "
                                   "down to {}x{})",
                                   io::printable(options.archive), io::printable(ref.path()), options.level, image.size, image.size,
                                   sizes.size() - 1, sizes.front(), sizes.front(), sizes.back(), sizes.back()));
  return reconstruct_geometry_image(image.positions, image.size, options.no_fuse ? nullptr : &image.sideband,
                                    options.level);
}

/// Level ℓ of a spherical geometry image: the domain's own connectivity on every 2^ℓ-th sample; faces
/// touching undefined samples (filled holes) are left out.
TriMesh reconstruct_sphere(const io::Archive& archive, const jobs::ImageRef& ref, const ReconstructOptions& options) {
  const std::string where = fmt::format("{}:/{}", io::printable(options.archive), io::printable(ref.path()));
  if (options.no_fuse)
    throw InvalidInput(fmt::format("{}: --no-fuse applies to geometry images and multi-chart geometry images only (a spherical geometry image has no "
                                   "cut to leave open)",
                                   where));
  const SphericalImage image = jobs::read_sphere(archive, ref);
  const std::vector<std::uint32_t> levels = spherical_lod_levels(image.n);
  if (options.level >= levels.size())
    throw InvalidInput(fmt::format("{}: level {} is out of range: n = {} has levels 0..{} (n = {} down to {})", where,
                                   options.level, image.n, levels.size() - 1, levels.front(), levels.back()));
  const auto undefined = std::count(image.mask.begin(), image.mask.end(), std::uint8_t{0});
  if (undefined > 0)
    fmt::print("{}: {} undefined samples (filled holes): their faces are left out\n", where, undefined);
  return reconstruct_spherical_geometry(image, options.level);
}

/// A relief map: the geometry-based reconstruction of §3.5.1 (one vertex per non-empty texel, two triangles
/// per 2x2 texel quad of a domain face). There are no coarser levels and nothing to fuse.
TriMesh reconstruct_relief_map(const io::Archive& archive, const jobs::ImageRef& ref,
                               const ReconstructOptions& options) {
  const std::string where = fmt::format("{}:/{}", io::printable(options.archive), io::printable(ref.path()));
  if (options.no_fuse)
    throw InvalidInput(fmt::format("{}: --no-fuse applies to geometry images and multi-chart geometry images only (a relief map has no cut)", where));
  if (options.level != 0)
    throw InvalidInput(fmt::format("{}: level {} is out of range: a relief map has level 0 only (for a coarser one, "
                                   "convert again with a smaller --texture)",
                                   where, options.level));
  const ReliefMap map = jobs::read_relief(archive, ref);
  const auto empty = std::count(map.distances.begin(), map.distances.end(), kEmptyTexel);
  fmt::print("{}: N = {}, {} grey cells, {} layers of {}x{} texels ({} empty)\n", where, map.n, map.cells.size(),
             map.num_layers(), map.texture, map.texture, empty);
  return reconstruct_relief(map);
}

/// A multi-chart geometry image: the rules of Sander et al. 2003 §3 (quads with three or four defined
/// samples, shorter diagonals), one vertex per zippered cluster. One level only.
TriMesh reconstruct_mcgim(const io::Archive& archive, const jobs::ImageRef& ref, const ReconstructOptions& options) {
  const std::string where = fmt::format("{}:/{}", io::printable(options.archive), io::printable(ref.path()));
  if (options.level != 0)
    throw InvalidInput(fmt::format("{}: level {} is out of range: a multi-chart geometry image has level 0 only "
                                   "(for a coarser one, convert again with a smaller --samples)",
                                   where, options.level));
  MultiChartImage image = jobs::read_mcgim(archive, ref);
  if (options.no_fuse) {  // every sample its own vertex: the charts' cracks stay open, no quad is pinned
    for (std::size_t s = 0; s < image.unified.size(); ++s)
      if (image.mask[s]) image.unified[s] = static_cast<std::uint32_t>(s);
    image.zipper_diagonals.clear();
  }
  return reconstruct_multichart(image);
}

}  // namespace

int run_reconstruct(const ReconstructOptions& options) {
  // Before any work: the output names a format, can be created, and is not the archive it is read from.
  (void)io::output_format(options.output);
  io::check_can_create(options.output);
  jobs::refuse_output_over_inputs(options.output, {options.archive});
  const io::Archive archive = io::Archive::open(options.archive);
  const jobs::ImageRef ref = jobs::choose_image(archive, options.name, jobs::BatchItems::kAccepted);
  // Read before the work: a damaged origin fails at once.
  const Vec3 origin = jobs::image_origin(archive, ref);
  TriMesh mesh = ref.kind == jobs::Method::Gim      ? reconstruct_gim(archive, ref, options)
                 : ref.kind == jobs::Method::Sphere ? reconstruct_sphere(archive, ref, options)
                 : ref.kind == jobs::Method::Mcgim  ? reconstruct_mcgim(archive, ref, options)
                                                    : reconstruct_relief_map(archive, ref, options);
  // The representation is stored in the input's local frame: back to the input's coordinates, in double
  // PLY when float32 could not hold them (a georeferenced scan).
  if (mesh.faces.empty())  // every sample undefined, say: no mesh file (gimforge refuses to read one)
    throw InvalidInput(fmt::format("{}:/{}: the image reconstructs to no face (no defined quad); nothing written",
                                   io::printable(options.archive), io::printable(ref.path())));
  jobs::to_input_frame(mesh, origin);
  io::write_mesh(options.output, mesh, jobs::ply_options_for(mesh));
  fmt::print("{}:/{} level {} -> {} ({} vertices, {} faces)\n", io::printable(options.archive),
             io::printable(ref.path()), options.level, io::printable(options.output), mesh.num_vertices(),
             mesh.num_faces());
  return kExitOk;
}

}  // namespace gimforge::cli
