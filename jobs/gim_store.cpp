#include "jobs/gim_store.h"

#include <unistd.h>

#include <algorithm>
#include <filesystem>

#include <fmt/format.h>

#include "io/gim_archive.h"
#include "io/sphere_archive.h"
#include "kernels/errors.h"

namespace gimforge::jobs {
namespace {

constexpr ImageKind kKinds[] = {ImageKind::Geometry, ImageKind::Spherical};

bool contains(const std::vector<std::string>& names, const std::string& name) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

/// Every image of the archive, as "gim/NAME" and "spherical/NAME".
std::vector<std::string> all_images(const io::Archive& archive) {
  std::vector<std::string> out;
  for (const ImageKind kind : kKinds)
    for (const std::string& name : image_names(archive, kind)) out.push_back(ImageRef{kind, name}.path());
  return out;
}

}  // namespace

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

const io::RepresentationKind& representation(ImageKind kind) {
  return kind == ImageKind::Geometry ? io::kGeometryImages : io::kSphericalImages;
}

std::vector<std::string> image_names(const io::Archive& archive, ImageKind kind) {
  return io::representation_names(archive, representation(kind));
}

std::string ImageRef::path() const { return fmt::format("{}/{}", representation(kind).group, name); }

ImageRef choose_image(const io::Archive& archive, const std::string& name) {
  const std::string archive_path = archive.path().string();
  const std::vector<std::string> all = all_images(archive);
  if (all.empty()) throw InvalidInput(fmt::format("{}: the archive holds no image", archive_path));
  if (name.empty()) {
    if (all.size() > 1)
      throw InvalidInput(fmt::format("{}: the archive holds {} images ({}); choose one with --name", archive_path,
                                     all.size(), fmt::join(all, ", ")));
    const ImageKind kind =
        image_names(archive, ImageKind::Geometry).empty() ? ImageKind::Spherical : ImageKind::Geometry;
    return {kind, image_names(archive, kind).front()};
  }
  std::vector<ImageRef> found;
  for (const ImageKind kind : kKinds) {
    const std::string prefix = fmt::format("{}/", representation(kind).group);
    if (name.starts_with(prefix)) {
      const ImageRef ref{kind, name.substr(prefix.size())};
      if (!contains(image_names(archive, kind), ref.name))
        throw InvalidInput(fmt::format("{}: no {} '{}' (has: {})", archive_path, representation(kind).what, ref.name,
                                       fmt::join(all, ", ")));
      return ref;
    }
    if (contains(image_names(archive, kind), name)) found.push_back({kind, name});
  }
  if (found.empty())
    throw InvalidInput(fmt::format("{}: no image '{}' (has: {})", archive_path, name, fmt::join(all, ", ")));
  if (found.size() > 1)
    throw InvalidInput(fmt::format("{}: '{}' is both a geometry image and a spherical geometry image; choose one "
                                   "with --name {} or --name {}",
                                   archive_path, name, found[0].path(), found[1].path()));
  return found.front();
}

void refuse_taken_name(const std::string& path, ImageKind kind, const std::string& name) {
  if (!std::filesystem::exists(path)) return;
  if (contains(image_names(io::Archive::open(path), kind), name))
    throw InvalidInput(fmt::format("{}: already holds a {} '{}' (choose another --name or output)", path,
                                   representation(kind).what, name));
}

}  // namespace gimforge::jobs
