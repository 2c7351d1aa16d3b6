#include <algorithm>

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
  std::size_t unreadable = 0;
  {
    const io::Archive archive = io::Archive::open(options.archive);
    const jobs::ArchiveListing listing = jobs::list_archive(archive);
    unreadable = static_cast<std::size_t>(std::ranges::count_if(
        listing.items, [](const jobs::ListedItem& item) { return !item.problem.empty(); }));
    if (options.json)
      // Strings from someone else's file may not be UTF-8: replace what is not, never throw.
      fmt::print("{}\n", jobs::listing_json(listing).dump(2, ' ', false, nlohmann::json::error_handler_t::replace));
    else
      fmt::print("{}", jobs::listing_text(listing));
  }
  if (options.xdmf) {
    bool grids = false;
    const std::filesystem::path sidecar = io::write_xdmf_sidecar(options.archive, &grids);
    // With unreadable items too: it describes what it can, and the line below (exit 1) says the listing is not whole.
    if (!options.json)
      fmt::print("wrote {}{}\n", io::printable(sidecar.string()),
                 grids ? "" : " (it describes nothing: only float32 geometry and spherical images and batch stacks are "
                                 "described, not relief maps, multi-chart images or quantized and coded items)");
  }
  if (unreadable > 0)
    throw InvalidInput(fmt::format("{}: {} item{} unreadable (listed above)", io::printable(options.archive), unreadable,
                                   unreadable == 1 ? " is" : "s are"));
  return kExitOk;
}

}  // namespace gimforge::cli
