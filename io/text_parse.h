#pragma once
/// \file text_parse.h
/// Internal to gimforge_io: the line reader, whitespace tokenizer and strict number parsing shared by the
/// text formats (ASCII PLY, OBJ, OFF, ASCII STL). Nothing here throws; callers turn a failed parse into a
/// FormatError that names the path, the line and the offending token.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace gimforge::io::detail {

/// Iterates over the lines of a buffer. A line ends at '\n' (a '\r' before it is dropped); the last line
/// may lack its '\n'. Lines are views into the buffer: no copies.
class LineReader {
 public:
  /// Reads `data` from byte `offset`; the first line returned is numbered `first_line` (1-based).
  explicit LineReader(std::string_view data, std::size_t offset = 0, std::size_t first_line = 1);

  /// Stores the next line in `line` and returns true, or returns false at the end of the data.
  bool next(std::string_view& line);

  /// Like next(), but skips lines that are blank once a `comment` character and what follows it are cut
  /// off (comment '\0': no comments). The returned line has its comment removed.
  bool next_content(std::string_view& line, char comment = '\0');

  /// Number of the line returned by the last next() (first_line - 1 before the first call).
  [[nodiscard]] std::size_t line_number() const { return line_no_; }

  /// Byte offset where the next line starts (just past the '\n' of the last line returned).
  [[nodiscard]] std::size_t offset() const { return pos_; }

 private:
  std::string_view data_;
  std::size_t pos_;
  std::size_t line_no_;
};

/// True for the whitespace characters that separate tokens: space, \t, \r, \f, \v.
[[nodiscard]] constexpr bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

/// `line` with everything from the first `comment` character on removed.
[[nodiscard]] std::string_view strip_comment(std::string_view line, char comment);

/// `s` without leading and trailing whitespace.
[[nodiscard]] std::string_view trim(std::string_view s);

/// Splits `line` at whitespace into `out` (cleared first; its capacity is reused).
void split_tokens(std::string_view line, std::vector<std::string_view>& out);

/// Parses a whole token as a decimal integer (optional '+' or '-'). False if the token is not exactly one
/// integer or does not fit in int64.
[[nodiscard]] bool parse_int(std::string_view token, std::int64_t& out);

/// Parses a whole token as a decimal floating-point number (optional '+'; "inf" and "nan" are accepted so
/// the caller can report them as non-finite; values too large for a double become +-inf). False if the
/// token is not exactly one number.
[[nodiscard]] bool parse_double(std::string_view token, double& out);

/// The token in single quotes for a message: at most 40 characters, bytes outside printable ASCII shown as
/// \xNN, so the message stays one printable line.
[[nodiscard]] std::string quote_token(std::string_view token);

/// Offset of the first byte that text files do not contain (control characters other than \t \n \v \f \r,
/// and DEL), looking at the first `limit` bytes; nullopt if there is none.
[[nodiscard]] std::optional<std::size_t> find_binary_byte(std::string_view data,
                                                          std::size_t limit = std::string_view::npos);

}  // namespace gimforge::io::detail
