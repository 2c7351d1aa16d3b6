#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "io/printable.h"
#include "jobs/cli/commands.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/load_mesh.h"
#include "jobs/pipeline.h"
#include "jobs/reports.h"
#include "kernels/core/errors.h"

namespace gimforge::cli {

int run_validate(const ValidateCmdOptions& options) {
  const jobs::LoadPolicy policy{.repair = true,
                                .require_manifold = !options.allow_non_manifold,
                                .require_oriented = !options.allow_inconsistent_orientation,
                                .warn = !options.json};
  // A single file fails like every other command (its error reaches main; with --json stdout also gets the
  // object {"file", "error"} that a failed file of several gets); several files are checked one by one, each
  // failure reported on its own line, and the exit code is 1 if any failed.
  if (options.meshes.size() == 1) {
    const std::string& path = options.meshes.front();
    const jobs::LoadedMesh m = [&] {
      try {
        jobs::LoadedMesh loaded = jobs::load_mesh(path, policy);
        jobs::check_frame_origin(path, jobs::local_frame_origin(loaded.mesh));  // as every method does
        return loaded;
      } catch (const Error& e) {
        if (options.json)
          fmt::print("{}\n", nlohmann::json{{"file", path}, {"error", e.what()}}.dump(
                                 2, ' ', false, nlohmann::json::error_handler_t::replace));
        throw;
      }
    }();
    if (options.json)
      fmt::print("{}\n", jobs::validation_json(m).dump(2, ' ', false, nlohmann::json::error_handler_t::replace));
    else
      fmt::print("{}: ok ({} vertices, {} faces{})\n", io::printable(m.path.string()), m.mesh.num_vertices(), m.mesh.num_faces(),
                 m.repair.changed() ? ", after repairs" : "");
    return kExitOk;
  }
  int failed = 0;
  nlohmann::json all = nlohmann::json::array();
  for (const std::string& path : options.meshes) {
    try {
      const jobs::LoadedMesh m = jobs::load_mesh(path, policy);
      jobs::check_frame_origin(path, jobs::local_frame_origin(m.mesh));
      if (options.json)
        all.push_back(jobs::validation_json(m));
      else
        fmt::print("{}: ok ({} vertices, {} faces{})\n", io::printable(path), m.mesh.num_vertices(), m.mesh.num_faces(),
                   m.repair.changed() ? ", after repairs" : "");
    } catch (const Error& e) {
      ++failed;
      spdlog::error("{}", e.what());
      if (options.json) all.push_back({{"file", path}, {"error", e.what()}});
    }
  }
  if (options.json) fmt::print("{}\n", all.dump(2, ' ', false, nlohmann::json::error_handler_t::replace));
  return failed ? kExitError : kExitOk;
}

}  // namespace gimforge::cli
