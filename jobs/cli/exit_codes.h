#pragma once
/// \file exit_codes.h
/// Process exit codes of the gimforge executable (documented in docs/cli.md).
namespace gimforge::cli {

inline constexpr int kExitOk = 0;       ///< success
inline constexpr int kExitError = 1;    ///< the command failed (bad input, I/O error, ...): one line on stderr says why
inline constexpr int kExitUsage = 2;    ///< the command line is wrong (unknown option, missing argument)
inline constexpr int kExitPartial = 3;  ///< a batch finished, but some items failed
inline constexpr int kExitResumable = 4;  ///< a batch stopped on SIGTERM/SIGUSR1 with its work committed: run it again with --resume

}  // namespace gimforge::cli
