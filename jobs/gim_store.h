#pragma once
/// \file gim_store.h
/// Opening archives for the image commands (convert, reconstruct, preview) and choosing the image a
/// command works on: geometry images (/gim/<name>), spherical geometry images (/spherical/<name>) and relief
/// maps (/relief/<name>).
#include <functional>
#include <string>
#include <vector>

#include "io/archive.h"
#include "io/representation.h"
#include "jobs/method.h"

namespace gimforge::jobs {

/// Adds one representation to the archive at `path` through `write`, atomically (io::write_atomically):
/// a new archive is created under a temporary name in the same directory; an existing one is first
/// checked (Archive::open), copied byte for byte to the temporary name, and the copy opened read-write.
/// The file is closed, synced and renamed over `path` only when complete, so a failed or killed run
/// leaves either the old archive intact or the complete new one, never a half-modified file. Costs a
/// copy of an existing archive per call. Conversions into the same directory hold an io::DirectoryLock
/// from the check for an existing archive to the rename, so concurrent ones take turns and none is lost.
/// Leftover temporaries of dead writers of `path` are removed first (io::remove_stale_temporaries). Throws what `write` and the archive layer throw, IoError
/// "PATH: cannot copy the archive to 'TMP': CAUSE".
void add_to_archive(const std::string& path, const std::string& creator, const std::string& parameters_json,
                    const std::function<void(io::Archive&)>& write);

/// Names of the images of `kind` in the archive, sorted.
[[nodiscard]] std::vector<std::string> image_names(const io::Archive& archive, Method kind);

/// One image in an archive.
struct ImageRef {
  Method kind{Method::Gim};
  std::string name;
  /// "gim/NAME", "spherical/NAME" or "relief/NAME": its path below the archive root.
  [[nodiscard]] std::string path() const;
};

/// The image a command should use. `name` is either qualified by its group ("gim/bunny",
/// "spherical/bunny", "relief/bunny") or plain ("bunny"), looked up in every group. An empty name means
/// the only image of the archive, of any kind. Throws InvalidInput naming the archive and the images it
/// holds when the archive holds none, when no name is given and it holds several, when the name is not
/// there, and when a plain name is held by more than one kind.
[[nodiscard]] ImageRef choose_image(const io::Archive& archive, const std::string& name);

/// Throws InvalidInput "PATH: already holds a <kind> 'NAME' (choose another --name or output)" when the
/// archive at `path` exists and holds an image `name` of `kind`. Meant to run before long work.
void refuse_taken_name(const std::string& path, Method kind, const std::string& name);

}  // namespace gimforge::jobs
