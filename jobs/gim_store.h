#pragma once
/// \file gim_store.h
/// Opening archives for the geometry-image commands and choosing the image a command works on.
#include <functional>
#include <string>

#include "io/archive.h"

namespace gimforge::jobs {

/// Adds one representation to the archive at `path` through `write`: an existing gimforge archive is
/// opened read-write; a new one is written under a temporary name in the same directory and renamed to
/// `path` only when complete, so a failed or killed run leaves no half-written new archive behind.
void add_to_archive(const std::string& path, const std::string& creator, const std::string& parameters_json,
                    const std::function<void(io::Archive&)>& write);

/// The geometry image a command should use: `name` if given, else the only one in the archive.
/// Throws InvalidInput naming the archive and the images it holds when the choice is ambiguous or empty.
[[nodiscard]] std::string choose_geometry_image(const io::Archive& archive, const std::string& name);

}  // namespace gimforge::jobs
