#include "jobs/gim_store.h"

#include <unistd.h>

#include <filesystem>

#include <fmt/format.h>

#include "io/gim_archive.h"
#include "kernels/errors.h"

namespace gimforge::jobs {

void add_to_archive(const std::string& path, const std::string& creator, const std::string& parameters_json,
                    const std::function<void(io::Archive&)>& write) {
  if (std::filesystem::exists(path)) {
    io::Archive archive = io::Archive::open(path, h5::OpenMode::kReadWrite);
    write(archive);
    archive.close();
    return;
  }
  const std::string tmp = fmt::format("{}.tmp-{}", path, ::getpid());
  try {
    io::Archive archive = io::Archive::create(tmp, {.creator = creator, .parameters_json = parameters_json});
    write(archive);
    archive.close();
    std::filesystem::rename(tmp, path);
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw;
  }
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
