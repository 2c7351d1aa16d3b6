#pragma once
/// \file fuzz_support.h
/// What the fuzz harnesses share: a per-process scratch folder (on tmpfs where there is one) for readers
/// that take a path, and the rule that a documented gimforge::Error is the expected answer to bad input
/// while anything else (another exception, a signal, a sanitizer report) is a finding.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <system_error>

#include "kernels/core/errors.h"

/// The libFuzzer entry point every harness defines (declared for -Wmissing-declarations).
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);

namespace gimforge::fuzz {

/// A folder of this process only, removed at exit: /dev/shm/gimforge-fuzz-PID (or under the system
/// temporary folder when /dev/shm is missing).
inline const std::filesystem::path& scratch_dir() {
  static const std::filesystem::path dir = [] {
    std::error_code ec;
    std::filesystem::path base = "/dev/shm";
    if (!std::filesystem::is_directory(base, ec)) base = std::filesystem::temp_directory_path();
    std::filesystem::path d = base / ("gimforge-fuzz-" + std::to_string(::getpid()));
    // A harness killed by a finding leaves its folder (no atexit then); a later process with the same pid
    // must not inherit it (its socket node would make image_name()'s bind fail).
    std::filesystem::remove_all(d, ec);
    std::filesystem::create_directories(d);
    std::atexit([] {
      std::error_code ignored;
      std::filesystem::remove_all(scratch_dir(), ignored);
    });
    return d;
  }();
  return dir;
}

/// Writes the input to scratch_dir()/name (replacing it) and returns that path.
inline std::filesystem::path write_input(std::string_view name, const std::uint8_t* data, std::size_t size) {
  const std::filesystem::path path = scratch_dir() / name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  out.close();
  if (!out) std::abort();  // the harness itself failed: not a finding about the reader
  return path;
}

/// Runs `f`; a gimforge::Error (the documented answer to bad input) is swallowed, anything else escapes
/// (libFuzzer reports the uncaught exception as a crash). Returns 0 for LLVMFuzzerTestOneInput.
/// With GIMFORGE_FUZZ_VERBOSE=1 in the environment the error is printed (to check what seeds reach).
template <class F>
int expect_errors(F&& f) {
  static const bool verbose = [] {
    const char* v = std::getenv("GIMFORGE_FUZZ_VERBOSE");
    return v != nullptr && std::string_view(v) == "1";
  }();
  try {
    f();
  } catch (const gimforge::Error& e) {
    if (verbose) std::fprintf(stderr, "expected error: %s\n", e.what());
  }
  return 0;
}

}  // namespace gimforge::fuzz
