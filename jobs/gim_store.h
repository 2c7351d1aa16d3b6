#pragma once
/// \file gim_store.h
/// Opening archives for the image commands (convert, reconstruct, preview) and choosing the image a
/// command works on: geometry images (/gim/<name>), spherical geometry images (/spherical/<name>) and relief
/// maps (/relief/<name>).
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "io/archive.h"
#include "io/atomic_file.h"
#include "io/batch_items.h"
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
/// "PATH: cannot write: CAUSE" when the copy fails (io::copy_contents: "No space left on device"), and InvalidInput when PATH.work holds the journal of an
/// interrupted batch into `path` (written to, the archive would no longer be that batch's: its
/// `--resume` would refuse it and lose every item it committed).
/// Throws InvalidInput "PATH: a batch into this archive has not finished (PATH.work holds its journal): ..."
/// when PATH.work (of the path as given, or of the file a link names) holds a batch journal: written to, the
/// archive would no longer be that batch's. add_to_archive checks it; convert checks it before any work.
void refuse_unfinished_batch(const std::string& path);

void add_to_archive(const std::string& path, const std::string& creator, const std::string& parameters_json,
                    const std::function<void(io::Archive&)>& write);

/// The file an output path names: the target of a symbolic link (written where it lies, keeping the
/// link), else `path` itself.
[[nodiscard]] std::filesystem::path output_target(const std::string& path);

/// Takes the writer lock of the archive at `path` (io::WriterLock on output_target(path): "<archive>.lock"),
/// before any work: a second writer of the same archive (convert or batch) is refused with ArchiveInUse
/// "PATH: archive in use by pid N (another gimforge is writing it); wait with --wait", or, with `wait`,
/// blocks until the first is done. Hold it until the archive is renamed into place. An archive path with a
/// mesh file's extension (.ply .obj .off .stl) is refused (InvalidInput) before anything.
[[nodiscard]] std::unique_ptr<io::WriterLock> lock_archive(const std::string& path, bool wait);

/// Refuses, before any work, an output path that names one of the command's inputs (the same file:
/// st_dev + st_ino, through symbolic and hard links), which the output would replace: throws InvalidInput
/// "OUTPUT: is the input INPUT (the output would replace it); choose another output".
void refuse_output_over_inputs(const std::filesystem::path& output, const std::vector<std::filesystem::path>& inputs);

/// A batch's work folder `work` (ARCHIVE.work) is gimforge's to fill and remove whole: refuses, before any work, one that is a symbolic
/// link (its journal and shards would go where it points), one that holds anything but a batch's journal,
/// shards and bricks (a user's folder that happens to be named ARCHIVE.work), and any input inside it.
/// Throws InvalidInput naming the folder and what is wrong, IoError when it cannot be listed.
void refuse_foreign_work_dir(const std::filesystem::path& work, const std::vector<std::filesystem::path>& inputs);

/// Names of the images of `kind` in the archive, sorted.
[[nodiscard]] std::vector<std::string> image_names(const io::Archive& archive, Method kind);

/// One image in an archive: a representation group /<group>/<name>, or an item of a batch output.
struct ImageRef {
  Method kind{Method::Gim};
  std::string name;
  /// Set for an item of a batch archive (--name batch/OUTPUT/ITEM); `name` is then the item's name.
  std::optional<io::BatchItem> batch{};
  /// "gim/NAME", "spherical/NAME", "relief/NAME", "mcgim/NAME" or "batch/OUTPUT/NAME": how commands name it.
  [[nodiscard]] std::string path() const;
};

/// Which images choose_image may return: the commands that read an image whole (reconstruct, preview,
/// render) also take the items of a batch archive.
enum class BatchItems { kRefused, kAccepted };

/// The image a command should use. `name` is either qualified by its group ("gim/bunny",
/// "spherical/bunny", "relief/bunny") or plain ("bunny"), looked up in every group; with
/// BatchItems::kAccepted also "batch/OUTPUT/ITEM", an item of a batch archive (io/batch_items.h). An empty
/// name means the only image of the archive, of any kind (with kAccepted: the only batch item of an archive
/// that holds nothing else). Throws InvalidInput naming the archive and the images it holds when the archive
/// holds none, when no name is given and it holds several, when the name is not there, and when a plain name
/// is held by more than one kind.
[[nodiscard]] ImageRef choose_image(const io::Archive& archive, const std::string& name,
                                    BatchItems batch = BatchItems::kRefused);

/// Throws InvalidInput "PATH: already holds a <kind> 'NAME' (choose another --name or output)" when the
/// archive at `path` exists and holds an image `name` of `kind` ("another output" when the command's --name
/// picks what to read and cannot rename: compress, decompress). Meant to run before long work.
void refuse_taken_name(const std::string& path, Method kind, const std::string& name, bool renamable = true);

}  // namespace gimforge::jobs
