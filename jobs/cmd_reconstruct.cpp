#include <fmt/format.h>

#include "io/gim_archive.h"
#include "io/mesh_io.h"
#include "jobs/commands.h"
#include "jobs/exit_codes.h"
#include "jobs/gim_store.h"

namespace gimforge::cli {

int run_reconstruct(const ReconstructOptions& options) {
  const io::Archive archive = io::Archive::open(options.archive);
  const std::string name = jobs::choose_geometry_image(archive, options.name);
  const GeometryImage image = io::read_geometry_image(archive, name);
  const TriMesh mesh = reconstruct_geometry_image(image.positions, image.size,
                                                  options.no_fuse ? nullptr : &image.sideband, options.level);
  io::write_ply(options.output, mesh);
  fmt::print("{}:/gim/{} level {} -> {} ({} vertices, {} faces)\n", options.archive, name, options.level,
             options.output, mesh.num_vertices(), mesh.num_faces());
  return kExitOk;
}

}  // namespace gimforge::cli
