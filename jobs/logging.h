#pragma once
/// \file logging.h
/// Process-wide logging for the executable: one stderr logger whose lines read "gimforge: <level>: <text>".
#include <string>

namespace gimforge::jobs {

/// Installs the stderr logger with the given level ("trace", "debug", "info", "warn", "error", "off").
/// Throws InvalidInput for an unknown level name.
void setup_logging(const std::string& level);

/// True when stderr is a terminal (progress bars are drawn only then).
[[nodiscard]] bool stderr_is_terminal();

}  // namespace gimforge::jobs
