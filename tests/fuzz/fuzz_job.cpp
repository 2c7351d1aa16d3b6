// Fuzz harness: TOML batch job files through jobs::load_job_file, as `gimforge batch --job` reads them.
// The job file lies in a scratch folder holding one mesh and one list file, so collections can succeed.
// A collection path that leaves the folder (absolute, or with "..") is skipped before the parser sees it:
// `input = "/"` would have discover() walk the whole machine, which is what it is asked to do, not a bug.
#include <cstddef>
#include <cstdint>
#include <fstream>
#include <string>

#include <toml++/toml.h>

#include "jobs/batch_job.h"
#include "tests/fuzz/fuzz_support.h"

namespace {

/// Whether a collection table names a path outside the scratch folder (then the input is not run).
bool leaves_folder(const toml::table& root) {
  const toml::array* cs = root["collection"].as_array();
  if (cs == nullptr) return false;
  for (const toml::node& node : *cs) {
    const toml::table* t = node.as_table();
    if (t == nullptr) continue;
    for (const char* key : {"input", "list"})
      if (const auto v = (*t)[key].value<std::string>()) {
        const std::filesystem::path p(*v);
        if (p.is_absolute() || v->find("..") != std::string::npos || v->starts_with('~')) return true;
      }
  }
  return false;
}

const std::filesystem::path& job_dir() {
  static const std::filesystem::path dir = [] {
    const std::filesystem::path d = gimforge::fuzz::scratch_dir() / "job";
    std::filesystem::create_directories(d / "meshes");
    std::ofstream(d / "meshes" / "tetra.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    std::ofstream(d / "list.txt") << "# one mesh\nmeshes/tetra.obj\n";
    return d;
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    if (leaves_folder(toml::parse(text))) return 0;
  } catch (const toml::parse_error&) {
    // the parser under test reports it
  }
  (void)job_dir();
  const auto path = gimforge::fuzz::write_input("job/job.toml", data, size);
  return gimforge::fuzz::expect_errors([&] {
    const gimforge::jobs::BatchJob job = gimforge::jobs::load_job_file(path);
    if (job.outputs.empty() || job.items.empty()) __builtin_trap();  // load_job_file promises both
    for (const auto& o : job.outputs) o.check();  // what it returns passes its own checks
  });
}
