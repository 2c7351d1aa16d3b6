#pragma once
/// \file logging.h
/// Process-wide logging for the executable: one stderr logger whose lines read "gimforge: <level>: <text>".
#include <string>

namespace gimforge::jobs {

/// Installs the stderr logger with the given level ("trace", "debug", "info", "warn", "error", "off").
/// Throws InvalidInput for an unknown level name.
void setup_logging(const std::string& level);

/// Also writes log lines down to debug level, with a time stamp and "rank R", to `path` (appending), e.g.
/// one file per MPI rank; stderr keeps its level. Throws IoError naming the file when it cannot be opened.
void add_log_file(const std::string& path, int rank);

/// True when stderr is a terminal (progress bars are drawn only then).
[[nodiscard]] bool stderr_is_terminal();
/// Overrides what stderr_is_terminal answers: for a child process whose stderr its parent relays
/// (jobs/cli/crash_guard.h) while the parent's stderr is a terminal.
void set_stderr_is_terminal(bool terminal);

}  // namespace gimforge::jobs
