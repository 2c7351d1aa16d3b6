#pragma once
/// \file printable.h
/// Text that came from outside (file names, item names and labels read from archives or job files) is
/// untrusted: a name can hold terminal escape sequences or newlines that forge log lines. Everything
/// gimforge prints passes such text through printable(); text that becomes part of a path goes through
/// check_path_component(). See docs/cli.md, "Names".
#include <string>
#include <string_view>

namespace gimforge::io {

/// `text` with every C0 control character (U+0000–U+001F), DEL (U+007F) and C1 control character
/// (U+0080–U+009F, which some terminals read as CSI) written as a visible escape — `\n`, `\t`, `\r`,
/// `\e` for ESC, else `\xNN` / `\u00NN` — and every byte that is not part of valid UTF-8 as `\xNN`.
/// Valid printable UTF-8 (accents, CJK, ...) is kept as it is. Idempotent on its own output.
[[nodiscard]] std::string printable(std::string_view text);

/// True when `text` is valid UTF-8 (what JSON and the archive's UTF-8 strings can hold).
[[nodiscard]] bool valid_utf8(std::string_view text);

/// True when `text` holds a character printable() would escape (a control character or invalid UTF-8).
[[nodiscard]] bool has_unprintable(std::string_view text);

/// The longest file-name component, in bytes (NAME_MAX of Linux file systems).
inline constexpr std::size_t kMaxPathComponent = 255;

/// Why `name` cannot be one component of a file name, or empty when it can: empty, "." or "..", a '/',
/// a NUL, a control character, invalid UTF-8 or (with `limit_length`: a name about to be written, not one an
/// archive already holds) more than kMaxPathComponent bytes are refused. Callers wrap the reason in their own
/// message ("job.toml: output name '..' ...").
[[nodiscard]] std::string path_component_problem(std::string_view name, bool limit_length = true);

}  // namespace gimforge::io
