#include "jobs/gim_store.h"

#include <filesystem>

#include <fmt/format.h>

#include "io/gim_archive.h"
#include "kernels/errors.h"

namespace gimforge::jobs {

io::Archive open_or_create_archive(const std::string& path, const std::string& creator,
                                   const std::string& parameters_json) {
  if (std::filesystem::exists(path)) return io::Archive::open(path, h5::OpenMode::kReadWrite);
  return io::Archive::create(path, {.creator = creator, .parameters_json = parameters_json});
}

std::string choose_geometry_image(const io::Archive& archive, const std::string& name) {
  const auto names = io::geometry_image_names(archive);
  if (!name.empty()) return name;
  if (names.size() == 1) return names.front();
  if (names.empty()) throw InvalidInput(fmt::format("{}: the archive holds no geometry image", archive.path().string()));
  throw InvalidInput(fmt::format("{}: the archive holds {} geometry images ({}); choose one with --name",
                                 archive.path().string(), names.size(), fmt::join(names, ", ")));
}

}  // namespace gimforge::jobs
