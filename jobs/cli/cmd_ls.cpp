#include <string>
#include <vector>

#include <fmt/format.h>

#include "io/archive.h"
#include "io/atomic_file.h"
#include "io/printable.h"
#include "io/xdmf.h"
#include "jobs/archive_listing.h"
#include "jobs/cli/commands.h"
#include "jobs/cli/exit_codes.h"
#include "kernels/core/errors.h"

namespace gimforge::cli {

int run_ls(const LsOptions& options) {
  // The sidecar's place is checked before anything is printed (a directory there is one error, no listing).
  if (options.xdmf) io::check_can_create(io::xdmf_sidecar_path(options.archive));
  std::vector<std::string> unreadable;  // "GROUP/NAME", left out of the sidecar
  {
    const io::Archive archive = io::Archive::open(options.archive);
    const jobs::ArchiveListing listing = jobs::list_archive(archive);
    for (const jobs::ListedItem& item : listing.items)
      if (!item.problem.empty()) unreadable.push_back(item.group + "/" + item.name);
    if (options.json)
      // Strings from someone else's file may not be UTF-8: replace what is not, never throw.
      fmt::print("{}\n", jobs::listing_json(listing).dump(2, ' ', false, nlohmann::json::error_handler_t::replace));
    else
      fmt::print("{}", jobs::listing_text(listing));
  }
  if (options.xdmf) {
    bool grids = false;
    const std::filesystem::path sidecar = io::write_xdmf_sidecar(options.archive, &grids, unreadable);
    // With unreadable items too: it describes the others, and the line below (exit 1) says the listing is not whole.
    const std::string left_out =
        unreadable.empty() ? ""
                           : fmt::format(" (without the {} unreadable item{})", unreadable.size(), unreadable.size() == 1 ? "" : "s");
    if (!options.json)
      fmt::print("wrote {}{}\n", io::printable(sidecar.string()),
                 grids ? left_out
                       : " (it describes nothing: only float32 geometry and spherical images and batch stacks are "
                         "described, not relief maps, multi-chart images, quantized and coded items or unreadable ones)");
  }
  if (!unreadable.empty())
    throw InvalidInput(fmt::format("{}: {} item{} unreadable (listed above)", io::printable(options.archive),
                                   unreadable.size(), unreadable.size() == 1 ? " is" : "s are"));
  return kExitOk;
}

}  // namespace gimforge::cli
