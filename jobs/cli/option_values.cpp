#include "jobs/cli/option_values.h"

#include <algorithm>
#include <charconv>
#include <cstdint>
#include <limits>
#include <system_error>

#include <fmt/format.h>

namespace gimforge::cli {

std::string integer_value_error(std::string_view text, bool is_unsigned) {
  const std::string quoted = fmt::format("'{}'", text);
  std::string_view v = text;
  if (is_unsigned && v.starts_with('-')) return quoted + " is negative";
  if (v.starts_with('-') || v.starts_with('+')) v.remove_prefix(1);
  const bool digits = !v.empty() && std::all_of(v.begin(), v.end(), [](char ch) { return ch >= '0' && ch <= '9'; });
  if (!digits || (v.size() > 1 && v.front() == '0')) return quoted + " is not a decimal integer";
  std::uint64_t value = 0;
  const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), value);
  const auto limit = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max()) + (text.starts_with('-') ? 1u : 0u);
  if (ec != std::errc{} || end != v.data() + v.size() || (!is_unsigned && value > limit)) return quoted + " is out of range";
  return {};
}

std::string name_value_error(std::string_view text) { return text.empty() ? "an empty name names nothing" : ""; }

}  // namespace gimforge::cli
