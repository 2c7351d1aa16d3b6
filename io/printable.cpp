#include "io/printable.h"

#include <array>
#include <cstdint>

namespace gimforge::io {
namespace {

/// Length of the valid UTF-8 sequence starting at text[i] (1..4), or 0 when the bytes there are not one
/// (overlong forms, surrogates and code points above U+10FFFF are invalid). Sets `code` to its code point.
std::size_t utf8_sequence(std::string_view text, std::size_t i, char32_t& code) {
  const auto byte = [&](std::size_t k) { return static_cast<std::uint8_t>(text[k]); };
  const std::uint8_t b0 = byte(i);
  if (b0 < 0x80) {
    code = b0;
    return 1;
  }
  std::size_t n = 0;
  char32_t min = 0;
  if ((b0 & 0xE0) == 0xC0) {
    n = 2, code = b0 & 0x1F, min = 0x80;
  } else if ((b0 & 0xF0) == 0xE0) {
    n = 3, code = b0 & 0x0F, min = 0x800;
  } else if ((b0 & 0xF8) == 0xF0) {
    n = 4, code = b0 & 0x07, min = 0x10000;
  } else {
    return 0;
  }
  if (i + n > text.size()) return 0;
  for (std::size_t k = 1; k < n; ++k) {
    const std::uint8_t b = byte(i + k);
    if ((b & 0xC0) != 0x80) return 0;
    code = (code << 6) | (b & 0x3F);
  }
  if (code < min || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return 0;
  return n;
}

bool is_control(char32_t c) { return c < 0x20 || c == 0x7F || (c >= 0x80 && c <= 0x9F); }

void append_hex(std::string& out, std::string_view prefix, unsigned value, int digits) {
  static constexpr std::array<char, 16> kHex{'0', '1', '2', '3', '4', '5', '6', '7',
                                             '8', '9', 'a', 'b', 'c', 'd', 'e', 'f'};
  out += prefix;
  for (int d = digits - 1; d >= 0; --d) out += kHex[(value >> (4 * d)) & 0xF];
}

}  // namespace

bool valid_utf8(std::string_view text) {
  for (std::size_t i = 0; i < text.size();) {
    char32_t code = 0;
    const std::size_t n = utf8_sequence(text, i, code);
    if (n == 0) return false;
    i += n;
  }
  return true;
}

std::string printable(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < text.size();) {
    char32_t code = 0;
    const std::size_t n = utf8_sequence(text, i, code);
    if (n == 0) {
      append_hex(out, "\\x", static_cast<std::uint8_t>(text[i]), 2);
      ++i;
      continue;
    }
    if (!is_control(code)) {
      out.append(text.substr(i, n));
    } else if (code == '\n') {
      out += "\\n";
    } else if (code == '\t') {
      out += "\\t";
    } else if (code == '\r') {
      out += "\\r";
    } else if (code == 0x1B) {
      out += "\\e";
    } else if (code < 0x80) {
      append_hex(out, "\\x", static_cast<unsigned>(code), 2);
    } else {
      append_hex(out, "\\u", static_cast<unsigned>(code), 4);
    }
    i += n;
  }
  return out;
}

bool has_unprintable(std::string_view text) {
  for (std::size_t i = 0; i < text.size();) {
    char32_t code = 0;
    const std::size_t n = utf8_sequence(text, i, code);
    if (n == 0 || is_control(code)) return true;
    i += n;
  }
  return false;
}

std::string path_component_problem(std::string_view name, bool limit_length) {
  if (name.empty()) return "is empty";
  if (name == "." || name == "..") return "is '" + std::string(name) + "'";
  if (name.find('/') != std::string_view::npos) return "contains '/'";
  if (has_unprintable(name)) return "contains a control character or invalid UTF-8";
  if (limit_length && name.size() > kMaxPathComponent)  // NAME_MAX of Linux file systems: the shards' folder is named so
    return "is " + std::to_string(name.size()) + " bytes long (a file name holds at most " +
           std::to_string(kMaxPathComponent) + ")";
  return {};
}

}  // namespace gimforge::io
