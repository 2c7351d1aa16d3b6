#include "jobs/gim_store.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <string_view>

#include <fmt/format.h>

#include "io/atomic_file.h"
#include "io/gim_archive.h"
#include "io/printable.h"
#include "io/relief_archive.h"
#include "io/sphere_archive.h"
#include "jobs/compress.h"
#include "kernels/core/errors.h"

namespace gimforge::jobs {
namespace {


bool contains(const std::vector<std::string>& names, const std::string& name) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

/// Every image of the archive, as "gim/NAME", "spherical/NAME" and "relief/NAME".
std::vector<std::string> all_images(const io::Archive& archive) {
  std::vector<std::string> out;
  for (const Method kind : kMethods)
    for (const std::string& name : image_names(archive, kind)) out.push_back(ImageRef{kind, name}.path());
  return out;
}

/// `text` as one shell word, quoted when it holds anything but letters, digits and -_./:@+ (for a
/// suggested command line; the text is also escaped for printing).
std::string shell_word(const std::string& text) {
  const bool plain = !text.empty() && std::all_of(text.begin(), text.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           std::string_view("-_./:@+").find(c) != std::string_view::npos;
  });
  if (plain) return text;
  std::string quoted = "'";
  for (const char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return io::printable(quoted + "'");
}

/// The batch item `qualified` ("batch/OUTPUT/ITEM") as an image reference.
ImageRef batch_item_ref(const io::Archive& archive, const std::string& qualified) {
  io::BatchItem item = io::find_batch_item(archive, std::string_view(qualified).substr(6));
  Method kind{};
  try {
    kind = parse_method(item.method);
  } catch (const InvalidInput&) {
    throw FormatError(fmt::format("{}:/batch/{}: attribute method '{}' names no method", archive.path().string(),
                                  io::printable(item.output), io::printable(item.method)));
  }
  return {kind, item.name, std::move(item)};
}

}  // namespace

std::filesystem::path output_target(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_symlink(path, ec)) {
    std::filesystem::path resolved = std::filesystem::weakly_canonical(path, ec);
    if (!ec) return resolved;
  }
  return path;
}

std::unique_ptr<io::WriterLock> lock_archive(const std::string& path, bool wait) {
  // An archive named like a mesh (batch -o c10/out.ply into its own collection) is listed as a broken mesh
  // by the next batch over that folder, and read as one by convert: certainly a slip.
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".ply" || ext == ".obj" || ext == ".off" || ext == ".stl")
    throw InvalidInput(fmt::format("{}: an archive named like a mesh file ({}); give it another extension (.h5)",
                                   io::printable(path), ext));
  const std::filesystem::path target = output_target(path);
  try {
    return std::make_unique<io::WriterLock>(target, wait ? io::WriterLock::Wait::kYes : io::WriterLock::Wait::kNo);
  } catch (const io::ArchiveInUse& e) {
    if (target == std::filesystem::path(path)) throw;
    std::string text = e.what();  // name the path the user gave
    text.replace(0, target.string().size(), path);
    throw io::ArchiveInUse(text);
  }
}

void refuse_output_over_inputs(const std::filesystem::path& output, const std::vector<std::filesystem::path>& inputs) {
  for (const std::filesystem::path& input : inputs)
    if (!input.empty() && io::same_file(output, input))
      throw InvalidInput(fmt::format("{}: is the input {} (the output would replace it); choose another output",
                                     output.string(), input.string()));
}

void refuse_foreign_work_dir(const std::filesystem::path& work, const std::vector<std::filesystem::path>& inputs) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status status = fs::symlink_status(work, ec);
  if (ec || status.type() == fs::file_type::not_found) return;
  const std::string shown = io::printable(work.string());
  if (status.type() == fs::file_type::symlink)
    throw InvalidInput(fmt::format("{}: the batch's work folder is a symbolic link; remove the link or choose "
                                   "another output", shown));
  if (status.type() != fs::file_type::directory)
    throw InvalidInput(fmt::format("{}: exists and is not the batch's work folder; move it away or choose another "
                                   "output", shown));
  for (auto it = fs::directory_iterator(work, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string name = it->path().filename().string();
    std::error_code type_ec;
    const fs::file_type type = it->symlink_status(type_ec).type();  // links are never ours
    const bool ours = (name == "journal.jsonl" && type == fs::file_type::regular) ||
                      ((name == "shards" || name == "bricks") && type == fs::file_type::directory);
    if (!ours)
      throw InvalidInput(fmt::format("{}: exists and is not a gimforge work folder (it holds '{}'), and a batch "
                                     "removes its work folder when it ends; move it away or choose another output",
                                     shown, io::printable(name)));
  }
  if (ec) throw IoError(fmt::format("{}: cannot list: {}", shown, ec.message()));
  // Lexically (no system call per item: a collection may hold 10^6 paths on a parallel file system).
  const fs::path root = fs::absolute(work, ec).lexically_normal();
  for (const fs::path& input : inputs) {
    if (input.empty()) continue;
    const fs::path in = fs::absolute(input, ec).lexically_normal();
    const auto [end, _] = std::mismatch(root.begin(), root.end(), in.begin(), in.end());
    if (!ec && end == root.end())
      throw InvalidInput(fmt::format("{}: the input {} lies in the batch's work folder, which the batch removes when "
                                     "it ends; move it away or choose another output",
                                     shown, io::printable(input.string())));
  }
}

void refuse_unfinished_batch(const std::string& path) {
  std::error_code ec;
  for (const std::filesystem::path& archive : {std::filesystem::path(path), output_target(path)})
    if (const std::filesystem::path work = archive.string() + ".work"; std::filesystem::exists(work / "journal.jsonl", ec))
      throw InvalidInput(fmt::format("{}: a batch into this archive has not finished ({} holds its journal): run its "
                                     "batch command again with --resume (it finishes the batch, or removes {} when the "
                                     "archive is complete), or remove {}, before writing to it",
                                     io::printable(path), io::printable(work.string()), io::printable(work.string()),
                                     io::printable(work.string())));
}

void add_to_archive(const std::string& path, const std::string& creator, const std::string& parameters_json,
                    const std::function<void(io::Archive&)>& write) {
  // An archive reached through a symbolic link is replaced where it lies, keeping the link.
  std::error_code ec;
  const std::filesystem::path target = output_target(path);
  refuse_unfinished_batch(path);
  // Held until the rename: another convert into the same directory waits instead of starting from the
  // same old archive and replacing this one's result.
  const io::DirectoryLock lock(target.parent_path());
  io::remove_stale_temporaries(target);  // leftovers of converts that were killed before their commit
  if (!std::filesystem::exists(target, ec)) {
    if (const auto dir = target.parent_path(); !dir.empty() && !std::filesystem::is_directory(dir, ec))
      throw IoError(fmt::format("{}: cannot create the archive: directory '{}' does not exist", target.string(),
                                dir.string()));
    io::write_atomically(
        target,
        [&](const std::filesystem::path& tmp) {
          io::Archive archive = io::Archive::create(tmp, {.creator = creator, .parameters_json = parameters_json});
          write(archive);
          archive.close();
        },
        io::ParentDirectory::kMustExist);
    return;
  }
  io::Archive::open(target).close();  // refuse a file that is no archive with an error naming it
  io::write_atomically(
      target,
      [&](const std::filesystem::path& tmp) {
        io::copy_contents(target, tmp);  // errors name the archive (write_atomically)
        io::Archive archive = io::Archive::open(tmp, h5::OpenMode::kReadWrite);
        write(archive);
        archive.close();
      },
      io::ParentDirectory::kMustExist);
}

std::vector<std::string> image_names(const io::Archive& archive, Method kind) {
  return io::representation_names(archive, representation(kind));
}

std::string ImageRef::path() const {
  return batch ? batch->path() : fmt::format("{}/{}", representation(kind).group, name);
}

/// "has: a, b" or "it holds no image": what an archive holds, for a message about a missing name.
static std::string holds(const std::vector<std::string>& all) {
  return all.empty() ? std::string("it holds no image") : fmt::format("has: {}", fmt::join(all, ", "));
}

ImageRef choose_image(const io::Archive& archive, const std::string& name, BatchItems batch) {
  const std::string archive_path = archive.path().string();
  if (batch == BatchItems::kAccepted && name.starts_with("batch/")) return batch_item_ref(archive, name);
  const std::vector<std::string> all = all_images(archive);
  if (all.empty() && batch == BatchItems::kAccepted && archive.root().exists("batch")) {
    const std::vector<io::BatchItem> items = io::batch_items(archive);
    if (name.empty() && items.size() == 1) return batch_item_ref(archive, items.front().path());
    if (items.empty())
      throw InvalidInput(fmt::format("{}: the archive holds no image, and its batch outputs no converted item", archive_path));
    throw InvalidInput(fmt::format("{}: the archive holds no image but {} batch item{}{}; choose one with --name "
                                   "batch/OUTPUT/ITEM, e.g. --name {}",
                                   archive_path, items.size(), items.size() == 1 ? "" : "s",
                                   name.empty() ? "" : fmt::format(" (no image '{}')", io::printable(name)),
                                   shell_word(items.front().path())));
  }
  if (all.empty())
    throw InvalidInput(fmt::format("{}: the archive holds no image{}", archive_path,
                                   !coded_batch_items(archive).empty()
                                       ? " (it holds batch --codec outputs: `gimforge decompress` writes their items as images)"
                                   : archive.root().exists("batch")
                                       ? " (it holds batch outputs, which examples/load_archive.py reads, and `gimforge "
                                         "reconstruct`, `preview` and `render` with --name batch/OUTPUT/ITEM)"
                                       : ""));
  if (name.empty()) {
    if (all.size() > 1)
      throw InvalidInput(fmt::format("{}: the archive holds {} images ({}); choose one with --name{}", archive_path,
                                     all.size(), fmt::join(all, ", "),
                                     batch == BatchItems::kAccepted && archive.root().exists("batch")
                                         ? " (or an item of its batch outputs with --name batch/OUTPUT/ITEM)"
                                         : ""));
    for (const Method kind : kMethods)
      if (const auto names = image_names(archive, kind); !names.empty()) return {kind, names.front()};
  }
  std::vector<ImageRef> found;
  for (const Method kind : kMethods) {
    const std::string prefix = fmt::format("{}/", representation(kind).group);
    if (name.starts_with(prefix)) {
      const ImageRef ref{kind, name.substr(prefix.size())};
      if (!contains(image_names(archive, kind), ref.name))
        throw InvalidInput(fmt::format("{}: no {} '{}' ({})", archive_path, representation(kind).what, ref.name,
                                       holds(all)));
      return ref;
    }
    if (contains(image_names(archive, kind), name)) found.push_back({kind, name});
  }
  if (found.empty())
    throw InvalidInput(fmt::format("{}: no image '{}' ({})", archive_path, name, holds(all)));
  if (found.size() > 1) {
    std::vector<std::string> kinds, options;
    for (const ImageRef& ref : found) {
      kinds.push_back(fmt::format("a {}", representation(ref.kind).what));
      options.push_back("--name " + ref.path());
    }
    const auto list = [](const std::vector<std::string>& items, std::string_view last) {
      std::vector<std::string> head(items.begin(), items.end() - 1);
      return fmt::format("{} {} {}", fmt::join(head, ", "), last, items.back());
    };
    throw InvalidInput(fmt::format("{}: '{}' is {}{}; choose one with {}", archive_path, name,
                                   found.size() == 2 ? "both " : "", list(kinds, "and"), list(options, "or")));
  }
  return found.front();
}

void refuse_taken_name(const std::string& path, Method kind, const std::string& name, bool renamable) {
  io::check_representation_name(representation(kind), name);  // a name the archive can hold, before the work
  if (!std::filesystem::exists(path)) return;
  if (contains(image_names(io::Archive::open(path), kind), name))
    throw InvalidInput(fmt::format("{}: already holds a {} '{}' (choose another {})", path,
                                   representation(kind).what, name, renamable ? "--name or output" : "output"));
}

}  // namespace gimforge::jobs
