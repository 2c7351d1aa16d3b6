#pragma once
/// \file crash_guard.h
/// Archives are other people's files, and the HDF5 library (Debian 12: 1.10.8) itself crashes on some
/// crafted files — inside its own metadata decoders, before gimforge sees any value (tests/fuzz/crashes/).
/// gimforge checks everything it reads, but cannot check what HDF5 decodes for it. So the commands that read
/// archives run their work in a child process: a crash there becomes one error line naming the archive and
/// exit 1, never a signal. HDF5 also loops forever on some crafted files: in the child every HDF5 metadata
/// call is bounded (h5::set_call_deadline: 30 s, GIMFORGE_HDF5_CALL_SECONDS), and one that does not return
/// in time is the error "ARCHIVE: the HDF5 library did not return within N s reading the archive: it is
/// damaged or crafted". Writers are atomic (io/atomic_file.h), so a child that dies leaves no partial
/// output.
#include <filesystem>
#include <functional>
#include <map>
#include <string>

#include "jobs/cli/commands.h"

namespace gimforge::cli {

/// Runs a parsed command (`dispatch`) as every command runs: logging set up and the thread limit taken from
/// `global`; its errors as one line (`subject`, the file the command reads, names what an out-of-memory
/// error is about); SIGINT/SIGTERM/SIGHUP clean-up (install_signal_cleanup); in a forked child when it only
/// reads `archive` (run_guarded; "" when it does not); and the process ended with std::_Exit when an HDF5
/// file failed to close (h5::file_close_failed). Returns the exit code.
int run_command(const std::string& archive, const std::string& subject, const GlobalOptions& global,
                const std::function<int()>& dispatch);

/// Makes SIGINT, SIGTERM and SIGHUP (unless ignored, as under nohup) delete the temporary files of this
/// process's writes (io::remove_pending_temporaries), pass the signal on to a run_guarded child, and then
/// end the process as the signal would have: an interrupted command leaves neither a temporary file of its
/// output nor a child that goes on writing it. (batch replaces the handlers of SIGINT and SIGTERM with its
/// own graceful stop while it runs.) Call once, before any child or thread starts.
void install_signal_cleanup();

/// Runs `work` in a forked child and returns its exit code. The child's stderr reaches the terminal through
/// the parent, one line behind, so that a crash is one line: the child's last line is dropped when it dies
/// of a signal and is not gimforge's own (glibc's "malloc(): corrupted ..." before an abort). When the child dies of a signal (SIGSEGV,
/// SIGBUS, SIGABRT, ...), prints "gimforge: error: ARCHIVE: the HDF5 library crashed reading the archive
/// (signal N, NAME): it is damaged or crafted" and returns 1. Stdout and stderr are shared with the child.
/// `archive` names the file in that message. The child dies with its parent (PR_SET_PDEATHSIG: SIGTERM,
/// even when the parent is killed with SIGKILL), so that a killed command writes nothing afterwards. Call
/// before any thread is started (TBB, MPI): fork copies the calling thread only.
int run_guarded(const std::string& archive, const std::function<int()>& work);

/// For commands that read an archive in a process that goes on to do long work (convert appending to an
/// archive, --sphere-map): reads everything the archive's readers read — the listing and every geometry
/// image, spherical image and relief map in full — in a forked child first. Returns when all of it reads;
/// throws the reader's error (FormatError, IoError, ...) as a FormatError with the same one-line message,
/// or FormatError "ARCHIVE: the HDF5 library crashed reading the archive (signal N, NAME): it is damaged or
/// crafted" when the child dies of a signal. Call before any thread is started.
void probe_archive(const std::string& archive);

/// For `batch --resume`, before MPI starts (forking an MPI process is not safe): reads every shard file
/// under WORK_DIR/shards (*.h5, as io::read_shard_fully: what the resume check and the merge read) in
/// forked children, each HDF5 metadata call bounded. Returns the shards that do not read — damaged, or
/// crashing or hanging HDF5 — as path relative to WORK_DIR ("shards/OUTPUT/INDEX.h5") → one-line reason;
/// the batch redoes their items instead of reading them in its own process. A child that dies is
/// replaced by a new one that goes on after the shard it died on. Call before any thread is started.
[[nodiscard]] std::map<std::string, std::string> probe_shards(const std::filesystem::path& work_dir);

}  // namespace gimforge::cli
