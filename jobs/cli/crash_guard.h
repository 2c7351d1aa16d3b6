#pragma once
/// \file crash_guard.h
/// Archives are other people's files, and the HDF5 library (Debian 12: 1.10.8) itself crashes on some
/// crafted files — inside its own metadata decoders, before gimforge sees any value (tests/fuzz/crashes/).
/// gimforge checks everything it reads, but cannot check what HDF5 decodes for it. So the commands that read
/// archives run their work in a child process: a crash there becomes one error line naming the archive and
/// exit 1, never a signal. Writers are atomic (io/atomic_file.h), so a child that dies leaves no partial
/// output.
#include <functional>
#include <string>

namespace gimforge::cli {

/// Runs `work` in a forked child and returns its exit code. When the child dies of a signal (SIGSEGV,
/// SIGBUS, SIGABRT, ...), prints "gimforge: error: ARCHIVE: the HDF5 library crashed reading the archive
/// (signal N, NAME): it is damaged or crafted" and returns 1. Stdout and stderr are shared with the child.
/// `archive` names the file in that message. Call before any thread is started (TBB, MPI): fork copies
/// the calling thread only.
int run_guarded(const std::string& archive, const std::function<int()>& work);

}  // namespace gimforge::cli
