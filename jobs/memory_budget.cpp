#include "jobs/memory_budget.h"

#include <sys/resource.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "io/printable.h"
#include "kernels/core/errors.h"
#include "kernels/sphere/spherical_domain.h"

namespace gimforge::jobs {
namespace {

namespace fs = std::filesystem;

// Bytes per unit of the dominant allocations, measured with /usr/bin/time -v (BENCHMARKS.md "Memory
// refused up front"); each a little below what was measured, so that an estimate is a lower bound.
constexpr std::uint64_t kGimPerSample = 40;        ///< gim: per image sample (1025² to 2049²: +138 MB)
constexpr std::uint64_t kNormalPerTexel = 12;      ///< gim: per normal-map texel (float x, y, z)
constexpr std::uint64_t kSpherePerSample = 180;    ///< sphere: per image sample (n = 1024: 0.97 GB)
constexpr std::uint64_t kMcgimPerSample = 150;     ///< mcgim: per sample of the rectangle bound (2^20: 284 MB)
constexpr std::uint64_t kReliefPerCell = 4;        ///< relief: per cell of the N³ grid (N = 128 to 256: +61 MB)
constexpr std::uint64_t kMetricPerSample = 40;     ///< fidelity: per sample and direction (16M: 880 MB)
constexpr std::uint64_t kReconstructionPerSample = 100;  ///< fidelity: reconstruction + BVH (sphere 513²: 145 MB)

/// The first whitespace-separated number after `key` in a "key value" file (/proc/meminfo: kB).
std::optional<std::uint64_t> field(const fs::path& path, std::string_view key) {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line))
    if (line.starts_with(key)) {
      std::istringstream rest(line.substr(key.size()));
      std::uint64_t value = 0;
      if (rest >> value) return value;
    }
  return std::nullopt;
}

/// A cgroup file's one number ("max" and absurd limits: none).
std::optional<std::uint64_t> number(const fs::path& path) {
  std::ifstream in(path);
  std::string text;
  if (!(in >> text) || text == "max") return std::nullopt;
  char* end = nullptr;
  const unsigned long long v = std::strtoull(text.c_str(), &end, 10);
  if (end == text.c_str() || *end != '\0' || v >= (std::uint64_t{1} << 60)) return std::nullopt;
  return v;
}

void take(std::optional<MemoryLimit>& best, std::optional<std::uint64_t> limit, std::optional<std::uint64_t> used,
          const std::string& source) {
  if (!limit) return;
  const std::uint64_t left = *limit > used.value_or(0) ? *limit - used.value_or(0) : 0;
  if (!best || left < best->bytes) best = MemoryLimit{left, source};
}

/// The memory cgroup limits of this process (v2, and v1's memory controller), every level up to the root.
void cgroup_limits(std::optional<MemoryLimit>& best) {
  std::ifstream in("/proc/self/cgroup");
  std::string line;
  while (std::getline(in, line)) {
    const std::size_t a = line.find(':'), b = line.find(':', a + 1);
    if (a == std::string::npos || b == std::string::npos) continue;
    const std::string controllers = line.substr(a + 1, b - a - 1);
    const fs::path own = fs::path(line.substr(b + 1)).relative_path();
    const bool v2 = line.starts_with("0::");
    if (!v2 && controllers != "memory") continue;
    const fs::path root = v2 ? fs::path("/sys/fs/cgroup") : fs::path("/sys/fs/cgroup/memory");
    const char* limit_file = v2 ? "memory.max" : "memory.limit_in_bytes";
    const char* usage_file = v2 ? "memory.current" : "memory.usage_in_bytes";
    // Inside a container the hierarchy is often mounted at the process's own cgroup: its root then.
    for (fs::path at = own;; at = at.parent_path()) {
      const fs::path dir = root / at;
      if (const auto limit = number(dir / limit_file)) {
        // The usage counts the page cache, which the kernel reclaims before it refuses memory: a job that
        // has read many meshes sits near its limit. Its inactive file pages are free for the taking.
        std::optional<std::uint64_t> used = number(dir / usage_file);
        const auto cache = field(dir / "memory.stat", v2 ? "inactive_file " : "total_inactive_file ");
        if (used && cache) used = *used > *cache ? *used - *cache : 0;
        take(best, limit, used, v2 ? "cgroup memory.max" : "cgroup memory limit");
      }
      if (at.empty()) break;
    }
  }
}

double gb(std::uint64_t bytes) { return static_cast<double>(bytes) / 1e9; }

std::uint64_t image_samples(const MethodOptions& m) {
  switch (m.method) {
    case Method::Gim: return std::uint64_t{m.size} * m.size;
    case Method::Sphere: return DomainImage(parse_spherical_domain(m.domain), m.n).num_samples();
    case Method::Mcgim: return m.samples;
    case Method::Relief: return 0;
  }
  return 0;
}

}  // namespace

std::optional<MemoryLimit> memory_limit() {
  if (const char* off = std::getenv("GIMFORGE_MEMORY_CHECK"); off != nullptr && std::string_view(off) == "off")
    return std::nullopt;
  std::optional<MemoryLimit> best;
  if (const auto kb = field("/proc/meminfo", "MemAvailable:")) take(best, *kb * 1024, std::nullopt, "MemAvailable");
  cgroup_limits(best);
  rlimit as{};
  if (getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) {
    const auto mapped_kb = field("/proc/self/status", "VmSize:");
    take(best, static_cast<std::uint64_t>(as.rlim_cur), mapped_kb ? std::optional(*mapped_kb * 1024) : std::nullopt,
         "ulimit -v");
  }
  return best;
}

std::uint64_t conversion_bytes(const MethodOptions& m) {
  switch (m.method) {
    case Method::Gim:
      return kGimPerSample * image_samples(m) + kNormalPerTexel * std::uint64_t{m.normal_size} * m.normal_size;
    case Method::Sphere: return kSpherePerSample * image_samples(m);
    case Method::Mcgim: return kMcgimPerSample * image_samples(m);
    case Method::Relief: {
      // A fixed grid's cells; --grid auto tries N = 1, 2, 4, ... and stops early on most surfaces.
      const std::uint64_t n = m.grid == "auto" ? 0 : std::strtoull(m.grid.c_str(), nullptr, 10);
      return kReliefPerCell * n * n * n;
    }
  }
  return 0;
}

std::uint64_t metric_bytes(std::size_t samples) { return kMetricPerSample * samples; }

std::uint64_t report_bytes(const MethodOptions& m, std::size_t samples) {
  return metric_bytes(samples) + kReconstructionPerSample * image_samples(m);
}

void check_memory(std::string_view subject, std::uint64_t bytes, std::string_view what, std::string_view advice) {
  const std::optional<MemoryLimit> limit = memory_limit();
  if (!limit || bytes <= limit->bytes) return;
  throw IoError(fmt::format("{}: {} needs about {:.1f} GB of memory, more than the {:.1f} GB this process can have "
                            "({}); {} (GIMFORGE_MEMORY_CHECK=off tries anyway)",
                            io::printable(subject), what, gb(bytes), gb(limit->bytes), limit->source, advice));
}

void check_conversion_memory(std::string_view subject, const MethodOptions& m, std::size_t samples) {
  const std::uint64_t construct = conversion_bytes(m);
  const std::uint64_t report = samples > 0 ? report_bytes(m, samples) : 0;
  if (construct + report == 0) return;
  std::string what;
  std::string advice;
  switch (m.method) {
    case Method::Gim:
      what = fmt::format("a {0} × {0} geometry image", m.size) +
             (m.normal_size > 0 ? fmt::format(" with a {0} × {0} normal map", m.normal_size) : "");
      advice = "lower --size or --normal-size";
      break;
    case Method::Sphere:
      what = fmt::format("a spherical image of {} samples (--n {})", image_samples(m), m.n);
      advice = "lower --n";
      break;
    case Method::Mcgim:
      what = fmt::format("a multi-chart image of up to {} samples", m.samples);
      advice = "lower --samples";
      break;
    case Method::Relief:
      what = fmt::format("a relief map on a {0}³ grid", m.grid);
      advice = "lower --grid";
      break;
  }
  if (report > 0 && 4 * report >= construct) {  // name the report where it weighs
    what += fmt::format(" and its fidelity report ({} samples per direction)", samples);
    advice += ", --metric-samples, or skip the report with --no-metric";
  }
  check_memory(subject, construct + report, what, advice);
}

}  // namespace gimforge::jobs
