#include <fmt/format.h>

#include "io/archive.h"
#include "io/printable.h"
#include "io/xdmf.h"
#include "jobs/archive_listing.h"
#include "jobs/cli/commands.h"
#include "jobs/cli/exit_codes.h"

namespace gimforge::cli {

int run_ls(const LsOptions& options) {
  {
    const io::Archive archive = io::Archive::open(options.archive);
    const jobs::ArchiveListing listing = jobs::list_archive(archive);
    if (options.json)
      // Strings from someone else's file may not be UTF-8: replace what is not, never throw.
      fmt::print("{}\n", jobs::listing_json(listing).dump(2, ' ', false, nlohmann::json::error_handler_t::replace));
    else
      fmt::print("{}", jobs::listing_text(listing));
  }
  if (options.xdmf) {
    const std::filesystem::path sidecar = io::write_xdmf_sidecar(options.archive);
    if (!options.json) fmt::print("wrote {}\n", io::printable(sidecar.string()));
  }
  return kExitOk;
}

}  // namespace gimforge::cli
