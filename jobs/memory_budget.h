#pragma once
/// \file memory_budget.h
/// Refusing work that cannot fit in memory before it starts. A large request (`sphere --n 4096`: about
/// 15 GB; `--metric-samples 2^27`: 6 GB; `relief --grid 1024`: 4 GB of cells) used to run until the kernel
/// asked for the memory, minutes later, and then either ended with "out of memory" or, under Linux's
/// overcommit, was killed by the OOM killer without a word (or, under Slurm, by the job's cgroup).
///
/// The estimates are of the dominant allocations only, measured on the shared meshes (BENCHMARKS.md
/// "Memory refused up front"), so they are lower bounds: a refusal means the work cannot fit. They are
/// compared with what this process may still take: the kernel's MemAvailable, the memory cgroup's limit
/// less its usage without the inactive page cache (v1 and v2: Slurm's --mem), and the address-space limit
/// (ulimit -v) less what the process already maps. GIMFORGE_MEMORY_CHECK=off skips the check (a machine with a large swap).
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "jobs/method.h"

namespace gimforge::jobs {

struct MemoryLimit {
  std::uint64_t bytes{0};
  std::string source;  ///< which limit: "MemAvailable", "cgroup memory.max", "ulimit -v"
};

/// The least of the limits above; nullopt when none can be read or the check is switched off.
[[nodiscard]] std::optional<MemoryLimit> memory_limit();

/// Bytes of the dominant allocations of converting a mesh of `faces` faces with `method` (the fidelity
/// report not included), and of its fidelity report with `samples` samples per direction.
[[nodiscard]] std::uint64_t conversion_bytes(const MethodOptions& method);
[[nodiscard]] std::uint64_t report_bytes(const MethodOptions& method, std::size_t samples);
/// Of `metrics` with `samples` samples per direction (the meshes already loaded are not counted).
[[nodiscard]] std::uint64_t metric_bytes(std::size_t samples);

/// Throws IoError "SUBJECT: WHAT needs about X GB of memory, more than the Y GB this process can have
/// (SOURCE); ADVICE (GIMFORGE_MEMORY_CHECK=off tries anyway)" when `bytes` exceed memory_limit().
void check_memory(std::string_view subject, std::uint64_t bytes, std::string_view what, std::string_view advice);

/// Both checks for a conversion: the method's estimate and, when `samples` > 0, the report's on top.
void check_conversion_memory(std::string_view subject, const MethodOptions& method, std::size_t samples);

}  // namespace gimforge::jobs
