#include "io/text_parse.h"

#include <algorithm>
#include <charconv>
#include <cstdlib>
#include <system_error>

#include <fmt/format.h>

namespace gimforge::io::detail {

LineReader::LineReader(std::string_view data, std::size_t offset, std::size_t first_line)
    : data_(data), pos_(std::min(offset, data.size())), line_no_(first_line - 1) {}

bool LineReader::next(std::string_view& line) {
  if (pos_ >= data_.size()) return false;
  std::size_t end = data_.find('\n', pos_);
  std::size_t next_pos = end + 1;
  if (end == std::string_view::npos) {
    end = data_.size();
    next_pos = end;
  }
  line = data_.substr(pos_, end - pos_);
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  pos_ = next_pos;
  ++line_no_;
  return true;
}

bool LineReader::next_content(std::string_view& line, char comment) {
  while (next(line)) {
    if (comment != '\0') line = strip_comment(line, comment);
    if (!trim(line).empty()) return true;
  }
  return false;
}

std::string_view strip_comment(std::string_view line, char comment) {
  const std::size_t at = line.find(comment);
  return at == std::string_view::npos ? line : line.substr(0, at);
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

void split_tokens(std::string_view line, std::vector<std::string_view>& out) {
  out.clear();
  std::size_t i = 0;
  const std::size_t n = line.size();
  while (i < n) {
    while (i < n && is_space(line[i])) ++i;
    const std::size_t start = i;
    while (i < n && !is_space(line[i])) ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
}

namespace {

std::string_view without_plus(std::string_view token) {
  if (token.size() > 1 && token.front() == '+' && token[1] != '-' && token[1] != '+') token.remove_prefix(1);
  return token;
}

}  // namespace

bool parse_int(std::string_view token, std::int64_t& out) {
  token = without_plus(token);
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, out);
  return ec == std::errc{} && ptr == end;
}

bool parse_double(std::string_view token, double& out) {
  token = without_plus(token);
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, out, std::chars_format::general);
  if (ptr != end || token.empty()) return false;
  if (ec == std::errc::result_out_of_range) {
    // from_chars leaves `out` untouched here; strtod gives +-inf for overflow and 0/denormal for underflow.
    const std::string copy(token);
    out = std::strtod(copy.c_str(), nullptr);
    return true;
  }
  return ec == std::errc{};
}

std::string quote_token(std::string_view token) {
  constexpr std::size_t kMax = 40;
  std::string s = "'";
  for (std::size_t i = 0; i < token.size() && i < kMax; ++i) {
    const auto c = static_cast<unsigned char>(token[i]);
    if (c >= 0x20 && c < 0x7f) {
      s += static_cast<char>(c);
    } else {
      s += fmt::format("\\x{:02x}", c);
    }
  }
  if (token.size() > kMax) s += "...";
  s += '\'';
  return s;
}

std::optional<std::size_t> find_binary_byte(std::string_view data, std::size_t limit) {
  const std::size_t n = std::min(limit, data.size());
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(data[i]);
    const bool text_control = c >= 0x09 && c <= 0x0d;  // \t \n \v \f \r
    if ((c < 0x20 && !text_control) || c == 0x7f) return i;
  }
  return std::nullopt;
}

}  // namespace gimforge::io::detail
