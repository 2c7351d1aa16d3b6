#pragma once
/// \file gim_store.h
/// Opening archives for the geometry-image commands and choosing the image a command works on.
#include <string>

#include "io/archive.h"

namespace gimforge::jobs {

/// Opens `path` for adding a representation: an existing gimforge archive read-write, or a new one.
[[nodiscard]] io::Archive open_or_create_archive(const std::string& path, const std::string& creator,
                                                 const std::string& parameters_json);

/// The geometry image a command should use: `name` if given, else the only one in the archive.
/// Throws InvalidInput naming the archive and the images it holds when the choice is ambiguous or empty.
[[nodiscard]] std::string choose_geometry_image(const io::Archive& archive, const std::string& name);

}  // namespace gimforge::jobs
